//! Trace events: one record per state transition and per decision the engine takes.
//!
//! This is the project's observable contract. The JSON-lines sink writes one [`TraceEvent`] per line
//! (schema in `docs/trace-format.md`, version [`TRACE_FORMAT_VERSION`]); the TCM text log, the tree
//! dump, the trace checker and the tests all read these records. Nodes are named by their display
//! number (`{id}` in TCM's log): creation order, 0 for the root, never reused within a run.

use crate::state::{Facet, NodeKind, Point, State};
use serde::{Deserialize, Serialize};

/// Version of the trace schema; bumped on any incompatible change.
pub const TRACE_FORMAT_VERSION: u32 = 1;

/// One trace record.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct TraceEvent {
    /// Position in the trace, from 0, without gaps.
    pub seq: u64,
    /// Virtual time in nanoseconds since the run started.
    pub t: u64,
    /// What happened.
    #[serde(flatten)]
    pub kind: TraceKind,
}

/// A reference to a node's facet reaching a state, as recorded in the trace.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct TraceEventRef {
    /// Display number of the node.
    pub node: u64,
    /// The facet.
    pub facet: Facet,
    /// The state reached.
    pub point: Point,
}

/// A constraint as applied, with every relative reference resolved and every relative time made
/// absolute (nanoseconds since the run started).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "form", rename_all = "snake_case")]
pub enum TraceConstraint {
    /// Execution waits for expansion completed.
    ExpandFirst,
    /// Expansion waits for execution enabled.
    DelayExpansion,
    /// `facet` may not become enabled before `event` happened.
    DisableUntilEvent {
        /// Constrained facet.
        facet: Facet,
        /// Awaited event.
        event: TraceEventRef,
    },
    /// `facet` may not become enabled before time `at`.
    DisableUntilTime {
        /// Constrained facet.
        facet: Facet,
        /// Absolute time (ns).
        at: u64,
    },
    /// `facet` may not become enabled before `delay_ns` after `event`.
    DisableForAfter {
        /// Constrained facet.
        facet: Facet,
        /// Delay (ns).
        delay_ns: u64,
        /// Event the delay counts from.
        event: TraceEventRef,
    },
    /// `facet` may not become enabled before the external event is raised.
    DisableUntilExternal {
        /// Constrained facet.
        facet: Facet,
        /// Name of the external event.
        name: String,
    },
    /// Terminate at once.
    TerminateNow,
    /// Terminate when `event` happens (not if its node is terminated first).
    TerminateAtEvent {
        /// Triggering event.
        event: TraceEventRef,
    },
    /// Terminate at time `at` (ns).
    TerminateAtTime {
        /// Absolute time (ns).
        at: u64,
    },
    /// Terminate `delay_ns` after `event`.
    TerminateInAfter {
        /// Delay (ns).
        delay_ns: u64,
        /// Event the delay counts from.
        event: TraceEventRef,
    },
    /// Terminate when the external event is raised.
    TerminateAtExternal {
        /// Name of the external event.
        name: String,
    },
    /// Activate the monitor as soon as its handling is active.
    ActivateNow,
    /// Activate the monitor when `event` happens (also by termination).
    ActivateAtEvent {
        /// Triggering event.
        event: TraceEventRef,
    },
    /// Activate the monitor at time `at` (ns).
    ActivateAtTime {
        /// Absolute time (ns).
        at: u64,
    },
    /// Activate the monitor `delay_ns` after `event`.
    ActivateInAfter {
        /// Delay (ns).
        delay_ns: u64,
        /// Event the delay counts from.
        event: TraceEventRef,
    },
    /// Activate the monitor every time the external event is raised.
    ActivateAtExternal {
        /// Name of the external event.
        name: String,
    },
}

