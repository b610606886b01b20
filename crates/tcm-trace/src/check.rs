//! The trace checker: verifies that a trace obeys the engine's emission discipline.
//!
//! [`check`] (or a [`Checker`] fed record by record) replays the trace and, at each record, verifies the
//! rules listed in [`Rule`]: the shape of the trace, the Figure 3 axioms and the parent/child
//! constraints of catalogue §3.2, and that every applied constraint was respected. Every runtime test
//! calls it on the engine's real traces, so each rule is exact: a rule that can be read two ways (see the
//! `Rule` docs) accepts both readings rather than guess.
//!
//! Cost: each record costs a few map look-ups plus, for a facet becoming enabled, one pass over that
//! node's own constraints. Subtree conditions ("some goal below has started", "every goal below is
//! handled") are aggregates kept by [`Replay`] and updated along the ancestor path only while they
//! change, which is amortised constant time. Due terminations wait in a binary heap keyed by time.

use crate::event::{TRACE_FORMAT_VERSION, TraceConstraint, TraceEvent, TraceEventRef, TraceKind};
use crate::replay::{Replay, ReplayNode};
use crate::state::{Facet, State, Termination};
use std::cmp::Reverse;
use std::collections::{BTreeMap, BTreeSet, BinaryHeap};
use std::fmt;

#[cfg(test)]
mod tests;

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
    /// A reservation is neither spawned nor dead when the trace ends, although its parent's handling
    /// completed (its body ended).
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
    /// An enablement constraint (not a `terminate` form) applied after the records that follow the
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
    /// Enabled before the awaited event (the event's node reached the point, or was found dead).
    DisableUntilEvent,
    /// Enabled before the absolute time.
    DisableUntilTime,
    /// Enabled before the delay after the event (counted from the moment the event's node reached the
    /// point, or was found dead) elapsed.
    DisableForAfter,
    /// Enabled before the external event was raised.
    DisableUntilExternal,
    /// Execution enabled before the node's own expansion completed.
    ExpandFirst,
    /// Expansion enabled before the node's own execution is at least enabled.
    DelayExpansion,
    /// Not terminating by the end of the records at the time `terminate` was applied.
    TerminateNow,
    /// Not terminating by the end of the records at the time the event happened. The constraint does not
    /// fire if the event's node was terminating when it reached the point (or when the constraint was
    /// applied); it fires at once if that node was dead, or had reached the point already.
    TerminateAtEvent,
    /// Not terminating by the end of the records at the absolute time (checked only if the trace goes
    /// past that time).
    TerminateAtTime,
    /// Not terminating by the end of the records at the event's time plus the delay (if the event had
    /// happened before the constraint was applied, the delay counts from the application).
    TerminateInAfter,
    /// Not terminating by the end of the records at the time the external event was raised (at once if
    /// it had been raised before the constraint was applied).
    TerminateAtExternal,
    /// A monitor activation while the monitor's handling is not active (or it is terminating), out of
    /// sequence, past its maximum, or not under its monitor.
    Activation,
    /// A monitor's handling completed before reaching its maximum activations or triggers, while it was
    /// not terminating.
    MonitorComplete,
    /// A handler was chosen for a node that did not fail, or its node is not under the failing node
    /// (or under a bypassing handler node).
    Handler,
    /// A retry not under a handler node, or a bypass from a node that is not a handler node.
    Retry,
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
            Rule::ExpansionActive => "expansion-active",
            Rule::ExecutionActive => "execution-active",
            Rule::ExpansionComplete => "expansion-complete",
            Rule::ExecutionComplete => "execution-complete",
            Rule::TerminatedEarly => "terminated-early",
            Rule::ReclaimEarly => "reclaim-early",
            Rule::DisableUntilEvent => "disable-until-event",
            Rule::DisableUntilTime => "disable-until-time",
            Rule::DisableForAfter => "disable-for-after",
            Rule::DisableUntilExternal => "disable-until-external",
            Rule::ExpandFirst => "expand-first",
            Rule::DelayExpansion => "delay-expansion",
            Rule::TerminateNow => "terminate-now",
            Rule::TerminateAtEvent => "terminate-at-event",
            Rule::TerminateAtTime => "terminate-at-time",
            Rule::TerminateInAfter => "terminate-in-after",
            Rule::TerminateAtExternal => "terminate-at-external",
            Rule::Activation => "activation",
            Rule::MonitorComplete => "monitor-complete",
            Rule::Handler => "handler",
            Rule::Retry => "retry",
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

