//! A job's task and how its end reaches the engine: spawned with a reporter that reports its end,
//! its panic or its drop exactly once; the end reported under the lock; the jobs the pump held
//! handed back as tasks or parked; panics recorded.

use super::{Access, Inner, Panicked, Shared};
use crate::pump::Parked;
use crate::task::{Action, ActionFuture, Factory, Launch, Value};
use std::any::Any;
use std::future::Future;
use std::panic::AssertUnwindSafe;
use std::pin::Pin;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use tcm_core::{Engine, Failure, Job, NodeId, Time};
use tokio::task::AbortHandle;

/// Spawns a job's future as a tokio task that reports its end (or its panic, or its drop).
pub(crate) fn spawn_task(
    shared: &Arc<Shared>,
    rt: Option<&tokio::runtime::Handle>,
    job: Job,
    fut: ActionFuture,
) -> tokio::task::JoinHandle<()> {
    let reporter = Reporter::new(shared.clone(), job);
    if shared.inline.load(Ordering::Relaxed) {
        // Its wake-ups are counted, so that the pump knows whether it is queued (`pump.rs`).
        let fut = crate::pump::Tracked::new(fut, &shared.queued, true);
        spawn_reporting(rt, fut, reporter)
    } else {
        spawn_reporting(rt, fut, reporter)
    }
}

fn spawn_reporting<F>(
    rt: Option<&tokio::runtime::Handle>,
    fut: F,
    reporter: Reporter,
) -> tokio::task::JoinHandle<()>
where
    F: Future<Output = Result<Value, Failure>> + Send + Unpin + 'static,
{
    let task = async move {
        let res = CatchUnwind(fut).await;
        reporter.finish(res);
    };
    match rt {
        Some(rt) => rt.spawn(task),
        None => tokio::spawn(task),
    }
}

/// How a job ended, for [`Inner::ended_job`].
pub(crate) enum Ended {
    /// It returned (or panicked).
    Returned(Job, Result<Result<Value, Failure>, Box<dyn Any + Send>>),
    /// It was dropped unfinished after its cancellation.
    Dropped(Job),
}

impl Access<'_> {
    /// Carries out the effects, then takes the jobs the pump is to poll into `batch` (empty, kept
    /// by the pump so that its buffer serves every batch; buffers are swapped, so neither is
    /// allocated again); taking them changes nothing of the engine, so the access ends without
    /// another look. Those cancelled before the pump could poll them stay in the batch, in their
    /// place, and their nodes go to `skip` (`Inner::cancelled_in`). When the run ended, every job
    /// goes to `dropped`, to drop unpolled.
    pub(crate) fn settle_and_take_launches(
        &mut self,
        batch: &mut Vec<(Job, Launch)>,
        dropped: &mut Vec<(Job, Launch)>,
        skip: &mut Vec<NodeId>,
    ) {
        self.carry_out();
        if self.guard.ended {
            dropped.append(&mut self.guard.launches);
            return;
        }
        std::mem::swap(&mut self.guard.launches, batch);
        self.guard.cancelled_in(batch, skip);
    }
}

/// A job's task ended: report it to the engine (under the lock); the access carries out what
/// follows.
fn finish(
    shared: &Arc<Shared>,
    job: Job,
    res: Result<Result<Value, Failure>, Box<dyn Any + Send>>,
) {
    let Ok(mut inner) = shared.enter() else {
        return;
    };
    inner.ended_job(None, Ended::Returned(job, res));
}

impl Inner {
    /// Reports a job's end to the engine, at `now`, or at the clock's time if `None` (read only
    /// if the report needs it, `Engine::at_clock`); while the run replays its journal, held until
    /// the journal gives it (`replay.rs`, rule 3).
    pub(crate) fn ended_job(&mut self, now: Option<Time>, ended: Ended) {
        if let Some(r) = self.replay.as_mut().filter(|r| r.active()) {
            let node = match &ended {
                Ended::Returned(j, _) | Ended::Dropped(j) => j.node(),
            };
            let display = self.engine.kind_and_display(node).map(|k| k.1);
            r.hold(ended, display);
            return;
        }
        self.report_end(now, ended);
    }