/// The body of a trace record.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "ev", rename_all = "snake_case")]
pub enum TraceKind {
    /// A run started; the root node has number 0.
    RunStarted {
        /// Trace schema version.
        version: u32,
        /// The run's number.
        run: u32,
    },
    /// A node number was reserved for a later spawn (a forward reference).
    Reserved {
        /// Display number.
        node: u64,
        /// Parent's display number.
        parent: u64,
        /// Name the reservation was made under.
        name: String,
    },
    /// A node was inserted into the tree (all facets disabled, or expansion completed for commands).
    Spawned {
        /// Display number.
        node: u64,
        /// Parent's display number.
        parent: u64,
        /// Kind of node.
        kind: NodeKind,
        /// Instance name.
        name: String,
    },
    /// A constraint was applied to a node.
    Constrained {
        /// Constrained node.
        node: u64,
        /// The constraint, resolved.
        constraint: TraceConstraint,
    },
    /// A constraint was dropped: its reference was void (no previous node) or its node never spawned.
    ConstraintVoid {
        /// Constrained node.
        node: u64,
        /// Why.
        reason: String,
    },
    /// A facet changed state.
    Transition {
        /// Node.
        node: u64,
        /// Facet.
        facet: Facet,
        /// Old state.
        from: State,
        /// New state.
        to: State,
    },
    /// The node was asked to terminate (Alive -> Terminating).
    Terminating {
        /// Node.
        node: u64,
    },
    /// The node and its subtree are terminated (Terminating -> Terminated).
    Terminated {
        /// Node.
        node: u64,
    },
    /// The node (and its subtree) was suspended.
    Suspended {
        /// Node.
        node: u64,
    },
    /// The node (and its subtree) was unsuspended.
    Unsuspended {
        /// Node.
        node: u64,
    },
    /// The node's action failed.
    Failed {
        /// Node.
        node: u64,
        /// Exception type name.
        exception: String,
        /// Human-readable message.
        message: String,
    },
    /// A reserved node was never spawned: its parent's body ended without spawning it.
    Dead {
        /// Node.
        node: u64,
    },
    /// A named external event was raised.
    External {
        /// Name of the event.
        name: String,
    },
    /// A completed (or terminated) node was reclaimed; its number is never used again.
    Reclaimed {
        /// Node.
        node: u64,
    },
    /// A monitor's parameters; right after its `spawned` record.
    MonitorParams {
        /// The monitor.
        node: u64,
        /// Maximum activations, if any.
        max_activations: Option<u32>,
        /// Maximum triggers, if any.
        max_triggers: Option<u32>,
        /// Polling period (ns), if polling.
        period_ns: Option<u64>,
        /// Whether the polling activation at start is skipped.
        initial_wait: bool,
    },
    /// A monitor was activated: `node` is the new activation node (its `spawned` record precedes).
    Activated {
        /// The monitor.
        monitor: u64,
        /// The activation node.
        node: u64,
        /// Activation number, from 1.
        number: u32,
    },
    /// A monitor counted a trigger.
    Triggered {
        /// The monitor.
        monitor: u64,
        /// Triggers so far.
        count: u32,
    },
    /// A handler was chosen for a failure: `node` is the new handler node (its `spawned` record
    /// precedes).
    HandlerChosen {
        /// The handler node.
        node: u64,
        /// The node whose action failed.
        failing: u64,
        /// The node the handler was attached to.
        attached: u64,
        /// The exception type.
        exception: String,
        /// The handler's name.
        handler: String,
    },
    /// A handler node passed its exception on.
    Bypassed {
        /// The bypassing handler node.
        node: u64,
        /// The exception type.
        exception: String,
    },
    /// A handler asked for a fresh run of a failed task: `node` is the new node.
    Retried {
        /// The new node.
        node: u64,
        /// The node that failed.
        of: u64,
    },
    /// A wiretap check started on a node.
    Tapped {
        /// The tapped node.
        node: u64,
        /// The wiretap's number.
        tap: u32,
        /// `before` (the action has not started) or `after` (it returned successfully).
        when: String,
    },
    /// Something worth a person's attention; the run goes on.
    Warning {
        /// Node concerned, if any.
        node: Option<u64>,
        /// Message.
        message: String,
    },
}

impl TraceKind {
    /// The node this record is about, if any.
    pub fn node(&self) -> Option<u64> {
        match self {
            TraceKind::RunStarted { .. } | TraceKind::External { .. } => None,
            TraceKind::Warning { node, .. } => *node,
            TraceKind::Reserved { node, .. }
            | TraceKind::Spawned { node, .. }
            | TraceKind::Constrained { node, .. }
            | TraceKind::ConstraintVoid { node, .. }
            | TraceKind::Transition { node, .. }
            | TraceKind::Terminating { node }
            | TraceKind::Terminated { node }
            | TraceKind::Suspended { node }
            | TraceKind::Unsuspended { node }
            | TraceKind::Failed { node, .. }
            | TraceKind::Dead { node }
            | TraceKind::Reclaimed { node }
            | TraceKind::MonitorParams { node, .. }
            | TraceKind::Activated { node, .. }
            | TraceKind::HandlerChosen { node, .. }
            | TraceKind::Bypassed { node, .. }
            | TraceKind::Retried { node, .. }
            | TraceKind::Tapped { node, .. } => Some(*node),
            TraceKind::Triggered { monitor, .. } => Some(*monitor),
        }
    }
}
