//! Trace events: one record per state transition and per decision the engine takes.
//!
//! This is the project's observable contract. The JSON-lines sink writes one [`TraceEvent`] per line
//! (schema in `docs/trace-format.md`, version [`TRACE_FORMAT_VERSION`]); the TCM text log, the tree
//! dump, the trace checker and the tests all read these records. Nodes are named by their display
//! number (`{id}` in TCM's log): creation order, 0 for the root, never reused within a run.

use crate::state::{Facet, NodeKind, Outcome, Point, State};
use serde::{Deserialize, Serialize};

/// Version of the trace schema; bumped on any incompatible change.
pub const TRACE_FORMAT_VERSION: u32 = 10;

/// The oldest schema version the readers still accept (see `docs/trace-format.md`, "Versions").
pub const OLDEST_READABLE_VERSION: u32 = 1;

/// One trace record.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
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
#[cfg_attr(
    feature = "schema",
    derive(schemars::JsonSchema),
    schemars(deny_unknown_fields)
)]
pub struct TraceEventRef {
    /// Display number of the node.
    pub node: u64,
    /// The facet.
    pub facet: Facet,
    /// The state reached.
    pub point: Point,
    /// For an outcome event (`X failed`): the execution's completion counts only with this
    /// outcome. Absent otherwise (and in traces before version 4).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub outcome: Option<Outcome>,
}

/// A constraint as applied, with every relative reference resolved and every relative time made
/// absolute (nanoseconds since the run started).
///
/// Every timed or event-driven constraint is one [`TraceConstraint::Trigger`]: *when* something
/// happens ([`TraceWhen`]), *then* something is done ([`TraceThen`]). `disable F until …` is a
/// trigger that enables `F`, `terminate …` one that terminates, `activate …` one that activates a
/// monitor. Version 1 traces wrote one form per combination (`disable_until_event`,
/// `terminate_at_time`, …); they are read into this shape (`LegacyConstraint`).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(
    feature = "schema",
    derive(schemars::JsonSchema),
    schemars(deny_unknown_fields)
)]
#[serde(tag = "form", rename_all = "snake_case", from = "AnyConstraint")]
pub enum TraceConstraint {
    /// Execution waits for expansion completed.
    ExpandFirst,
    /// Expansion waits for execution enabled.
    DelayExpansion,
    /// When `when` happens, do `then`.
    Trigger {
        /// What it waits for.
        when: TraceWhen,
        /// What it does then.
        then: TraceThen,
    },
}

impl TraceConstraint {
    /// A trigger.
    pub fn trigger(when: TraceWhen, then: TraceThen) -> TraceConstraint {
        TraceConstraint::Trigger { when, then }
    }

    /// The event a trigger waits for, if it waits for one.
    pub fn event(&self) -> Option<TraceEventRef> {
        match self {
            TraceConstraint::Trigger { when, .. } => when.event(),
            _ => None,
        }
    }
}

/// When a trigger fires, as recorded: relative times already made absolute.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(
    feature = "schema",
    derive(schemars::JsonSchema),
    schemars(deny_unknown_fields)
)]
#[serde(rename_all = "snake_case")]
pub enum TraceWhen {
    /// At once.
    Now,
    /// At an absolute time (ns since the run started).
    At(u64),
    /// When the event happens.
    Event(TraceEventRef),
    /// A delay after the event happens.
    After {
        /// Delay (ns).
        delay_ns: u64,
        /// The event the delay counts from.
        event: TraceEventRef,
    },
    /// When the named external event is raised.
    External(String),
    /// When a condition over state variables holds (docs/semantics.md, "State and conditions").
    /// What "holds" means depends on what it does: an enabling or terminating trigger fires once
    /// it is true, an activation each time it becomes true; a skip, an invariant or a pause reads
    /// it at their own moments (see [`TraceThen`]).
    Condition(tcm_expr::Expr),
    /// Each time the named state variable changes value (`activate on change of v`).
    Changed(String),
    /// When every one of these events happened (a `with` group's event: each member reached
    /// it), after a delay if any. With no event, at once.
    All {
        /// The members' events.
        events: Vec<TraceEventRef>,
        /// Delay after the last of them (ns).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        delay_ns: Option<u64>,
    },
}

impl TraceWhen {
    /// The event waited for, if any.
    pub fn event(&self) -> Option<TraceEventRef> {
        match self {
            TraceWhen::Event(e) | TraceWhen::After { event: e, .. } => Some(*e),
            _ => None,
        }
    }
}

/// An amount of one resource, as a request, grant or release names it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(
    feature = "schema",
    derive(schemars::JsonSchema),
    schemars(deny_unknown_fields)
)]
pub struct ResourceUse {
    /// The resource's name (its `resource` record).
    pub resource: String,
    /// How much of its capacity.
    pub amount: u32,
}

