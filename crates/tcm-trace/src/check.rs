//! The trace checker: verifies that a trace obeys the engine's emission discipline.
//!
//! [`check`] (or a [`Checker`] fed record by record) replays the trace and, at each record, verifies the
//! rules listed in [`Rule`]: the shape of the trace, the Figure 3 axioms and the parent/child
//! constraints (docs/semantics.md, "Facets and states"), and that every applied constraint was respected. Every runtime test
//! calls it on the engine's real traces, so each rule is exact: a rule that can be read two ways (see the
//! `Rule` docs) accepts both readings rather than guess.
//!
//! Cost: each record costs a few map look-ups plus, for a facet becoming enabled, one pass over that
//! node's own constraints. Subtree conditions ("some goal below has started", "every goal below is
//! handled") are aggregates kept by [`Replay`] and updated along the ancestor path only while they
//! change, which is amortised constant time. Due terminations wait in a binary heap keyed by time.

use crate::event::{
    OLDEST_READABLE_VERSION, TRACE_FORMAT_VERSION, TraceEvent, TraceEventRef, TraceKind, TraceWhen,
};
use crate::replay::Replay;
use crate::state::{Facet, State, Termination};
use std::cmp::Reverse;
use std::collections::{BTreeMap, BTreeSet, BinaryHeap};

mod conditions;
mod facets;
mod resources;
mod rule;
#[cfg(test)]
mod tests;
mod triggers;

pub use rule::{CheckReport, MAX_VIOLATIONS, Rule, Violation};
use triggers::{Owed, Watch};

/// Checks a whole trace.
pub fn check(trace: &[TraceEvent]) -> Result<CheckReport, Vec<Violation>> {
    let mut checker = Checker::new();
    for ev in trace {
        checker.push(ev);
    }
    checker.finish()
}

/// Checks a prefix of a trace: the records a run wrote before it was cut (a process killed, a
/// file still being written). Every rule applies to the records present; only what a whole
/// trace owes at its end is not asked for (a termination due at the last record's time, a
/// reservation not yet resolved), since the cut may have taken it.
pub fn check_prefix(trace: &[TraceEvent]) -> Result<CheckReport, Vec<Violation>> {
    let mut checker = Checker::new();
    for ev in trace {
        checker.push(ev);
    }
    checker.finish_prefix()
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
    // `terminate` triggers on a whole group: members still to reach their event.
    groups: Vec<triggers::GroupWatch>,
    external_watches: BTreeMap<String, Vec<u64>>,
    owed: BinaryHeap<Reverse<Owed>>,
    // Timer callbacks set: when each runs, and whether it ran.
    callbacks: BTreeMap<u64, (TraceWhen, bool)>,
    // Checking a prefix: the end of the records is not the end of the run (`finish_prefix`).
    prefix: bool,
    // Triggers on conditions over state variables (`conditions.rs`).
    conditions: Vec<conditions::CondTrigger>,
}

