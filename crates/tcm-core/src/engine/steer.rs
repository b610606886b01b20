//! Steering a run from outside (docs/semantics.md, "Steering a run"): pausing, stepping,
//! breakpoints, injected faults and approvals. None of it costs a run that is not steered: the
//! engine keeps it in one box, made at the first request.
//!
//! The rules:
//! 1. **Paused**, no node starts and no timer of the tree fires; what already runs goes on, and
//!    its ends, external events and state changes are applied as usual (a node they make ready
//!    waits). Resuming moves every pending timer (and each polling monitor's schedule) later by
//!    the pause's length on the run's clock, so the tree's timers stand still while it is paused
//!    (on virtual time no time passes, and nothing moves).
//! 2. **A step** lets exactly one held thing happen, then pauses again: the oldest ready node
//!    starts, or, with none ready, the earliest timer fires (with what it causes, but no start).
//!    **To the next start** resumes until a node's turn to start comes, and pauses before it.
//! 3. **A breakpoint** pauses the run *before* a matching node starts (the node keeps its turn: it
//!    starts first when the run goes on, without breaking again), *after* a matching node's action
//!    ended (its end applied, nothing it released started yet), when a matching node *raises* an
//!    exception, or when a matching *handler is chosen*.
//! 4. **A fault** stands for the next `times` ends of matching nodes: at the node's start its
//!    action does not run; the node fails at once with the fault's exception, succeeds at once
//!    (with a value the shell is handed for whoever waits for it, `Effect::Value`), or never ends
//!    (until it is terminated). An `injected` record says which.
//! 5. **An approval rule** holds a matching node whose turn to start came (`held`) until an
//!    operator approves it (`approved`, then it starts at its turn) or refuses it, or its time runs
//!    out: then it fails with [`ApprovalRefused`]. A held node gives back what it was granted and
//!    asks again once approved.
//! 6. Every request from outside is also a `control` record naming who asked.

use super::node::Node;
use super::timers::TimerKind;
use super::{Engine, EngineError};
use crate::Name;
use crate::arena::Keep;
use crate::failure::Failure;
use crate::ids::NodeId;
use crate::time::Time;
use std::time::Duration;
use tcm_trace::{Facet, State, TraceKind};

/// Which nodes a breakpoint, fault or approval rule is about.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Matcher {
    /// Every node.
    Any,
    /// The nodes of a task (their task name, as wiretaps match).
    Task(Name),
    /// The nodes whose path (names from the top-level task down, joined by `/`) matches: a `*`
    /// segment matches one name, `**` any number of names, `a*` a name starting with `a`.
    Path(String),
    /// One node.
    Node(NodeId),
    /// For breakpoints on exceptions: the failures of that exception type or a descendant.
    Exception(Name),
}

/// When a breakpoint pauses the run (rule 3).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BreakAt {
    /// Before a matching node starts.
    Start,
    /// After a matching node's action ended.
    End,
    /// When a matching node raises an exception (or one matching [`Matcher::Exception`] is
    /// raised).
    Raised,
    /// When a handler is chosen whose name matches (or for an exception that matches).
    Handler,
}

/// A breakpoint.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Breakpoint {
    /// When it pauses.
    pub at: BreakAt,
    /// For which nodes.
    pub on: Matcher,
}

/// What an injected fault makes of a node's end (rule 4).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum FaultOutcome {
    /// The node fails with this exception.
    Fail(Failure),
    /// The node succeeds, with this value for whoever waits for it (none: as if its action
    /// returned nothing anybody reads).
    Succeed(Option<FaultValue>),
    /// The node never ends, until it is terminated.
    Never,
}

/// A value that stands for an action's: made afresh for each node the fault takes (the shell
/// keeps values as `Box<dyn Any + Send>`, as an action returns them), with how the trace tells
/// it.
#[derive(Clone)]
pub struct FaultValue {
    make: std::sync::Arc<dyn Fn() -> Box<dyn std::any::Any + Send> + Send + Sync>,
    text: String,
}

impl FaultValue {
    /// A value made by `make`, told as `text` in the trace.
    pub fn new(
        text: impl Into<String>,
        make: impl Fn() -> Box<dyn std::any::Any + Send> + Send + Sync + 'static,
    ) -> FaultValue {
        FaultValue {
            make: std::sync::Arc::new(make),
            text: text.into(),
        }
    }

