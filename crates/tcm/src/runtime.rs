//! The shell: runs a task tree on tokio, real or virtual time.
//!
//! The driver loop ([`Runtime::run`]) owns no semantics. Each turn it drains the engine's effects
//! (start an action as a tokio task, abort a cancelled one, answer a waiter), hands trace records to
//! the sinks, then sleeps until one of three things: an action finished, an action or handle touched
//! the engine (spawn, terminate, raise …), or the next timer is due. The engine itself sits behind a
//! mutex so that actions, on any worker thread, call it directly and briefly.

use crate::Error;
use crate::ctx::Ctx;
use crate::sink::TraceSink;
use crate::task::{Action, Factory, Task, Value};
use std::any::Any;
use std::collections::BTreeMap;
use std::future::Future;
use std::panic::AssertUnwindSafe;
use std::pin::Pin;
use std::sync::atomic::{AtomicU32, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;
use tcm_core::{
    Blocked, Effect, Engine, Event, Failure, FailurePolicy, FatalFailure, NodeId, Stats, Time,
    WatchOutcome, WatchToken,
};
use tcm_core::{Purpose, TapWhen, WiretapId};
use tcm_trace::{Facet, Point};
use tokio::sync::{Notify, oneshot};
use tokio::task::AbortHandle;

pub(crate) struct Inner {
    pub(crate) engine: Engine<Action, Factory>,
    pub(crate) watchers: BTreeMap<u64, oneshot::Sender<WatchOutcome>>,
    // Nodes whose action's value someone waits for; filled when the action returns.
    pub(crate) values: BTreeMap<NodeId, Option<Value>>,
    // Running actions, to abort on cancellation. Only looked up, never iterated in an order that
    // shows in the trace, so a hash map keeps determinism.
    aborts: Aborts,
    next_token: u64,
    // Where actions are spawned: the tokio runtime of `Runtime::run`.
    spawner: Option<tokio::runtime::Handle>,
    // How the top-level task ended, once it did.
    top_done: Option<WatchOutcome>,
    // The deadline the driver sleeps until; an earlier timer must wake it.
    armed: Option<Time>,
    // Handler nodes whose body called `Ctx::bypass`.
    pub(crate) bypassed: std::collections::BTreeSet<NodeId>,
}

impl Inner {
    pub(crate) fn next_token(&mut self) -> u64 {
        self.next_token += 1;
        self.next_token
    }
}

pub(crate) struct Shared {
    pub(crate) inner: Mutex<Inner>,
    pub(crate) wake: Notify,
    start: tokio::time::Instant,
    // The wall clock when the run's time zero was taken, for times of day.
    wall_start: std::time::SystemTime,
    handles: AtomicUsize,
}

impl Shared {
    /// Virtual time of the engine: tokio's clock (paused or real) since the runtime was created.
    pub(crate) fn now(&self) -> Time {
        let d = tokio::time::Instant::now().saturating_duration_since(self.start);
        Time::from_nanos(u64::try_from(d.as_nanos()).unwrap_or(u64::MAX))
    }
}

impl Shared {
    /// See [`Ctx::time_of_day`].
    pub(crate) fn time_of_day(&self, secs: f64) -> Time {
        const DAY: f64 = 86_400.0;
        let now = self.now();
        let wall = self.wall_start + now.since_start();
        let since_epoch = wall
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0.0, |d| d.as_secs_f64());
        let today = since_epoch - since_epoch.rem_euclid(DAY);
        let ahead = (today + secs.clamp(0.0, DAY) - since_epoch).max(0.0);
        now + Duration::from_secs_f64(ahead)
    }
}

pub(crate) fn lock(shared: &Shared) -> Result<MutexGuard<'_, Inner>, Error> {
    shared.inner.lock().map_err(|_| Error::Poisoned)
}

/// Exclusive access to the engine. When it ends, the engine's effects are carried out at once, by
/// whoever changed the engine (an action, a handle, the driver): actions start, cancelled ones are
/// aborted, waiters are answered. The driver is woken only for what only it can do: hand trace
/// records to the sinks, re-arm the timer, end the run.
pub(crate) struct Session<'a> {
    guard: MutexGuard<'a, Inner>,
    shared: &'a Arc<Shared>,
}

impl Shared {
    pub(crate) fn enter(self: &Arc<Shared>) -> Result<Session<'_>, Error> {
        Ok(Session {
            guard: lock(self)?,
            shared: self,
        })
    }
}

impl std::ops::Deref for Session<'_> {
    type Target = Inner;
    fn deref(&self) -> &Inner {
        &self.guard
    }
}

