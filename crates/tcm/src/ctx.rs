//! The context an action gets: its own node, and the means to spawn, wait for, constrain and
//! terminate nodes of its run; in a monitor activation, to trigger; in a handler, to read the
//! exception, bypass it or retry the failed task.

use crate::Error;
use crate::host::{Shared, lock};
use crate::task::{Action, AnyArgs, Factory, Kept, Task};
use std::any::Any;
use std::future::Future;
use std::sync::atomic::Ordering;
use std::sync::{Arc, OnceLock};
use std::time::Duration;
use tcm_core::{
    Constraint, Event, ExternalId, Facet, Failure, Job, NodeId, Point, Purpose, Termination,
    WatchOutcome, WatchToken,
};
use tokio::sync::{oneshot, watch};

mod journal;
mod place;
mod resource;
mod spawner;
mod state;

pub use spawner::{Ended, Spawner};

/// What an action sees of the runtime. Cheap to clone; usable from any task or thread of the run.
#[derive(Clone)]
pub struct Ctx {
    pub(crate) shared: Arc<Shared>,
    pub(crate) node: NodeId,
    pub(crate) purpose: Option<Arc<Purpose>>,
    // The job this context belongs to: the node's action or invocation, or a wiretap check; `None`
    // for a timer callback or the program's session. Its awaits on the engine count as parked
    // (docs/semantics.md, "Run outcome").
    pub(crate) job: Option<Job>,
    // The arguments the host keeps for `node` (`Task::with_args`), when the context was made.
    pub(crate) args: Option<AnyArgs>,
    // The job's cancellation signal, taken from the host on the first look (`cancel.rs`): a
    // context that never looks costs no allocation, and later looks read it without the lock.
    pub(crate) signal: OnceLock<watch::Receiver<bool>>,
}

impl Ctx {
    /// The context of a job's action (not an invocation's): the node's own, holding its kept
    /// arguments; its children are held until it returns (`Engine::hold_by_default`).
    #[inline(always)]
    pub(crate) fn of_job(shared: Arc<Shared>, job: Job, args: Option<AnyArgs>) -> Ctx {
        Ctx {
            shared,
            node: job.node(),
            purpose: None,
            job: Some(job),
            args,
            signal: OnceLock::new(),
        }
    }

    /// This action's node.
    pub fn node(&self) -> NodeId {
        self.node
    }

    /// Virtual time since the run started.
    pub fn now(&self) -> Duration {
        self.shared.now().since_start()
    }

    /// Sleeps `d` of the run's time: on a scaled clock ([`crate::Runtime::time_scale`]), `d`
    /// divided by the scale of tokio's time; otherwise the same as `tokio::time::sleep(d)`
    /// (virtual on tokio's paused clock).
    pub async fn sleep(&self, d: Duration) {
        let at = self.shared.now() + d;
        tokio::time::sleep_until(self.shared.clock.instant(at)).await;
    }

    /// The engine time of today's occurrence of a time of day (`secs` since midnight, UTC), for
    /// `disable until` / `terminate at` an absolute time (docs/semantics.md, "Time": resolved against the
    /// wall clock now; a time already past today is due at once).
    pub fn time_of_day(&self, secs: f64) -> tcm_core::Time {
        self.shared.clock.time_of_day(secs)
    }

    // ---- Cancellation (docs/semantics.md, "Termination").

