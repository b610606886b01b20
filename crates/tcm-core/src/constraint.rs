//! Synchronisation constraints (TDL paper, Figure 5; docs/semantics.md, "Constraints").
//!
//! A [`Constraint`] is given when a node is spawned, or later through `Engine::constrain`. Shorthands
//! (`sequential`, `serial`, `parallel`) are kept as written so the trace shows what the user said;
//! the engine lowers them to enablement waits:
//!
//! - `sequential F of X` = disable F until X's F completed (handling: X's handling completed);
//! - `serial X` = disable expansion and execution until X's execution completed;
//! - `parallel` = nothing.

use crate::ids::{CondId, ExternalId, NodeId, StateId};
use std::time::Duration;
use tcm_trace::{Facet, Outcome, Point};

use crate::time::Time;

/// Which node a constraint refers to. Relative references are resolved when the constraint is applied.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NodeRef {
    /// A node handle (possibly reserved for a later spawn: a forward reference).
    Node(NodeId),
    /// The node spawned by the same parent just before this one. If there is none, a constraint
    /// on its event is void, and `After(d, previous …)` keeps its delay, counted from when it is
    /// applied (TDL drops the `after` part).
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
    /// For an outcome event (`X succeeded`, `X failed`, `X terminated`): the execution's
    /// completion counts only with this outcome; with another the event never happens, and an
    /// enablement waiting for it terminates its node (docs/semantics.md, "Outcomes").
    pub outcome: Option<Outcome>,
}

impl Event {
    /// An event with TDL's default facet: `enabled`/`active` mean the handling, `completed` the
    /// execution (the node and its whole subtree done); docs/semantics.md, "Events".
    pub fn new(node: impl Into<NodeRef>, point: Point) -> Event {
        let facet = match point {
            Point::Completed => Facet::Execution,
            Point::Enabled | Point::Active => Facet::Handling,
        };
        Event {
            node: node.into(),
            facet,
            point,
            outcome: None,
        }
    }

    /// An event on an explicit facet.
    pub fn on(node: impl Into<NodeRef>, facet: Facet, point: Point) -> Event {
        Event {
            node: node.into(),
            facet,
            point,
            outcome: None,
        }
    }

    /// An outcome event: the node's execution completed with `outcome` (`X failed`).
    pub fn ended(node: impl Into<NodeRef>, outcome: Outcome) -> Event {
        Event {
            node: node.into(),
            facet: Facet::Execution,
            point: Point::Completed,
            outcome: Some(outcome),
        }
    }
}

/// When a trigger fires: the one "when" of every timed or event-driven constraint.
///
/// `disable F until …`, `terminate …` and `activate …` differ only in what they do then ([`Then`]);
/// the engine arms all of them by one code path (`engine/arm.rs`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum When {
    /// At once (for `activate`: as soon as the monitor's handling is active).
    Now,
    /// At an absolute time.
    At(Time),
    /// A duration from when the constraint is applied (`disable for`, `terminate in`, `activate in`).
    In(Duration),
    /// When a node's facet reaches a state.
    Event(Event),
    /// A duration after a node's facet reaches a state.
    After(Duration, Event),
    /// When a named external event is raised. Enabling and terminating are latched (a raise before
    /// the constraint counts); activation happens on every raise after it.
    External(ExternalId),
    /// When a condition over state variables holds (`Engine::condition`). Enabling and
    /// terminating fire once it is true (at once if it already is); activation each time it
    /// becomes true; [`Then::Skip`], [`Then::Invariant`] and [`Then::Pause`] read it at their own
    /// moments (docs/semantics.md, "State and conditions").
    Condition(CondId),
    /// Each time a state variable changes value (`activate on change of v`; monitors only).
    Changed(StateId),
}

impl When {
    /// The event this waits for, if any.
    pub fn event(&self) -> Option<Event> {
        match *self {
            When::Event(e) | When::After(_, e) => Some(e),
            _ => None,
        }
    }
}