    /// A clone of `value` each time.
    pub fn of<T: Clone + std::fmt::Debug + Send + Sync + 'static>(value: T) -> FaultValue {
        let text = format!("{value:?}");
        FaultValue::new(text, move || Box::new(value.clone()))
    }

    /// One value, made afresh.
    pub fn make(&self) -> Box<dyn std::any::Any + Send> {
        (self.make)()
    }

    /// How the trace tells it.
    pub fn text(&self) -> &str {
        &self.text
    }
}

impl std::fmt::Debug for FaultValue {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "FaultValue({})", self.text)
    }
}

/// Two fault values are equal when they are the same maker.
impl PartialEq for FaultValue {
    fn eq(&self, other: &FaultValue) -> bool {
        std::sync::Arc::ptr_eq(&self.make, &other.make) && self.text == other.text
    }
}

impl Eq for FaultValue {}

/// A fault for the next `times` matching nodes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Fault {
    /// Which nodes.
    pub on: Matcher,
    /// How many of their starts it takes, in all.
    pub times: u32,
    /// What stands for their ends.
    pub outcome: FaultOutcome,
}

/// A rule that holds matching nodes until an operator approves them (rule 5).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Approval {
    /// Which nodes.
    pub on: Matcher,
    /// How long a node waits before it fails with [`ApprovalRefused`]; `None`: as long as it takes.
    pub timeout: Option<Duration>,
}

/// The number of a breakpoint, fault or approval rule, to remove it again.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct SteerId(pub u32);

/// The exception of a node held for approval that was refused, or whose time ran out.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("not approved: {reason}")]
pub struct ApprovalRefused {
    /// Who refused it (`timeout` when its time ran out).
    pub by: String,
    /// Why, for people.
    pub reason: String,
}

/// Where a step stands (rule 2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Step {
    /// One held thing may happen, then the run pauses.
    One,
    /// The run pauses before the next start.
    ToStart,
}

/// What `start` does with a node whose turn came (`Engine::start_gate`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) enum Gate {
    /// It starts.
    Go,
    /// It starts, and a fault stands for its action (kept in `Steering::injecting` until its
    /// handling is active).
    Inject,
    /// It does not start now (paused before it, or held for approval).
    Stop,
}

/// A run's steering, in [`Engine`]'s box (see the module's documentation).
#[derive(Clone, Default)]
pub(super) struct Steering {
    // Since when the run is paused.
    paused: Option<Time>,
    // The node a breakpoint paused before: it starts at the next go without breaking again.
    passed: Option<NodeId>,
    step: Option<Step>,
    // Set by a step that let one start through: the run pauses once the start is done.
    pause_after: bool,
    breakpoints: Vec<(SteerId, Breakpoint)>,
    faults: Vec<(SteerId, Fault)>,
    approvals: Vec<(SteerId, Approval)>,
    // Nodes held for approval, in the order held.
    held: Vec<NodeId>,
    // The fault standing for the action of the node starting now (`Gate::Inject`).
    injecting: Option<(NodeId, FaultOutcome)>,
    last: u32,
}

impl Steering {
    fn next_id(&mut self) -> SteerId {
        self.last += 1;
        SteerId(self.last)
    }
}

mod op;
mod path;
mod text;

pub use op::{FaultOp, MatcherOp, SteerOp};

pub(crate) use path::path_matches;
use text::{at_text, outcome_text};

impl<A, F: Clone, S: Keep<Node<A, F>>> Engine<A, F, S> {
    fn steering(&mut self) -> &mut Steering {
        self.steer.get_or_insert_with(Box::default)
    }

    /// Whether the run is paused (rule 1).
    pub fn is_paused(&self) -> bool {
        self.steer.as_ref().is_some_and(|s| s.paused.is_some())
    }

    /// Whether the run waits for whoever steers it: it is paused, or a node is held for approval.
    /// Such a run is not stuck (docs/semantics.md, "Run outcome").
    pub fn waits_for_operator(&self) -> bool {
        self.steer
            .as_ref()
            .is_some_and(|s| s.paused.is_some() || s.held.iter().any(|n| self.is_held(*n)))
    }

