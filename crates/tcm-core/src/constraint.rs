//! Synchronisation constraints (TDL paper, Figure 5; catalogue §1.4 and §7).
//!
//! A [`Constraint`] is given when a node is spawned, or later through `Engine::constrain`. Shorthands
//! (`sequential`, `serial`, `parallel`) are kept as written so the trace shows what the user said;
//! the engine lowers them to enablement waits:
//!
//! - `sequential F of X` = disable F until X's F completed (handling: X's handling completed);
//! - `serial X` = disable expansion and execution until X's execution completed;
//! - `parallel` = nothing.

use crate::ids::{ExternalId, NodeId};
use std::time::Duration;
use tcm_trace::{Facet, Point};

use crate::time::Time;

/// Which node a constraint refers to. Relative references are resolved when the constraint is applied.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NodeRef {
    /// A node handle (possibly reserved for a later spawn: a forward reference).
    Node(NodeId),
    /// The node spawned by the same parent just before this one; none means the constraint is void.
    Previous,
    /// The node being constrained itself (TDL `self` / `child`).
    This,
    /// The parent of the node being constrained (TDL `parent` / `this`).
    Parent,
}

impl From<NodeId> for NodeRef {
    fn from(id: NodeId) -> NodeRef {
        NodeRef::Node(id)
    }
}

/// A state transition of a node's facet: `X [facet] (enabled|active|completed)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Event {
    /// The node whose facet is watched.
    pub node: NodeRef,
    /// The facet watched.
    pub facet: Facet,
    /// The state it must reach.
    pub point: Point,
}

impl Event {
    /// An event with TDL's default facet: `enabled`/`active` mean the handling, `completed` the
    /// execution (the node and its whole subtree done), catalogue §1.6.
    pub fn new(node: impl Into<NodeRef>, point: Point) -> Event {
        let facet = match point {
            Point::Completed => Facet::Execution,
            Point::Enabled | Point::Active => Facet::Handling,
        };
        Event {
            node: node.into(),
            facet,
            point,
        }
    }

    /// An event on an explicit facet.
    pub fn on(node: impl Into<NodeRef>, facet: Facet, point: Point) -> Event {
        Event {
            node: node.into(),
            facet,
            point,
        }
    }
}

/// What a `disable … until` waits for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Until {
    /// A state transition of some node.
    Event(Event),
    /// An absolute time.
    Time(Time),
    /// A duration from when the constraint is applied.
    For(Duration),
    /// A duration after an event happens.
    ForAfter(Duration, Event),
    /// A named external event or manual signal gate (latched: once raised, it stays raised).
    External(ExternalId),
}

/// When a `terminate` constraint fires.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TerminateWhen {
    /// At once.
    Now,
    /// When an event happens; never if the event's node is itself terminated first.
    Event(Event),
    /// At an absolute time.
    Time(Time),
    /// A duration from when the constraint is applied.
    In(Duration),
    /// A duration after an event happens.
    InAfter(Duration, Event),
    /// When a named external event is raised.
    External(ExternalId),
}

/// When an `activate` constraint activates a monitor (catalogue §1.4, monitors only).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ActivateWhen {
    /// As soon as the monitor's handling is active.
    Now,
    /// When an event happens (also when its node reached it by being terminated).
    Event(Event),
    /// At an absolute time.
    Time(Time),
    /// A duration from when the constraint is applied.
    In(Duration),
    /// A duration after an event happens.
    InAfter(Duration, Event),
    /// Every time a named external event is raised.
    External(ExternalId),
}

/// A synchronisation constraint on one node.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Constraint {
    /// The execution may not start until the expansion completed (TCM `PLAN_FIRST`).
    ExpandFirst,
    /// The expansion may not start until the execution is enabled (TCM `DELAY_PLANNING`).
    DelayExpansion,
    /// `sequential <facet> <ref>`: the facet waits for the referenced node's same facet to complete.
    Sequential(Facet, NodeRef),
    /// `serial <ref>`: expansion and execution wait for the referenced node's execution to complete.
    Serial(NodeRef),
    /// `parallel`: no constraint.
    Parallel,
    /// `disable <facet> until …`.
    Disable(Facet, Until),
    /// `terminate …`.
    Terminate(TerminateWhen),
    /// `activate …` (monitors only).
    Activate(ActivateWhen),
}

impl Constraint {
    /// `sequential execution previous`, the most common form.
    pub fn sequential_previous() -> Constraint {
        Constraint::Sequential(Facet::Execution, NodeRef::Previous)
    }

    /// Whether this constraint may still be applied to a node whose handling has started.
    pub fn applies_after_start(&self) -> bool {
        matches!(
            self,
            Constraint::Terminate(_) | Constraint::Activate(_) | Constraint::Parallel
        )
    }
}