/// What a trigger does when it fires.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Then {
    /// Satisfies one enablement constraint of the facet: `disable <facet> until <when>`.
    Enable(Facet),
    /// Terminates the node and its subtree: `terminate <when>`. Never fires if the event's node
    /// reaches the event by being terminated itself (docs/semantics.md, "Termination").
    Terminate,
    /// Activates the monitor: `activate <when>` (monitors only). Fires also when the event's node
    /// reaches the event by termination.
    Activate,
    /// As [`Then::Activate`], the activation carrying the data the monitor keeps at this index
    /// (TCM's `TCM_ActivateAt(monitor, event, data)`). Made by [`crate::Engine::activate_when`],
    /// which keeps the data; a constraint written with it otherwise is void.
    ActivateWith(u16),
    /// `skip if <condition>`: when the node's turn comes (it would start), it completes without
    /// running if the condition holds; its outcome is `skipped`.
    Skip,
    /// `with invariant <condition>`: the node fails with `InvariantFailed` when the condition is
    /// false while it runs (from its handling's activation to its execution's completion).
    Invariant,
    /// `pause while <condition>`: the node's subtree is suspended while the condition holds.
    Pause,
}

/// The constraints of one spawn, kept inline up to two (most spawns carry none, one or two), so a
/// spawn allocates nothing for them.
pub type Constraints = smallvec::SmallVec<[Constraint; 2]>;

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
    /// When something happens, do something: `disable … until`, `terminate …`, `activate …`.
    Trigger(When, Then),
    /// `with approval [within T]`: held at its turn to start until an operator approves it;
    /// refused, or not approved within the time, it fails with [`crate::ApprovalRefused`]
    /// (docs/semantics.md, "Steering a run", rule 5). No `constrained` record: its `held` record
    /// says it when its turn comes.
    Approval(Option<std::time::Duration>),
}

impl Then {
    /// Whether it activates a monitor ([`Then::Activate`] or [`Then::ActivateWith`]).
    pub fn activates(self) -> bool {
        matches!(self, Then::Activate | Then::ActivateWith(_))
    }
}

impl Constraint {
    /// `sequential execution previous`, the most common form.
    pub fn sequential_previous() -> Constraint {
        Constraint::Sequential(Facet::Execution, NodeRef::Previous)
    }

    /// `disable <facet> until <when>`.
    pub fn disable(facet: Facet, when: When) -> Constraint {
        Constraint::Trigger(when, Then::Enable(facet))
    }

    /// `terminate <when>`.
    pub fn terminate(when: When) -> Constraint {
        Constraint::Trigger(when, Then::Terminate)
    }

    /// `activate <when>` (monitors only).
    pub fn activate(when: When) -> Constraint {
        Constraint::Trigger(when, Then::Activate)
    }

    /// `skip if <condition>`.
    pub fn skip_if(cond: CondId) -> Constraint {
        Constraint::Trigger(When::Condition(cond), Then::Skip)
    }

    /// `with invariant <condition>`.
    pub fn invariant(cond: CondId) -> Constraint {
        Constraint::Trigger(When::Condition(cond), Then::Invariant)
    }

    /// `pause while <condition>`.
    pub fn pause_while(cond: CondId) -> Constraint {
        Constraint::Trigger(When::Condition(cond), Then::Pause)
    }

    /// Whether this constraint may still be applied to a node whose handling has started.
    pub fn applies_after_start(&self) -> bool {
        matches!(
            self,
            Constraint::Trigger(
                _,
                Then::Terminate
                    | Then::Activate
                    | Then::ActivateWith(_)
                    | Then::Invariant
                    | Then::Pause
            ) | Constraint::Parallel
        )
    }

    /// Whether it is applied after the node is linked under its parent (terminate, activate and
    /// pause forms may act at once, which needs the node in the tree).
    pub(crate) fn applies_after_link(&self) -> bool {
        matches!(
            self,
            Constraint::Trigger(
                _,
                Then::Terminate
                    | Then::Activate
                    | Then::ActivateWith(_)
                    | Then::Invariant
                    | Then::Pause
            )
        )
    }
}