    /// Whether nothing starts and no timer fires now: paused, and no step lets one through.
    #[inline]
    pub(super) fn halted(&self) -> bool {
        self.steer.as_ref().is_some_and(|s| s.paused.is_some())
    }

    fn note(&mut self, what: String, by: &str, op: Option<SteerOp>) {
        self.record(|_| super::InputRecord::Control {
            what: what.clone(),
            by: by.to_string(),
            op,
        });
        self.trace_control(what, by);
    }

    /// The `control` record of an operation, or of a part of one (a release's resumption, which
    /// the release's input stands for).
    fn trace_control(&mut self, what: String, by: &str) {
        if self.tracing {
            self.push_trace(TraceKind::Control {
                what,
                by: by.to_string(),
            });
        }
    }

    /// Pauses the run (rule 1), as `by` asked; `false` if it was paused already.
    pub fn pause(&mut self, now: Time, by: &str) -> bool {
        self.advance(now);
        if self.is_paused() {
            return false;
        }
        self.note("pause".into(), by, Some(SteerOp::Pause));
        self.pause_at(None, format!("asked by {by}"));
        true
    }

    /// Pauses the run at `node`, for `why`.
    pub(super) fn pause_at(&mut self, node: Option<NodeId>, why: String) {
        let now = self.now;
        let s = self.steering();
        if s.paused.is_some() {
            return;
        }
        s.paused = Some(now);
        s.step = None;
        let node = node.and_then(|n| self.nodes.get(n)).map(|n| n.display);
        emit!(self, TraceKind::Paused { node, why });
    }

    /// Resumes a paused run (rule 1), as `by` asked; `false` if it was not paused.
    pub fn resume(&mut self, now: Time, by: &str) -> bool {
        self.go(now, by, "continue", None, Some(SteerOp::Resume))
    }

    /// Lets one held thing happen, then pauses again (rule 2); `false` if the run was not paused.
    pub fn step(&mut self, now: Time, by: &str) -> bool {
        self.go(now, by, "step", Some(Step::One), Some(SteerOp::Step))
    }

    /// Resumes until the next node's turn to start, and pauses before it (rule 2); `false` if the
    /// run was not paused.
    pub fn step_to_start(&mut self, now: Time, by: &str) -> bool {
        self.go(
            now,
            by,
            "step to the next start",
            Some(Step::ToStart),
            Some(SteerOp::StepToStart),
        )
    }

    /// Resumes (with `step`, to step); `op`: the operation it is, or `None` when it is part of
    /// another, whose input stands for it.
    fn go(
        &mut self,
        now: Time,
        by: &str,
        what: &str,
        step: Option<Step>,
        op: Option<SteerOp>,
    ) -> bool {
        self.advance(now);
        let Some(since) = self.steer.as_ref().and_then(|s| s.paused) else {
            return false;
        };
        match op {
            Some(op) => self.note(what.into(), by, Some(op)),
            None => self.trace_control(what.into(), by),
        }
        let held = now.max(self.now) - since;
        let s = self.steering();
        s.paused = None;
        s.step = step;
        if !held.is_zero() {
            self.shift_timers(held);
        }
        let held_ns = u64::try_from(held.as_nanos()).unwrap_or(u64::MAX);
        emit!(self, TraceKind::Resumed { held_ns });
        self.settle();
        true
    }

    /// Rule 1: the tree's timers and its monitors' polling schedules move `by` later.
    fn shift_timers(&mut self, by: Duration) {
        self.timers.shift(by);
        let monitors: Vec<NodeId> = self
            .nodes
            .iter()
            .filter(|(_, n)| n.monitor().is_some())
            .map(|(id, _)| id)
            .collect();
        for id in monitors {
            if let Some(m) = self.node_mut(id).monitor_mut() {
                m.anchor.0 = m.anchor.0 + by;
            }
        }
    }

    /// A timer is about to fire while a step is pending: it is the step's one thing (rule 2).
    /// Returns whether the run pauses after it.
    pub(super) fn timer_steps(&mut self) -> bool {
        match self.steer.as_mut() {
            Some(s) if s.step == Some(Step::One) => {
                s.step = None;
                true
            }
            _ => false,
        }
    }

