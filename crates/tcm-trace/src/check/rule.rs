//! The rules the checker verifies, and what it reports.

use std::fmt;

/// Most violations one check collects; past it the checker stops recording (the first ones matter).
pub const MAX_VIOLATIONS: usize = 1000;

/// A rule of the emission discipline. The kebab-case name (`Display`) is what reports print.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[non_exhaustive]
pub enum Rule {
    /// The first record is `run_started` (with this schema's version), and no other record is.
    RunStarted,
    /// `seq` counts 0, 1, 2, ... without gaps.
    SeqGap,
    /// `t` never decreases.
    TimeBackwards,
    /// A record names a node before its `reserved`/`spawned` record (or a reserved node that is not
    /// spawned yet, for a record that needs a spawned node).
    BeforeSpawn,
    /// A record names a node after its `reclaimed` record.
    AfterReclaim,
    /// A node number is reserved or spawned twice.
    DuplicateNode,
    /// A `dead` record for a node that is not a pending reservation, or a record about a dead node.
    DeadNode,
    /// A reservation is neither spawned nor dead when the trace ends, although its parent's execution
    /// completed.
    ReservedUnresolved,
    /// A node is reserved or spawned under a parent that is not a spawned, unreclaimed node.
    UnknownParent,
    /// A record spawns, changes, constrains or reclaims the implicit root (node 0).
    RootRecord,
    /// A transition's `from` is not the facet's current state (initial states: all disabled, but the
    /// expansion of a node that does not expand starts completed).
    TransitionFrom,
    /// A facet does not move forward.
    FacetForward,
    /// Termination does not move Alive -> Terminating -> Terminated.
    TerminationOrder,
    /// An enablement constraint (not a `terminate` or `activate` trigger) applied after the records that follow the
    /// node's `spawned` (its `constrained`, `constraint_void` and `suspended` records).
    LateConstraint,
    /// A constraint's event names a node never seen in the trace.
    UnknownReference,
    /// Handling enabled before the node's own expansion (goal-like) or execution (command-like) is
    /// at least enabled.
    HandlingEnable,
    /// A goal-like node's expansion enabled before its parent's expansion is at least enabled.
    ExpansionEnable,
    /// Execution enabled before the parent's execution is at least enabled.
    ExecutionEnable,
    /// Handling became active without being enabled first.
    HandlingSkipsEnabled,
    /// Handling became active while the node was terminating or terminated.
    ActiveWhileTerminating,
    /// Handling became active while the node was suspended.
    ActiveWhileSuspended,
    /// Handling became active while the run was paused (between `paused` and `resumed`).
    ActiveWhilePaused,
    /// Handling became active while the node was held for approval (`held`, no `approved`).
    ActiveWhileHeld,
    /// Expansion became active while no goal-like node of the subtree had handling at least active.
    ExpansionActive,
    /// Execution became active while no command-like node of the subtree had handling at least active.
    ExecutionActive,
    /// Expansion completed while the node's own handling (goal-like), or some goal-like descendant's
    /// handling, was not completed.
    ExpansionComplete,
    /// Execution completed while the node's own handling or expansion, or some child's execution, was
    /// not completed.
    ExecutionComplete,
    /// Terminated while a facet of the node was not completed, or some child was neither terminated nor
    /// execution-completed.
    TerminatedEarly,
    /// Reclaimed before execution completed, while terminating but not terminated, or before all
    /// children were reclaimed.
    ReclaimEarly,
    /// A facet enabled before one of its `disable … until` triggers fired: the awaited event had not
    /// happened (its node had not reached the point, nor been found dead), the absolute time had not
    /// come, the delay after the event (counted from when its node reached the point or was found
    /// dead) had not elapsed, or the external event had not been raised.
    Disable,
    /// Execution enabled before the node's own expansion completed.
    ExpandFirst,
    /// Expansion enabled before the node's own execution is at least enabled.
    DelayExpansion,
    /// A node not terminating by the end of the records at the time one of its `terminate` triggers
    /// fired: at once (`now`), at the absolute time (checked only if the trace goes past it), when the
    /// event happened (plus the delay, for `after`; if the event had happened before the trigger was
    /// applied, the delay counts from the application), or when the external event was raised. A
    /// trigger whose event's node was terminating when it reached the point (or when the trigger was
    /// applied) never fires; one whose event's node was dead fires at once.
    Terminate,
    /// A monitor activation while the monitor's handling is not active (or it is terminating), out of
    /// sequence, past its maximum, or not under its monitor.
    Activation,
    /// A transition a condition over state variables explains, while the recorded values say
    /// otherwise: a skip whose condition does not hold, a start whose `skip if` holds, an
    /// `InvariantFailed` failure whose invariants all hold (or are unknown), or a condition that
    /// cannot be evaluated on the declared variables. Enabling and terminating triggers on
    /// conditions are checked by [`Rule::Disable`] and [`Rule::Terminate`].
    Condition,
    /// A monitor's handling completed before reaching its maximum activations or triggers, while it was
    /// not terminating and had not failed.
    MonitorComplete,
    /// A handler was chosen for a node that did not fail, or its node is not under the failing node
    /// (or under a bypassing handler node).
    Handler,
    /// A retry not under a handler node, or a bypass from a node that is not a handler node.
    Retry,
    /// A timer callback set twice under one number, run without being set, run twice, or run before
    /// its event happened (its node reached the point, or was found dead) or its time came.
    Callback,
    /// A resource record that does not fit what came before: a resource declared twice or never
    /// declared, a request from a node that already waits for or holds resources, a grant,
    /// withdrawal, denial or drop without a waiting request, a grant of other amounts than those
    /// requested, a release without a grant or of other amounts than those granted.
    ResourceRequest,
    /// More requests wait for a resource than its pending limit allows, once the request that
    /// went past it was dealt with (checked at the next request and at the end).
    ResourcePending,
    /// A grant takes a resource past its capacity.
    ResourceCapacity,
    /// A grant of a locked resource, or of a resource reserved for a node outside whose subtree
    /// the grantee is.
    ResourceLock,
    /// A node that asked for resources went active without holding its grant.
    ResourceGrant,
    /// A node's handling completed, while it was not terminating, with resources still granted
    /// or a request still waiting; or its execution completed, it was terminated or reclaimed
    /// with either.
    ResourceRelease,
}

