//! The host: the runtime's side of the core's [`Driver`]. It owns the engine behind a mutex, carries
//! its effects out on tokio (start an action as a task, abort a cancelled one, answer a waiter) and
//! reports each task's end back to the engine.
//!
//! Effects are carried out in one place, [`Host::effects`], whoever changed the engine: an action
//! (through [`Session`], whose end runs it), an event handle, or the driver loop in `runtime.rs`.

use crate::Error;
use crate::clock::Clock;
use crate::ctx::Ctx;
use crate::task::{Action, Factory, Value};
use std::any::Any;
use std::collections::BTreeMap;
use std::future::Future;
use std::panic::AssertUnwindSafe;
use std::pin::Pin;
use std::sync::atomic::AtomicUsize;
use std::sync::{Arc, Mutex, MutexGuard, mpsc};
use tcm_core::{
    Driver, Engine, Failure, Job, NodeId, Purpose, Shell, Time, WatchOutcome, WatchToken,
};
use tcm_trace::TraceEvent;
use tokio::sync::{Notify, oneshot};
use tokio::task::AbortHandle;

/// The token of the watch on the top-level task.
pub(crate) const TOP: u64 = 0;

pub(crate) struct Inner {
    pub(crate) engine: Engine<Action, Factory>,
    pub(crate) watchers: BTreeMap<u64, oneshot::Sender<WatchOutcome>>,
    // Nodes whose action's value someone waits for; filled when the action returns.
    pub(crate) values: BTreeMap<NodeId, Option<Value>>,
    // Running actions, to abort on cancellation.
    pub(crate) aborts: Aborts,
    next_token: u64,
    // Where actions are spawned: the tokio runtime of `Runtime::run`.
    pub(crate) spawner: Option<tokio::runtime::Handle>,
    // How the top-level task ended, once it did.
    pub(crate) top_done: Option<WatchOutcome>,
    // The deadline the driver sleeps until; an earlier timer must wake it.
    pub(crate) armed: Option<Time>,
    // Trace records taken from the engine, for the driver to hand to the sinks outside the lock.
    pub(crate) trace: Vec<TraceEvent>,
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
            next_token: TOP,
            spawner: None,
            top_done: None,
            armed: None,
            trace: Vec::new(),
        }
    }

    /// Reports to the engine the jobs whose task was dropped unfinished since the last call.
    pub(crate) fn report_stopped(&mut self, now: Time) {
        while let Ok(job) = self.stopped.try_recv() {
            self.engine.handle_action_stopped(now, job);
        }
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
            aborts: &mut self.aborts,
            spawner: self.spawner.as_ref(),
            watchers: &mut self.watchers,
            top_done: &mut self.top_done,
            trace: &mut self.trace,
        };
        (&mut self.engine, host)
    }

    /// Carries out the engine's effects; returns whether the driver must wake (only for what only
    /// it can do: hand trace records to the sinks, re-arm the timer, end the run).
    pub(crate) fn effects(&mut self, shared: &Arc<Shared>) -> bool {
        let (engine, mut host) = self.split(shared);
        Driver::effects(engine, &mut host);
        let mut wake =
            self.top_done.is_some() || self.engine.fatal().is_some() || self.engine.has_trace();
        if let Some(t) = self.engine.poll_timeout() {
            wake = wake || self.armed.is_none_or(|a| t < a);
        }
        wake || (self.aborts.is_empty() && self.engine.is_idle())
    }
}

pub(crate) struct Shared {
    pub(crate) inner: Mutex<Inner>,
    pub(crate) wake: Notify,
    pub(crate) clock: Clock,
    // Open event handles: while any is open, an idle run waits instead of ending stuck.
    pub(crate) handles: AtomicUsize,
    // Where a `Reporter` sends the job of a task dropped unfinished (it must not take the lock).
    pub(crate) stopped: Mutex<mpsc::Sender<Job>>,
}

impl Shared {
    /// The engine's time now (see [`Clock`]).
    pub(crate) fn now(&self) -> Time {
        self.clock.now()
    }

    /// Exclusive access to the engine; its effects are carried out when the session ends.
    pub(crate) fn enter(self: &Arc<Shared>) -> Result<Session<'_>, Error> {
        Ok(Session {
            guard: lock(self)?,
            shared: self,
        })
    }
}

pub(crate) fn lock(shared: &Shared) -> Result<MutexGuard<'_, Inner>, Error> {
    shared.inner.lock().map_err(|_| Error::Poisoned)
}