impl std::ops::DerefMut for Session<'_> {
    fn deref_mut(&mut self) -> &mut Inner {
        &mut self.guard
    }
}

impl Drop for Session<'_> {
    fn drop(&mut self) {
        if pump(self.shared, &mut self.guard) {
            self.shared.wake.notify_one();
        }
    }
}

/// Carries out the engine's effects; returns whether the driver must wake.
fn pump(shared: &Arc<Shared>, inner: &mut Inner) -> bool {
    let mut wake = false;
    while let Some(effect) = inner.engine.poll_effect() {
        match effect {
            Effect::Start { node, action } => {
                // Spawned under the lock: the task's own completion takes the lock, so its abort
                // handle is recorded before it can finish.
                let ctx = Ctx {
                    shared: shared.clone(),
                    node,
                    purpose: None,
                };
                let h = (action.0)(Launch {
                    ctx,
                    rt: inner.spawner.as_ref(),
                });
                inner.aborts.insert(node, h.abort_handle());
            }
            Effect::Invoke {
                node,
                body,
                purpose,
            } => {
                let tap = match *purpose {
                    Purpose::Tap { tap, .. } => Some(tap),
                    _ => None,
                };
                let ctx = Ctx {
                    shared: shared.clone(),
                    node,
                    purpose: Some(Arc::from(purpose)),
                };
                let fut = body(ctx);
                let sh = shared.clone();
                let task = async move {
                    let res = CatchUnwind(fut).await;
                    finish(&sh, node, tap, res);
                };
                let h = match &inner.spawner {
                    Some(rt) => rt.spawn(task),
                    None => tokio::spawn(task),
                };
                // A wiretap check runs to its end; only actions are cancelled with their node.
                if tap.is_none() {
                    inner.aborts.insert(node, h.abort_handle());
                }
            }
            Effect::Cancel { node } => {
                if let Some(h) = inner.aborts.remove(&node) {
                    h.abort();
                }
            }
            Effect::Notify { token, outcome } if token.0 == TOP => {
                inner.top_done = Some(outcome);
                wake = true;
            }
            Effect::Notify { token, outcome } => {
                if let Some(tx) = inner.watchers.remove(&token.0) {
                    let _ = tx.send(outcome);
                }
            }
        }
    }
    wake = wake || inner.engine.fatal().is_some() || inner.engine.has_trace();
    let deadline = inner.engine.poll_timeout();
    if let Some(t) = deadline {
        wake = wake || inner.armed.is_none_or(|a| t < a);
    }
    wake || (inner.aborts.is_empty() && inner.engine.is_idle())
}

/// The token of the watch on the top-level task.
const TOP: u64 = 0;

static RUNS: AtomicU32 = AtomicU32::new(1);

/// How a run ended.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum RunOutcome {
    /// The top-level task's execution completed (it and its whole subtree).
    Completed,
    /// The top-level task's own action failed (no handler took the failure).
    TaskFailed(Failure),
    /// The top-level task was terminated.
    Terminated,
    /// An unhandled failure under [`FailurePolicy::Fatal`].
    Fatal(FatalFailure),
    /// Nothing can progress, no timer is pending and no event handle is open: these nodes wait on
    /// events that will never come (decision 3).
    Stuck(Vec<Blocked>),
}

/// The result of [`Runtime::run`].
#[derive(Clone, Debug)]
pub struct Report {
    /// How the run ended.
    pub outcome: RunOutcome,
    /// Virtual (or real) time from the runtime's creation to the end of the run.
    pub elapsed: Duration,
    /// Engine counters at the end.
    pub stats: Stats,
}

/// A handle to raise named external events from any thread or task. While any handle is open, a
/// run with nothing else to do waits for it instead of ending as stuck.
pub struct EventHandle {
    shared: Arc<Shared>,
}

impl EventHandle {
    /// Raises the event `name` (latched: constraints applied later find it raised).
    pub fn raise(&self, name: &str) -> Result<(), Error> {
        let mut s = self.shared.enter()?;
        let now = self.shared.now();
        let id = s.engine.external(name);
        s.engine.raise(now, id);
        Ok(())
    }
}

impl Clone for EventHandle {
    fn clone(&self) -> Self {
        self.shared.handles.fetch_add(1, Ordering::SeqCst);
        EventHandle {
            shared: self.shared.clone(),
        }
    }
}

impl Drop for EventHandle {
    fn drop(&mut self) {
        self.shared.handles.fetch_sub(1, Ordering::SeqCst);
        self.shared.wake.notify_one();
    }
}

