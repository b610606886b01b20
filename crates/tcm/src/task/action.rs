//! An action (what a node's task runs) and how it starts: an async action's future, or a
//! synchronous action the pump calls where it would poll that future (`pump.rs`).

use super::AnyArgs;
use crate::ctx::Ctx;
use crate::host::Shared;
use std::any::Any;
use std::future::Future;
use std::pin::Pin;
use std::sync::Arc;
use tcm_core::{Failure, Job};

/// A value an action returns, handed to whoever waits for the node ([`crate::Spawner::wait_value`]).
pub type Value = Box<dyn Any + Send>;

/// The future of a running action.
pub type ActionFuture = Pin<Box<dyn Future<Output = Result<Value, Failure>> + Send>>;

/// An action: called once when its node starts. An async one makes the action's future, which
/// the host polls once where the node started and spawns as a tokio task only if it is not done
/// then (`pump.rs`): an action that ends without awaiting costs one allocation (its future), no
/// task. A synchronous one ([`Task::command_now`], [`Task::goal_now`]) is a plain function the
/// pump calls where it would have polled the future: no future at all. One pointer either way, so
/// that a task and a node are no larger for the choice.
pub struct Action(pub(crate) Box<dyn Start>);

/// The erased start of an action (`AsyncStart`, `NowStart`).
pub(crate) trait Start: Send {
    /// Starts the action of `job`, whose node keeps `args`: an async action's future is made now
    /// (its closure runs), a synchronous action waits for its turn.
    fn start(self: Box<Self>, shared: &Arc<Shared>, job: Job, args: Option<AnyArgs>) -> Launch;
}

/// A synchronous action, erased: run to its end with its context.
pub(crate) trait RunNow: Send {
    fn run(self: Box<Self>, ctx: Ctx) -> Result<Value, Failure>;
}

struct AsyncStart<F>(F);

impl<F: FnOnce(Ctx) -> ActionFuture + Send> Start for AsyncStart<F> {
    #[inline]
    fn start(self: Box<Self>, shared: &Arc<Shared>, job: Job, args: Option<AnyArgs>) -> Launch {
        Launch::Future((self.0)(Ctx::of_job(shared.clone(), job, args)))
    }
}

struct NowStart<F>(F);

impl<F: FnOnce(Ctx) -> Result<Value, Failure> + Send + 'static> Start for NowStart<F> {
    #[inline]
    fn start(self: Box<Self>, _: &Arc<Shared>, _: Job, args: Option<AnyArgs>) -> Launch {
        Launch::Now(self, args)
    }
}

impl<F: FnOnce(Ctx) -> Result<Value, Failure> + Send> RunNow for NowStart<F> {
    #[inline]
    fn run(self: Box<Self>, ctx: Ctx) -> Result<Value, Failure> {
        (self.0)(ctx)
    }
}

/// An action started: its future, or a synchronous action with its node's kept arguments, to
/// run where the future would be first polled, with a context made then (`Ctx::of_job`). Small,
/// as the pump moves it in and out of its batches.
pub(crate) enum Launch {
    /// An async action's future.
    Future(ActionFuture),
    /// A synchronous action and the arguments its context is to hold.
    Now(Box<dyn RunNow>, Option<AnyArgs>),
}

impl Launch {
    /// As a future, for a tokio task: a synchronous action runs at the task's first poll, as an
    /// async action that ends without awaiting would end there. Out of line: the host's start
    /// path stays small enough to be inlined where the pump serves it.
    #[inline(never)]
    pub(crate) fn into_future(self, shared: &Arc<Shared>, job: Job) -> ActionFuture {
        match self {
            Launch::Future(fut) => fut,
            Launch::Now(f, args) => {
                let ctx = Ctx::of_job(shared.clone(), job, args);
                Box::pin(async move { f.run(ctx) })
            }
        }
    }
}

impl Action {
    pub(crate) fn new<F, Fut, T>(f: F) -> Action
    where
        F: FnOnce(Ctx) -> Fut + Send + 'static,
        Fut: Future<Output = Result<T, Failure>> + Send + 'static,
        T: Any + Send,
    {
        Action::from_fn(move |ctx: Ctx| erase(f(ctx)))
    }

    pub(crate) fn from_fn(f: impl FnOnce(Ctx) -> ActionFuture + Send + 'static) -> Action {
        Action(Box::new(AsyncStart(f)))
    }

    pub(crate) fn now<F, T>(f: F) -> Action
    where
        F: FnOnce(Ctx) -> Result<T, Failure> + Send + 'static,
        T: Any + Send,
    {
        Action(Box::new(NowStart(move |ctx: Ctx| f(ctx).map(value))))
    }

    /// Starts the action of `job`, whose node keeps `args` (see [`Start::start`]).
    #[inline(always)]
    pub(crate) fn launch(self, shared: &Arc<Shared>, job: Job, args: Option<AnyArgs>) -> Launch {
        self.0.start(shared, job, args)
    }
}

/// A future of any value, erased.
pub(crate) fn erase<Fut, T>(fut: Fut) -> ActionFuture
where
    Fut: Future<Output = Result<T, Failure>> + Send + 'static,
    T: Any + Send,
{
    Box::pin(async move { fut.await.map(value) })
}

/// An action's value, erased: a value that is already erased (an action returning `Value`, whose
/// type is chosen at run time, as TDL's interpreter does) is taken as it is, not boxed again.
pub(crate) fn value<T: Any + Send>(v: T) -> Value {
    let boxed: Value = Box::new(v);
    match boxed.downcast::<Value>() {
        Ok(inner) => *inner,
        Err(boxed) => boxed,
    }
}

/// A reusable action: a monitor's body (once per activation), a handler (once per use), a retryable
/// task, a wiretap check.
pub type Factory = Arc<dyn Fn(Ctx) -> ActionFuture + Send + Sync>;

/// Wraps an async closure as a [`Factory`].
pub fn factory<F, Fut, T>(f: F) -> Factory
where
    F: Fn(Ctx) -> Fut + Send + Sync + 'static,
    Fut: Future<Output = Result<T, Failure>> + Send + 'static,
    T: Any + Send,
{
    Arc::new(move |ctx| erase(f(ctx)))
}