/// Checks a whole trace.
pub fn check(trace: &[TraceEvent]) -> Result<CheckReport, Vec<Violation>> {
    let mut checker = Checker::new();
    for ev in trace {
        checker.push(ev);
    }
    checker.finish()
}

// A termination some constraint made due.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
struct Owed {
    due: u64,
    // `seq` of the record that made it due (keeps the heap order deterministic).
    seq: u64,
    node: u64,
    rule: Rule,
    // Whether the trace owes it even if it ends at `due` (true for terminations due at once).
    owed_at_end: bool,
}

// A termination constraint waiting for its event.
#[derive(Clone, Debug)]
struct Watch {
    target: u64,
    facet: Facet,
    state: State,
    // `None` for `terminate at`, the delay for `terminate in .. after`.
    delay: Option<u64>,
}

/// The checker, fed one record at a time (for a live sink); [`check`] drives it over a slice.
#[derive(Debug, Default)]
pub struct Checker {
    replay: Replay,
    report: CheckReport,
    violations: Vec<Violation>,
    n_records: u64,
    last: Option<(u64, u64)>,
    // The node whose constraints may still be applied (just spawned).
    window: Option<u64>,
    pending_reserved: BTreeSet<u64>,
    externals: BTreeSet<String>,
    watches: BTreeMap<u64, Vec<Watch>>,
    external_watches: BTreeMap<String, Vec<u64>>,
    owed: BinaryHeap<Reverse<Owed>>,
}

fn ref_text(r: &TraceEventRef) -> String {
    format!("node {} {} {}", r.node, r.facet, r.point.as_str())
}

fn secs(t: u64) -> String {
    format!("{}.{:09}s", t / 1_000_000_000, t % 1_000_000_000)
}

impl Checker {
    /// A checker for a new trace.
    pub fn new() -> Checker {
        Checker::default()
    }

    /// The tree as rebuilt so far.
    pub fn replay(&self) -> &Replay {
        &self.replay
    }

    fn flag(&mut self, seq: u64, node: Option<u64>, rule: Rule, message: String) {
        if self.violations.len() < MAX_VIOLATIONS {
            self.violations.push(Violation {
                seq,
                node,
                rule,
                message,
            });
        }
    }

    fn name(&self, node: u64) -> String {
        match self.replay.node(node) {
            Some(n) => format!("{} {{{node}}}", n.name()),
            None => format!("{{{node}}}"),
        }
    }

    /// Checks one record.
    pub fn push(&mut self, ev: &TraceEvent) {
        let seq = ev.seq;
        if ev.seq != self.n_records {
            self.flag(
                seq,
                None,
                Rule::SeqGap,
                format!(
                    "record number {} has seq {}; seq must count from 0 without gaps",
                    self.n_records, ev.seq
                ),
            );
        }
        let is_run_started = matches!(ev.kind, TraceKind::RunStarted { .. });
        if self.n_records == 0 && !is_run_started {
            self.flag(
                seq,
                None,
                Rule::RunStarted,
                "the first record must be `run_started`".into(),
            );
        } else if self.n_records > 0 && is_run_started {
            self.flag(
                seq,
                None,
                Rule::RunStarted,
                "`run_started` may only be the first record".into(),
            );
        }
        if let TraceKind::RunStarted { version, .. } = ev.kind {
            if version != TRACE_FORMAT_VERSION {
                self.flag(
                    seq,
                    None,
                    Rule::RunStarted,
                    format!("format version {version}; this checker knows version {TRACE_FORMAT_VERSION}"),
                );
            }
        }
        if let Some((_, last_t)) = self.last {
            if ev.t < last_t {
                self.flag(
                    seq,
                    ev.kind.node(),
                    Rule::TimeBackwards,
                    format!("t goes back from {} to {}", secs(last_t), secs(ev.t)),
                );
            }
        }
        self.settle_owed(Some(ev.t), seq);
        self.n_records += 1;
        self.report.n_records += 1;
        let last_t = self.last.map_or(ev.t, |(_, t)| t.max(ev.t));
        self.last = Some((seq, last_t));

        let node = ev.kind.node();
        let keeps_window = matches!(
            ev.kind,
            TraceKind::Constrained { .. }
                | TraceKind::ConstraintVoid { .. }
                | TraceKind::Suspended { .. }
                | TraceKind::MonitorParams { .. }
        ) && node == self.window;
        if !keeps_window {
            self.window = None;
        }
        if self.subject_ok(ev) {
            self.check_record(ev);
        }
        // The checker reported anything the replay refuses; keep going with the state it has.
        let _ = self.replay.apply(ev);
        self.after_record(ev);
    }