/// A run of one top-level task.
///
/// ```
/// # #[tokio::main(flavor = "current_thread", start_paused = true)]
/// # async fn main() -> Result<(), tcm::Error> {
/// use std::time::Duration;
/// use tcm::{Facet, NodeRef, RunOutcome, Runtime, Task};
///
/// let report = Runtime::new()
///     .run(Task::goal("deliver", |ctx| async move {
///         ctx.spawn(Task::command("navigate", |_| async {
///             tokio::time::sleep(Duration::from_secs(3)).await;
///             Ok(())
///         }))
///         .start()?;
///         ctx.spawn(Task::command("speak", |_| async { Ok(()) }))
///             .sequential(Facet::Execution, NodeRef::Previous)
///             .start()?;
///         Ok(())
///     }))
///     .await?;
/// assert_eq!(report.outcome, RunOutcome::Completed);
/// assert_eq!(report.elapsed, Duration::from_secs(3));
/// # Ok(())
/// # }
/// ```
pub struct Runtime {
    shared: Arc<Shared>,
    sinks: Vec<Box<dyn TraceSink>>,
    precise: bool,
}

impl Default for Runtime {
    fn default() -> Self {
        Runtime::new()
    }
}

impl Runtime {
    /// A new run. Time zero is now (on tokio's clock: paused in tests, for virtual time).
    pub fn new() -> Runtime {
        let run = RUNS.fetch_add(1, Ordering::Relaxed);
        Runtime {
            shared: Arc::new(Shared {
                inner: Mutex::new(Inner {
                    engine: Engine::new(run),
                    watchers: BTreeMap::new(),
                    values: BTreeMap::new(),
                    aborts: Aborts::default(),
                    next_token: TOP,
                    spawner: None,
                    top_done: None,
                    armed: None,
                    bypassed: std::collections::BTreeSet::new(),
                }),
                wake: Notify::new(),
                start: tokio::time::Instant::now(),
                wall_start: std::time::SystemTime::now(),
                handles: AtomicUsize::new(0),
            }),
            sinks: Vec::new(),
            precise: false,
        }
    }

    /// Wakes for timers with a dedicated thread instead of tokio's millisecond timer, so polling
    /// monitors keep sub-millisecond schedules (see the `timer` module). Real time only: under
    /// tokio's paused clock, leave it off.
    pub fn precise_timer(mut self) -> Runtime {
        self.precise = true;
        self
    }

    /// Adds a trace sink.
    pub fn with_sink(mut self, sink: impl TraceSink + 'static) -> Runtime {
        self.sinks.push(Box::new(sink));
        self
    }

    /// Chooses what an unhandled failure does (default: warn and go on, as TCM).
    pub fn failure_policy(self, policy: FailurePolicy) -> Runtime {
        if let Ok(mut inner) = self.shared.inner.lock() {
            inner.engine.set_failure_policy(policy);
        }
        self
    }

    /// Registers a wiretap (the TCA paper's wiretap monitors): `check` runs whenever a node whose
    /// instance name is `task` is about to start its action (`Before`) or returned successfully
    /// (`After`), without touching that task's code. A failing check fails the tapped node with the
    /// check's failure (handlers then apply as to any failure).
    pub fn wiretap<F, Fut, T>(
        self,
        task: impl Into<tcm_core::Name>,
        when: TapWhen,
        check: F,
    ) -> Runtime
    where
        F: Fn(Ctx) -> Fut + Send + Sync + 'static,
        Fut: Future<Output = Result<T, Failure>> + Send + 'static,
        T: Any + Send,
    {
        if let Ok(mut inner) = self.shared.inner.lock() {
            inner
                .engine
                .wiretap(task, when, crate::task::factory(check));
        }
        self
    }

    /// A handle to raise external events.
    pub fn events(&self) -> EventHandle {
        self.shared.handles.fetch_add(1, Ordering::SeqCst);
        EventHandle {
            shared: self.shared.clone(),
        }
    }