    /// Adds a breakpoint, as `by` asked; returns its number.
    pub fn add_breakpoint(&mut self, now: Time, bp: Breakpoint, by: &str) -> SteerId {
        self.advance(now);
        let what = format!(
            "breakpoint {} {}",
            at_text(bp.at),
            self.matcher_text(&bp.on)
        );
        let op = SteerOp::Breakpoint {
            at: bp.at,
            on: self.on_of(&bp.on),
        };
        let s = self.steering();
        let id = s.next_id();
        s.breakpoints.push((id, bp));
        self.note(format!("{what} (#{})", id.0), by, Some(op));
        id
    }

    /// Removes a breakpoint, fault or approval rule: `false` if there is none of that number.
    pub fn remove_steer(&mut self, now: Time, id: SteerId, by: &str) -> bool {
        self.advance(now);
        let Some(s) = self.steer.as_mut() else {
            return false;
        };
        let before = s.breakpoints.len() + s.faults.len() + s.approvals.len();
        s.breakpoints.retain(|(i, _)| *i != id);
        s.faults.retain(|(i, _)| *i != id);
        s.approvals.retain(|(i, _)| *i != id);
        let removed = before != s.breakpoints.len() + s.faults.len() + s.approvals.len();
        if removed {
            self.note(
                format!("removed #{}", id.0),
                by,
                Some(SteerOp::Remove { id: id.0 }),
            );
        }
        removed
    }

    /// Removes every breakpoint and approval rule and resumes the run if paused; each node held
    /// for approval is approved (a closed page must not leave the robot waiting: docs/viewer.md).
    /// Faults stay.
    pub fn release(&mut self, now: Time, by: &str) {
        self.advance(now);
        let Some(s) = self.steer.as_mut() else {
            return;
        };
        s.breakpoints.clear();
        s.approvals.clear();
        s.step = None;
        let held = std::mem::take(&mut s.held);
        self.note(
            "release breakpoints and holds".into(),
            by,
            Some(SteerOp::Release),
        );
        for node in held {
            self.approve_held(node, by);
        }
        self.go(now, by, "continue", None, None);
        self.settle();
    }

    /// Injects a fault (rule 4), as `by` asked; returns its number.
    pub fn inject(&mut self, now: Time, fault: Fault, by: &str) -> SteerId {
        self.advance(now);
        let what = format!(
            "inject {} into the next {} of {}",
            outcome_text(&fault.outcome),
            fault.times,
            self.matcher_text(&fault.on)
        );
        let op = op::fault_op(&fault.outcome).map(|outcome| SteerOp::Fault {
            on: self.on_of(&fault.on),
            times: fault.times,
            outcome,
        });
        let s = self.steering();
        let id = s.next_id();
        s.faults.push((id, fault));
        self.note(format!("{what} (#{})", id.0), by, op);
        id
    }

    /// Adds an approval rule (rule 5), as `by` asked; returns its number.
    pub fn require_approval(&mut self, now: Time, rule: Approval, by: &str) -> SteerId {
        self.advance(now);
        let what = format!("approval for {}", self.matcher_text(&rule.on));
        let op = SteerOp::Approval {
            on: self.on_of(&rule.on),
            timeout_ns: rule
                .timeout
                .map(|t| u64::try_from(t.as_nanos()).unwrap_or(u64::MAX)),
        };
        let s = self.steering();
        let id = s.next_id();
        s.approvals.push((id, rule));
        self.note(format!("{what} (#{})", id.0), by, Some(op));
        id
    }

    /// The live node whose display number (the one traces show) is `number`; a linear search,
    /// for requests from people.
    pub fn node_by_display(&self, number: u64) -> Option<NodeId> {
        self.nodes
            .iter()
            .find(|(_, n)| n.display == number)
            .map(|(id, _)| id)
    }

    /// The nodes held for approval now, in the order held.
    pub fn held(&self) -> Vec<NodeId> {
        self.steer.as_ref().map_or_else(Vec::new, |s| {
            s.held
                .iter()
                .copied()
                .filter(|n| self.is_held(*n))
                .collect()
        })
    }

    fn is_held(&self, node: NodeId) -> bool {
        self.nodes
            .get(node)
            .is_some_and(|n| n.alive() && n.state(Facet::Handling) == State::Enabled)
    }