impl ResourceUse {
    /// `amount` of `resource`.
    pub fn new(resource: impl Into<String>, amount: u32) -> ResourceUse {
        ResourceUse {
            resource: resource.into(),
            amount,
        }
    }
}

/// What a trigger does when it fires.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "snake_case")]
pub enum TraceThen {
    /// Satisfies one enablement constraint of the facet (`disable <facet> until …`).
    Enable(Facet),
    /// Terminates the node (`terminate …`).
    Terminate,
    /// Activates the monitor (`activate …`).
    Activate,
    /// Completes the node without running it if the condition holds when its turn comes
    /// (`skip if …`): a `skipped` record, outcome `skipped`.
    Skip,
    /// Fails the node with `InvariantFailed` when the condition is false while it runs, from
    /// its handling's activation to its execution's completion (`with invariant …`).
    Invariant,
    /// Suspends the node's subtree while the condition holds, unsuspends it when it stops
    /// holding (`pause while …`).
    Pause,
}

/// A constraint record as either version writes it: the current forms, or version 1's one form per
/// combination. Only used to read; writing always uses [`TraceConstraint`]'s current forms.
#[derive(Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(untagged)]
enum AnyConstraint {
    Current(CurrentConstraint),
    Legacy(LegacyConstraint),
}

#[derive(Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(tag = "form", rename_all = "snake_case")]
enum CurrentConstraint {
    ExpandFirst,
    DelayExpansion,
    Trigger { when: TraceWhen, then: TraceThen },
}

/// The constraint forms of trace format version 1, kept so that old traces still read.
#[derive(Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(tag = "form", rename_all = "snake_case")]
enum LegacyConstraint {
    DisableUntilEvent {
        facet: Facet,
        event: TraceEventRef,
    },
    DisableUntilTime {
        facet: Facet,
        at: u64,
    },
    DisableForAfter {
        facet: Facet,
        delay_ns: u64,
        event: TraceEventRef,
    },
    DisableUntilExternal {
        facet: Facet,
        name: String,
    },
    TerminateNow,
    TerminateAtEvent {
        event: TraceEventRef,
    },
    TerminateAtTime {
        at: u64,
    },
    TerminateInAfter {
        delay_ns: u64,
        event: TraceEventRef,
    },
    TerminateAtExternal {
        name: String,
    },
    ActivateNow,
    ActivateAtEvent {
        event: TraceEventRef,
    },
    ActivateAtTime {
        at: u64,
    },
    ActivateInAfter {
        delay_ns: u64,
        event: TraceEventRef,
    },
    ActivateAtExternal {
        name: String,
    },
}

impl From<AnyConstraint> for TraceConstraint {
    fn from(c: AnyConstraint) -> TraceConstraint {
        use LegacyConstraint as L;
        use TraceThen::{Activate, Enable, Terminate};
        use TraceWhen as W;
        let t = TraceConstraint::trigger;
        match c {
            AnyConstraint::Current(CurrentConstraint::ExpandFirst) => TraceConstraint::ExpandFirst,
            AnyConstraint::Current(CurrentConstraint::DelayExpansion) => {
                TraceConstraint::DelayExpansion
            }
            AnyConstraint::Current(CurrentConstraint::Trigger { when, then }) => t(when, then),
            AnyConstraint::Legacy(l) => match l {
                L::DisableUntilEvent { facet, event } => t(W::Event(event), Enable(facet)),
                L::DisableUntilTime { facet, at } => t(W::At(at), Enable(facet)),
                L::DisableForAfter {
                    facet,
                    delay_ns,
                    event,
                } => t(W::After { delay_ns, event }, Enable(facet)),
                L::DisableUntilExternal { facet, name } => t(W::External(name), Enable(facet)),
                L::TerminateNow => t(W::Now, Terminate),
                L::TerminateAtEvent { event } => t(W::Event(event), Terminate),
                L::TerminateAtTime { at } => t(W::At(at), Terminate),
                L::TerminateInAfter { delay_ns, event } => {
                    t(W::After { delay_ns, event }, Terminate)
                }
                L::TerminateAtExternal { name } => t(W::External(name), Terminate),
                L::ActivateNow => t(W::Now, Activate),
                L::ActivateAtEvent { event } => t(W::Event(event), Activate),
                L::ActivateAtTime { at } => t(W::At(at), Activate),
                L::ActivateInAfter { delay_ns, event } => t(W::After { delay_ns, event }, Activate),
                L::ActivateAtExternal { name } => t(W::External(name), Activate),
            },
        }
    }
}

