//! The engine: a sans-IO state machine that owns the task tree, the constraints and the agenda.
//!
//! # Method families
//!
//! The shell feeds the engine *inputs* (things that happened, `handle_*`) and *commands* (what the
//! program or a running action asks), each with the current virtual time; then it drains the
//! *outputs* (`poll_*`). Every input and command settles the engine completely before it returns:
//! all signals it caused are delivered and every node that became ready is started, so the outputs
//! are complete. The steps every shell runs to do this, for the tokio runtime and the simulator
//! alike, are [`crate::Driver`]'s.
//!
//! | family | methods | file |
//! |---|---|---|
//! | inputs | [`Engine::handle_action_finished`], [`Engine::handle_action_stopped`], [`Engine::handle_timeout`] | `progress.rs` |
//! | | [`Engine::handle_external`] | `arm/external.rs` |
//! | | [`Engine::set_state`] | `state.rs` |
//! | commands: the tree | [`Engine::spawn`], [`Engine::reserve`], [`Engine::hold_children`] | `tree.rs` |
//! | commands: constraints | [`Engine::constrain`] | `arm.rs` |
//! | | [`Engine::trigger_group`] | `arm/group.rs` |
//! | | [`Engine::watch`], [`Engine::external`] | `arm/external.rs` |
//! | commands: termination | [`Engine::terminate`], [`Engine::terminate_children`], [`Engine::terminate_siblings`], [`Engine::suspend`], [`Engine::unsuspend`] | `terminate.rs` |
//! | commands: monitors | [`Engine::activate`], [`Engine::trigger`], [`Engine::set_max_activations`], [`Engine::set_max_triggers`], [`Engine::set_period`] | `monitor.rs` |
//! | commands: exceptions | [`Engine::request_bypass`], [`Engine::retry`] | `exception.rs` |
//! | commands: wiretaps | [`Engine::wiretap`] | `wiretap.rs` |
//! | commands: state | [`Engine::declare_state`], [`Engine::condition`] | `state.rs` |
//! | commands: resources | [`Engine::declare_resource`], [`Engine::reserve_resource`], [`Engine::unreserve_resource`], [`Engine::lock_resource`], [`Engine::unlock_resource`] | `resource.rs` |
//! | commands: timer callbacks | [`Engine::invoke_when`], [`Engine::invoke_at`], [`Engine::notify_at`], [`Engine::callback_ran`] | `callback.rs` |
//! | outputs | [`Engine::poll_effect`], [`Engine::poll_trace`], [`Engine::poll_timeout`] | here |
//! | queries | [`Engine::root`], [`Engine::now`], [`Engine::stats`], [`Engine::path`], [`Engine::fatal`], [`Engine::is_idle`], [`Engine::is_settled`] | here |
//! | | [`Engine::info`], [`Engine::parent`], [`Engine::children`], [`Engine::monitor_info`], [`Engine::blocked`], [`Engine::blocked_awaiting`] | `report.rs` |
//! | | [`Engine::resource_id`], [`Engine::resource_info`] | `resource.rs` |
//!
//! Every entry point that takes a node handle checks first that it belongs to this run
//! (`check_run`, through `live` or `lookup`): a handle of another run is an error, never an alias.
//! Queries go through `query`, which answers a handle of another run as a node that is gone.
//!
//! # How one event flows
//!
//! 1. An input changes a node: an action returned, so its handling completes (`progress.rs`).
//! 2. The change is a *transition*; it is traced and fires the node's *waiters*, left there by the
//!    triggers that name that point (`arm.rs`: "disable B's execution until A's execution
//!    completed").
//! 3. A fired trigger releases one block of its target's facet, or arms a timer, or terminates the
//!    target (`terminate.rs`), or activates a monitor (`monitor.rs`), and queues *progress* of the
//!    target. Completions queue progress of the parent.
//! 4. `settle` drains the queue: progress moves a node as far as its constraints allow (facets
//!    become enabled, complete, the node terminates or is reclaimed). A node whose handling becomes
//!    enabled joins the ready queue.
//! 5. When no work is left, the oldest ready node starts: its action becomes an [`Effect::Start`]
//!    (after its "before" wiretaps, `wiretap.rs`); a node terminated before it started completes
//!    there instead. Starting fires "active" waiters, so the loop repeats until all is quiet.
//!
//! Work is queued, never recursive, so a 10,000-deep tree costs no stack. Aggregates (open children
//! per facet) are counters kept on each parent (`tree.rs`): a transition costs O(1) plus the
//! waiters it fires.

