//! The state model of a task-tree node: three facets and termination (TDL paper, Figure 3).
//!
//! Every node has a *handling* (its own action), an *expansion* (the goal nodes of its subtree) and an
//! *execution* (every node of its subtree). Each facet moves forward only, through
//! disabled, enabled, active and completed. Termination is a fourth, separate state.

use serde::{Deserialize, Serialize};
use std::fmt;

/// One of the three facets of a node.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "snake_case")]
pub enum Facet {
    /// The node's own action.
    Handling,
    /// The aggregate of the goal nodes in the subtree (TCM's "planning").
    Expansion,
    /// The aggregate of all nodes in the subtree (TCM's "achieving").
    Execution,
}

impl Facet {
    /// All facets, in index order.
    pub const ALL: [Facet; 3] = [Facet::Handling, Facet::Expansion, Facet::Execution];

    /// Index of the facet in per-facet arrays: handling 0, expansion 1, execution 2.
    pub fn index(self) -> usize {
        self as usize
    }

    /// The word used in TDL and in the trace.
    pub fn as_str(self) -> &'static str {
        match self {
            Facet::Handling => "handling",
            Facet::Expansion => "expansion",
            Facet::Execution => "execution",
        }
    }
}

impl fmt::Display for Facet {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// The state of one facet. States are ordered; a facet only moves forward.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "snake_case")]
pub enum State {
    /// Some enablement constraint does not hold yet.
    Disabled,
    /// All enablement constraints hold; the work has not started.
    Enabled,
    /// The work has started.
    Active,
    /// The work is done.
    Completed,
}

impl State {
    /// The word used in TDL and in the trace.
    pub fn as_str(self) -> &'static str {
        match self {
            State::Disabled => "disabled",
            State::Enabled => "enabled",
            State::Active => "active",
            State::Completed => "completed",
        }
    }
}

impl fmt::Display for State {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// How a node ended, decided when its execution completes: the outcome events `X succeeded`,
/// `X failed` and `X terminated` (docs/semantics.md, "Outcomes").
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// Its action succeeded, or a retry of it did.
    Succeeded,
    /// Its action failed and no retry of it succeeded (whether a handler took the failure or not).
    Failed,
    /// It was terminated.
    Terminated,
    /// It was skipped: its `skip if` condition held when its turn came, and it completed without
    /// running (docs/semantics.md, "State and conditions").
    Skipped,
}

impl Outcome {
    /// The word used in TDL and in the trace.
    pub fn as_str(self) -> &'static str {
        match self {
            Outcome::Succeeded => "succeeded",
            Outcome::Failed => "failed",
            Outcome::Terminated => "terminated",
            Outcome::Skipped => "skipped",
        }
    }
}

/// A state that an event waits for: the point at which a facet reaches it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "snake_case")]
pub enum Point {
    /// The facet became enabled.
    Enabled,
    /// The facet's work started.
    Active,
    /// The facet completed.
    Completed,
}

impl Point {
    /// The facet state this point is reached at.
    pub fn state(self) -> State {
        match self {
            Point::Enabled => State::Enabled,
            Point::Active => State::Active,
            Point::Completed => State::Completed,
        }
    }

    /// The word used in TDL and in the trace.
    pub fn as_str(self) -> &'static str {
        self.state().as_str()
    }
}

/// Termination state of a node.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Termination {
    /// Not asked to terminate.
    Alive,
    /// Asked to terminate; waiting for its subtree to wind down.
    Terminating,
    /// Terminated: the node and its subtree are done.
    Terminated,
}

/// The kind of a node.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "snake_case")]
pub enum NodeKind {
    /// The invisible root of a run.
    Root,
    /// A node whose action expands the tree (spawns children).
    Goal,
    /// An executable behaviour, typically a leaf.
    Command,
    /// A node whose action runs once per activation (monitor issue).
    Monitor,
    /// An exception-handler node (exceptions issue).
    Handler,
}

impl NodeKind {
    /// Whether the node's handling is part of its expansion (goal-like) rather than its execution.
    pub fn expands(self) -> bool {
        matches!(self, NodeKind::Goal | NodeKind::Handler)
    }

    /// The class word of TCM's text log.
    pub fn tcm_class(self) -> &'static str {
        match self {
            NodeKind::Root => "Node",
            NodeKind::Goal | NodeKind::Handler => "Goal",
            NodeKind::Command => "Command",
            NodeKind::Monitor => "Monitor",
        }
    }
}