    /// Resolves once this action is cancelled: its node was terminated while it ran (or the run
    /// ended under it). Then the action has its grace period ([`Task::grace`],
    /// [`crate::Runtime::default_grace`]; one second by default) to cancel what it started outside
    /// (a ROS 2 goal, a remote task, a motion) and return; it is dropped at the end of the period.
    /// Its node stays terminating, and is terminated once the action returned; what it returns
    /// is ignored.
    ///
    /// Calling this (or [`Ctx::is_cancelled`]) is what gives the action its grace period: an
    /// action that never looked at the signal is dropped at once when its node is terminated, as
    /// it cannot react. The look counts when this is called, not when the future is first polled,
    /// so create the future before the work it guards:
    ///
    /// ```
    /// # use tcm::{Ctx, Failure};
    /// # async fn start_goal() {}
    /// # async fn goal_done() {}
    /// # async fn cancel_goal() {}
    /// async fn navigate(ctx: Ctx) -> Result<(), Failure> {
    ///     start_goal().await;
    ///     tcm::tokio::select! {
    ///         () = goal_done() => {}
    ///         // Terminated: cancel the goal on the server, within the grace period.
    ///         () = ctx.cancelled() => cancel_goal().await,
    ///     }
    ///     Ok(())
    /// }
    /// ```
    ///
    /// The future owns what it needs (it may move into another task). It never resolves in a
    /// context of no cancellable job (the program's session, a timer callback, a wiretap check),
    /// nor once the action ended by itself. A context that outlives its action and looks first
    /// after the action ended resolves at once if the node is still there, terminating or
    /// terminated, and never otherwise.
    pub fn cancelled(&self) -> impl Future<Output = ()> + Send + 'static {
        let rx = self.signal().cloned();
        async move {
            if let Some(mut rx) = rx {
                let fired = rx.wait_for(|cancelled| *cancelled).await.is_ok();
                if fired {
                    return;
                }
            }
            // Closed without firing: the action ended by itself, and never will be cancelled.
            std::future::pending::<()>().await;
        }
    }

    /// Whether this action was cancelled (see [`Ctx::cancelled`]): for an action that polls, as a
    /// loop over the steps of a motion. The first call takes the engine's lock once; later calls
    /// only read the signal's latched value. Like [`Ctx::cancelled`], calling it gives the action its grace period.
    pub fn is_cancelled(&self) -> bool {
        self.signal().is_some_and(|rx| *rx.borrow())
    }

    /// Runs `f`, code that blocks or computes (a planner, a blocking driver call), on one of
    /// tokio's blocking threads (`spawn_blocking`), so it never stalls the tree, its timers or the
    /// other actions; the future ends with what `f` returns. [`Task::blocking`] is an action that
    /// is only this. `f` gets a clone of this context: it may spawn, constrain, raise events, and
    /// check [`Ctx::is_cancelled`] (a read of a latched flag once made) between its steps.
    ///
    /// No thread can be stopped from outside, so from the moment `f` starts, the action is never
    /// dropped: when its node is terminated, it is signalled, and its node stays terminating until
    /// the action returns (docs/semantics.md, "Termination"); a body that checks
    /// [`Ctx::is_cancelled`] returns early, one that never does runs to its end. If the node was
    /// terminated before `f` could start, `f` never runs. A panic in `f` fails the node as a
    /// panicking action does. Bound how many bodies run at once with the tokio runtime's
    /// `max_blocking_threads` (or a resource, docs/semantics.md, "Resources").
    ///
    /// On virtual time (tokio's paused clock) the clock stands still while `f` runs: blocking work
    /// takes no virtual time, and two bodies that run side by side end in the order they end on
    /// the real clock.
    pub fn blocking<F, T>(
        &self,
        f: F,
    ) -> impl Future<Output = Result<T, Failure>> + Send + use<F, T>
    where
        F: FnOnce(Ctx) -> Result<T, Failure> + Send + 'static,
        T: Send + 'static,
    {
        let ctx = self.clone();
        async move {
            if !ctx.pin() {
                return Err(Failure::new(
                    "Terminated",
                    "terminated before its blocking body started",
                ));
            }
            let rt = lock(&ctx.shared)?.spawner.clone();
            let nice = ctx.shared.blocking_nice.load(Ordering::Relaxed);
            let body = ctx.clone();
            let run = move || {
                let _nice = crate::niced::Niced::enter(nice);
                f(body)
            };
            let handle = match rt {
                Some(rt) => rt.spawn_blocking(run),
                None => tokio::task::spawn_blocking(run),
            };
            match handle.await {
                Ok(res) => res,
                // Reported as the action's own panic (`host.rs`).
                Err(e) if e.is_panic() => std::panic::resume_unwind(e.into_panic()),
                Err(e) => Err(Failure::new("BlockingCancelled", e.to_string())),
            }
        }
    }

    /// Before a blocking body starts: looks at the job's signal and pins the job, so that a
    /// cancellation only signals it (`cancel.rs`). False if the job no longer runs (its node was
    /// terminated meanwhile): the body must not start.
    fn pin(&self) -> bool {
        let Some(job) = self.job.filter(Job::cancellable) else {
            return true;
        };
        let _ = self.signal();
        let Ok(mut inner) = lock(&self.shared) else {
            return false;
        };
        if !inner.aborts.contains(job.node()) {
            return false;
        }
        inner.cancels.pin(job.node());
        true
    }

    /// The job's cancellation signal, taken from the host on the first look; `None` for a context
    /// of no cancellable job.
    fn signal(&self) -> Option<&watch::Receiver<bool>> {
        let job = self.job.filter(Job::cancellable)?;
        Some(self.signal.get_or_init(|| {
            let node = job.node();
            let Ok(mut inner) = lock(&self.shared) else {
                // The run is poisoned: nothing will cancel this action any more.
                return watch::channel(false).1;
            };
            let inner = &mut *inner;
            let running = inner.aborts.contains(node);
            let engine = &inner.engine;
            inner.cancels.signal(node, running, || {
                engine
                    .info(node)
                    .is_some_and(|i| i.termination != Termination::Alive)
            })
        }))
    }

    /// Starts building a spawn of `task` as a child of this node.
    #[inline]
    pub fn spawn(&self, task: Task) -> Spawner<'_> {
        let (spec, kept) = task.into_parts(self.node);
        Spawner {
            ctx: self,
            spec,
            kept,
        }
    }

    /// Reserves a child for a later spawn, so constraints can name it now (a forward reference).
    /// If this action ends without spawning it (through [`Spawner::fulfils`]), it is dead.
    pub fn reserve(&self, name: &'static str) -> Result<NodeId, Error> {
        self.with_engine(|e, now| e.reserve(now, self.node, name))
    }

    /// Holds (`true`) or releases the start of the children this action spawns. While held, they
    /// are inserted and constrained but do not start; they start when the action returns, when it
    /// releases them, or while it waits ([`Ctx::wait`] releases and then holds again). This is
    /// TDL's semantics (a body ends before its children run), so that constraint statements after
    /// a spawn still apply; every action starts holding (docs/semantics.md, "Bodies and
    /// children"). An action that wants its children to start at once calls
    /// `ctx.hold_children(false)?` first; so must one that awaits a child by other means than a
    /// wait (a channel), or the child never starts.
    pub fn hold_children(&self, on: bool) -> Result<(), Error> {
        self.with_engine(|e, now| e.hold_children(now, self.node, on).map(|_| ()))
    }

    /// Waits until `node`'s execution completes (the node and its whole subtree), as TDL's `wait`.
    /// The action's held children start meanwhile. While it waits, the action counts as parked: if
    /// every running action is parked and nothing else can happen, the run is stuck
    /// (docs/semantics.md, "Run outcome").
    pub async fn wait(&self, node: NodeId) -> Result<WatchOutcome, Error> {
        let mut held = false;
        let res = self.wait_released(node, &mut held).await;
        if held {
            self.with_engine(|e, now| e.hold_children(now, self.node, true))?;
        }
        res
    }

    /// Waits for `node`'s execution to complete, releasing this action's held children once the
    /// watch is set (`held` tells whether it held them), so a child that ends at once when it is
    /// released (a resource denied) is still seen ending, with its failure.
    async fn wait_released(&self, node: NodeId, held: &mut bool) -> Result<WatchOutcome, Error> {
        let event = Event::on(node, Facet::Execution, Point::Completed);
        let (rx, token) = {
            let mut inner = self.shared.enter()?;
            let token = inner.next_token();
            let (tx, rx) = oneshot::channel();
            inner.watchers.insert(token, tx);
            let now = inner.engine.at_clock();
            if let Err(e) = inner.engine.watch(now, event, WatchToken(token)) {
                inner.watchers.remove(&token);
                return Err(e.into());
            }
            // Parked until the notification (carried out when this access ends, if the node
            // already completed) or until this future is dropped.
            if let Some(job) = self.job {
                inner.park(token, job, event);
                // Only an action holds children (not a callback's or the program's context).
                match inner.engine.hold_children(now, self.node, false) {
                    Ok(was) => *held = was,
                    Err(e) => {
                        inner.parking.unpark(token);
                        inner.watchers.remove(&token);
                        return Err(e.into());
                    }
                }
            }
            (rx, token)
        };
        let mut unpark = crate::host::Unpark {
            shared: &self.shared,
            token,
            armed: self.job.is_some(),
        };
        // Its wake-up is counted, so that the pump knows the waiting task is queued (`pump.rs`).
        let res = crate::pump::MaybeTracked::new(&self.shared, rx, false).await;
        // Answered: the notification already unparked it.
        unpark.armed = unpark.armed && res.is_err();
        res.map_err(|_| Error::RunEnded)
    }

    /// Applies a constraint to an existing node (termination and activation constraints at any
    /// time; enablement constraints only before the facet is enabled).
    pub fn constrain(&self, node: NodeId, c: Constraint) -> Result<(), Error> {
        self.with_engine(|e, now| e.constrain(now, node, c))
    }

    /// Arms a trigger on a whole group: `then` happens to `target` once every member of `members`
    /// reached `point` of `facet` (after `delay`, if any); with no members it fires at once
    /// (docs/semantics.md, "Tags and forward references"). TDL's `terminate at <group> …` and
    /// `activate at <group> …` use it.
    pub fn trigger_group(
        &self,
        target: NodeId,
        members: &[NodeId],
        facet: Facet,
        point: Point,
        delay: Option<Duration>,
        then: tcm_core::Then,
    ) -> Result<(), Error> {
        self.with_engine(|e, now| e.trigger_group(now, target, members, facet, point, delay, then))
    }

    /// Terminates `node` and its subtree.
    pub fn terminate(&self, node: NodeId) -> Result<(), Error> {
        self.with_engine(|e, now| e.terminate(now, node))
    }

    /// Terminates every child of `node`.
    pub fn terminate_children(&self, node: NodeId) -> Result<(), Error> {
        self.with_engine(|e, now| e.terminate_children(now, node))
    }

    /// Terminates every sibling of `node`.
    pub fn terminate_siblings(&self, node: NodeId) -> Result<(), Error> {
        self.with_engine(|e, now| e.terminate_siblings(now, node))
    }

    /// Suspends `node` and its subtree: nothing new starts there until [`Ctx::unsuspend`].
    pub fn suspend(&self, node: NodeId) -> Result<(), Error> {
        self.with_engine(|e, now| e.suspend(now, node))
    }

    /// Unsuspends `node` and its subtree.
    pub fn unsuspend(&self, node: NodeId) -> Result<(), Error> {
        self.with_engine(|e, now| e.unsuspend(now, node))
    }

    /// The id of a named external event, for constraints.
    pub fn external(&self, name: &str) -> Result<ExternalId, Error> {
        let mut inner = self.shared.enter()?;
        Ok(inner.engine.external(name))
    }

    /// Raises a named external event.
    pub fn raise(&self, name: &str) -> Result<(), Error> {
        self.with_engine(|e, now| {
            let id = e.external(name);
            e.handle_external(now, id);
            Ok(())
        })
    }

    /// Says that this node's action runs on another process, the agent `agent` (a `placed` trace
    /// record; docs/distributed.md). For distribution layers such as `tcm-zenoh`, which call it
    /// when they send the action there.
    pub fn placed(&self, agent: &str) -> Result<(), Error> {
        let node = self.node;
        self.with_engine(|e, now| e.note_placed(now, node, agent))
    }

    /// Writes `message` to the run's log: a `log` record about this node, stamped with the run's
    /// time (TDL's `log` statement). It goes where the trace goes: the trace file, the viewer,
    /// `tcm::TracingSink` (at `INFO`). The run's time is the virtual clock's on a simulated run,
    /// so a log line of a test is the same on every run.
    pub fn log(&self, message: impl Into<String>) -> Result<(), Error> {
        let node = self.node;
        let message = message.into();
        self.engine_call(true, |e, now| e.log(now, node, message))
    }

    /// Adds a `warning` record about this node (about the run once the node has left the tree):
    /// something worth a person's attention that the tree cannot see itself (a message from an
    /// agent that arrived twice, say). The run goes on; it is counted with the run's other
    /// warnings and logged as they are.
    pub fn warn(&self, message: impl Into<String>) -> Result<(), Error> {
        let node = self.node;
        let message = message.into();
        self.with_engine(|e, now| {
            e.warn(now, Some(node), message);
            Ok(())
        })
    }

    // ---- Monitors.

    /// In a monitor activation: this activation's number (from 1) and the triggers counted when it
    /// was created.
    pub fn activation(&self) -> Option<(u32, u32)> {
        match self.purpose.as_deref() {
            Some(Purpose::Activation {
                number, triggers, ..
            }) => Some((*number, *triggers)),
            _ => None,
        }
    }

    /// In a monitor activation: counts a trigger of the monitor (TDL's `trigger`); at the maximum,
    /// the monitor completes.
    pub fn trigger(&self) -> Result<(), Error> {
        self.with_engine(|e, now| e.trigger(now, self.node))
    }

    /// Activates a monitor now; returns the activation node (`None` past its maximum).
    pub fn activate(&self, monitor: NodeId) -> Result<Option<NodeId>, Error> {
        self.with_engine(|e, now| e.activate(now, monitor))
    }

    /// The activations and triggers a monitor counted so far (from the monitor or an activation).
    pub fn monitor_counts(&self, node: NodeId) -> Result<Option<(u32, u32)>, Error> {
        Ok(lock(&self.shared)?.engine.monitor_counts(node))
    }

    // ---- Exception handlers.

    /// In a handler: the failure being handled.
    pub fn failure(&self) -> Option<&Failure> {
        match self.purpose.as_deref() {
            Some(Purpose::Handler { failure, .. }) => Some(failure),
            _ => None,
        }
    }

    /// In a handler: the exception value, if it is an `E`.
    pub fn caught<E: Any + Send + Sync>(&self) -> Option<Arc<E>> {
        self.failure().and_then(|f| f.data::<E>())
    }

    /// In a handler: the node whose action failed.
    pub fn failing_node(&self) -> Option<NodeId> {
        match self.purpose.as_deref() {
            Some(Purpose::Handler { failing, .. }) => Some(*failing),
            _ => None,
        }
    }

    /// In a handler: the node the handler was attached to.
    pub fn attached_node(&self) -> Option<NodeId> {
        match self.purpose.as_deref() {
            Some(Purpose::Handler { attached, .. }) => Some(*attached),
            _ => None,
        }
    }

    /// In a handler: passes the exception on to the next handler up the tree (TDL's `bypass`).
    /// Return its result from the handler body: `return ctx.bypass();`.
    pub fn bypass(&self) -> Result<(), Failure> {
        match (self.failure(), self.shared.enter()) {
            (Some(_), Ok(mut inner)) => {
                let now = inner.engine.at_clock();
                inner
                    .engine
                    .request_bypass(now, self.node)
                    .map_err(|e| Failure::from(Error::from(e)))
            }
            (None, _) => Err(Failure::new(
                "NotAHandler",
                "`bypass` outside an exception handler",
            )),
            (_, Err(e)) => Err(Failure::from(e)),
        }
    }

    /// In a handler: runs the failed task again (a fresh node with the same arguments, under this
    /// handler). The task must be [`Task::retryable`] or [`Task::retryable_with`]. Wait for the
    /// returned node to see how it went.
    pub fn retry(&self) -> Result<NodeId, Error> {
        self.retry_args(None)
    }

    /// In a handler: runs the failed task again with other arguments `args` (TCA's error recovery
    /// changed a message's data, then re-sent it): a fresh node under this handler, whose action
    /// and wiretap checks see `args`. The task must be [`Task::retryable_with`] with arguments of
    /// type `A` (generated TDL goals and commands are, with the tuple of their arguments);
    /// otherwise [`Error::ArgsType`], and nothing is retried.
    pub fn retry_with<A: Any + Send + Sync>(&self, args: A) -> Result<NodeId, Error> {
        if let Some(old) = lock(&self.shared).ok().and_then(|i| {
            let failed = i.engine.failed_task(self.node)?;
            i.args.get(&failed).cloned()
        }) {
            if !old.is::<A>() {
                return Err(Error::ArgsType(std::any::type_name::<A>()));
            }
        } else {
            return Err(Error::ArgsType(std::any::type_name::<A>()));
        }
        self.retry_args(Some(Arc::new(args)))
    }

    fn retry_args(&self, args: Option<AnyArgs>) -> Result<NodeId, Error> {
        let mut inner = self.shared.enter()?;
        let now = inner.engine.at_clock();
        let id = inner.engine.retry(now, self.node)?;
        // A fresh run of the same task: an instance of the same task, renamed or not, with the
        // failed run's arguments unless new ones are given. Kept before this access ends, which
        // starts the new node.
        let failing = inner.engine.failed_task(self.node);
        let name = failing.and_then(|f| inner.task_names.get(&f).cloned());
        let args = args.or_else(|| failing.and_then(|f| inner.args.get(&f).cloned()));
        // A waited task's value is the last successful run's: keep the retry's too.
        if failing.is_some_and(|f| inner.values.contains_key(&f)) {
            inner.values.insert(id, None);
        }
        let grace = failing.and_then(|f| inner.cancels.grace_of(f));
        inner.keep(
            id,
            Kept {
                task_name: name,
                args,
                grace,
                fail_parent: false,
                wanted: None,
                durable: None,
                describe: None,
            },
        );
        Ok(id)
    }

    // ---- Arguments (`Task::with_args`).

    /// The arguments of this context's node, if its task keeps arguments of type `A`
    /// ([`Task::with_args`]; generated TDL tasks keep the tuple of theirs). In a wiretap check,
    /// the tapped node's (see [`Ctx::tapped_args`]).
    pub fn args<A: Any + Send + Sync>(&self) -> Option<Arc<A>> {
        self.args.clone().and_then(|a| a.downcast::<A>().ok())
    }

    /// As [`Ctx::args`], borrowed, for any `'static` type; for generated code.
    #[doc(hidden)]
    pub fn args_ref<A: Any>(&self) -> Option<&A> {
        self.args.as_deref().and_then(|a| a.downcast_ref::<A>())
    }

    /// In a wiretap check: the tapped node's arguments, if its task keeps arguments of type `A`
    /// (TCA's monitors saw the message's data). `None` outside a check.
    pub fn tapped_args<A: Any + Send + Sync>(&self) -> Option<Arc<A>> {
        match self.purpose.as_deref() {
            Some(Purpose::Tap { .. }) => self.args::<A>(),
            _ => None,
        }
    }

    /// In a handler: the failed node's arguments, if its task keeps arguments of type `A`; to
    /// change them and [`Ctx::retry_with`] the result.
    pub fn failing_args<A: Any + Send + Sync>(&self) -> Option<Arc<A>> {
        let inner = lock(&self.shared).ok()?;
        let failed = inner.engine.failed_task(self.node)?;
        let args = inner.args.get(&failed).cloned()?;
        args.downcast::<A>().ok()
    }

    /// In a handler: the arguments of the node it is attached to (the failed node or one of its
    /// ancestors), if its task keeps arguments of type `A`: what a handler attached to a task
    /// ([`crate::Runtime::attach`]) reads of the node it recovers.
    pub fn attached_args<A: Any + Send + Sync>(&self) -> Option<Arc<A>> {
        let attached = self.attached_node()?;
        let args = lock(&self.shared).ok()?.args.get(&attached).cloned()?;
        args.downcast::<A>().ok()
    }

    pub(crate) fn with_engine<T>(
        &self,
        f: impl FnOnce(
            &mut tcm_core::Engine<Action, Factory>,
            tcm_core::Time,
        ) -> Result<T, tcm_core::EngineError>,
    ) -> Result<T, Error> {
        self.engine_call(false, f)
    }

    /// [`Ctx::with_engine`]; `journaled`: for a request the engine journals as an input whoever
    /// asks it (a log line), made at the clock's time even from a command's own action, since a
    /// replay gives the command's from the journal, at the same time.
    fn engine_call<T>(
        &self,
        journaled: bool,
        f: impl FnOnce(
            &mut tcm_core::Engine<Action, Factory>,
            tcm_core::Time,
        ) -> Result<T, tcm_core::EngineError>,
    ) -> Result<T, Error> {
        let mut inner = self.shared.enter()?;
        let records = inner.engine.records_inputs();
        let kind = records
            .then(|| inner.engine.kind_and_display(self.node).map(|(k, _)| k))
            .flatten();
        // A command's own action (a monitor's activations are command nodes whose bodies run).
        let command =
            records && self.purpose.is_none() && kind == Some(tcm_core::NodeKind::Command);
        // An action that outlived its node (a remote command's late message, once the command
        // was terminated and left the tree): the replay does not make its request either.
        let gone = records && kind.is_none() && self.node != inner.engine.root();
        if gone || (command && !journaled) {
            // A replay does not run commands (`replay.rs`): the request is no step of the run,
            // and at the engine's latest time, so that it reads no clock and fires no timer.
            let now = inner.engine.now();
            return Ok(inner.engine.aside(|e| f(e, now))?);
        }
        let now = inner.engine.at_clock();
        // A body's (or a callback's), not the program's session's: run again by a replay, which
        // gives what it gives again.
        if inner.engine.records_inputs() && !command && self.node != inner.engine.root() {
            return Ok(inner.engine.by_body(|e| f(e, now))?);
        }
        Ok(f(&mut inner.engine, now)?)
    }
}