fn ref_text(r: &TraceEventRef) -> String {
    match r.outcome {
        Some(o) => format!("node {} {}", r.node, o.as_str()),
        None => format!("node {} {} {}", r.node, r.facet, r.point.as_str()),
    }
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
            if !(OLDEST_READABLE_VERSION..=TRACE_FORMAT_VERSION).contains(&version) {
                self.flag(
                    seq,
                    None,
                    Rule::RunStarted,
                    format!(
                        "format version {version}; this checker knows versions \
                         {OLDEST_READABLE_VERSION} to {TRACE_FORMAT_VERSION}"
                    ),
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
            self.check_condition_record(ev);
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
                self.check_resource_state(seq, *node, &ev.kind);
            }
            TraceKind::Terminating { node } => {
                if let Some(n) = self.replay.node(*node) {
                    if n.termination() != Termination::Alive {
                        let msg = format!("{} is asked to terminate twice", self.name(*node));
                        self.flag(seq, Some(*node), Rule::TerminationOrder, msg);
                    }
                }
            }
            TraceKind::Terminated { node } => {
                self.check_terminated(seq, *node);
                self.check_resource_state(seq, *node, &ev.kind);
            }
            TraceKind::Reclaimed { node } => {
                self.check_reclaimed(seq, *node);
                self.check_resource_state(seq, *node, &ev.kind);
            }
            TraceKind::Resource { .. }
            | TraceKind::Requested { .. }
            | TraceKind::Granted { .. }
            | TraceKind::Released { .. }
            | TraceKind::Withdrawn { .. }
            | TraceKind::Denied { .. }
            | TraceKind::Dropped { .. }
            | TraceKind::ResourceReserved { .. }
            | TraceKind::ResourceUnreserved { .. }
            | TraceKind::ResourceLocked { .. }
            | TraceKind::ResourceUnlocked { .. } => self.check_resource(ev),
            TraceKind::Activated {
                monitor,
                node,
                number,
            } => self.check_activated(seq, *monitor, *node, *number),
            TraceKind::HandlerChosen { node, failing, .. } => {
                self.check_handler(seq, *node, *failing)
            }
            TraceKind::CallbackSet { callback, when, .. } => {
                self.check_callback_set(seq, *callback, when)
            }
            TraceKind::CallbackRan { callback, name } => {
                self.check_callback_ran(ev, *callback, name)
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

    fn check_callback_set(&mut self, seq: u64, callback: u64, when: &TraceWhen) {
        if let Some(r) = when.event() {
            if self.replay.node(r.node).is_none() {
                let msg = format!(
                    "callback {callback} waits for {}, a node never seen in the trace",
                    ref_text(&r)
                );
                self.flag(seq, None, Rule::UnknownReference, msg);
            }
        }
        if self
            .callbacks
            .insert(callback, (when.clone(), false))
            .is_some()
        {
            let msg = format!("callback {callback} is set twice");
            self.flag(seq, None, Rule::Callback, msg);
        }
    }

    fn check_callback_ran(&mut self, ev: &TraceEvent, callback: u64, name: &str) {
        let problem = match self.callbacks.get(&callback).cloned() {
            None => Some("it was never set".to_string()),
            Some((_, true)) => Some("it already ran".to_string()),
            Some((when, false)) => {
                self.callbacks.insert(callback, (when.clone(), true));
                self.trigger_pending(ev, None, &when, false)
            }
        };
        if let Some(problem) = problem {
            let msg = format!("callback {callback} (`{name}`) ran, but {problem}");
            self.flag(ev.seq, None, Rule::Callback, msg);
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

    /// Ends the trace: verifies what was still owed and returns the verdict.
    /// Ends a prefix of a trace (see [`check_prefix`]): the end-of-trace obligations are waived.
    pub fn finish_prefix(mut self) -> Result<CheckReport, Vec<Violation>> {
        self.prefix = true;
        self.finish()
    }

    /// Ends a whole trace: what is still owed at its end is flagged too.
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
        if !self.prefix {
            // The request that went past a pending limit was dealt with before the trace ended.
            self.pending_within_limits(last_seq);
        }
        // A reservation dies when its parent's body ends, or, for the label of an on-terminate task,
        // which the trace records under the body that stated it, when the spawned node that took it
        // over completes its execution (docs/semantics.md, "Tags and forward references"). So only
        // a parent whose execution completed owes a resolution; a trace that ends while its subtree
        // still runs (a stuck or fatal run) owes nothing yet.
        let pending: Vec<u64> = self
            .pending_reserved
            .iter()
            .copied()
            .filter(|n| {
                if self.prefix {
                    return false;
                }
                let parent = self.replay.node(*n).and_then(|it| it.parent());
                parent
                    .and_then(|p| self.replay.node(p))
                    .is_some_and(|p| p.state(Facet::Execution) == State::Completed)
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