    // Verifies that the record's node is in a condition where such a record may name it.
    fn subject_ok(&mut self, ev: &TraceEvent) -> bool {
        let Some(number) = ev.kind.node() else {
            return true;
        };
        let seq = ev.seq;
        match &ev.kind {
            TraceKind::Warning { .. } => return true,
            TraceKind::Reserved { .. } | TraceKind::Spawned { .. } | TraceKind::Dead { .. } => {
                // Checked with their own rules.
                return true;
            }
            _ => {}
        }
        if number == 0 {
            self.flag(
                seq,
                Some(0),
                Rule::RootRecord,
                "the root (node 0) is implicit: no record may change or constrain it".into(),
            );
            return false;
        }
        let Some(n) = self.replay.node(number) else {
            self.flag(
                seq,
                Some(number),
                Rule::BeforeSpawn,
                format!("node {number} is named before any `reserved` or `spawned` record for it"),
            );
            return false;
        };
        if matches!(ev.kind, TraceKind::ConstraintVoid { .. }) {
            return true;
        }
        if n.is_dead() {
            self.flag(
                seq,
                Some(number),
                Rule::DeadNode,
                format!(
                    "{} is dead (never spawned); only `constraint_void` and `warning` may name it",
                    self.name(number)
                ),
            );
            return false;
        }
        if !n.is_spawned() {
            self.flag(
                seq,
                Some(number),
                Rule::BeforeSpawn,
                format!("{} is reserved but not spawned yet", self.name(number)),
            );
            return false;
        }
        if n.is_reclaimed() {
            self.flag(
                seq,
                Some(number),
                Rule::AfterReclaim,
                format!("{} was already reclaimed", self.name(number)),
            );
            return false;
        }
        true
    }

    fn check_record(&mut self, ev: &TraceEvent) {
        let seq = ev.seq;
        match &ev.kind {
            TraceKind::Reserved { node, parent, .. } => {
                let ok = self.new_node_ok(seq, *node, *parent, false);
                if ok {
                    self.pending_reserved.insert(*node);
                }
            }
            TraceKind::Spawned {
                node, parent, kind, ..
            } => {
                if *kind == crate::state::NodeKind::Root {
                    self.flag(
                        seq,
                        Some(*node),
                        Rule::RootRecord,
                        "a `spawned` record may not spawn a root".into(),
                    );
                }
                if self.new_node_ok(seq, *node, *parent, true) {
                    self.pending_reserved.remove(node);
                    self.window = Some(*node);
                    self.report.n_nodes += 1;
                }
            }
            TraceKind::Dead { node } => match self.replay.node(*node) {
                Some(n) if n.is_reserved() => {
                    self.pending_reserved.remove(node);
                }
                Some(_) => self.flag(
                    seq,
                    Some(*node),
                    Rule::DeadNode,
                    format!(
                        "`dead` for {}, which is not a pending reservation",
                        self.name(*node)
                    ),
                ),
                None => self.flag(
                    seq,
                    Some(*node),
                    Rule::BeforeSpawn,
                    format!("`dead` for node {node}, which was never reserved"),
                ),
            },
            TraceKind::Constrained { node, constraint } => {
                self.check_constrained(ev, *node, constraint)
            }
            TraceKind::Transition {
                node,
                facet,
                from,
                to,
            } => {
                self.check_transition(ev, *node, *facet, *from, *to);
            }
            TraceKind::Terminating { node } => {
                if let Some(n) = self.replay.node(*node) {
                    if n.termination() != Termination::Alive {
                        let msg = format!("{} is asked to terminate twice", self.name(*node));
                        self.flag(seq, Some(*node), Rule::TerminationOrder, msg);
                    }
                }
            }
            TraceKind::Terminated { node } => self.check_terminated(seq, *node),
            TraceKind::Reclaimed { node } => self.check_reclaimed(seq, *node),
            TraceKind::Activated {
                monitor,
                node,
                number,
            } => self.check_activated(seq, *monitor, *node, *number),
            TraceKind::HandlerChosen { node, failing, .. } => {
                self.check_handler(seq, *node, *failing)
            }
            TraceKind::Retried { node, .. } | TraceKind::Bypassed { node, .. } => {
                let parent_or_self = match &ev.kind {
                    TraceKind::Retried { .. } => self.replay.node(*node).and_then(|n| n.parent()),
                    _ => Some(*node),
                };
                let ok = parent_or_self
                    .and_then(|p| self.replay.node(p))
                    .is_some_and(|p| p.handler_for().is_some());
                if !ok {
                    let msg = format!(
                        "{} is not (under) an exception handler node",
                        self.name(*node)
                    );
                    self.flag(seq, Some(*node), Rule::Retry, msg);
                }
            }
            _ => {}
        }
    }

