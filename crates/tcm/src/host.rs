//! The host: the runtime's side of the core's [`Driver`]. It owns the engine behind a mutex, carries
//! its effects out on tokio (start an action as a task, abort a cancelled one, answer a waiter, queue
//! a due timer callback) and reports each task's end back to the engine.
//!
//! Effects are carried out in one place, [`Host::effects`], whoever changed the engine: an action
//! (through [`Access`], whose end runs it), an event handle, the program's [`crate::Session`], or
//! the driver loop in `runtime.rs`.
//!
//! The host also keeps what the engine need not know: the actions parked in an await on an engine
//! watch ([`Parking`]; docs/semantics.md, "Run outcome"), the top-level tasks and how each ended,
//! timer callbacks, activation data, task names and the panics of actions.

use crate::Error;
use crate::cancel::Cancels;
use crate::clock::Clock;
use crate::ctx::Ctx;
use crate::task::{Action, AnyArgs, Factory, Kept, Launch, Value};
use std::any::Any;
use std::collections::{BTreeMap, BTreeSet};
use std::sync::atomic::{AtomicBool, AtomicI32, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, mpsc};
use tcm_core::{
    Driver, Engine, EngineError, Event, Job, Name, NodeId, Spawn, Time, WatchOutcome, WatchToken,
};
use tcm_trace::TraceEvent;
use tokio::sync::{Notify, oneshot, watch};

mod aborts;
mod end;
mod ended;
mod locked;
mod shell;

pub(crate) use crate::outcome::Panicked;
pub(crate) use aborts::{Aborts, Running};
pub(crate) use end::{end_run, outcome_of_roots, report};
pub(crate) use ended::{CatchUnwind, Ended, TaskRef, panic_message, panicked, spawn_task};
pub(crate) use locked::{Locked, lock, lock_as_is, run_callback};
pub(crate) use shell::Host;

/// A timer callback (`Ctx::invoke_when`, `Ctx::invoke_after`): run once, when the lock under which
/// it came due is let go (`host/locked.rs`), or by the driver for one its timers made due.
pub(crate) type Callback = Box<dyn FnOnce(Ctx, WatchOutcome) + Send>;

/// A timer callback waiting for its event or time.
pub(crate) struct PendingCallback {
    pub(crate) name: Name,
    // The node whose context set it; the callback gets a context of this node.
    pub(crate) node: NodeId,
    pub(crate) f: Callback,
}

/// A timer callback whose event happened or whose time came: traced and run outside the lock
/// (`host/locked.rs`).
pub(crate) struct DueCallback {
    pub(crate) token: WatchToken,
    pub(crate) name: Name,
    pub(crate) node: NodeId,
    pub(crate) f: Callback,
    pub(crate) outcome: WatchOutcome,
}

/// A top-level task and how it ended.
pub(crate) struct Root {
    pub(crate) node: NodeId,
    token: u64,
    pub(crate) outcome: Option<WatchOutcome>,
}

/// The actions parked in an await on an engine watch (`Ctx::wait` and the waits built on it), by
/// watch token. An entry lives from the watch until its notification, or until the awaiting future
/// is dropped, or its job ends; only jobs that run are entered, so `jobs()` never counts more than
/// the engine's running jobs.
#[derive(Default)]
pub(crate) struct Parking {
    by_token: BTreeMap<u64, (Job, Event)>,
    // Invariant: the number of entries of `by_token` per job, for the jobs that have any.
    by_job: BTreeMap<Job, u32>,
}

impl Parking {
    fn park(&mut self, token: u64, job: Job, event: Event) {
        if self.by_token.insert(token, (job, event)).is_none() {
            *self.by_job.entry(job).or_default() += 1;
        }
    }

    pub(crate) fn unpark(&mut self, token: u64) {
        let Some((job, _)) = self.by_token.remove(&token) else {
            return;
        };
        if let Some(n) = self.by_job.get_mut(&job) {
            *n -= 1;
            if *n == 0 {
                self.by_job.remove(&job);
            }
        }
    }

    /// The job ended (or was cancelled): whatever it left parked no longer counts.
    fn forget_job(&mut self, job: Job) {
        if !self.by_job.is_empty() && self.by_job.remove(&job).is_some() {
            self.by_token.retain(|_, (j, _)| *j != job);
        }
    }

