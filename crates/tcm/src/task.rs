//! Tasks: what a node runs. A task is a kind (goal or command), an instance name and an async action.

use crate::ctx::Ctx;
use std::any::Any;
use std::future::Future;
use std::pin::Pin;
use tcm_core::{Constraint, Failure, Name, NodeId, NodeKind, OnTerminate, Spawn};

/// A value an action returns, handed to whoever waits for the node ([`crate::Spawner::wait_value`]).
pub type Value = Box<dyn Any + Send>;

/// The future of a running action.
pub type ActionFuture = Pin<Box<dyn Future<Output = Result<Value, Failure>> + Send>>;

/// An action, called once with its context.
pub type Action = Box<dyn FnOnce(Ctx) -> ActionFuture + Send>;

/// Something to spawn: a node kind, an instance name and an action.
pub struct Task {
    pub(crate) kind: NodeKind,
    pub(crate) name: Name,
    pub(crate) action: Action,
    pub(crate) constraints: Vec<Constraint>,
    pub(crate) on_terminate: Vec<Task>,
}

impl Task {
    /// A task of any kind.
    pub fn new<F, Fut, T>(kind: NodeKind, name: impl Into<Name>, f: F) -> Task
    where
        F: FnOnce(Ctx) -> Fut + Send + 'static,
        Fut: Future<Output = Result<T, Failure>> + Send + 'static,
        T: Any + Send,
    {
        Task {
            kind,
            name: name.into(),
            action: Box::new(move |ctx| {
                Box::pin(async move { f(ctx).await.map(|v| Box::new(v) as Value) })
            }),
            constraints: Vec::new(),
            on_terminate: Vec::new(),
        }
    }

    /// A goal: its action expands the tree by spawning children through its [`Ctx`].
    pub fn goal<F, Fut, T>(name: impl Into<Name>, f: F) -> Task
    where
        F: FnOnce(Ctx) -> Fut + Send + 'static,
        Fut: Future<Output = Result<T, Failure>> + Send + 'static,
        T: Any + Send,
    {
        Task::new(NodeKind::Goal, name, f)
    }

    /// A command: an executable behaviour; its action typically awaits hardware.
    pub fn command<F, Fut, T>(name: impl Into<Name>, f: F) -> Task
    where
        F: FnOnce(Ctx) -> Fut + Send + 'static,
        Fut: Future<Output = Result<T, Failure>> + Send + 'static,
        T: Any + Send,
    {
        Task::new(NodeKind::Command, name, f)
    }

    /// The instance name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The node kind.
    pub fn kind(&self) -> NodeKind {
        self.kind
    }

    /// Adds a task-level constraint, applied to every spawn of this task (TDL's constraints between
    /// a task's arguments and its body, such as `delay expansion` or `expand first`).
    pub fn with(mut self, c: Constraint) -> Task {
        self.constraints.push(c);
        self
    }

    /// Adds a task-level `on terminate` task: spawned as a child if a node of this task is terminated
    /// while its action runs; it runs to completion.
    pub fn on_terminate(mut self, cleanup: Task) -> Task {
        self.on_terminate.push(cleanup);
        self
    }

    /// The engine's spawn request for this task under `parent`.
    pub(crate) fn into_spawn(self, parent: NodeId) -> Spawn<Action> {
        let mut spec = Spawn::new(parent, self.kind, self.name, self.action);
        spec.constraints = self.constraints;
        spec.on_terminate = self
            .on_terminate
            .into_iter()
            .map(Task::into_cleanup)
            .collect();
        spec
    }

    pub(crate) fn into_cleanup(self) -> OnTerminate<Action> {
        OnTerminate {
            kind: self.kind,
            name: self.name,
            action: self.action,
        }
    }

    /// Renames the instance (TDL's `name` constraint).
    pub fn named(mut self, name: impl Into<Name>) -> Task {
        self.name = name.into();
        self
    }
}