/// Traces a record, building it only when someone reads the trace (records carry names and
/// messages; building and dropping them would cost every transition when tracing is off).
/// Warnings and failures are also counted (and warnings kept for the shell's log even when tracing
/// is off, see [`Engine::trace_warnings`]), so a run's report can say how many there were.
macro_rules! emit {
    ($engine:expr, TraceKind::Warning $body:tt $(,)?) => {
        if $engine.tracing || $engine.keep_warnings {
            let kind = TraceKind::Warning $body;
            $engine.push_trace(kind);
        }
        $engine.warnings += 1;
    };
    ($engine:expr, TraceKind::Log $body:tt $(,)?) => {
        if $engine.tracing || $engine.keep_warnings {
            let kind = TraceKind::Log $body;
            $engine.push_trace(kind);
        }
    };
    ($engine:expr, TraceKind::Failed $body:tt $(,)?) => {
        if $engine.tracing {
            let kind = TraceKind::Failed $body;
            $engine.push_trace(kind);
        }
        $engine.failures += 1;
    };
    ($engine:expr, $kind:expr $(,)?) => {
        if $engine.tracing {
            let kind = $kind;
            $engine.push_trace(kind);
        }
    };
}

mod api;
mod arm;
mod callback;
mod canon;
mod exception;
mod extend;
mod inputs;
mod monitor;
pub(crate) mod node;
mod progress;
mod report;
mod resource;
mod start;
mod state;
mod steer;
mod terminate;
mod timers;
mod tree;
mod wiretap;

use crate::arena::{Arena, Keep, Lookup, Owned};
use crate::failure::{FailurePolicy, FatalFailure};
use crate::ids::{AttachId, ExternalId, NodeId};
use crate::time::{Clock, Time};
use crate::{Name, NodeKind};
pub use api::{Effect, EngineError, Job, Spawn, Stats, WatchOutcome};
use arm::{External, Join};
pub use canon::Canonical;
pub use exception::HandlerSpec;
pub use inputs::InputRecord;
pub use monitor::{EachActivation, MonitorSpec, Overrun};
use node::Node;
pub use node::{OnTerminate, Purpose};
use progress::timer_is_live;
pub use report::{Blocked, MonitorInfo, NodeInfo};
pub use resource::{ResourceDenied, ResourceDropped, ResourceInfo, Uses};
pub use state::InvariantFailed;
use std::collections::{BTreeMap, VecDeque};
pub use steer::{
    Approval, ApprovalRefused, BreakAt, Breakpoint, Fault, FaultOp, FaultOutcome, FaultValue,
    Matcher, MatcherOp, SteerId, SteerOp,
};
use tcm_trace::{State, TRACE_FORMAT_VERSION, TraceEvent, TraceKind};
use timers::Timers;
use wiretap::Wiretap;

/// Queued work of `settle`.
#[derive(Clone, Copy, Debug)]
enum Work {
    /// Move the node as far as its constraints allow (`progress.rs`).
    Progress(NodeId),
    /// Terminate the node and its subtree (`terminate.rs`); `explicit`: asked for by a command,
    /// not made due by a termination constraint.
    Terminate { node: NodeId, explicit: bool },
    /// The progress of a run of linked children, in order, as if a `Progress` of each were
    /// queued here (`progress_children` on a wide parent; see `ChildRun`).
    Children(u32),
}

/// One `Work::Children` entry: the children from `next` to `last` (in sibling order) whose
/// progress is still queued. It stands for the `Progress` entries of those children, one queue
/// slot for them all, so releasing a million held children does not queue a million entries.
/// `unlink` keeps it exact: an unlinked child's entry would have been a no-op, so the run only
/// steps over it (`next` or `last` moves to its neighbour; `next` is `Link::NONE` once none is
/// left). `last_id` is the last child as queued, which `queue_progress` compares with as the
/// queue's last entry.
#[derive(Clone, Copy, Debug)]
struct ChildRun {
    id: u32,
    next: node::Link,
    last: node::Link,
    last_id: NodeId,
}

/// Children of one parent from which `progress_children` queues one run instead of one entry
/// each, and how many runs may be pending at once (each `unlink` looks at every pending run).
const RUN_FROM: u32 = 16;
const MAX_RUNS: usize = 8;