/// The body of a trace record.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
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
        /// The version of the program whose definition the node runs, when its program was
        /// loaded at run time under one (a serving executive's content hash); absent otherwise.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        version: Option<String>,
        /// The arguments its task was given, as text (`name = value, …`), when its task
        /// describes them (TDL's tasks do, for arguments whose types print with `Debug`); absent
        /// otherwise.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        args: Option<String>,
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
    /// A state variable was declared, with its type and initial value; before any record names
    /// it (docs/semantics.md, "State and conditions").
    StateDeclared {
        /// The variable.
        var: String,
        /// Its type.
        ty: tcm_expr::Type,
        /// Its initial value.
        value: tcm_expr::Value,
    },
    /// A state variable was set (an input: from the program, the shell, an agent). Recorded even
    /// when the value is the one it had; only a different value is a change.
    StateSet {
        /// The variable.
        var: String,
        /// Its new value.
        value: tcm_expr::Value,
    },
    /// The node's turn came while its `skip if` condition held: it completes without running
    /// (its handling goes from enabled to completed), with outcome `skipped`.
    Skipped {
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
        #[cfg_attr(feature = "schema", schemars(extend("enum" = ["before", "after"])))]
        when: String,
    },
    /// A timer callback was set (TCM's `InvokeWhen`, `InvokeAfter`): a function the shell runs at
    /// an event or a time. It is no node of the tree.
    CallbackSet {
        /// The callback's number, chosen by the shell; `callback_ran` names it again.
        callback: u64,
        /// The callback's name, for people.
        name: String,
        /// The node whose action set it, if any (`null` when the program set it).
        node: Option<u64>,
        /// When it runs: at an event (`event`), at a time (`at`), or at once (`now`, when its
        /// event had passed long before: its node was reclaimed).
        when: TraceWhen,
    },
    /// A timer callback's event happened or its time came: the shell runs it now.
    CallbackRan {
        /// The callback's number, as in its `callback_set` record.
        callback: u64,
        /// The callback's name.
        name: String,
    },
    /// A resource was declared (docs/semantics.md, "Resources"): `capacity` units, at most
    /// `pending_limit` requests waiting for it (`None`: no limit).
    Resource {
        /// Its name, unique in the run.
        resource: String,
        /// Units it has.
        capacity: u32,
        /// Most requests that may wait for it; past it the oldest is dropped.
        pending_limit: Option<u32>,
    },
    /// A node asks for resources: its handling is enabled and it would start.
    Requested {
        /// The node.
        node: u64,
        /// What it asks for, all at once.
        uses: Vec<ResourceUse>,
        /// Lower is granted first.
        priority: i32,
    },
    /// A node's request was granted: it holds `uses` until its action ends.
    Granted {
        /// The node.
        node: u64,
        /// What it holds now.
        uses: Vec<ResourceUse>,
    },
    /// A node gave back what it was granted (its handling completed, or its terminated action
    /// stopped).
    Released {
        /// The node.
        node: u64,
        /// What it gave back.
        uses: Vec<ResourceUse>,
    },
    /// A waiting request was withdrawn: its node was terminated before it was granted.
    Withdrawn {
        /// The node.
        node: u64,
    },
    /// A request was refused (a `deny if busy` request that could not be granted at once, or one
    /// asking for more than a capacity); its node fails with `ResourceDenied`.
    Denied {
        /// The node.
        node: u64,
        /// The resource that could not be granted.
        resource: String,
    },
    /// A waiting request was dropped: a newer one came past the resource's pending limit. Its node
    /// fails with `ResourceDropped`.
    Dropped {
        /// The node.
        node: u64,
        /// The resource whose pending limit was passed.
        resource: String,
    },
    /// A resource was reserved for a node: only that node's subtree may be granted it.
    ResourceReserved {
        /// The resource.
        resource: String,
        /// The node whose subtree may use it.
        holder: u64,
    },
    /// A resource's reservation ended.
    ResourceUnreserved {
        /// The resource.
        resource: String,
    },
    /// A resource was locked: nobody is granted it until it is unlocked.
    ResourceLocked {
        /// The resource.
        resource: String,
    },
    /// A resource was unlocked.
    ResourceUnlocked {
        /// The resource.
        resource: String,
    },
    /// The node's action runs on another process of a distributed system, the agent `agent`
    /// (docs/distributed.md); what it does there comes back as this trace's records of the node.
    Placed {
        /// The node.
        node: u64,
        /// The agent's name.
        agent: String,
    },
    /// A handler was attached from outside to a task while the run ran: the task's live nodes
    /// and those spawned from now on try it after their own handlers.
    HandlerAttached {
        /// The attachment's number; `handler_detached` names it again.
        attach: u32,
        /// The task whose nodes it is attached to.
        task: String,
        /// The handler's instance name.
        handler: String,
        /// The exception it handles.
        exception: String,
    },
    /// A handler attached while the run ran was removed: no node tries it from now on (a use
    /// already running goes on).
    HandlerDetached {
        /// The attachment's number.
        attach: u32,
    },
    /// A wiretap was added while the run ran.
    TapAdded {
        /// The wiretap's number, as `tapped` records name it.
        tap: u32,
        /// The task (or, with `instance`, the instance name) it taps.
        task: String,
        /// Whether it matches instance names instead of task names.
        instance: bool,
        /// `before` or `after`.
        #[cfg_attr(feature = "schema", schemars(extend("enum" = ["before", "after"])))]
        when: String,
    },
    /// A wiretap was removed: no check of it starts from now on.
    TapRemoved {
        /// The wiretap's number.
        tap: u32,
    },
    /// An operation from outside the run on it: a program loaded into it, a run stopped or
    /// swapped, an operator's request.
    Control {
        /// What was done, for people (`load tidy@3f2a…`, `stop`).
        what: String,
        /// Who asked (a client's name or identity, as the executive knows it).
        by: String,
    },
    /// The run paused (docs/semantics.md, "Steering a run"): no node starts and no timer of the
    /// tree fires until `resumed`; what already runs goes on and its ends are applied.
    Paused {
        /// The node it paused at (a breakpoint's), if any.
        node: Option<u64>,
        /// Why, for people (`breakpoint 1: before centerOnDoor`, `step`, `asked by operator`).
        why: String,
    },
    /// The run resumed after a pause; the timers of the tree pending then moved `held_ns` later,
    /// the pause's length on the run's clock.
    Resumed {
        /// How long the pause held the tree's timers, in nanoseconds.
        held_ns: u64,
    },
    /// A fault was injected into the node at its start: its action did not run, and the node
    /// ends as `outcome` says (`fail Blocked: …`, `never ends`).
    Injected {
        /// The node.
        node: u64,
        /// The outcome that stands for its action's end, for people.
        outcome: String,
    },
    /// The node's turn to start came, and it waits for an operator's approval first.
    Held {
        /// The node.
        node: u64,
    },
    /// A node held for approval was approved, and starts at its turn.
    Approved {
        /// The node.
        node: u64,
        /// Who approved it.
        by: String,
    },
    /// Something worth a person's attention; the run goes on.
    Warning {
        /// Node concerned, if any.
        node: Option<u64>,
        /// Message.
        message: String,
    },
    /// A line a task's body wrote to the run's log (TDL's `log` statement, `Ctx::log`), stamped
    /// with the run's time when it wrote it.
    Log {
        /// The node whose body wrote it.
        node: u64,
        /// The line.
        message: String,
    },
}