    fn check_activated(&mut self, seq: u64, monitor: u64, node: u64, number: u32) {
        let Some(m) = self.replay.node(monitor) else {
            return;
        };
        let mut problems = Vec::new();
        if m.state(Facet::Handling) != State::Active || m.termination() != Termination::Alive {
            problems.push(format!(
                "the monitor's handling is {}",
                m.state(Facet::Handling)
            ));
        }
        match m.monitor() {
            None => problems.push("no `monitor_params` record came before".into()),
            Some(info) => {
                if number != info.activations + 1 {
                    problems.push(format!(
                        "activation {number} follows activation {}",
                        info.activations
                    ));
                }
                if info.max_activations.is_some_and(|max| number > max) {
                    problems.push(format!(
                        "past the maximum of {:?} activations",
                        info.max_activations
                    ));
                }
            }
        }
        if self.replay.node(node).and_then(|n| n.parent()) != Some(monitor) {
            problems.push("the activation node is not a child of the monitor".into());
        }
        if !problems.is_empty() {
            let msg = format!(
                "activation {number} of {}: {}",
                self.name(monitor),
                problems.join("; ")
            );
            self.flag(seq, Some(node), Rule::Activation, msg);
        }
    }

    fn check_handler(&mut self, seq: u64, node: u64, failing: u64) {
        let failed = self.replay.node(failing).is_some_and(|n| n.is_failed());
        let parent = self.replay.node(node).and_then(|n| n.parent());
        let parent_ok = parent == Some(failing)
            || parent
                .and_then(|p| self.replay.node(p))
                .is_some_and(|p| p.handler_for().is_some());
        if !failed || !parent_ok {
            let msg = format!(
                "handler {} for {}: {}",
                self.name(node),
                self.name(failing),
                if failed {
                    "it is not under the failing node or a bypassing handler"
                } else {
                    "that node never failed"
                }
            );
            self.flag(seq, Some(node), Rule::Handler, msg);
        }
    }

    fn new_node_ok(&mut self, seq: u64, node: u64, parent: u64, spawn: bool) -> bool {
        if node == 0 {
            self.flag(
                seq,
                Some(0),
                Rule::RootRecord,
                "node 0 is the implicit root; it is never reserved or spawned".into(),
            );
            return false;
        }
        if let Some(n) = self.replay.node(node) {
            if n.is_dead() {
                let msg = format!("{} is spawned after it was found dead", self.name(node));
                self.flag(seq, Some(node), Rule::DeadNode, msg);
                return false;
            }
            if !(spawn && n.is_reserved()) {
                let what = if spawn { "spawned" } else { "reserved" };
                let msg = format!("node {node} is {what} again; display numbers are never reused");
                self.flag(seq, Some(node), Rule::DuplicateNode, msg);
                return false;
            }
        }
        match self.replay.node(parent) {
            Some(p) if p.is_spawned() && !p.is_reclaimed() => true,
            _ => {
                let msg = format!(
                    "the parent of node {node}, node {parent}, is not a spawned, unreclaimed node"
                );
                self.flag(seq, Some(node), Rule::UnknownParent, msg);
                false
            }
        }
    }