/// The deterministic task-tree engine. `A` is the shell's action type; the engine only stores it and
/// hands it back in [`Effect::Start`]. `F` is a reusable factory (monitor bodies, handlers,
/// retries, wiretap checks), handed out in [`Effect::Invoke`]. `S` says how nodes are kept:
/// [`Owned`](crate::Owned) by a run, [`Shared`](crate::Shared) between clones by a model checker.
#[derive(Clone)]
pub struct Engine<A, F = (), S: Keep<Node<A, F>> = Owned> {
    run: u32,
    // The latest time known; behind the clock while `behind` (see `Engine::at_clock`).
    now: Time,
    // The shell's clock, read only when the time is needed (`Engine::set_clock`).
    clock: Option<Clock>,
    // Since `Engine::at_clock`, until the clock is read or an input is given a later time: `now`
    // may be behind the clock, which the next use of the time reads.
    behind: bool,
    nodes: Arena<A, F, S>,
    root: NodeId,
    next_display: u64,
    seq: u64,
    // The steps the run took: the inputs and requests it was given a time for (`advance`). A
    // journal places each input by it (`inputs.rs`).
    steps: u64,
    // The steps before the latest input or request came in.
    mark: u64,
    tracing: bool,
    // Warning records are traced even with tracing off (`trace_warnings`).
    keep_warnings: bool,
    // Failed nodes and warnings so far (`emit!`).
    failures: u64,
    warnings: u64,
    // Every failure no handler took, in order (`exception.rs`, `search`).
    unhandled: Vec<FatalFailure>,
    trace: VecDeque<TraceEvent>,
    work: VecDeque<Work>,
    // The runs `Work::Children` entries of `work` stand for, and the next run's number.
    runs: Vec<ChildRun>,
    next_run: u32,
    // From how many children a parent's are queued as one run (`RUN_FROM`).
    run_from: u32,
    ready: VecDeque<NodeId>,
    effects: VecDeque<Effect<A, F>>,
    timers: Timers,
    externals: Vec<External>,
    // Group triggers still waiting for members (`arm.rs`); a slot is reused once it fired.
    joins: Vec<Option<Join>>,
    external_ids: BTreeMap<String, ExternalId>,
    // Invariant: the number of actions, invocations and wiretap checks handed out and not yet
    // finished or cancelled.
    running: u32,
    policy: FailurePolicy,
    // Whether an action or invocation holds its children from its start (`hold_by_default`).
    hold_default: bool,
    fatal: Option<FatalFailure>,
    taps: Vec<Wiretap<F>>,
    // Handlers attached from outside to a task name (`Engine::handler_for`, `Engine::attach`), in
    // the order attached, each with its number.
    class_handlers: BTreeMap<Name, Vec<(AttachId, HandlerSpec<F>)>>,
    // The number of the last attachment (`AttachId`s start at 1).
    attachments: u32,
    // Resources and the requests waiting for them (`resource.rs`).
    res: resource::Resources,
    // State variables, conditions and their watches (`state.rs`).
    states: state::States,
    // Pausing, breakpoints, faults and approvals, from the first request (`steer.rs`).
    steer: Option<Box<steer::Steering>>,
    // The inputs taken, while recording them for a journal (`inputs.rs`).
    inputs: Option<VecDeque<(Time, u64, inputs::InputRecord, bool)>>,
    // A body is giving the engine an input itself (`Engine::by_body`).
    by_body: bool,
    // How many inputs (readings aside) were recorded so far (`Engine::aside`).
    recorded: u64,
}

impl<A, F: Clone, S: Keep<Node<A, F>>> Engine<A, F, S> {
    /// A new run with its root node. `run` numbers the run: handles of other runs are refused.
    pub fn new(run: u32) -> Engine<A, F, S> {
        let mut nodes = Arena::new(run);
        let mut root = Node::new(0, NodeKind::Root, Name::Borrowed("Root Node"), None);
        root.states = [State::Active, State::Active, State::Active];
        let root_id = nodes.insert(root);
        let mut engine = Engine {
            run,
            now: Time::ZERO,
            clock: None,
            behind: false,
            nodes,
            root: root_id,
            next_display: 1,
            seq: 0,
            steps: 0,
            mark: 0,
            tracing: true,
            keep_warnings: false,
            failures: 0,
            warnings: 0,
            unhandled: Vec::new(),
            trace: VecDeque::new(),
            work: VecDeque::new(),
            runs: Vec::new(),
            next_run: 0,
            run_from: RUN_FROM,
            ready: VecDeque::new(),
            effects: VecDeque::new(),
            timers: Timers::default(),
            externals: Vec::new(),
            joins: Vec::new(),
            external_ids: BTreeMap::new(),
            running: 0,
            policy: FailurePolicy::Warn,
            hold_default: false,
            fatal: None,
            taps: Vec::new(),
            class_handlers: BTreeMap::new(),
            attachments: 0,
            res: resource::Resources::default(),
            states: state::States::default(),
            steer: None,
            inputs: None,
            recorded: 0,
            by_body: false,
        };
        engine.push_trace(TraceKind::RunStarted {
            version: TRACE_FORMAT_VERSION,
            run,
        });
        engine
    }