/// Exclusive access to the engine. When it ends, the engine's effects are carried out at once, by
/// whoever changed the engine, and the driver is woken if it must.
pub(crate) struct Session<'a> {
    guard: MutexGuard<'a, Inner>,
    shared: &'a Arc<Shared>,
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
        if self.guard.effects(self.shared) {
            self.shared.wake.notify_one();
        }
    }
}

/// The host's side of the [`Driver`], borrowed from [`Inner`] for one step.
pub(crate) struct Host<'a> {
    shared: &'a Arc<Shared>,
    aborts: &'a mut Aborts,
    spawner: Option<&'a tokio::runtime::Handle>,
    watchers: &'a mut BTreeMap<u64, oneshot::Sender<WatchOutcome>>,
    top_done: &'a mut Option<WatchOutcome>,
    trace: &'a mut Vec<TraceEvent>,
}

impl Shell<Action, Factory> for Host<'_> {
    fn start(&mut self, _: &mut Engine<Action, Factory>, node: NodeId, action: Action) {
        // Spawned under the lock: the task's own end takes the lock, so its abort handle is
        // recorded before it can finish.
        let ctx = Ctx {
            shared: self.shared.clone(),
            node,
            purpose: None,
        };
        let h = (action.0)(Launch {
            ctx,
            rt: self.spawner,
        });
        self.aborts.insert(node, h.abort_handle());
    }

    fn invoke(
        &mut self,
        _: &mut Engine<Action, Factory>,
        job: Job,
        body: Factory,
        p: Box<Purpose>,
    ) {
        let ctx = Ctx {
            shared: self.shared.clone(),
            node: job.node(),
            purpose: Some(Arc::from(p)),
        };
        let fut = body(ctx);
        let reporter = Reporter::new(self.shared.clone(), job);
        let task = async move {
            let res = CatchUnwind(fut).await;
            reporter.finish(res);
        };
        let h = match self.spawner {
            Some(rt) => rt.spawn(task),
            None => tokio::spawn(task),
        };
        if job.cancellable() {
            self.aborts.insert(job.node(), h.abort_handle());
        }
    }

    fn cancel(&mut self, node: NodeId) {
        if let Some(h) = self.aborts.remove(&node) {
            h.abort();
        }
    }

    fn notify(
        &mut self,
        _: &mut Engine<Action, Factory>,
        token: WatchToken,
        outcome: WatchOutcome,
    ) {
        if token.0 == TOP {
            *self.top_done = Some(outcome);
        } else if let Some(tx) = self.watchers.remove(&token.0) {
            let _ = tx.send(outcome);
        }
    }

    fn trace(&mut self, record: TraceEvent) {
        self.trace.push(record);
    }
}

/// A job's task ended: report it to the engine (under the lock); the session carries out what
/// follows.
fn finish(
    shared: &Arc<Shared>,
    job: Job,
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
    let node = job.node();
    if job.cancellable() {
        inner.aborts.remove(&node);
    }
    let result = result.map(|value| {
        if let Some(slot) = inner.values.get_mut(&node) {
            *slot = Some(value);
        }
    });
    // A node terminated meanwhile, or already reclaimed, has nothing left to finish.
    let now = shared.now();
    let _ = inner.engine.handle_action_finished(now, job, result);
}

/// The abort handles of running actions, by the node's storage slot (dense, so a vector beats a
/// map on the path every action takes).
#[derive(Default)]
pub(crate) struct Aborts {
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

    pub(crate) fn is_empty(&self) -> bool {
        self.len == 0
    }

    pub(crate) fn drain(&mut self) -> impl Iterator<Item = AbortHandle> + '_ {
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
        let reporter = Reporter::new(ctx.shared.clone(), Job::from(ctx.node));
        let fut = f(ctx);
        let task = async move {
            let fut = std::pin::pin!(fut);
            let res = CatchUnwind(fut).await;
            reporter.finish(res);
        };
        match rt {
            Some(rt) => rt.spawn(task),
            None => tokio::spawn(task),
        }
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

    fn finish(mut self, res: Result<Result<Value, Failure>, Box<dyn Any + Send>>) {
        self.done = true;
        finish(&self.shared, self.job, res);
    }
}

impl Drop for Reporter {
    fn drop(&mut self) {
        if self.done {
            return;
        }
        if let Ok(tx) = self.shared.stopped.lock() {
            let _ = tx.send(self.job);
        }
        self.shared.wake.notify_one();
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

fn panic_message(p: &(dyn std::any::Any + Send)) -> String {
    if let Some(s) = p.downcast_ref::<&str>() {
        (*s).to_string()
    } else if let Some(s) = p.downcast_ref::<String>() {
        s.clone()
    } else {
        "panic with a non-string payload".to_string()
    }
}