    /// How many running jobs are parked.
    pub(crate) fn jobs(&self) -> usize {
        self.by_job.len()
    }

    /// What each parked job awaits, in the order the awaits began, for the stuck report.
    pub(crate) fn awaits(&self) -> Vec<(NodeId, Event)> {
        self.by_token
            .values()
            .map(|(job, event)| (job.node(), *event))
            .collect()
    }
}

/// How often the maps keyed by node are swept for nodes that are gone: when they hold more than
/// this, and twice what the last sweep left (amortised O(1) per entry).
const SWEEP_MIN: usize = 256;

pub(crate) struct Inner {
    pub(crate) engine: Engine<Action, Factory>,
    pub(crate) watchers: BTreeMap<u64, oneshot::Sender<WatchOutcome>>,
    // Nodes whose action's value someone waits for; filled when the action returns.
    pub(crate) values: BTreeMap<NodeId, Option<Value>>,
    // Running actions, to abort on cancellation.
    pub(crate) aborts: Aborts,
    // Jobs started while the pump of this thread runs (`pump.rs`), for it to poll, in start order.
    pub(crate) launches: Vec<(Job, Launch)>,
    // Jobs cancelled while the pump holds them (started, not yet a task): rare, so a vector.
    inline_cancelled: Vec<NodeId>,
    // Cancellation signals, grace periods and the actions running in theirs (`cancel.rs`).
    pub(crate) cancels: Cancels,
    // Running wiretap checks (not cancellable, so not in `aborts`).
    checks: BTreeSet<Job>,
    pub(crate) parking: Parking,
    next_token: u64,
    // Where actions are spawned: the tokio runtime of `Runtime::run` or `Runtime::start`.
    pub(crate) spawner: Option<tokio::runtime::Handle>,
    // The top-level tasks, in spawn order, and whether one ended since the driver last looked.
    pub(crate) roots: Vec<Root>,
    roots_changed: bool,
    // The run ends once the roots are done (or it is stuck); a session sets it at `finish`.
    pub(crate) finishing: bool,
    // The driver loop ended: nothing more runs.
    pub(crate) ended: bool,
    // The engine's counters when the driver took the run's last trace records: the report's, so
    // that it counts what the trace holds (a warning may come after, from another process).
    pub(crate) final_stats: Option<tcm_core::Stats>,
    pub(crate) callbacks: BTreeMap<u64, PendingCallback>,
    pub(crate) due: Vec<DueCallback>,
    // Data given to a monitor activation (`Ctx::activate_with`), by activation node.
    pub(crate) activation_data: BTreeMap<NodeId, Arc<dyn Any + Send + Sync>>,
    // Task names of nodes whose instance name differs (`Task::named`).
    pub(crate) task_names: BTreeMap<NodeId, Name>,
    // Arguments of nodes whose task keeps them (`Task::with_args`), for their actions, wiretap
    // checks, handlers and retries; dropped by the sweep once the node is gone.
    pub(crate) args: BTreeMap<NodeId, AnyArgs>,
    sweep_at: usize,
    pub(crate) panics: Vec<Panicked>,
    // The deadline the driver sleeps until; an earlier timer must wake it.
    pub(crate) armed: Option<Time>,
    // Trace records taken from the engine, for the driver to hand to the sinks outside the lock.
    pub(crate) trace: Vec<TraceEvent>,
    // The run's journal, if it keeps one (`journal.rs`): written before effects are carried out.
    pub(crate) journal: Option<Box<crate::journal::Journaled>>,
    // The journal the run replays, if it does (`replay.rs`).
    pub(crate) replay: Option<Box<crate::replay::Replay>>,
    // Jobs whose task was dropped unfinished (see `Reporter`), for the driver to report.
    stopped: mpsc::Receiver<Job>,
}

impl Inner {
    pub(crate) fn new(engine: Engine<Action, Factory>, stopped: mpsc::Receiver<Job>) -> Inner {
        Inner {
            stopped,
            engine,
            watchers: BTreeMap::new(),
            values: BTreeMap::new(),
            aborts: Aborts::default(),
            launches: Vec::new(),
            inline_cancelled: Vec::new(),
            cancels: Cancels::default(),
            checks: BTreeSet::new(),
            parking: Parking::default(),
            next_token: 0,
            spawner: None,
            roots: Vec::new(),
            roots_changed: false,
            finishing: false,
            ended: false,
            final_stats: None,
            callbacks: BTreeMap::new(),
            due: Vec::new(),
            activation_data: BTreeMap::new(),
            task_names: BTreeMap::new(),
            args: BTreeMap::new(),
            sweep_at: SWEEP_MIN,
            panics: Vec::new(),
            armed: None,
            trace: Vec::new(),
            journal: None,
            replay: None,
        }
    }