    /// Turns trace recording on or off (on by default). Off, [`Engine::poll_trace`] yields nothing.
    pub fn set_tracing(&mut self, on: bool) {
        self.tracing = on;
    }

    /// Whether the engine traces (`set_tracing`): a shell builds what only the trace reads (a
    /// spawn's description of its arguments) only then.
    pub fn traces(&self) -> bool {
        self.tracing
    }

    /// Keeps tracing `warning` and `log` records while tracing is off (off by default), so a
    /// shell can log them without paying for the rest of the trace.
    pub fn trace_warnings(&mut self, on: bool) {
        self.keep_warnings = on;
    }

    /// Makes every action and invocation of a node (monitor activation, handler, retry) hold its
    /// children from its start, as if it called [`Engine::hold_children`] first; it releases them
    /// by returning or by `hold_children(.., false)` (docs/semantics.md, "Bodies and children").
    /// Off by default: the simulator's scripted bodies start their children at once.
    pub fn hold_by_default(&mut self, on: bool) {
        self.hold_default = on;
    }

    /// Chooses what an unhandled failure does.
    pub fn set_failure_policy(&mut self, policy: FailurePolicy) {
        self.policy = policy;
    }

    /// Attaches a handler from outside to every node of the task named `task` (its task name,
    /// whatever its instance name) spawned from now on, without touching the task's code (TCA's
    /// recovery added to existing components). At such a node the search tries it after the
    /// node's own handlers; handlers attached to the same task are tried in the order attached.
    /// Each node counts its own uses (`maximum activate`). A retried node has none of its own: its
    /// failures meet those of the node it retries (docs/semantics.md, "Handlers attached to a task").
    /// Returns the attachment's number, for [`Engine::detach`].
    pub fn handler_for(&mut self, task: impl Into<Name>, spec: HandlerSpec<F>) -> AttachId {
        self.attachments += 1;
        let id = AttachId(self.attachments);
        self.class_handlers
            .entry(task.into())
            .or_default()
            .push((id, spec));
        id
    }

    /// The root node: top-level tasks are its children.
    pub fn root(&self) -> NodeId {
        self.root
    }

    /// The current virtual time (the latest given to an input, or read from the clock).
    pub fn now(&self) -> Time {
        self.now
    }

    /// Gives the engine the shell's clock, for [`Engine::at_clock`]. It must read the same
    /// time as the shell gives its inputs, never going back.
    pub fn set_clock(&mut self, clock: Clock) {
        self.clock = Some(clock);
    }

    /// The time to give the next input so that it happens at the clock's time
    /// ([`Engine::set_clock`]), read only if the input needs it: to date a trace record, to fire
    /// due timers, to start a timer or a monitor. An input that needs none of these (an untraced
    /// spawn or end of a node, with no timer pending) costs no reading, which is most of what a
    /// reading costs an input. What happens is what the input would do given the clock's time,
    /// as the clock reads at the input's first use of it instead of before the call. The engine
    /// stays behind its clock until it reads it (an input given a later time than the one
    /// returned here sets the time, as always). Without a clock, the latest time known.
    pub fn at_clock(&mut self) -> Time {
        self.behind = self.clock.is_some();
        self.now
    }

    /// The clock's time now, read (and recorded, for a journal) if the engine has a clock; else
    /// the latest time known. For a time a command computes from now, such as a delay's end.
    pub fn clock_time(&mut self) -> Time {
        self.behind = self.clock.is_some();
        self.time()
    }

    /// Calls `input` at the clock's time ([`Engine::at_clock`]).
    pub fn with_clock<R>(&mut self, input: impl FnOnce(&mut Self, Time) -> R) -> R {
        let now = self.at_clock();
        input(self, now)
    }

    /// Whether an input is likely to need the time (it is traced, or a timer is pending), so
    /// that a shell which shares one clock reading between several inputs gives it at once
    /// rather than through [`Engine::at_clock`].
    pub fn wants_time(&self) -> bool {
        self.tracing || !self.timers.is_empty()
    }