    /// Approves a node held for approval: it starts at its turn. An error if it is not held.
    pub fn approve(&mut self, now: Time, node: NodeId, by: &str) -> Result<(), EngineError> {
        self.advance(now);
        self.check_run(node)?;
        if !self.take_held(node) {
            return Err(EngineError::NotHeld(node));
        }
        let op = SteerOp::Approve {
            node: self.display_of(node),
        };
        self.note(format!("approve {}", self.node_text(node)), by, Some(op));
        self.approve_held(node, by);
        self.settle();
        Ok(())
    }

    /// Refuses a node held for approval: it fails with [`ApprovalRefused`]. An error if it is not
    /// held.
    pub fn refuse(
        &mut self,
        now: Time,
        node: NodeId,
        by: &str,
        reason: &str,
    ) -> Result<(), EngineError> {
        self.advance(now);
        self.check_run(node)?;
        if !self.take_held(node) {
            return Err(EngineError::NotHeld(node));
        }
        let op = SteerOp::Refuse {
            node: self.display_of(node),
            reason: reason.to_string(),
        };
        self.note(format!("refuse {}", self.node_text(node)), by, Some(op));
        self.refuse_held(node, by, reason.to_string());
        self.settle();
        Ok(())
    }

    fn take_held(&mut self, node: NodeId) -> bool {
        let held = self.is_held(node);
        match self.steer.as_mut() {
            Some(s) if held => {
                let before = s.held.len();
                s.held.retain(|n| *n != node);
                before != s.held.len()
            }
            _ => false,
        }
    }

    fn approve_held(&mut self, node: NodeId, by: &str) {
        if !self.is_held(node) {
            return;
        }
        let display = self.node(node).display;
        self.node_mut(node).cold_mut().approved = true;
        emit!(
            self,
            TraceKind::Approved {
                node: display,
                by: by.to_string(),
            }
        );
        self.ready.push_back(node);
    }

    fn refuse_held(&mut self, node: NodeId, by: &str, reason: String) {
        if !self.is_held(node) {
            return;
        }
        let failure = Failure::from(ApprovalRefused {
            by: by.to_string(),
            reason,
        });
        self.fail(node, failure);
        self.complete_handling(node);
    }

    /// The approval timer of `node` fired: a node still held fails (rule 5).
    pub(super) fn approval_timed_out(&mut self, node: NodeId, after: Duration) {
        if self.take_held(node) {
            self.refuse_held(node, "timeout", format!("no approval within {after:?}"));
        }
    }

    /// `node`'s turn to start came and it passed its checks (`start.rs`): whether it starts
    /// (rules 2 to 5). Only called on a steered run.
    pub(super) fn start_gate(&mut self, node: NodeId, is_monitor: bool) -> Gate {
        let s = self.steering();
        if s.passed == Some(node) {
            s.passed = None;
        } else if s.step == Some(Step::ToStart) {
            s.step = None;
            s.passed = Some(node);
            self.ready.push_front(node);
            self.pause_at(Some(node), "step: before its start".into());
            return Gate::Stop;
        } else if let Some(id) = self.breaks(BreakAt::Start, node, None) {
            let s = self.steering();
            s.passed = Some(node);
            self.ready.push_front(node);
            let why = format!("breakpoint #{}: before {}", id.0, self.node_text(node));
            self.pause_at(Some(node), why);
            return Gate::Stop;
        }
        let approved = self
            .nodes
            .get(node)
            .and_then(|n| n.cold.as_ref())
            .is_some_and(|c| c.approved);
        if !approved {
            if let Some(timeout) = self.approval_rule(node) {
                self.hold(node, timeout);
                return Gate::Stop;
            }
        }
        let s = self.steering();
        if s.step == Some(Step::One) {
            s.step = None;
            s.pause_after = true;
        }
        if is_monitor {
            return Gate::Go;
        }
        match self.fault_for(node) {
            Some(outcome) => {
                self.steering().injecting = Some((node, outcome));
                Gate::Inject
            }
            None => Gate::Go,
        }
    }

    /// After a start a step let through: the run pauses (rule 2).
    pub(super) fn after_start(&mut self) {
        if let Some(s) = self.steer.as_mut() {
            if std::mem::take(&mut s.pause_after) {
                self.pause_at(None, "step".into());
            }
        }
    }