    /// Runs `task` as the top-level task until its execution completes, it fails fatally, or the run
    /// is stuck. Actions run as tokio tasks of the current runtime.
    pub async fn run(mut self, task: Task) -> Result<Report, Error> {
        let shared = self.shared.clone();
        let top = {
            let mut inner = shared.enter()?;
            inner.spawner = Some(tokio::runtime::Handle::current());
            // Nobody reads the trace: do not build it.
            inner.engine.set_tracing(!self.sinks.is_empty());
            let now = shared.now();
            let root = inner.engine.root();
            let top = inner.engine.spawn(now, task.into_spawn(root).0)?;
            inner.engine.watch(
                now,
                Event::on(top, Facet::Execution, Point::Completed),
                WatchToken(TOP),
            )?;
            top
        };
        let _ = top;
        let timer = if self.precise {
            Some(crate::timer::PreciseTimer::start(shared.clone()).map_err(Error::Timer)?)
        } else {
            None
        };
        let outcome = Driver::new(shared.clone(), timer)
            .drive(&mut self.sinks)
            .await;
        for s in &mut self.sinks {
            s.flush();
        }
        let outcome = outcome?;
        let stats = lock(&shared)?.engine.stats();
        Ok(Report {
            outcome,
            elapsed: shared.now().since_start(),
            stats,
        })
    }
}

struct Driver {
    shared: Arc<Shared>,
    timer: Option<crate::timer::PreciseTimer>,
}

impl Driver {
    fn new(shared: Arc<Shared>, timer: Option<crate::timer::PreciseTimer>) -> Driver {
        Driver { shared, timer }
    }

    /// The driver loop. It is the one intentionally endless loop of the runtime: each turn ends in
    /// an await on the next thing that can change the engine.
    async fn drive(self, sinks: &mut [Box<dyn TraceSink>]) -> Result<RunOutcome, Error> {
        let mut trace = Vec::new();
        let result = loop {
            let (deadline, idle, running, fatal, blocked, top_done) = {
                // A plain lock, not a `Session`: the driver decides itself what to do next, and
                // waking itself would spin while the run waits for an event handle.
                let mut inner = lock(&self.shared)?;
                // Due timers fire here (cheap when none is due), whoever woke the driver.
                let now = self.shared.now();
                inner.engine.handle_timeout(now);
                pump(&self.shared, &mut inner);
                while let Some(ev) = inner.engine.poll_trace() {
                    trace.push(ev);
                }
                let idle = inner.engine.is_idle();
                let running = !inner.aborts.is_empty();
                // The stuck report scans every node: only when the run is over.
                let blocked = if idle && !running && self.shared.handles.load(Ordering::SeqCst) == 0
                {
                    inner.engine.blocked()
                } else {
                    Vec::new()
                };
                let deadline = inner.engine.poll_timeout();
                inner.armed = deadline;
                let fatal = inner.engine.fatal().cloned();
                (
                    deadline,
                    idle,
                    running,
                    fatal,
                    blocked,
                    inner.top_done.clone(),
                )
            };
            for ev in trace.drain(..) {
                for s in sinks.iter_mut() {
                    s.record(&ev);
                }
            }
            if let Some(f) = fatal {
                break RunOutcome::Fatal(f);
            }
            if let Some(outcome) = top_done {
                break match outcome {
                    WatchOutcome::Reached => RunOutcome::Completed,
                    WatchOutcome::Failed(f) | WatchOutcome::Handled(f) => RunOutcome::TaskFailed(f),
                    WatchOutcome::Terminated | WatchOutcome::Dead => RunOutcome::Terminated,
                };
            }
            if idle && !running && self.shared.handles.load(Ordering::SeqCst) == 0 {
                break RunOutcome::Stuck(blocked);
            }
            let mut sleep = deadline.map(|t| self.shared.start + t.since_start());
            if let Some(timer) = &self.timer {
                timer.set(sleep.map(tokio::time::Instant::into_std));
                sleep = None;
            }
            tokio::select! {
                biased;
                () = self.shared.wake.notified() => {}
                () = sleep_until(sleep), if sleep.is_some() => {
                    let mut inner = lock(&self.shared)?;
                    let now = self.shared.now();
                    inner.armed = None;
                    inner.engine.handle_timeout(now);
                    pump(&self.shared, &mut inner);
                }
            }
        };
        // Whatever still runs belongs to a run that is over.
        let mut inner = lock(&self.shared)?;
        for h in inner.aborts.drain() {
            h.abort();
        }
        Ok(result)
    }
}

/// A running action ended: record it in the engine (under the lock) and wake the driver.
fn finish(
    shared: &Arc<Shared>,
    node: NodeId,
    tap: Option<WiretapId>,
    res: Result<Result<Value, Failure>, Box<dyn Any + Send>>,
) {
    let result = match res {
        Ok(r) => r,
        Err(panic) => Err(Failure::new(
            "ActionPanicked",
            panic_message(panic.as_ref()),
        )),
    };
    let Ok(mut inner) = shared.enter() else {
        return;
    };
    if let Some(tap) = tap {
        let now = shared.now();
        let _ = inner
            .engine
            .tap_finished(now, node, tap, result.map(|_| ()));
        return;
    }
    inner.aborts.remove(&node);
    if inner.bypassed.remove(&node) {
        let now = shared.now();
        let _ = inner.engine.bypass(now, node);
        return;
    }
    let now = shared.now();
    let result = match result {
        Ok(value) => {
            if let Some(slot) = inner.values.get_mut(&node) {
                *slot = Some(value);
            }
            Ok(())
        }
        Err(f) => Err(f),
    };
    // A node terminated meanwhile, or already reclaimed, has nothing left to finish.
    let _ = inner.engine.action_finished(now, node, result);
}