    fn check_constrained(&mut self, ev: &TraceEvent, node: u64, constraint: &TraceConstraint) {
        let seq = ev.seq;
        self.report.n_constraints += 1;
        let is_terminate = matches!(
            constraint,
            TraceConstraint::TerminateNow
                | TraceConstraint::TerminateAtEvent { .. }
                | TraceConstraint::TerminateAtTime { .. }
                | TraceConstraint::TerminateInAfter { .. }
                | TraceConstraint::TerminateAtExternal { .. }
                | TraceConstraint::ActivateNow
                | TraceConstraint::ActivateAtEvent { .. }
                | TraceConstraint::ActivateAtTime { .. }
                | TraceConstraint::ActivateInAfter { .. }
                | TraceConstraint::ActivateAtExternal { .. }
        );
        if !is_terminate && self.window != Some(node) {
            let msg = format!(
                "an enablement constraint ({constraint:?}) is applied to {} after its spawn records; only \
                 `terminate` forms may come later",
                self.name(node)
            );
            self.flag(seq, Some(node), Rule::LateConstraint, msg);
        }
        let event = match constraint {
            TraceConstraint::DisableUntilEvent { event, .. }
            | TraceConstraint::DisableForAfter { event, .. }
            | TraceConstraint::TerminateAtEvent { event }
            | TraceConstraint::TerminateInAfter { event, .. } => Some(*event),
            _ => None,
        };
        if let Some(r) = event {
            if self.replay.node(r.node).is_none() && r.node != node {
                let msg = format!(
                    "the constraint waits for {}, a node never seen in the trace",
                    ref_text(&r)
                );
                self.flag(seq, Some(node), Rule::UnknownReference, msg);
                return;
            }
        }
        match constraint {
            TraceConstraint::TerminateNow => self.fire(node, Rule::TerminateNow, ev.t, true, seq),
            TraceConstraint::TerminateAtTime { at } => {
                self.fire(
                    node,
                    Rule::TerminateAtTime,
                    (*at).max(ev.t),
                    *at <= ev.t,
                    seq,
                );
            }
            TraceConstraint::TerminateAtExternal { name } => {
                if self.externals.contains(name) {
                    self.fire(node, Rule::TerminateAtExternal, ev.t, true, seq);
                } else {
                    self.external_watches
                        .entry(name.clone())
                        .or_default()
                        .push(node);
                }
            }
            TraceConstraint::TerminateAtEvent { event } => self.arm(ev, node, event, None),
            TraceConstraint::TerminateInAfter { delay_ns, event } => {
                self.arm(ev, node, event, Some(*delay_ns))
            }
            _ => {}
        }
    }

    // A termination constraint on `node` waiting for `event`: fire now, never, or watch.
    fn arm(&mut self, ev: &TraceEvent, node: u64, event: &TraceEventRef, delay: Option<u64>) {
        let (rule, delay_ns) = match delay {
            Some(d) => (Rule::TerminateInAfter, d),
            None => (Rule::TerminateAtEvent, 0),
        };
        let Some(r) = self.replay.node(event.node) else {
            return;
        };
        if r.is_dead() {
            self.fire(
                node,
                rule,
                ev.t.saturating_add(delay_ns),
                delay_ns == 0,
                ev.seq,
            );
        } else if r.termination() != Termination::Alive {
            // Termination constraints whose event node was terminated do not fire (catalogue §3.4).
        } else if r.reached_at(event.facet, event.point).is_some() {
            self.fire(
                node,
                rule,
                ev.t.saturating_add(delay_ns),
                delay_ns == 0,
                ev.seq,
            );
        } else {
            self.watches.entry(event.node).or_default().push(Watch {
                target: node,
                facet: event.facet,
                state: event.point.state(),
                delay,
            });
        }
    }

    // Records that `node` must be terminating by the end of the records at time `due`, unless it has
    // completed its execution or is terminating already.
    fn fire(&mut self, node: u64, rule: Rule, due: u64, owed_at_end: bool, seq: u64) {
        let Some(n) = self.replay.node(node) else {
            return;
        };
        if n.termination() != Termination::Alive || n.state(Facet::Execution) == State::Completed {
            return;
        }
        self.owed.push(Reverse(Owed {
            due,
            seq,
            node,
            rule,
            owed_at_end,
        }));
    }

    // Verifies the terminations due before `now` (all of them at the end of the trace, `now == None`).
    fn settle_owed(&mut self, now: Option<u64>, seq: u64) {
        let end_t = self.last.map_or(0, |(_, t)| t);
        while let Some(Reverse(top)) = self.owed.peek() {
            if now.is_some_and(|t| top.due >= t) {
                return;
            }
            let Some(Reverse(owed)) = self.owed.pop() else {
                return;
            };
            let Some(n) = self.replay.node(owed.node) else {
                continue;
            };
            let done = n.termination() != Termination::Alive
                || n.state(Facet::Execution) == State::Completed
                || n.is_reclaimed();
            // At the end of the trace, a timer due at (or after) the last record's time is not owed yet.
            let owed_now = now.is_some() || owed.owed_at_end || owed.due < end_t;
            if done || owed_now {
                self.report.n_terminations_checked += 1;
            }
            if !done && owed_now {
                let msg = format!(
                    "{} should be terminating by t={} (made due by the record with seq {}), but it is still \
                     alive and its execution is {}",
                    self.name(owed.node),
                    secs(owed.due),
                    owed.seq,
                    n.state(Facet::Execution)
                );
                self.flag(seq, Some(owed.node), owed.rule, msg);
            }
        }
    }