    /// Whether a breakpoint `at` matches `node` (and `failure`), and which.
    pub(super) fn breaks(
        &self,
        at: BreakAt,
        node: NodeId,
        failure: Option<&Failure>,
    ) -> Option<SteerId> {
        let s = self.steer.as_ref()?;
        s.breakpoints
            .iter()
            .find(|(_, bp)| bp.at == at && self.matches(&bp.on, node, failure))
            .map(|(id, _)| *id)
    }

    /// Rule 3 for the points other than a start: pauses the run if a breakpoint `at` matches.
    #[cold]
    #[inline(never)]
    pub(super) fn break_at(&mut self, at: BreakAt, node: NodeId, failure: Option<&Failure>) {
        if self.steer.is_none() {
            return;
        }
        if let Some(id) = self.breaks(at, node, failure) {
            let point = match at {
                BreakAt::Start => "before",
                BreakAt::End => "after the end of",
                BreakAt::Raised => "exception raised by",
                BreakAt::Handler => "handler chosen:",
            };
            let why = format!("breakpoint #{}: {point} {}", id.0, self.node_text(node));
            self.pause_at(Some(node), why);
        }
    }

    fn matches(&self, m: &Matcher, node: NodeId, failure: Option<&Failure>) -> bool {
        let Some(n) = self.nodes.get(node) else {
            return false;
        };
        match m {
            Matcher::Any => true,
            Matcher::Task(name) => n.task_name() == name || n.name == *name,
            Matcher::Path(p) => path_matches(p, &self.path(node)),
            Matcher::Node(id) => *id == node,
            Matcher::Exception(e) => failure.is_some_and(|f| f.is_a(e)),
        }
    }

    fn approval_rule(&self, node: NodeId) -> Option<Option<Duration>> {
        let own = self
            .nodes
            .get(node)
            .and_then(|n| n.cold.as_ref())
            .and_then(|c| c.approval);
        if own.is_some() {
            return own;
        }
        let s = self.steer.as_ref()?;
        s.approvals
            .iter()
            .find(|(_, a)| self.matches(&a.on, node, None))
            .map(|(_, a)| a.timeout)
    }

    fn fault_for(&mut self, node: NodeId) -> Option<FaultOutcome> {
        let i = {
            let s = self.steer.as_ref()?;
            s.faults
                .iter()
                .position(|(_, f)| f.times > 0 && self.matches(&f.on, node, None))?
        };
        let s = self.steering();
        let f = &mut s.faults[i].1;
        f.times -= 1;
        let outcome = f.outcome.clone();
        if f.times == 0 {
            s.faults.remove(i);
        }
        Some(outcome)
    }

    /// Holds `node` for approval (rule 5).
    fn hold(&mut self, node: NodeId, timeout: Option<Duration>) {
        if self.node(node).grant() == super::resource::Grant::Held {
            self.release_resources(node);
        }
        self.steering().held.push(node);
        let display = self.node(node).display;
        emit!(self, TraceKind::Held { node: display });
        if let Some(t) = timeout {
            let at = self.now + t;
            self.timers.push(at, TimerKind::Approval { node, after: t });
        }
    }

    /// What happens at the start of a node a fault stands for (rule 4); its handling is active.
    pub(super) fn injected(&mut self, node: NodeId) {
        let Some((_, outcome)) = self
            .steer
            .as_mut()
            .and_then(|s| s.injecting.take())
            .filter(|(n, _)| *n == node)
        else {
            return;
        };
        let display = self.node(node).display;
        emit!(
            self,
            TraceKind::Injected {
                node: display,
                outcome: outcome_text(&outcome),
            }
        );
        match outcome {
            FaultOutcome::Fail(failure) => {
                self.fail(node, failure);
                self.complete_handling(node);
                self.break_at(BreakAt::End, node, None);
            }
            FaultOutcome::Succeed(value) => {
                if let Some(value) = value {
                    self.effects.push_back(super::Effect::Value {
                        node,
                        value: Box::new(value),
                    });
                }
                self.complete_handling(node);
                self.break_at(BreakAt::End, node, None);
            }
            FaultOutcome::Never => self.node_mut(node).cold_mut().never_ends = true,
        }
    }
}