// ---- Monitor limits set from a body (TDL constraint statements).

impl Ctx {
    /// Sets a monitor's maximum activations (TDL's `m maximum activate N;` after the spawn): before
    /// the monitor starts it replaces the spawned value; once it runs, a maximum already reached
    /// completes the monitor's handling at once (docs/semantics.md, "Monitors"). A monitor that
    /// completed or was terminated is left alone.
    pub fn set_max_activations(&self, monitor: NodeId, n: u32) -> Result<(), Error> {
        self.with_engine(|e, now| e.set_max_activations(now, monitor, n))
    }

    /// Sets a monitor's maximum triggers (TDL's `m maximum trigger N;`), as
    /// [`Ctx::set_max_activations`] does the maximum activations.
    pub fn set_max_triggers(&self, monitor: NodeId, n: u32) -> Result<(), Error> {
        self.with_engine(|e, now| e.set_max_triggers(now, monitor, n))
    }

    /// Sets a monitor's polling period (TDL's `m period T;`): before the monitor starts it replaces
    /// the spawned value; once it polls, the poll already due keeps its time and the next ones come
    /// every `period` after it.
    pub fn set_period(&self, monitor: NodeId, period: Duration) -> Result<(), Error> {
        self.with_engine(|e, now| e.set_period(now, monitor, period))
    }
}