    fn check_transition(
        &mut self,
        ev: &TraceEvent,
        number: u64,
        facet: Facet,
        from: State,
        to: State,
    ) {
        let seq = ev.seq;
        self.report.n_transitions += 1;
        let Some(n) = self.replay.node(number) else {
            return;
        };
        let cur = n.state(facet);
        if from != cur {
            let msg = format!(
                "{} {facet} is recorded as moving from {from}, but it is {cur}",
                self.name(number)
            );
            self.flag(seq, Some(number), Rule::TransitionFrom, msg);
        }
        if to <= cur {
            let msg = format!(
                "{} {facet} moves back from {cur} to {to}",
                self.name(number)
            );
            self.flag(seq, Some(number), Rule::FacetForward, msg);
            return;
        }
        let Some(n) = self.replay.node(number) else {
            return;
        };
        let mut found: Vec<(Rule, String)> = Vec::new();
        let alive = n.termination() == Termination::Alive;
        // A facet pushed straight to completed by termination is exempt from enablement conditions.
        let exempt = to == State::Completed && !alive;
        let mut n_checked = 0;
        if cur == State::Disabled && !exempt {
            n_checked = self.enablement(ev, n, facet, &mut found);
        }
        if to == State::Active {
            self.activation(n, facet, cur, &mut found);
        }
        if to == State::Completed {
            self.completion(n, facet, &mut found);
            if let (Facet::Handling, Some(info), true) = (facet, n.monitor(), alive) {
                let reached = info.max_activations.is_some_and(|m| info.activations >= m)
                    || info.max_triggers.is_some_and(|m| info.triggers >= m);
                if !reached {
                    found.push((
                        Rule::MonitorComplete,
                        format!(
                            "the monitor completed after {} activations and {} triggers, below its maxima ({:?}, {:?})",
                            info.activations, info.triggers, info.max_activations, info.max_triggers
                        ),
                    ));
                }
            }
        }
        self.report.n_enablement_checks += n_checked;
        for (rule, msg) in found {
            let msg = format!("{} {facet} {cur} -> {to}: {msg}", self.name(number));
            self.flag(seq, Some(number), rule, msg);
        }
    }

    // Returns how many constraints were evaluated.
    fn enablement(
        &self,
        ev: &TraceEvent,
        n: &ReplayNode,
        facet: Facet,
        found: &mut Vec<(Rule, String)>,
    ) -> u64 {
        let parent = n.parent().and_then(|p| self.replay.node(p));
        match facet {
            Facet::Handling => {
                let (own, what) = if n.expands() {
                    (
                        Facet::Expansion,
                        "a goal-like node's handling needs its expansion enabled",
                    )
                } else {
                    (
                        Facet::Execution,
                        "a command-like node's handling needs its execution enabled",
                    )
                };
                if n.state(own) < State::Enabled {
                    found.push((
                        Rule::HandlingEnable,
                        format!("{what}, but it is {}", n.state(own)),
                    ));
                }
            }
            Facet::Expansion => {
                if let Some(p) = parent {
                    if n.expands() && p.state(Facet::Expansion) < State::Enabled {
                        let msg =
                            format!("the parent's expansion is {}", p.state(Facet::Expansion));
                        found.push((Rule::ExpansionEnable, msg));
                    }
                }
            }
            Facet::Execution => {
                if let Some(p) = parent {
                    if p.state(Facet::Execution) < State::Enabled {
                        let msg =
                            format!("the parent's execution is {}", p.state(Facet::Execution));
                        found.push((Rule::ExecutionEnable, msg));
                    }
                }
            }
        }
        let mut n_checked = 0;
        for c in n.constraints() {
            n_checked += 1;
            if let Some(problem) = self.constraint_blocks(ev, n, facet, c) {
                found.push(problem);
            }
        }
        n_checked
    }