    /// Reports to the engine the jobs whose task was dropped unfinished since the last call.
    pub(crate) fn report_stopped(&mut self, shared: &Shared, now: Time) {
        while let Ok(job) = self.stopped.try_recv() {
            shared.stops.fetch_sub(1, Ordering::SeqCst);
            // Its abort is over: it no longer counts as queued (`Cancels::aborted`).
            self.cancels.aborted = self.cancels.aborted.saturating_sub(1);
            if let Some(r) = self.replay.as_mut() {
                if r.reported(job) {
                    // Held when it was aborted (`Replay::dropped_at_once`).
                    continue;
                }
                if r.active() {
                    // Given when the journal gives it (`replay.rs`, rule 3).
                    let display = self.engine.kind_and_display(job.node()).map(|k| k.1);
                    r.hold(Ended::Dropped(job), display);
                    continue;
                }
            }
            self.engine.handle_action_stopped(now, job);
        }
    }

    /// Hands the stops of jobs the pump dropped unpolled to whoever takes the lock next, as the
    /// drops of their tasks, aborted, would be (`Reporter`): until then they count as aborted
    /// tasks still queued.
    pub(crate) fn hand_over_stops(&mut self, shared: &Shared, jobs: impl Iterator<Item = Job>) {
        for job in jobs {
            self.cancels.aborted += 1;
            shared.send_stop(job);
        }
        shared.wake.notify_one();
    }

    /// The driver looked at the roots.
    pub(crate) fn clear_roots_changed(&mut self) {
        self.roots_changed = false;
    }

    pub(crate) fn next_token(&mut self) -> u64 {
        self.next_token += 1;
        self.next_token
    }