impl TraceKind {
    /// The node this record is about, if any.
    pub fn node(&self) -> Option<u64> {
        match self {
            TraceKind::RunStarted { .. }
            | TraceKind::External { .. }
            | TraceKind::StateDeclared { .. }
            | TraceKind::StateSet { .. }
            | TraceKind::CallbackRan { .. }
            | TraceKind::Resource { .. }
            | TraceKind::ResourceUnreserved { .. }
            | TraceKind::ResourceLocked { .. }
            | TraceKind::ResourceUnlocked { .. }
            | TraceKind::HandlerAttached { .. }
            | TraceKind::HandlerDetached { .. }
            | TraceKind::TapAdded { .. }
            | TraceKind::TapRemoved { .. }
            | TraceKind::Control { .. }
            | TraceKind::Resumed { .. } => None,
            TraceKind::Paused { node, .. } => *node,
            TraceKind::Warning { node, .. } | TraceKind::CallbackSet { node, .. } => *node,
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
            | TraceKind::Skipped { node }
            | TraceKind::Reclaimed { node }
            | TraceKind::Placed { node, .. }
            | TraceKind::Log { node, .. }
            | TraceKind::MonitorParams { node, .. }
            | TraceKind::Activated { node, .. }
            | TraceKind::HandlerChosen { node, .. }
            | TraceKind::Bypassed { node, .. }
            | TraceKind::Retried { node, .. }
            | TraceKind::Tapped { node, .. }
            | TraceKind::Requested { node, .. }
            | TraceKind::Granted { node, .. }
            | TraceKind::Released { node, .. }
            | TraceKind::Withdrawn { node }
            | TraceKind::Denied { node, .. }
            | TraceKind::Dropped { node, .. }
            | TraceKind::Injected { node, .. }
            | TraceKind::Held { node }
            | TraceKind::Approved { node, .. } => Some(*node),
            TraceKind::ResourceReserved { holder, .. } => Some(*holder),
            TraceKind::Triggered { monitor, .. } => Some(*monitor),
        }
    }
}