    // Whether constraint `c` of node `n` still forbade `facet` from becoming enabled at `ev`.
    fn constraint_blocks(
        &self,
        ev: &TraceEvent,
        n: &ReplayNode,
        facet: Facet,
        c: &TraceConstraint,
    ) -> Option<(Rule, String)> {
        match c {
            TraceConstraint::DisableUntilEvent { facet: f, event } if *f == facet => {
                let ok = match self.replay.node(event.node) {
                    Some(r) => r.is_dead() || r.reached_at(event.facet, event.point).is_some(),
                    None => false,
                };
                (!ok).then(|| {
                    (
                        Rule::DisableUntilEvent,
                        format!("it waits for {}, which has not happened", ref_text(event)),
                    )
                })
            }
            TraceConstraint::DisableUntilTime { facet: f, at } if *f == facet => {
                (ev.t < *at).then(|| {
                    (
                        Rule::DisableUntilTime,
                        format!("it is disabled until t={}", secs(*at)),
                    )
                })
            }
            TraceConstraint::DisableForAfter {
                facet: f,
                delay_ns,
                event,
            } if *f == facet => {
                let since = self.replay.node(event.node).and_then(|r| {
                    r.dead_at()
                        .or_else(|| r.reached_at(event.facet, event.point))
                });
                match since {
                    None => Some((
                        Rule::DisableForAfter,
                        format!(
                            "it waits {} after {}, which has not happened",
                            secs(*delay_ns),
                            ref_text(event)
                        ),
                    )),
                    Some(s) if ev.t < s.saturating_add(*delay_ns) => Some((
                        Rule::DisableForAfter,
                        format!(
                            "it waits {} after {} (at t={}), until t={}",
                            secs(*delay_ns),
                            ref_text(event),
                            secs(s),
                            secs(s.saturating_add(*delay_ns))
                        ),
                    )),
                    Some(_) => None,
                }
            }
            TraceConstraint::DisableUntilExternal { facet: f, name } if *f == facet => {
                (!self.externals.contains(name)).then(|| {
                    (
                        Rule::DisableUntilExternal,
                        format!("it waits for the external event `{name}`, not raised yet"),
                    )
                })
            }
            TraceConstraint::ExpandFirst if facet == Facet::Execution => {
                (n.state(Facet::Expansion) != State::Completed).then(|| {
                    (
                        Rule::ExpandFirst,
                        format!(
                            "`expand first`, but the expansion is {}",
                            n.state(Facet::Expansion)
                        ),
                    )
                })
            }
            TraceConstraint::DelayExpansion if facet == Facet::Expansion => {
                (n.state(Facet::Execution) < State::Enabled).then(|| {
                    (
                        Rule::DelayExpansion,
                        format!(
                            "`delay expansion`, but the execution is {}",
                            n.state(Facet::Execution)
                        ),
                    )
                })
            }
            _ => None,
        }
    }

    fn activation(
        &self,
        n: &ReplayNode,
        facet: Facet,
        cur: State,
        found: &mut Vec<(Rule, String)>,
    ) {
        match facet {
            Facet::Handling => {
                if cur != State::Enabled {
                    found.push((
                        Rule::HandlingSkipsEnabled,
                        "handling must be enabled before it is active".into(),
                    ));
                }
                if n.termination() != Termination::Alive {
                    found.push((
                        Rule::ActiveWhileTerminating,
                        "a terminating node never starts its action".into(),
                    ));
                }
                if n.is_suspended() {
                    found.push((Rule::ActiveWhileSuspended, "the node is suspended".into()));
                }
            }
            Facet::Expansion => {
                if !n.goal_started_below {
                    found.push((
                        Rule::ExpansionActive,
                        "no goal-like node of its subtree has started handling".into(),
                    ));
                }
            }
            Facet::Execution => {
                if !n.command_started_below {
                    found.push((
                        Rule::ExecutionActive,
                        "no command-like node of its subtree has started handling".into(),
                    ));
                }
            }
        }
    }

    fn completion(&self, n: &ReplayNode, facet: Facet, found: &mut Vec<(Rule, String)>) {
        match facet {
            Facet::Handling => {}
            Facet::Expansion => {
                if !n.goals_done() {
                    let msg = if n.expands() && n.state(Facet::Handling) != State::Completed {
                        format!("its own handling is {}", n.state(Facet::Handling))
                    } else {
                        format!(
                            "{} child subtree(s) still have goals not handled",
                            n.n_children_goals_open
                        )
                    };
                    found.push((Rule::ExpansionComplete, msg));
                }
            }
            Facet::Execution => {
                let mut open = Vec::new();
                for f in [Facet::Handling, Facet::Expansion] {
                    if n.state(f) != State::Completed {
                        open.push(format!("its {f} is {}", n.state(f)));
                    }
                }
                if n.n_children_exec_open > 0 {
                    open.push(format!(
                        "{} child(ren) have not completed execution",
                        n.n_children_exec_open
                    ));
                }
                if !open.is_empty() {
                    found.push((Rule::ExecutionComplete, open.join(", ")));
                }
            }
        }
    }