    /// The engine and the host's side of the driver, borrowed apart.
    pub(crate) fn split<'a>(
        &'a mut self,
        shared: &'a Arc<Shared>,
    ) -> (&'a mut Engine<Action, Factory>, Host<'a>) {
        let host = Host {
            shared,
            pumps: None,
            aborts: &mut self.aborts,
            launches: &mut self.launches,
            inline_cancelled: &mut self.inline_cancelled,
            cancels: &mut self.cancels,
            checks: &mut self.checks,
            parking: &mut self.parking,
            spawner: self.spawner.as_ref(),
            watchers: &mut self.watchers,
            roots: &mut self.roots,
            roots_changed: &mut self.roots_changed,
            callbacks: &mut self.callbacks,
            due: &mut self.due,
            activation_data: &mut self.activation_data,
            args: &self.args,
            trace: &mut self.trace,
            values: &mut self.values,
            replay: self.replay.as_deref_mut().filter(|r| r.active()),
        };
        (&mut self.engine, host)
    }

    /// Carries out the engine's effects; returns whether the driver must wake (only for what only
    /// it can do: re-arm the timer, run a due callback, see that a top-level task ended or that the
    /// run is quiet), or only to hand trace records to the sinks.
    pub(crate) fn effects(&mut self, shared: &Arc<Shared>) -> Wake {
        self.start_effects(shared);
        if self.replay.is_some() {
            crate::replay::feed(self, shared);
        }
        let wake = self.roots_changed
            || !self.due.is_empty()
            || self.engine.fatal().is_some()
            || self
                .engine
                .poll_timeout()
                .is_some_and(|t| self.armed.is_none_or(|a| t < a));
        if wake || self.quiet() {
            Wake::Now
        } else if self.engine.has_trace() {
            Wake::Trace
        } else {
            Wake::No
        }
    }

    /// Hands the engine's effects (starts, cancellations, notifications) to the host.
    #[inline]
    pub(crate) fn start_effects(&mut self, shared: &Arc<Shared>) {
        self.start_effects_pumping(shared, None);
    }

    /// [`Inner::start_effects`], told whether the pump of this thread runs for this run (`None`:
    /// the host looks, on its first start).
    #[inline]
    pub(crate) fn start_effects_pumping(&mut self, shared: &Arc<Shared>, pumps: Option<bool>) {
        // The inputs that caused these effects are journaled first (`journal.rs`).
        if let Some(j) = self.journal.as_mut() {
            // Synced before acting, an access with no input may still have to sync what earlier
            // ones wrote, before the commands it starts.
            if self.engine.has_inputs() || j.syncs_before_acting() {
                j.drain(&mut self.engine);
            }
        }
        // Most accesses leave no effect (a spawn whose parent holds its children): the host is
        // borrowed only for one.
        if let Some(first) = self.engine.poll_effect() {
            let (engine, mut host) = self.split(shared);
            host.pumps = pumps;
            Driver::effect(engine, &mut host, first);
            Driver::effects(engine, &mut host);
        }
    }

    /// Whether ends reported together share one reading of the clock (the pump's batches), given
    /// to the engine rather than read by it: when they need the time, and the run neither keeps a
    /// journal nor replays one (whose every reading is the engine's own, `Engine::at_clock`).
    pub(crate) fn shares_readings(&self) -> bool {
        self.engine.wants_time() && self.journal.is_none() && self.replay.is_none()
    }

    /// Whether nothing can happen on its own any more (docs/semantics.md, "Run outcome"): nothing
    /// is ready, no timer is pending, no callback is due, and every running job (action,
    /// invocation, wiretap check) is parked in an await on an engine watch.
    pub(crate) fn quiet(&mut self) -> bool {
        if let Some(r) = self.replay.as_ref().filter(|r| r.active()) {
            // A replay's commands and held ends wait for the journal, and its timers fire where
            // the journal says (`replay.rs`).
            let waiting = self.parking.jobs() + r.waiting();
            return self.engine.stats().running as usize <= waiting
                && self.due.is_empty()
                && self.launches.is_empty()
                && self.engine.is_settled_but_timers();
        }
        // Cheapest first: while an action runs unparked, the answer is no.
        self.engine.stats().running as usize <= self.parking.jobs()
            && self.due.is_empty()
            && self.engine.is_settled()
    }

    /// Enters an await of `job` on `event` (watch `token`) as parked, if the job runs (a task an
    /// action left behind is no running job).
    pub(crate) fn park(&mut self, token: u64, job: Job, event: Event) {
        let running = if job.cancellable() {
            self.aborts.contains(job.node())
        } else {
            self.checks.contains(&job)
        };
        if running {
            self.parking.park(token, job, event);
        }
    }

    /// Inserts a node for the program or an action, and keeps its task name if it differs from its
    /// instance name (`Task::named`) and its arguments (`Task::with_args`).
    #[inline]
    /// At `now`, or at the clock's time if `None` (read only if the spawn needs it,
    /// `Engine::at_clock`).
    pub(crate) fn spawn(
        &mut self,
        now: Option<Time>,
        mut spec: Spawn<Action, Factory>,
        mut kept: Kept,
    ) -> Result<NodeId, EngineError> {
        if let Some(wanted) = kept.wanted.take() {
            spec.uses = crate::resource::resolve(&mut self.engine, *wanted)?;
        }
        if let (Some(describe), Some(args)) = (kept.describe, kept.args.as_deref()) {
            if self.engine.traces() {
                spec.args = describe(args).map(String::into_boxed_str);
            }
        }
        let now = now.unwrap_or_else(|| self.engine.at_clock());
        let id = self.engine.spawn(now, spec)?;
        if kept.fail_parent {
            self.engine.propagate_to_parent(id)?;
        }
        self.keep(id, kept);
        Ok(id)
    }

    /// Keeps what the host keeps beside `node` (before the node starts: the effects that start it
    /// are carried out when the engine access ends).
    pub(crate) fn keep(&mut self, node: NodeId, kept: Kept) {
        let mut any = false;
        if let Some(name) = kept.task_name {
            self.task_names.insert(node, name);
            any = true;
        }
        if let Some(args) = kept.args {
            self.args.insert(node, args);
            any = true;
        }
        if let Some(d) = kept.durable {
            if self.journal.is_some() || self.replay.is_some() {
                let display = self.engine.kind_and_display(node).map_or(0, |k| k.1);
                if let (Some(j), Some(e)) = (self.journal.as_mut(), &d.encode) {
                    j.encoder(display, e.clone());
                }
                if let Some(r) = self.replay.as_mut() {
                    r.durable(node, d);
                }
            }
        }
        if let Some(grace) = kept.grace {
            let engine = &self.engine;
            // Nodes in the map are never the root, whose parent is `None` too.
            self.cancels
                .keep_grace(node, grace, |id| engine.parent(id).is_some());
        }
        if any {
            self.sweep();
        }
    }

    /// Inserts a top-level task and watches its end.
    pub(crate) fn spawn_root(
        &mut self,
        now: Time,
        spec: Spawn<Action, Factory>,
        kept: Kept,
    ) -> Result<NodeId, EngineError> {
        let id = self.spawn(Some(now), spec, kept)?;
        let token = self.next_token();
        self.roots.push(Root {
            node: id,
            token,
            outcome: None,
        });
        self.engine.watch(
            now,
            tcm_core::Event::on(id, tcm_core::Facet::Execution, tcm_core::Point::Completed),
            WatchToken(token),
        )?;
        Ok(id)
    }

    /// Keeps data for a monitor activation.
    pub(crate) fn keep_activation_data(&mut self, node: NodeId, data: Arc<dyn Any + Send + Sync>) {
        self.activation_data.insert(node, data);
        self.sweep();
    }

    /// Drops what the maps keyed by node keep for nodes that are gone (an activation terminated
    /// before it ran never reports its end).
    fn sweep(&mut self) {
        let len = |i: &Inner| i.task_names.len() + i.activation_data.len() + i.args.len();
        if len(self) <= self.sweep_at {
            return;
        }
        let engine = &self.engine;
        // Nodes in these maps are never the root, whose parent is `None` too.
        self.task_names.retain(|id, _| engine.parent(*id).is_some());
        self.activation_data
            .retain(|id, _| engine.parent(*id).is_some());
        self.args.retain(|id, _| engine.parent(*id).is_some());
        self.sweep_at = SWEEP_MIN.max(2 * len(self));
    }
}