impl Rule {
    /// The rule's kebab-case name.
    pub fn as_str(self) -> &'static str {
        match self {
            Rule::RunStarted => "run-started",
            Rule::SeqGap => "seq-gap",
            Rule::TimeBackwards => "time-backwards",
            Rule::BeforeSpawn => "before-spawn",
            Rule::AfterReclaim => "after-reclaim",
            Rule::DuplicateNode => "duplicate-node",
            Rule::DeadNode => "dead-node",
            Rule::ReservedUnresolved => "reserved-unresolved",
            Rule::UnknownParent => "unknown-parent",
            Rule::RootRecord => "root-record",
            Rule::TransitionFrom => "transition-from",
            Rule::FacetForward => "facet-forward",
            Rule::TerminationOrder => "termination-order",
            Rule::LateConstraint => "late-constraint",
            Rule::UnknownReference => "unknown-reference",
            Rule::HandlingEnable => "handling-enable",
            Rule::ExpansionEnable => "expansion-enable",
            Rule::ExecutionEnable => "execution-enable",
            Rule::HandlingSkipsEnabled => "handling-skips-enabled",
            Rule::ActiveWhileTerminating => "active-while-terminating",
            Rule::ActiveWhileSuspended => "active-while-suspended",
            Rule::ActiveWhilePaused => "active-while-paused",
            Rule::ActiveWhileHeld => "active-while-held",
            Rule::ExpansionActive => "expansion-active",
            Rule::ExecutionActive => "execution-active",
            Rule::ExpansionComplete => "expansion-complete",
            Rule::ExecutionComplete => "execution-complete",
            Rule::TerminatedEarly => "terminated-early",
            Rule::ReclaimEarly => "reclaim-early",
            Rule::Disable => "disable",
            Rule::ExpandFirst => "expand-first",
            Rule::DelayExpansion => "delay-expansion",
            Rule::Terminate => "terminate",
            Rule::Activation => "activation",
            Rule::Condition => "condition",
            Rule::MonitorComplete => "monitor-complete",
            Rule::Handler => "handler",
            Rule::Retry => "retry",
            Rule::Callback => "callback",
            Rule::ResourceRequest => "resource-request",
            Rule::ResourcePending => "resource-pending",
            Rule::ResourceCapacity => "resource-capacity",
            Rule::ResourceLock => "resource-lock",
            Rule::ResourceGrant => "resource-grant",
            Rule::ResourceRelease => "resource-release",
        }
    }
}

impl fmt::Display for Rule {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// One broken rule.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Violation {
    /// `seq` of the offending record (for a termination that never came: the first record after it was
    /// due, or the last record of the trace).
    pub seq: u64,
    /// The node concerned, if any.
    pub node: Option<u64>,
    /// The rule.
    pub rule: Rule,
    /// What is wrong, for a person.
    pub message: String,
}

impl fmt::Display for Violation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "seq {}", self.seq)?;
        if let Some(n) = self.node {
            write!(f, ", node {n}")?;
        }
        write!(f, ": [{}] {}", self.rule, self.message)
    }
}

/// What a successful check looked at, so tests can assert it looked at something.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CheckReport {
    /// Records checked.
    pub n_records: u64,
    /// Nodes spawned.
    pub n_nodes: u64,
    /// Facet transitions.
    pub n_transitions: u64,
    /// Constraints applied (`constrained` records).
    pub n_constraints: u64,
    /// Times an enablement constraint was evaluated when its facet became enabled.
    pub n_enablement_checks: u64,
    /// Terminations owed by termination constraints and verified.
    pub n_terminations_checked: u64,
}
