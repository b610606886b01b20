//! The shell: runs a task tree on tokio, real or virtual time.
//!
//! The driver loop ([`Runtime::run`]) owns no semantics. Each turn it drains the engine's effects
//! (start an action as a tokio task, abort a cancelled one, answer a waiter), hands trace records to
//! the sinks, then sleeps until one of three things: an action finished, an action or handle touched
//! the engine (spawn, terminate, raise …), or the next timer is due. The engine itself sits behind a
//! mutex so that actions, on any worker thread, call it directly and briefly.

use crate::ctx::Ctx;
use crate::sink::TraceSink;
use crate::task::{Action, Task, Value};
use crate::Error;
use std::collections::{BTreeMap, HashMap};
use std::sync::atomic::{AtomicU32, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;
use tcm_core::{
    Blocked, Effect, Engine, Event, FailurePolicy, FatalFailure, Failure, NodeId, Spawn, Stats, Time,
    WatchOutcome, WatchToken,
};
use tcm_trace::{Facet, Point};
use tokio::sync::{Notify, oneshot};
use tokio::task::{AbortHandle, JoinSet};

pub(crate) struct Inner {
    pub(crate) engine: Engine<Action>,
    pub(crate) watchers: BTreeMap<u64, oneshot::Sender<WatchOutcome>>,
    // Nodes whose action's value someone waits for; filled when the action returns.
    pub(crate) values: BTreeMap<NodeId, Option<Value>>,
    next_token: u64,
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
    handles: AtomicUsize,
}

impl Shared {
    /// Virtual time of the engine: tokio's clock (paused or real) since the runtime was created.
    pub(crate) fn now(&self) -> Time {
        let d = tokio::time::Instant::now().saturating_duration_since(self.start);
        Time::from_nanos(u64::try_from(d.as_nanos()).unwrap_or(u64::MAX))
    }
}

pub(crate) fn lock(shared: &Shared) -> Result<MutexGuard<'_, Inner>, Error> {
    shared.inner.lock().map_err(|_| Error::Poisoned)
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
        {
            let mut inner = lock(&self.shared)?;
            let now = self.shared.now();
            let id = inner.engine.external(name);
            inner.engine.raise(now, id);
        }
        self.shared.wake.notify_one();
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
                    next_token: TOP,
                }),
                wake: Notify::new(),
                start: tokio::time::Instant::now(),
                handles: AtomicUsize::new(0),
            }),
            sinks: Vec::new(),
        }
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
            let mut inner = lock(&shared)?;
            let now = shared.now();
            let root = inner.engine.root();
            let mut spec = Spawn::new(root, task.kind, task.name, task.action);
            spec.constraints = task.constraints;
            let top = inner.engine.spawn(now, spec)?;
            inner.engine.watch(now, Event::on(top, Facet::Execution, Point::Completed), WatchToken(TOP))?;
            top
        };
        let _ = top;
        let outcome = Driver::new(shared.clone()).drive(&mut self.sinks).await;
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
    tasks: JoinSet<Result<Value, Failure>>,
    nodes: HashMap<tokio::task::Id, NodeId>,
    aborts: BTreeMap<NodeId, AbortHandle>,
}

impl Driver {
    fn new(shared: Arc<Shared>) -> Driver {
        Driver {
            shared,
            tasks: JoinSet::new(),
            nodes: HashMap::new(),
            aborts: BTreeMap::new(),
        }
    }

    /// The driver loop. It is the one intentionally endless loop of the runtime: each turn ends in
    /// an await on the next thing that can change the engine.
    async fn drive(mut self, sinks: &mut [Box<dyn TraceSink>]) -> Result<RunOutcome, Error> {
        let mut trace = Vec::new();
        loop {
            let mut starts = Vec::new();
            let mut cancels = Vec::new();
            let mut answers = Vec::new();
            let mut top_done = None;
            let (deadline, idle, fatal, blocked) = {
                let mut inner = lock(&self.shared)?;
                while let Some(effect) = inner.engine.poll_effect() {
                    match effect {
                        Effect::Start { node, action } => starts.push((node, action)),
                        Effect::Cancel { node } => cancels.push(node),
                        Effect::Notify { token, outcome } if token.0 == TOP => top_done = Some(outcome),
                        Effect::Notify { token, outcome } => {
                            if let Some(tx) = inner.watchers.remove(&token.0) {
                                answers.push((tx, outcome));
                            }
                        }
                    }
                }
                while let Some(ev) = inner.engine.poll_trace() {
                    trace.push(ev);
                }
                let idle = inner.engine.is_idle();
                let blocked = if idle { inner.engine.blocked() } else { Vec::new() };
                (inner.engine.poll_timeout(), idle, inner.engine.fatal().cloned(), blocked)
            };
            for ev in trace.drain(..) {
                for s in sinks.iter_mut() {
                    s.record(&ev);
                }
            }
            for node in cancels {
                if let Some(h) = self.aborts.remove(&node) {
                    h.abort();
                }
            }
            for (tx, outcome) in answers {
                let _ = tx.send(outcome);
            }
            for (node, action) in starts {
                let ctx = Ctx {
                    shared: self.shared.clone(),
                    node,
                };
                let h = self.tasks.spawn(action(ctx));
                self.nodes.insert(h.id(), node);
                self.aborts.insert(node, h);
            }
            if let Some(f) = fatal {
                self.tasks.abort_all();
                return Ok(RunOutcome::Fatal(f));
            }
            if let Some(outcome) = top_done {
                self.tasks.abort_all();
                return Ok(match outcome {
                    WatchOutcome::Reached => RunOutcome::Completed,
                    WatchOutcome::Failed(f) => RunOutcome::TaskFailed(f),
                    WatchOutcome::Terminated | WatchOutcome::Dead => RunOutcome::Terminated,
                });
            }
            if idle && self.tasks.is_empty() && self.shared.handles.load(Ordering::SeqCst) == 0 {
                return Ok(RunOutcome::Stuck(blocked));
            }
            let sleep = deadline.map(|t| self.shared.start + t.since_start());
            tokio::select! {
                biased;
                Some(done) = self.tasks.join_next_with_id() => self.finished(done)?,
                () = self.shared.wake.notified() => {}
                () = sleep_until(sleep), if sleep.is_some() => {
                    let mut inner = lock(&self.shared)?;
                    let now = self.shared.now();
                    inner.engine.handle_timeout(now);
                }
            }
        }
    }

    fn finished(
        &mut self,
        done: Result<(tokio::task::Id, Result<Value, Failure>), tokio::task::JoinError>,
    ) -> Result<(), Error> {
        let (id, result) = match done {
            Ok((id, result)) => (id, result),
            Err(e) if e.is_cancelled() => {
                self.nodes.remove(&e.id());
                return Ok(());
            }
            Err(e) => {
                let id = e.id();
                let message = match e.try_into_panic() {
                    Ok(p) => panic_message(p.as_ref()),
                    Err(e) => e.to_string(),
                };
                (id, Err(Failure::new("ActionPanicked", message)))
            }
        };
        let Some(node) = self.nodes.remove(&id) else {
            return Ok(());
        };
        self.aborts.remove(&node);
        let mut inner = lock(&self.shared)?;
        let now = self.shared.now();
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
        Ok(())
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