/// Whether the driver must be woken after an access (`Inner::effects`).
#[derive(Clone, Copy, PartialEq, Eq)]
pub(crate) enum Wake {
    No,
    // Only to hand trace records to the sinks.
    Trace,
    Now,
}

/// The status the driver publishes after each turn, for [`crate::Session::quiescent`].
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Status {
    // Turns so far.
    pub(crate) turn: u64,
    // Whether the run was quiet after that turn (`Inner::quiet`).
    pub(crate) quiet: bool,
    // Whether the driver loop ended.
    pub(crate) ended: bool,
}

pub(crate) struct Shared {
    pub(crate) inner: Mutex<Inner>,
    pub(crate) wake: Notify,
    pub(crate) clock: Arc<Clock>,
    // Open event handles: while any is open, an idle run waits instead of ending stuck.
    pub(crate) handles: AtomicUsize,
    // Where a `Reporter` sends the job of a task dropped unfinished (it must not take the lock).
    pub(crate) stopped: Mutex<mpsc::Sender<Job>>,
    // How many jobs were sent there and not yet reported: whoever takes the lock next reports
    // them (`Shared::enter`), so that their order in the trace does not depend on when the
    // driver runs.
    pub(crate) stops: AtomicUsize,
    // How many jobs were cancelled while the pump held them, ever: the pump looks again at the
    // rest of its batch when it grows (`pump.rs`), so that a job cancelled by one polled before
    // it is dropped unpolled.
    pub(crate) inline_cancels: AtomicUsize,
    // Published by the driver under the engine's lock.
    pub(crate) status: watch::Sender<Status>,
    // Whether the end of a job's task pumps what it released (`pump.rs`): on a current-thread
    // runtime only, where tasks run one at a time anyway; on a multi-thread runtime each action is
    // a task of its own, so that actions run in parallel on its workers.
    pub(crate) inline: AtomicBool,
    // How many of the run's tracked futures are queued, woken and not yet polled (`pump.rs`).
    pub(crate) queued: Arc<AtomicUsize>,
    // The nice value blocking bodies run at (`Runtime::blocking_nice`); 0 leaves it alone.
    pub(crate) blocking_nice: AtomicI32,
    // What makes the tasks placed on other processes (`Runtime::placer`), if anything.
    pub(crate) placer: Mutex<Option<Arc<dyn crate::Placer>>>,
}