    /// Reports a job's end to the engine, at `now`, or at the clock's time if `None`.
    pub(crate) fn report_end(&mut self, now: Option<Time>, ended: Ended) {
        let (job, res) = match ended {
            Ended::Returned(job, res) => (job, res),
            Ended::Dropped(job) => {
                let now = now.unwrap_or_else(|| self.engine.at_clock());
                self.engine.handle_action_stopped(now, job);
                return;
            }
        };
        let node = job.node();
        if job.cancellable() {
            self.aborts.remove(&node);
            if !self.activation_data.is_empty() {
                self.activation_data.remove(&node);
            }
            self.cancels.finished(node);
            if !self.inline_cancelled.is_empty() {
                self.inline_cancelled.retain(|n| *n != node);
            }
        } else {
            self.checks.remove(&job);
        }
        self.parking.forget_job(job);
        let result = match res {
            Ok(Ok(value)) => {
                if let Some(j) = self.journal.as_mut() {
                    let engine = &self.engine;
                    j.value(
                        || engine.kind_and_display(node).map(|k| k.1),
                        value.as_ref(),
                    );
                }
                if !self.values.is_empty() {
                    if let Some(slot) = self.values.get_mut(&node) {
                        *slot = Some(value);
                    }
                }
                Ok(())
            }
            Ok(Err(failure)) => Err(failure),
            Err(panic) => {
                let message = panic_message(panic.as_ref());
                let record = panicked(
                    &self.engine,
                    Some(node),
                    String::new(),
                    false,
                    message.clone(),
                );
                self.panics.push(record);
                Err(Failure::new("ActionPanicked", message))
            }
        };
        // A node terminated meanwhile, or already reclaimed, has nothing left to finish.
        let now = now.unwrap_or_else(|| self.engine.at_clock());
        let _ = self.engine.handle_action_finished(now, job, result);
    }

    /// Adds to `skip` the nodes of the jobs in `batch` cancelled while the pump held them: the
    /// pump drops each unpolled when its turn comes, as tokio drops an aborted task when it reaches
    /// it in its queue.
    pub(crate) fn cancelled_in(&mut self, batch: &[(Job, Launch)], skip: &mut Vec<NodeId>) {
        if self.inline_cancelled.is_empty() {
            return;
        }
        let cancelled = &mut self.inline_cancelled;
        for (job, _) in batch {
            let node = job.node();
            if let Some(i) = cancelled.iter().position(|n| *n == node) {
                if job.cancellable() {
                    cancelled.swap_remove(i);
                    skip.push(node);
                }
            }
        }
    }

    /// Spawns, as a tokio task, a job the pump polled once and left pending; if it was cancelled
    /// meanwhile, the task is cancelled at once (signalled with its grace period, or aborted).
    /// Gives the future back when the run ended, for the caller to drop outside the lock.
    pub(crate) fn spawn_job(
        &mut self,
        shared: &Arc<Shared>,
        job: Job,
        fut: ActionFuture,
    ) -> Option<ActionFuture> {
        if self.ended {
            return Some(fut);
        }
        let h = spawn_task(shared, self.spawner.as_ref(), job, fut).abort_handle();
        let node = job.node();
        if !job.cancellable() || self.aborts.set_task(node, h.clone()) {
            return None;
        }
        self.cancel_if_cancelled_inline(shared, node, TaskRef::Task(h));
        None
    }

    /// A job the pump held, now a task or parked, is no longer running: if it was cancelled while
    /// the pump held it, it is cancelled now (signalled with its grace period, or aborted).
    fn cancel_if_cancelled_inline(&mut self, shared: &Arc<Shared>, node: NodeId, task: TaskRef) {
        if let Some(i) = self.inline_cancelled.iter().position(|n| *n == node) {
            self.inline_cancelled.swap_remove(i);
            let rt = self.spawner.clone();
            self.cancels.cancel(shared, rt.as_ref(), node, task);
        }
    }