    /// The time now: the clock's, if the engine is behind it (`at_clock`), else the latest known.
    #[inline]
    fn time(&mut self) -> Time {
        if self.behind {
            self.catch_up();
        }
        self.now
    }

    #[cold]
    #[inline(never)]
    fn catch_up(&mut self) {
        self.behind = false;
        if let Some(clock) = &self.clock {
            let t = clock(self.steps);
            self.clock_read(t);
            if t > self.now {
                self.now = t;
            }
        }
    }

    /// [`Engine::catch_up`] for an input's own time, which its journal entry holds: the reading
    /// is not recorded on its own (`inputs.rs`).
    #[cold]
    #[inline(never)]
    fn catch_up_quietly(&mut self) {
        self.behind = false;
        if let Some(clock) = &self.clock {
            let t = clock(self.steps);
            if t > self.now {
                self.now = t;
            }
        }
    }

    /// The first unhandled failure, under [`FailurePolicy::Fatal`].
    pub fn fatal(&self) -> Option<&FatalFailure> {
        self.fatal.as_ref()
    }

    /// Every failure no handler took so far, in order, whatever the failure policy
    /// (docs/semantics.md, "Failure without a handler").
    pub fn unhandled(&self) -> &[FatalFailure] {
        &self.unhandled
    }

    /// Counters.
    pub fn stats(&self) -> Stats {
        Stats {
            live_nodes: self.nodes.live(),
            high_water: self.nodes.high_water(),
            created: self.next_display - 1,
            running: self.running,
            failures: self.failures,
            warnings: self.warnings,
        }
    }

    /// Instance names from the top-level task down to `id`, joined by `/`.
    pub fn path(&self, id: NodeId) -> String {
        let mut names = Vec::new();
        let mut cur = self.query(id).map(|_| id);
        while let Some(c) = cur {
            let Some(n) = self.nodes.get(c) else { break };
            if n.kind == NodeKind::Root {
                break;
            }
            names.push(n.name.to_string());
            cur = n.parent;
        }
        names.reverse();
        names.join("/")
    }

    /// Output: the next effect to carry out.
    #[must_use]
    pub fn poll_effect(&mut self) -> Option<Effect<A, F>> {
        self.effects.pop_front()
    }

    /// Whether an effect waiting to be polled starts or cancels a command's action: the run is
    /// about to act outside the process (a journal with `BeforeActing` durability syncs first).
    pub fn effects_reach_commands(&self) -> bool {
        self.effects.iter().any(|e| match e {
            Effect::Start { node, .. } | Effect::Cancel { node } => self
                .query(*node)
                .is_some_and(|n| n.kind == crate::NodeKind::Command),
            _ => false,
        })
    }

    /// Output: the next trace record.
    #[must_use]
    pub fn poll_trace(&mut self) -> Option<TraceEvent> {
        self.trace.pop_front()
    }

    /// Whether trace records wait to be polled.
    pub fn has_trace(&self) -> bool {
        !self.trace.is_empty()
    }

    /// Output: the earliest pending timer that still matters; call `handle_timeout` then.
    #[must_use]
    #[inline]
    pub fn poll_timeout(&mut self) -> Option<Time> {
        // The shell asks after every step; most steps of most runs have no timer.
        if self.timers.is_empty() || self.halted() {
            return None;
        }
        let nodes = &self.nodes;
        self.timers.next_deadline(|k| timer_is_live(nodes, k))
    }

    /// Whether nothing can happen without a new input: no action runs, no timer is pending, nothing
    /// is ready. A run that is idle before its task completed is stuck (see [`Engine::blocked`]).
    pub fn is_idle(&mut self) -> bool {
        self.running == 0 && self.is_settled()
    }

    /// Whether only the running actions (or a new input) can change anything: nothing is ready and
    /// no timer is pending. A shell that knows every running action waits on the engine itself
    /// (parked in an await on a watch) knows the run is stuck then (docs/semantics.md, "Run
    /// outcome").
    /// A paused run is settled: what is ready waits for it to resume (see [`Engine::is_paused`]).
    pub fn is_settled(&mut self) -> bool {
        self.is_settled_but_timers() && self.poll_timeout().is_none()
    }

    /// Whether nothing is ready and no work is queued: [`Engine::is_settled`], timers aside (a
    /// replay fires them where its journal says).
    pub fn is_settled_but_timers(&self) -> bool {
        (self.ready.is_empty() || self.halted()) && self.work.is_empty()
    }