impl Shared {
    /// The run's placer, if it has one.
    pub(crate) fn placer(&self) -> Option<Arc<dyn crate::Placer>> {
        self.placer
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .clone()
    }

    /// Sends the stop of a job whose future was dropped unfinished, for whoever takes the lock
    /// next to report (`Shared::enter`).
    pub(crate) fn send_stop(&self, job: Job) {
        // Counted first: a count above zero may find the channel still empty, never the reverse.
        self.stops.fetch_add(1, Ordering::SeqCst);
        if let Ok(tx) = self.stopped.lock() {
            let _ = tx.send(job);
        }
    }

    /// The engine's time now (see [`Clock`]).
    pub(crate) fn now(&self) -> Time {
        self.clock.now()
    }

    /// Exclusive access to the engine; its effects are carried out when the access ends.
    #[inline(always)]
    pub(crate) fn enter(self: &Arc<Shared>) -> Result<Access<'_>, Error> {
        // What the engine does under the lock happens in its own order, not the polled future's.
        let polling = crate::pump::polling(false);
        let mut guard = lock(self)?;
        if self.stops.load(Ordering::Relaxed) > 0 {
            stops_first(&mut guard, self);
        }
        Ok(Access {
            guard,
            shared: self,
            settled: false,
            polling,
        })
    }
}

/// Reports the stops sent since the last look, before anything else sees the engine, and hands
/// their effects to the host, as the end of a job does (`pump::flush`): an action a stop starts is
/// running when what took the lock cancels it.
#[cold]
#[inline(never)]
pub(crate) fn stops_first(inner: &mut Inner, shared: &Arc<Shared>) {
    let now = inner.engine.at_clock();
    inner.report_stopped(shared, now);
    inner.start_effects(shared);
    if inner.replay.is_some() {
        // A stop the journal gives now is given before what took the lock asks anything, as in
        // the run, where the stop came first (`replay.rs`, rule 3).
        crate::replay::feed(inner, shared);
    }
}

/// Exclusive access to the engine. When it ends, the engine's effects are carried out at once, by
/// whoever changed the engine, and the driver is woken if it must.
pub(crate) struct Access<'a> {
    guard: Locked<'a>,
    shared: &'a Arc<Shared>,
    // The effects were carried out and nothing changed since (`Access::carry_out`).
    settled: bool,
    // The pump of this thread was polling a future when the access began: wake-ups it causes are
    // held back again once it ends (`pump::hold_wake`); those the engine causes are not.
    polling: bool,
}

impl std::ops::Deref for Access<'_> {
    type Target = Inner;
    fn deref(&self) -> &Inner {
        &self.guard
    }
}

impl std::ops::DerefMut for Access<'_> {
    fn deref_mut(&mut self) -> &mut Inner {
        self.settled = false;
        &mut self.guard
    }
}

impl Access<'_> {
    /// Carries out the engine's effects now, rather than when the access ends.
    pub(crate) fn carry_out(&mut self) {
        self.settled = true;
        carry_out(&mut self.guard, self.shared);
    }
}

/// Carries out the engine's effects (under its lock), and wakes the driver if it must.
pub(crate) fn carry_out(inner: &mut Inner, shared: &Arc<Shared>) {
    match inner.effects(shared) {
        Wake::No => {}
        // Taking trace records changes nothing of the engine: while this thread pumps, the
        // driver takes them when the pump ends (`pump.rs`).
        Wake::Trace if crate::pump::defer_wake(shared) => {}
        Wake::Trace | Wake::Now => shared.wake.notify_one(),
    }
}

impl Drop for Access<'_> {
    #[inline]
    fn drop(&mut self) {
        if !self.settled {
            self.carry_out();
        }
        if self.polling {
            crate::pump::polling(true);
        }
    }
}

/// Removes a parked await when its future is dropped before the notification (or the run ended
/// under it); a notified await was already removed by [`Host`]'s `Shell::notify`.
pub(crate) struct Unpark<'a> {
    pub(crate) shared: &'a Shared,
    pub(crate) token: u64,
    pub(crate) armed: bool,
}

impl Drop for Unpark<'_> {
    fn drop(&mut self) {
        if self.armed {
            if let Ok(mut inner) = self.shared.inner.lock() {
                inner.parking.unpark(self.token);
                inner.watchers.remove(&self.token);
            }
        }
    }
}
