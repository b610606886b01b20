//! The shell: runs a task tree on tokio, real or virtual time.
//!
//! The driver loop (`RunLoop`, behind [`Runtime::run`]) owns no semantics. Each turn it runs the
//! core's `Driver::turn` under the engine's lock (due timers fire, effects are carried out by the
//! `Host` of `host.rs`, trace records are taken), hands the records to the sinks outside the lock,
//! then sleeps until an action or handle touched the engine (spawn, terminate, raise …, each ending
//! in a `Session` that wakes it when needed) or the next deadline, converted by `clock.rs`.

use crate::Error;
use crate::clock::Clock;
use crate::ctx::Ctx;
use crate::host::{Inner, Shared, TOP, lock};
use crate::sink::TraceSink;
use crate::task::Task;
use std::any::Any;
use std::future::Future;
use std::sync::atomic::{AtomicU32, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tcm_core::{
    Blocked, Engine, Event, Failure, FailurePolicy, FatalFailure, Next, Stats, TapWhen,
    WatchOutcome, WatchToken,
};
use tcm_trace::{Facet, Point};
use tokio::sync::Notify;

static RUNS: AtomicU32 = AtomicU32::new(1);

/// How a run ended.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum RunOutcome {
    /// The top-level task's execution completed (it and its whole subtree).
    Completed,
    /// The top-level task's own action failed (whether or not a handler then took the failure).
    TaskFailed(Failure),
    /// The top-level task was terminated.
    Terminated,
    /// An unhandled failure under [`FailurePolicy::Fatal`].
    Fatal(FatalFailure),
    /// Nothing can progress, no timer is pending and no event handle is open: these nodes wait on
    /// events that will never come (docs/semantics.md, "Run outcome").
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
        s.engine.handle_external(now, id);
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
        let (stopped, stopped_rx) = std::sync::mpsc::channel();
        Runtime {
            shared: Arc::new(Shared {
                inner: Mutex::new(Inner::new(Engine::new(run), stopped_rx)),
                stopped: Mutex::new(stopped),
                wake: Notify::new(),
                clock: Clock::new(),
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
        let outcome = RunLoop::new(shared.clone(), timer)
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

/// The driver loop's view of the run after one turn.
struct Turn {
    next: Next,
    fatal: Option<FatalFailure>,
    // The stuck report, when the run can no longer progress.
    blocked: Option<Vec<Blocked>>,
    top_done: Option<WatchOutcome>,
}

struct RunLoop {
    shared: Arc<Shared>,
    timer: Option<crate::timer::PreciseTimer>,
}

impl RunLoop {
    fn new(shared: Arc<Shared>, timer: Option<crate::timer::PreciseTimer>) -> RunLoop {
        RunLoop { shared, timer }
    }

    /// One turn of the core's driver under the lock: due timers fire, effects are carried out,
    /// trace records are taken for the sinks.
    fn turn(&self, trace: &mut Vec<tcm_trace::TraceEvent>) -> Result<Turn, Error> {
        // A plain lock, not a `Session`: the driver decides itself what to do next, and waking
        // itself would spin while the run waits for an event handle.
        let mut inner = lock(&self.shared)?;
        let now = self.shared.now();
        inner.report_stopped(now);
        let (engine, mut host) = inner.split(&self.shared);
        let next = tcm_core::Driver::turn(engine, &mut host, now);
        trace.append(&mut inner.trace);
        inner.armed = next.deadline;
        let running = !inner.aborts.is_empty();
        let over = next.idle && !running && self.shared.handles.load(Ordering::SeqCst) == 0;
        Ok(Turn {
            next,
            fatal: inner.engine.fatal().cloned(),
            // The stuck report scans every node: only when the run is over.
            blocked: over.then(|| inner.engine.blocked()),
            top_done: inner.top_done.clone(),
        })
    }

    /// The driver loop. It is the one intentionally endless loop of the runtime: each turn ends in
    /// an await on the next thing that can change the engine.
    async fn drive(self, sinks: &mut [Box<dyn TraceSink>]) -> Result<RunOutcome, Error> {
        let mut trace = Vec::new();
        let result = loop {
            let turn = self.turn(&mut trace)?;
            for ev in trace.drain(..) {
                for s in sinks.iter_mut() {
                    s.record(&ev);
                }
            }
            if let Some(f) = turn.fatal {
                break RunOutcome::Fatal(f);
            }
            if let Some(outcome) = turn.top_done {
                break match outcome {
                    WatchOutcome::Reached => RunOutcome::Completed,
                    WatchOutcome::Failed(f) | WatchOutcome::Handled(f) => RunOutcome::TaskFailed(f),
                    WatchOutcome::Terminated | WatchOutcome::Dead => RunOutcome::Terminated,
                };
            }
            if let Some(blocked) = turn.blocked {
                break RunOutcome::Stuck(blocked);
            }
            let mut sleep = turn.next.deadline.map(|t| self.shared.clock.instant(t));
            if let Some(timer) = &self.timer {
                timer.set(sleep.map(tokio::time::Instant::into_std));
                sleep = None;
            }
            tokio::select! {
                biased;
                () = self.shared.wake.notified() => {}
                () = sleep_until(sleep), if sleep.is_some() => {
                    // The next turn fires the timer; nobody need wake it for a deadline it set.
                    lock(&self.shared)?.armed = None;
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

async fn sleep_until(at: Option<tokio::time::Instant>) {
    if let Some(at) = at {
        tokio::time::sleep_until(at).await;
    }
}