    /// Moves the engine's clock to `now`. It never skips a deadline: timers due before `now` fire
    /// first, each at its own time, so an input that arrives late (on real time the shell wakes a
    /// little after a deadline) never overtakes a timer that was due before it.
    #[inline(always)]
    fn advance(&mut self, now: Time) {
        // Where the run was when this came in (`inputs.rs`).
        self.mark = self.steps;
        self.steps += 1;
        if self.behind {
            if now <= self.now {
                return self.advance_to_clock();
            }
            // An input given a later time: the engine is no longer behind its clock.
            self.behind = false;
        }
        if !self.timers.is_empty() {
            self.fire_timers(now, false);
        }
        if now > self.now {
            self.now = now;
        }
    }

    /// `advance` at the clock's time (`at_clock`): the clock is read only if a timer may be due.
    /// Due timers fire at their own times, before the engine's time moves on to the reading.
    #[inline(never)]
    fn advance_to_clock(&mut self) {
        if self.timers.is_empty() {
            return;
        }
        self.behind = false;
        if let Some(now) = self.clock.as_ref().map(|clock| clock(self.steps)) {
            self.clock_read(now);
            self.fire_timers(now, false);
            if now > self.now {
                self.now = now;
            }
        }
    }

    /// From how many linked children of one parent their progress is queued as one run instead
    /// of one entry each (default 16; `u32::MAX`: never). The trace is the same either way; this is
    /// for the tests that compare the two.
    #[doc(hidden)]
    pub fn set_child_runs_from(&mut self, children: u32) {
        self.run_from = children.max(1);
    }

    /// Queues `Work::Progress(id)`, unless it is already the last work queued: `progress` moves a
    /// node as far as it can go, so a second run right after the first would find nothing to do
    /// (a completing child asks for its parent's progress up to three times in a row).
    #[inline]
    fn queue_progress(&mut self, id: NodeId) {
        if !self.last_queued_is(id) {
            self.work.push_back(Work::Progress(id));
        }
    }

    /// Whether the last work queued is the progress of `id` (a run of children counts as its last
    /// child's).
    #[inline]
    fn last_queued_is(&self, id: NodeId) -> bool {
        match self.work.back() {
            Some(Work::Progress(last)) => *last == id,
            Some(Work::Children(run)) => self.run_ends_with(*run, id),
            _ => false,
        }
    }

    /// Whether the last child of the run of children `run` as queued is `id`.
    #[cold]
    fn run_ends_with(&self, run: u32, id: NodeId) -> bool {
        self.runs.iter().any(|r| r.id == run && r.last_id == id)
    }

    fn next_display(&mut self) -> u64 {
        let d = self.next_display;
        self.next_display += 1;
        d
    }

    /// Appends a record; use `emit!`, which builds the record only when tracing is on.
    fn push_trace(&mut self, kind: TraceKind) {
        let seq = self.seq;
        self.seq += 1;
        let t = self.time().as_nanos();
        self.trace.push_back(TraceEvent { seq, t, kind });
    }

    fn check_run(&self, id: NodeId) -> Result<(), EngineError> {
        if id.run != self.run {
            return Err(EngineError::ForeignNode {
                node: id,
                run: self.run,
            });
        }
        Ok(())
    }

    /// The gate every entry point goes through: the handle must belong to this run.
    fn lookup(&self, id: NodeId) -> Result<Lookup, EngineError> {
        self.check_run(id)?;
        Ok(self.nodes.lookup(id))
    }

    /// A live node of this run, or why not.
    fn live(&self, id: NodeId) -> Result<&Node<A, F>, EngineError> {
        self.check_run(id)?;
        // Not `ok_or`: an error built and dropped on every call costs a drop of its own.
        match self.nodes.get(id) {
            Some(n) => Ok(n),
            None => Err(EngineError::Gone(id)),
        }
    }

    /// A live node of this run for a query: `None` for a handle of another run, as for one gone.
    fn query(&self, id: NodeId) -> Option<&Node<A, F>> {
        self.check_run(id).ok()?;
        self.nodes.get(id)
    }

    #[inline]
    pub(crate) fn node(&self, id: NodeId) -> &Node<A, F> {
        self.nodes.get(id).expect("engine invariant: node exists")
    }

    #[inline]
    fn node_mut(&mut self, id: NodeId) -> &mut Node<A, F> {
        self.nodes
            .get_mut(id)
            .expect("engine invariant: node exists")
    }
}