    fn check_terminated(&mut self, seq: u64, node: u64) {
        let Some(n) = self.replay.node(node) else {
            return;
        };
        if n.termination() != Termination::Terminating {
            let msg = format!(
                "{} is terminated without terminating first ({:?})",
                self.name(node),
                n.termination()
            );
            self.flag(seq, Some(node), Rule::TerminationOrder, msg);
            return;
        }
        let mut open = Vec::new();
        for f in Facet::ALL {
            if n.state(f) != State::Completed {
                open.push(format!("its {f} is {}", n.state(f)));
            }
        }
        if n.n_children_unsettled > 0 {
            open.push(format!(
                "{} child(ren) are neither terminated nor execution-completed",
                n.n_children_unsettled
            ));
        }
        if !open.is_empty() {
            let msg = format!("{} is terminated but {}", self.name(node), open.join(", "));
            self.flag(seq, Some(node), Rule::TerminatedEarly, msg);
        }
    }

    fn check_reclaimed(&mut self, seq: u64, node: u64) {
        let Some(n) = self.replay.node(node) else {
            return;
        };
        let mut open = Vec::new();
        if n.state(Facet::Execution) != State::Completed {
            open.push(format!("its execution is {}", n.state(Facet::Execution)));
        }
        if n.termination() == Termination::Terminating {
            open.push("it is terminating but not terminated".to_string());
        }
        if n.n_children_live > 0 {
            open.push(format!(
                "{} child(ren) are not reclaimed",
                n.n_children_live
            ));
        }
        if !open.is_empty() {
            let msg = format!("{} is reclaimed but {}", self.name(node), open.join(", "));
            self.flag(seq, Some(node), Rule::ReclaimEarly, msg);
        }
    }

    // Fires the termination constraints the record's event triggers.
    fn after_record(&mut self, ev: &TraceEvent) {
        match &ev.kind {
            TraceKind::Transition {
                node,
                facet,
                from,
                to,
            } => {
                let Some(mut watches) = self.watches.remove(node) else {
                    return;
                };
                // Termination constraints do not fire on points reached because the node was terminating.
                let terminating = self
                    .replay
                    .node(*node)
                    .is_some_and(|n| n.termination() != Termination::Alive);
                let mut keep = Vec::new();
                for w in watches.drain(..) {
                    if w.facet == *facet && *from < w.state && w.state <= *to {
                        if !terminating {
                            self.fire_watch(ev, &w);
                        }
                    } else {
                        keep.push(w);
                    }
                }
                if !keep.is_empty() {
                    self.watches.insert(*node, keep);
                }
            }
            TraceKind::Dead { node } => {
                if let Some(watches) = self.watches.remove(node) {
                    for w in &watches {
                        self.fire_watch(ev, w);
                    }
                }
            }
            TraceKind::External { name } => {
                self.externals.insert(name.clone());
                if let Some(targets) = self.external_watches.remove(name) {
                    for target in targets {
                        self.fire(target, Rule::TerminateAtExternal, ev.t, true, ev.seq);
                    }
                }
            }
            _ => {}
        }
    }

    fn fire_watch(&mut self, ev: &TraceEvent, w: &Watch) {
        match w.delay {
            None => self.fire(w.target, Rule::TerminateAtEvent, ev.t, true, ev.seq),
            Some(d) => self.fire(
                w.target,
                Rule::TerminateInAfter,
                ev.t.saturating_add(d),
                d == 0,
                ev.seq,
            ),
        }
    }

    /// Ends the trace: verifies what was still owed and returns the verdict.
    pub fn finish(mut self) -> Result<CheckReport, Vec<Violation>> {
        let last_seq = self.last.map_or(0, |(s, _)| s);
        if self.n_records == 0 {
            self.flag(
                0,
                None,
                Rule::RunStarted,
                "the trace is empty; it must start with `run_started`".into(),
            );
        }
        self.settle_owed(None, last_seq);
        // A reservation dies when its parent's body ends; a trace that ends while that body still runs
        // (a stuck run) owes nothing yet.
        let pending: Vec<u64> = self
            .pending_reserved
            .iter()
            .copied()
            .filter(|n| {
                let parent = self.replay.node(*n).and_then(|it| it.parent());
                parent
                    .and_then(|p| self.replay.node(p))
                    .is_some_and(|p| p.state(Facet::Handling) == State::Completed)
            })
            .collect();
        for node in pending {
            let msg = format!(
                "{} was reserved, and its parent's body has ended, but it is neither spawned nor dead when \
                 the trace ends",
                self.name(node)
            );
            self.flag(last_seq, Some(node), Rule::ReservedUnresolved, msg);
        }
        if self.violations.is_empty() {
            Ok(self.report)
        } else {
            Err(self.violations)
        }
    }
}