    /// Records a job the pump polled once and parked (`pump::Parked`); if it was cancelled
    /// meanwhile, it is cancelled at once (signalled with its grace period, or aborted). Gives the
    /// future back when the run ended, for the caller to drop outside the lock.
    pub(crate) fn park_job(
        &mut self,
        shared: &Arc<Shared>,
        job: Job,
        parked: Arc<Parked>,
    ) -> Option<ActionFuture> {
        if self.ended {
            return parked.take();
        }
        let node = job.node();
        if self.aborts.set_parked(node, parked.clone()) {
            return None;
        }
        self.cancel_if_cancelled_inline(shared, node, TaskRef::Parked(parked));
        None
    }
}

/// A running job's task, for its cancellation: a tokio task, or a future the pump parked after its
/// first poll, until its first wake-up (`pump::Parked`).
pub(crate) enum TaskRef {
    Task(AbortHandle),
    Parked(Arc<Parked>),
}

impl TaskRef {
    /// Aborts the job's task; returns whether a stop will be reported (by the `Reporter` of a task
    /// dropped unfinished).
    pub(crate) fn abort(&self) -> bool {
        match self {
            TaskRef::Task(h) => {
                h.abort();
                true
            }
            TaskRef::Parked(p) => p.abort(),
        }
    }
}

/// The record of a panic in the action (or callback) of `node`.
pub(crate) fn panicked(
    engine: &Engine<Action, Factory>,
    node: Option<NodeId>,
    name: String,
    callback: bool,
    message: String,
) -> Panicked {
    let info = node.and_then(|n| engine.info(n));
    let path = node.map(|n| engine.path(n)).unwrap_or_default();
    let name = match (&info, callback) {
        (Some(i), false) => i.name.clone(),
        _ => name,
    };
    Panicked {
        node: info.map(|i| i.display),
        name,
        path,
        callback,
        message,
    }
}

/// Reports a job's end exactly once: when its task returns ([`finish`]), or, when the task is
/// dropped unfinished (aborted after its node was terminated), as stopped: the engine terminates
/// the node only then (docs/semantics.md, "Termination"). A drop can happen anywhere, even while
/// the engine's lock is held, so the stop goes through a channel the driver drains.
struct Reporter {
    shared: Arc<Shared>,
    job: Job,
    done: bool,
}

impl Reporter {
    fn new(shared: Arc<Shared>, job: Job) -> Reporter {
        Reporter {
            shared,
            job,
            done: false,
        }
    }

    /// Reports the end, then pumps what it released (`pump.rs`).
    fn finish(mut self, res: Result<Result<Value, Failure>, Box<dyn Any + Send>>) {
        self.done = true;
        if !self.shared.inline.load(Ordering::Relaxed) {
            finish(&self.shared, self.job, res);
            return;
        }
        let pump = crate::pump::Guard::enter(&self.shared);
        finish(&self.shared, self.job, res);
        pump.pump();
    }
}

impl Drop for Reporter {
    fn drop(&mut self) {
        if self.done {
            return;
        }
        self.shared.send_stop(self.job);
        self.shared.wake.notify_one();
    }
}

/// Polls a future, turning a panic into an error (a panicking action fails its node).
pub(crate) struct CatchUnwind<F>(pub(crate) F);

impl<F: Future + Unpin> Future for CatchUnwind<F> {
    type Output = Result<F::Output, Box<dyn Any + Send>>;
    fn poll(
        mut self: Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
    ) -> std::task::Poll<Self::Output> {
        let fut = &mut self.0;
        // While a replay runs, its inputs wait for the end of this poll (`replay.rs`, rule 3).
        let _poll = crate::replay::ActionPoll::begin();
        match std::panic::catch_unwind(AssertUnwindSafe(|| Pin::new(fut).poll(cx))) {
            Ok(std::task::Poll::Pending) => std::task::Poll::Pending,
            Ok(std::task::Poll::Ready(v)) => std::task::Poll::Ready(Ok(v)),
            Err(panic) => std::task::Poll::Ready(Err(panic)),
        }
    }
}

pub(crate) fn panic_message(p: &(dyn std::any::Any + Send)) -> String {
    if let Some(s) = p.downcast_ref::<&str>() {
        (*s).to_string()
    } else if let Some(s) = p.downcast_ref::<String>() {
        s.clone()
    } else {
        "panic with a non-string payload".to_string()
    }
}
