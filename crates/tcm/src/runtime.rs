//! The shell: runs a task tree on tokio, real or virtual time.
//!
//! The driver loop (`RunLoop`, behind [`Runtime::run`] and the program's [`Session`]) owns no
//! semantics. Each turn it runs the core's `Driver::turn` under the engine's lock (due timers fire,
//! effects are carried out by the `Host` of `host.rs`, trace records are taken), hands the records
//! to the sinks outside the lock, runs the timer callbacks that came due, then sleeps until an
//! action or handle touched the engine (spawn, terminate, raise …, each ending in an `Access` that
//! wakes it when needed) or the next deadline, converted by `clock.rs`.
//!
//! [`Runtime::run`] drives the loop in the caller's task until its one top-level task ended;
//! [`Runtime::start`] drives the same loop on a task of its own, for a program that spawns several
//! top-level tasks, waits until the run is quiescent, inspects and terminates, then finishes.

use crate::Error;
use crate::clock::Clock;
use crate::ctx::Ctx;
use crate::host::{DueCallback, Inner, Shared, Status, lock};
use crate::session::Session;
use crate::sink::TraceSink;
use crate::task::Task;
use std::any::Any;
use std::future::Future;
use std::sync::atomic::{AtomicBool, AtomicI32, AtomicU32, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tcm_core::{Engine, Failure, FailurePolicy, Next, TapWhen};
use tokio::sync::{Notify, watch};

mod run_loop;

use crate::events::EventHandle;
use crate::host::{end_run, report};
use crate::outcome::{Report, RunOutcome};
pub(crate) use run_loop::RunLoop;

static RUNS: AtomicU32 = AtomicU32::new(1);

/// The engine of run `run`: every action holds its children until it returns or waits, as
/// generated TDL does (docs/semantics.md, "Bodies and children").
fn engine(run: u32) -> Engine<crate::task::Action, crate::task::Factory> {
    let mut engine = Engine::new(run);
    engine.hold_by_default(true);
    engine
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
    // Whether released actions may run inline on a current-thread runtime (`pump.rs`).
    pump: bool,
    // A declaration the builder could not make (`Runtime::declare`), returned when the run starts.
    setup: Option<tcm_core::EngineError>,
}

impl Default for Runtime {
    fn default() -> Self {
        Runtime::new()
    }
}

impl Runtime {
    /// A new run. Its time zero is when it starts ([`Runtime::run`], [`Runtime::start`]), on the
    /// clock of the tokio runtime that drives it (paused in tests, for virtual time).
    pub fn new() -> Runtime {
        let run = RUNS.fetch_add(1, Ordering::Relaxed);
        let (stopped, stopped_rx) = std::sync::mpsc::channel();
        let clock = Arc::new(Clock::new());
        let mut engine = engine(run);
        // The engine reads the clock itself for the inputs that may not need it (`Engine::at_clock`).
        let read = clock.clone();
        engine.set_clock(Arc::new(move |steps| read.engine_reading(steps)));
        Runtime {
            shared: Arc::new(Shared {
                inner: Mutex::new(Inner::new(engine, stopped_rx)),
                stopped: Mutex::new(stopped),
                stops: AtomicUsize::new(0),
                inline_cancels: AtomicUsize::new(0),
                wake: Notify::new(),
                clock,
                handles: AtomicUsize::new(0),
                status: watch::Sender::new(Status::default()),
                inline: AtomicBool::new(false),
                queued: Arc::default(),
                blocking_nice: AtomicI32::new(0),
                placer: Mutex::new(None),
            }),
            sinks: Vec::new(),
            precise: false,
            pump: true,
            setup: None,
        }
    }

    /// Sets what makes the tasks this run places on other processes (TDL's `on AGENT`,
    /// [`Ctx::remote_task`]): a distribution layer such as `tcm_zenoh::Executive`.
    pub fn placer(self, placer: impl crate::Placer) -> Runtime {
        *self
            .shared
            .placer
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner) = Some(Arc::new(placer));
        self
    }

    /// Declares a resource of `capacity` units (docs/semantics.md, "Resources"): a robot's base,
    /// an arm, a camera, a CPU that runs one heavy planner at a time. Tasks and spawns name it in
    /// their `uses`. A name declared twice, or a capacity of 0, is an error when the run starts.
    pub fn resource(self, name: impl Into<tcm_core::Name>, capacity: u32) -> Runtime {
        self.declare(crate::Resource::new(name, capacity))
    }

    /// Declares a state variable before the run starts (the program's own declaration of it, if
    /// any, must agree on the type; the value set here is kept).
    pub fn state(mut self, var: crate::StateVar) -> Runtime {
        if self.setup.is_none() {
            let declared = match self.shared.inner.lock() {
                Ok(mut inner) => var.declare(&mut inner.engine).map(|_| ()),
                Err(_) => Ok(()),
            };
            self.setup = declared.err();
        }
        self
    }

    /// Declares a resource with its options ([`crate::Resource::pending_limit`]), as
    /// [`Runtime::resource`] does.
    pub fn declare(mut self, resource: crate::Resource) -> Runtime {
        if self.setup.is_none() {
            let declared = match self.shared.inner.lock() {
                Ok(mut inner) => crate::resource::declare(&mut inner.engine, &resource).map(|_| ()),
                Err(_) => Ok(()),
            };
            self.setup = declared.err();
        }
        self
    }

    /// Wakes for timers with a dedicated thread instead of tokio's millisecond timer, so polling
    /// monitors keep sub-millisecond schedules (see the `timer` module). Real time only: under
    /// tokio's paused clock, leave it off.
    pub fn precise_timer(mut self) -> Runtime {
        self.precise = true;
        self
    }

    /// Runs the run's clock `scale` times as fast as tokio's (a finite number above 0; default 1):
    /// on the real clock, a simulation that runs faster than real time, as a demo paced for
    /// watching does. Every time of the run is on it: constraint timers, monitor periods, grace
    /// periods, [`crate::Ctx::now`], [`crate::Ctx::sleep`] and the report's `elapsed`. An action
    /// that sleeps with tokio's own `sleep` sleeps tokio's time, unscaled: use `Ctx::sleep`.
    pub fn time_scale(self, scale: f64) -> Runtime {
        self.shared.clock.set_scale(scale);
        self
    }

    /// Spawns every action as a tokio task, as on a multi-thread runtime: for tests that compare
    /// the two ways (`pump.rs`).
    #[cfg(test)]
    pub(crate) fn without_pump(mut self) -> Runtime {
        self.pump = false;
        self
    }

    /// Runs blocking bodies ([`Task::blocking`], [`crate::Ctx::blocking`]) at the nice value
    /// `nice` (Linux; from 1, lowest priority of all, to 19, the lowest of the normal ones), so
    /// that on a CPU they keep busy, the tree's timers, monitors and other actions come first:
    /// a body raises the nice value of its thread when it starts and puts it back when it ends.
    /// Putting it back needs the right to raise a priority (root, `CAP_SYS_NICE`, or an
    /// `RLIMIT_NICE` that allows it); without it, the tokio blocking thread keeps the lower
    /// priority for whatever it runs next. Default 0: bodies run at their thread's priority
    /// (docs/semantics.md, "Blocking actions").
    pub fn blocking_nice(self, nice: i32) -> Runtime {
        self.shared
            .blocking_nice
            .store(nice.clamp(0, 19), Ordering::Relaxed);
        self
    }

    /// Adds a trace sink.
    pub fn with_sink(mut self, sink: impl TraceSink + 'static) -> Runtime {
        self.sinks.push(Box::new(sink));
        self
    }

    /// Sets the grace period of the actions whose task sets none ([`Task::grace`]); default
    /// [`DEFAULT_GRACE`](crate::DEFAULT_GRACE), one second. When a node is terminated while its
    /// action runs, an action that looked at its cancellation signal ([`Ctx::cancelled`],
    /// [`Ctx::is_cancelled`]) is signalled and may run this long to cancel what it started
    /// outside; it is dropped when it returns or when the period ends (then with a warning). An
    /// action that never looked is dropped at once, whatever the period. `Duration::ZERO` drops
    /// every action at once (docs/semantics.md, "Termination").
    pub fn default_grace(self, grace: Duration) -> Runtime {
        if let Ok(mut inner) = self.shared.inner.lock() {
            inner.cancels.default = grace;
        }
        self
    }

    /// Chooses what an unhandled failure does (default: warn and go on, as TCM).
    pub fn failure_policy(self, policy: FailurePolicy) -> Runtime {
        if let Ok(mut inner) = self.shared.inner.lock() {
            inner.engine.set_failure_policy(policy);
        }
        self
    }

    /// Registers a wiretap (the TCA paper's wiretap monitors) on a class of tasks: `check` runs
    /// whenever a node that is an instance of the task named `task` (its [`Task::task_name`],
    /// whatever instance name [`Task::named`] gave it) is about to start its action (`Before`) or
    /// returned successfully (`After`), without touching that task's code. A failing check fails
    /// the tapped node with the check's failure (handlers then apply as to any failure). To tap
    /// one instance name instead, use [`Runtime::wiretap_instance`] (docs/semantics.md,
    /// "Wiretaps").
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

    /// As [`Runtime::wiretap`], on the nodes whose instance name is `instance`, whatever task
    /// they are instances of (an explicit choice: naming instances changes what this taps).
    pub fn wiretap_instance<F, Fut, T>(
        self,
        instance: impl Into<tcm_core::Name>,
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
                .wiretap_instance(instance, when, crate::task::factory(check));
        }
        self
    }

    /// Attaches `handler` from outside to every node of the task named `task` (its
    /// [`Task::task_name`], whatever instance name it was given), without touching the task's
    /// code: TCA's recovery "without modifying existing components". The handler search finds it
    /// at such a node after the node's own handlers (task-level, then spawn-level); handlers
    /// attached to one task are tried in the order attached. Each node counts its own uses for
    /// [`crate::Handler::max_activations`] (docs/semantics.md, "Handlers attached to a task").
    pub fn handler_for(
        self,
        task: impl Into<tcm_core::Name>,
        handler: crate::task::Handler,
    ) -> Runtime {
        if let Ok(mut inner) = self.shared.inner.lock() {
            inner.engine.handler_for(task, handler.spec);
        }
        self
    }

    /// Injects `fault` from the start of the run (docs/semantics.md, "Steering a run", rule 4):
    /// the next ends of the nodes it matches are what it says, their actions never running. For
    /// tests and simulation: `--faults faults.json` ([`read_faults`](crate::read_faults)).
    pub fn inject(self, fault: tcm_core::Fault) -> Runtime {
        if let Ok(mut inner) = self.shared.inner.lock() {
            inner
                .engine
                .inject(tcm_core::Time::ZERO, fault, "faults file");
        }
        self
    }

    /// Adds a rule that holds the nodes it matches until an operator approves them through the
    /// run's [`Control`](crate::Control) (docs/semantics.md, "Steering a run", rule 5).
    pub fn require_approval(self, rule: tcm_core::Approval) -> Runtime {
        if let Ok(mut inner) = self.shared.inner.lock() {
            inner
                .engine
                .require_approval(tcm_core::Time::ZERO, rule, "the program");
        }
        self
    }

    /// Keeps a journal of the run (docs/semantics.md, "Durable runs"): every input its engine
    /// takes is appended to `writer` before what it causes is carried out; a failed write ends
    /// the run with the unhandled exception `JournalFailed` at the root. The journal is synced
    /// and closed when the run ends.
    pub fn journal(self, writer: tcm_journal::Writer) -> Runtime {
        self.journal_with(writer, crate::journal::json_values)
    }

    /// As [`Runtime::journal`], each action's value written as `encode` makes it JSON (an
    /// interpreted program's values, say); a value it cannot write is left out of its entry.
    pub fn journal_with(
        self,
        writer: tcm_journal::Writer,
        encode: crate::journal::ValueEncoder,
    ) -> Runtime {
        if let Ok(mut inner) = self.shared.inner.lock() {
            inner.engine.record_inputs(true);
            inner.journal = Some(Box::new(crate::journal::Journaled::new(writer, encode)));
        }
        self
    }

    /// Replays `journal` (read by `tcm_journal::read` for this program): the run is rebuilt from
    /// the inputs its engine took, its bodies run again and its commands' ends come from the
    /// journal, on the journal's time; at the journal's end the run ends with
    /// [`RunOutcome::JournalEnded`] (unless it ended first), and at the first difference between
    /// the program and the run with [`RunOutcome::Diverged`] (docs/semantics.md, "Durable runs").
    /// The trace is the run's, record for record.
    pub fn replay(self, journal: tcm_journal::Journal) -> Runtime {
        self.replaying(journal, crate::replay::AtEnd::Stop)
    }

    /// As [`Runtime::replay`], then the run goes on live: its time from the journal's last, a
    /// `control` record by `journal` saying where it resumed, each command that was running at
    /// the crash failed with the exception `Interrupted`. Give it the journal to go on writing
    /// (`tcm_journal::Writer::reopen`, [`Runtime::journal`]) to survive a second crash.
    pub fn resume(self, journal: tcm_journal::Journal) -> Runtime {
        self.replaying(journal, crate::replay::AtEnd::GoLive)
    }

    /// How a replay reads values from the journal: `decode` makes a command's value from its
    /// entry, and `encode` (the run's encoder, given to [`Runtime::journal_with`]) writes a
    /// body's returned value to compare it with the run's; JSON values by default
    /// ([`crate::json_values`], [`crate::json_decoded`]).
    pub fn replay_values(
        self,
        encode: crate::ValueEncoder,
        decode: crate::ValueDecoder,
    ) -> Runtime {
        if let Ok(mut inner) = self.shared.inner.lock() {
            if let Some(r) = inner.replay.as_mut() {
                r.encode = encode;
                r.decode = decode;
            }
        }
        self
    }

    fn replaying(self, journal: tcm_journal::Journal, at_end: crate::replay::AtEnd) -> Runtime {
        let replay = crate::replay::Replay::new(journal, crate::json_decoded, at_end);
        self.shared.clock.replay_from(replay.feed.clone());
        if let Ok(mut inner) = self.shared.inner.lock() {
            inner.replay = Some(Box::new(replay));
        }
        self
    }

    /// Adds a wiretap built for one task (TDL's `wiretap w() before T { … }`): the same as
    /// [`Runtime::wiretap`] with the task and the point it names.
    pub fn tap(self, tap: crate::task::Tap) -> Runtime {
        if let Ok(mut inner) = self.shared.inner.lock() {
            inner.engine.wiretap(tap.task, tap.when, tap.check);
        }
        self
    }

    /// Attaches a handler built for one task (TDL's `handler h() handles E for T`): the same as
    /// [`Runtime::handler_for`] with the task it names.
    pub fn attach(self, attached: crate::task::Attached) -> Runtime {
        self.handler_for(attached.task, attached.handler)
    }

    /// A handle to raise external events.
    pub fn events(&self) -> EventHandle {
        self.shared.handles.fetch_add(1, Ordering::SeqCst);
        EventHandle::new(self.shared.clone())
    }

    /// Runs `task` as the top-level task until its execution completes, it fails fatally, or the run
    /// is stuck. Actions run as tokio tasks of the current runtime. The same as
    /// [`Runtime::start`], [`Session::spawn`] and [`Session::finish`], with the driver loop in the
    /// caller's task.
    pub async fn run(mut self, task: Task) -> Result<Report, Error> {
        let shared = self.prepare(tokio::runtime::Handle::current())?;
        {
            let mut inner = shared.enter()?;
            // As in `start`: what the journal's run took before its first task comes first.
            if inner.replay.is_some() {
                crate::replay::feed_operations(&mut inner, &shared);
            }
            inner.finishing = true;
            let now = inner.engine.at_clock();
            let root = inner.engine.root();
            let (spec, kept) = task.into_parts(root);
            inner.spawn_root(now, spec, kept)?;
        }
        let timer = self.timer()?;
        let driver = RunLoop::new(shared.clone(), timer);
        // Its wake-ups are counted when it runs in a task (`pump.rs`); the caller runs now.
        let drive = Box::pin(driver.drive(&mut self.sinks));
        let outcome = crate::pump::MaybeTracked::new(&shared, drive, false).await;
        for s in &mut self.sinks {
            s.flush();
        }
        report(&shared, outcome?)
    }

    /// Starts the run for a program in TCM's style (TCM's `TCM_ProcessAgenda`): spawn several
    /// top-level tasks with [`Session::spawn`], wait until nothing more can run with
    /// [`Session::quiescent`], inspect or terminate nodes, and end with [`Session::finish`]. The
    /// driver loop runs on a task of the current tokio runtime meanwhile (an error outside one).
    ///
    /// ```
    /// # #[tokio::main(flavor = "current_thread", start_paused = true)]
    /// # async fn main() -> Result<(), tcm::Error> {
    /// use tcm::{Constraint, Facet, RunOutcome, Runtime, State, Task, When};
    ///
    /// let session = Runtime::new().start()?;
    /// let beep = session.spawn(Task::command("beep", |_| async { Ok(()) }))?;
    /// let door = session.external("door_open")?;
    /// let enter = session.spawn(
    ///     Task::command("enter", |_| async { Ok(()) })
    ///         .with(Constraint::disable(Facet::Handling, When::External(door))),
    /// )?;
    /// // Nothing more can run: `beep` is done, `enter` waits for an event nobody raises.
    /// session.quiescent().await?;
    /// assert!(session.info(beep)?.is_none(), "completed, and reclaimed");
    /// let state = session.info(enter)?.map(|i| i.state(Facet::Handling));
    /// assert_eq!(state, Some(State::Disabled));
    /// session.terminate(enter)?;
    /// let report = session.finish().await?;
    /// assert_eq!(report.outcome, RunOutcome::Terminated);
    /// # Ok(())
    /// # }
    /// ```
    pub fn start(mut self) -> Result<Session, Error> {
        let handle = tokio::runtime::Handle::try_current().map_err(|_| Error::NoRuntime)?;
        let shared = self.prepare(handle.clone())?;
        let root = {
            let mut inner = lock(&shared)?;
            // What the journal's run took before its first task (an operation from outside, as
            // `tdl run` steers before it spawns), the replay gives before the session's first.
            if inner.replay.is_some() {
                crate::replay::feed_operations(&mut inner, &shared);
            }
            inner.engine.root()
        };
        let timer = self.timer()?;
        let mut sinks = std::mem::take(&mut self.sinks);
        let driver = RunLoop::new(shared.clone(), timer);
        let tracking = shared.clone();
        let driver = handle.spawn(async move {
            // Its wake-ups are counted (`pump.rs`); a new task is queued.
            let drive = Box::pin(driver.drive(&mut sinks));
            let outcome = crate::pump::MaybeTracked::new(&tracking, drive, true).await;
            for s in &mut sinks {
                s.flush();
            }
            outcome
        });
        Ok(Session::new(shared, root, driver))
    }

    /// Makes the run ready to drive: where actions are spawned, and whether to build the trace.
    fn prepare(&mut self, rt: tokio::runtime::Handle) -> Result<Arc<Shared>, Error> {
        if let Some(e) = self.setup.take() {
            return Err(e.into());
        }
        // Time zero, on the clock of the tokio runtime that drives the run.
        self.shared.clock.start();
        let flavor = rt.runtime_flavor();
        self.shared.inline.store(
            flavor == tokio::runtime::RuntimeFlavor::CurrentThread && self.pump,
            Ordering::Relaxed,
        );
        let mut inner = lock(&self.shared)?;
        inner.spawner = Some(rt);
        // Nobody reads the trace: do not build it, but for its warnings, which are logged.
        inner.engine.set_tracing(!self.sinks.is_empty());
        inner.engine.trace_warnings(true);
        if inner.replay.is_some() {
            // A replay's inputs are in its journal already; a resumed run records its new ones.
            inner.engine.record_inputs(false);
        }
        Ok(self.shared.clone())
    }

    fn timer(&self) -> Result<Option<crate::timer::PreciseTimer>, Error> {
        if self.precise {
            let t = crate::timer::PreciseTimer::start(self.shared.clone()).map_err(Error::Timer)?;
            Ok(Some(t))
        } else {
            Ok(None)
        }
    }
}