/// The abort handles of running actions, by the node's storage slot (dense, so a vector beats a
/// hash map on the path every action takes).
#[derive(Default)]
struct Aborts {
    slots: Vec<Option<(NodeId, AbortHandle)>>,
    len: usize,
}

impl Aborts {
    fn insert(&mut self, node: NodeId, h: AbortHandle) {
        let i = node.slot() as usize;
        if self.slots.len() <= i {
            self.slots.resize_with(i + 1, || None);
        }
        if self.slots[i].replace((node, h)).is_none() {
            self.len += 1;
        }
    }

    fn remove(&mut self, node: &NodeId) -> Option<AbortHandle> {
        let slot = self.slots.get_mut(node.slot() as usize)?;
        match slot {
            Some((id, _)) if id == node => {
                self.len -= 1;
                slot.take().map(|(_, h)| h)
            }
            _ => None,
        }
    }

    fn is_empty(&self) -> bool {
        self.len == 0
    }

    fn drain(&mut self) -> impl Iterator<Item = AbortHandle> + '_ {
        self.len = 0;
        self.slots
            .iter_mut()
            .filter_map(|s| s.take().map(|(_, h)| h))
    }
}

/// What an [`Action`] needs to start: its context and where to spawn.
pub(crate) struct Launch<'a> {
    pub(crate) ctx: Ctx,
    pub(crate) rt: Option<&'a tokio::runtime::Handle>,
}

impl Launch<'_> {
    /// Spawns `f(ctx)` as a tokio task that reports its end (or its panic) to the engine; its
    /// value is kept for whoever waits for it.
    pub(crate) fn spawn<F, Fut, T>(self, f: F) -> tokio::task::JoinHandle<()>
    where
        F: FnOnce(Ctx) -> Fut,
        Fut: Future<Output = Result<T, Failure>> + Send + 'static,
        T: Any + Send,
    {
        self.spawn_value(move |ctx| {
            let fut = f(ctx);
            async move { fut.await.map(|v| Box::new(v) as Value) }
        })
    }

    /// As [`Launch::spawn`], for a future whose value is already erased.
    pub(crate) fn spawn_value<F, Fut>(self, f: F) -> tokio::task::JoinHandle<()>
    where
        F: FnOnce(Ctx) -> Fut,
        Fut: Future<Output = Result<Value, Failure>> + Send + 'static,
    {
        let Launch { ctx, rt } = self;
        let (shared, node) = (ctx.shared.clone(), ctx.node);
        let fut = f(ctx);
        let task = async move {
            let fut = std::pin::pin!(fut);
            let res = CatchUnwind(fut).await;
            finish(&shared, node, None, res);
        };
        match rt {
            Some(rt) => rt.spawn(task),
            None => tokio::spawn(task),
        }
    }
}

/// Polls a future, turning a panic into an error (a panicking action fails its node).
struct CatchUnwind<F>(F);

impl<F: Future + Unpin> Future for CatchUnwind<F> {
    type Output = Result<F::Output, Box<dyn Any + Send>>;
    fn poll(
        mut self: Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
    ) -> std::task::Poll<Self::Output> {
        let fut = &mut self.0;
        match std::panic::catch_unwind(AssertUnwindSafe(|| Pin::new(fut).poll(cx))) {
            Ok(std::task::Poll::Pending) => std::task::Poll::Pending,
            Ok(std::task::Poll::Ready(v)) => std::task::Poll::Ready(Ok(v)),
            Err(panic) => std::task::Poll::Ready(Err(panic)),
        }
    }
}

async fn sleep_until(at: Option<tokio::time::Instant>) {
    if let Some(at) = at {
        tokio::time::sleep_until(at).await;
    }
}

fn panic_message(p: &(dyn std::any::Any + Send)) -> String {
    if let Some(s) = p.downcast_ref::<&str>() {
        (*s).to_string()
    } else if let Some(s) = p.downcast_ref::<String>() {
        s.clone()
    } else {
        "panic with a non-string payload".to_string()
    }
}
