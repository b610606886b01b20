//! Tasks: what a node runs. A task is a kind (goal, command, monitor), an instance name, and an
//! async action; plus task-level constraints, on-terminate tasks and exception handlers.

use crate::Error;
use crate::ctx::Ctx;
use crate::exception::Exception;
use crate::journal::EncodeFn;
use crate::place::Json;
use std::any::Any;
use std::future::Future;
use std::sync::Arc;
use std::time::Duration;
mod action;

pub use action::{Action, ActionFuture, Factory, Value, factory};
pub(crate) use action::{Launch, RunNow, erase, value};

use tcm_core::{
    Constraint, EachActivation, Failure, HandlerSpec, MonitorSpec, Name, NodeId, NodeKind,
    OnTerminate, Overrun, Spawn,
};

/// A task's arguments as the host keeps them ([`Task::with_args`]), type-erased.
pub(crate) type AnyArgs = Arc<dyn Any + Send + Sync>;

/// What the host keeps beside a node, taken from its task at spawn: the task name when the
/// instance was renamed, and the arguments.
pub(crate) struct Kept {
    pub(crate) task_name: Option<Name>,
    pub(crate) args: Option<AnyArgs>,
    // The grace period the task or the spawn set (`Task::grace`, `Spawner::grace`).
    pub(crate) grace: Option<Duration>,
    // The spawn's failure fails its parent (`Spawner::propagate`).
    pub(crate) fail_parent: bool,
    // The resources it uses, by name until the spawn resolves them (`resource.rs`).
    pub(crate) wanted: Option<Box<crate::resource::Wanted>>,
    // How it lives through a crash of the run (`Task::idempotent`, `Task::journaled`,
    // `Task::reattach`).
    pub(crate) durable: Option<Arc<Durable>>,
    // Describes `args` for the node's `spawned` record (`Task::describe_args`).
    pub(crate) describe: Option<DescribeArgs>,
}

/// Describes a task's kept arguments ([`Task::with_args`]) as text for its nodes' `spawned`
/// records (`name = value, …`; `None` when they cannot be told). Called only when the run is
/// traced.
pub type DescribeArgs = fn(&(dyn Any + Send + Sync)) -> Option<String>;

/// How a task's nodes live through a crash of their run (docs/semantics.md, "Durable runs"):
/// whether the action may run twice, how the journal writes and reads back its value, and how a
/// resumed run re-attaches to what it started outside.
#[derive(Clone, Default)]
pub(crate) struct Durable {
    pub(crate) idempotent: bool,
    pub(crate) encode: Option<Arc<EncodeFn>>,
    pub(crate) decode: Option<Arc<DecodeFn>>,
    pub(crate) reattach: Option<Reattach>,
}

/// A task's own [`crate::ValueDecoder`].
pub(crate) type DecodeFn = dyn Fn(serde_json::Value) -> Option<Value> + Send + Sync;
/// A task's re-attachment: the action that goes on with what the node's action started, given
/// what it recorded (`Ctx::record`) in the run.
pub(crate) type Reattach = Arc<dyn Fn(Vec<serde_json::Value>) -> Action + Send + Sync>;

/// The parameters of a monitor (TDL's `maximum activate`, `maximum trigger`, `period`, …).
#[derive(Clone, Debug, Default)]
pub struct Monitor {
    /// Complete after this many activations.
    pub max_activations: Option<u32>,
    /// Complete after this many triggers.
    pub max_triggers: Option<u32>,
    /// Poll: activate every period, on absolute deadlines.
    pub period: Option<Duration>,
    /// Skip the polling activation at start.
    pub initial_wait: bool,
    /// Constraints between successive activations.
    pub each: EachActivation,
    /// What a poll does when it falls due while the last activation still runs: made at once
    /// (`Burst`, the default), dropped (`Skip`), or held until that activation ends (`Delay`);
    /// docs/semantics.md, "Monitors", rule 7.
    pub overrun: Overrun,
    /// Name of activation nodes (default `ACT-<monitor>`).
    pub activation_name: Option<Name>,
}

/// An exception handler: a reusable async body for one exception type and its descendants.
#[derive(Clone)]
pub struct Handler {
    pub(crate) spec: HandlerSpec<Factory>,
}

impl Handler {
    /// A handler named `name` for exceptions named `exception` (and types naming it as an
    /// ancestor). In its body, [`Ctx::failure`] gives the failure, [`Ctx::caught`] its value.
    pub fn new<F, Fut, T>(name: impl Into<Name>, exception: impl Into<Name>, body: F) -> Handler
    where
        F: Fn(Ctx) -> Fut + Send + Sync + 'static,
        Fut: Future<Output = Result<T, Failure>> + Send + 'static,
        T: Any + Send,
    {
        Handler {
            spec: HandlerSpec {
                name: name.into(),
                exception: exception.into(),
                max_activations: None,
                body: factory(body),
            },
        }
    }

    /// A handler for the exception type `E`.
    pub fn on<E: Exception, F, Fut, T>(name: impl Into<Name>, body: F) -> Handler
    where
        F: Fn(Ctx) -> Fut + Send + Sync + 'static,
        Fut: Future<Output = Result<T, Failure>> + Send + 'static,
        T: Any + Send,
    {
        Handler::new(name, E::name(), body)
    }

    /// Uses the handler at most `n` times (TDL's `maximum activate`).
    pub fn max_activations(mut self, n: u32) -> Handler {
        self.spec.max_activations = Some(n);
        self
    }
}

/// A handler attached from outside to every node of one task ([`crate::Runtime::attach`]): TCA's
/// recovery added "without modifying existing components". TDL's `handler h() handles E for T`
/// builds one.
#[derive(Clone)]
pub struct Attached {
    pub(crate) task: Name,
    pub(crate) handler: Handler,
}

impl Attached {
    /// `handler`, attached to every node of the task named `task` (its [`Task::task_name`]).
    pub fn new(task: impl Into<Name>, handler: Handler) -> Attached {
        Attached {
            task: task.into(),
            handler,
        }
    }

    /// The task's name.
    pub fn task(&self) -> &Name {
        &self.task
    }
}

/// A wiretap built for one task ([`crate::Runtime::tap`], [`crate::Control::tap`]): a check that
/// runs before every node of the task starts its action, or after it returned successfully, and
/// fails the node when it fails. TDL's `wiretap w() before T { … }` builds one.
#[derive(Clone)]
pub struct Tap {
    pub(crate) task: Name,
    pub(crate) when: tcm_core::TapWhen,
    pub(crate) check: Factory,
}

impl Tap {
    /// A check of every node of the task named `task`, at `when`.
    pub fn new<F, Fut, T>(task: impl Into<Name>, when: tcm_core::TapWhen, check: F) -> Tap
    where
        F: Fn(Ctx) -> Fut + Send + Sync + 'static,
        Fut: Future<Output = Result<T, Failure>> + Send + 'static,
        T: Any + Send,
    {
        Tap {
            task: task.into(),
            when,
            check: factory(check),
        }
    }

    /// As [`Tap::new`], with the check's factory built already.
    pub fn from_factory(task: impl Into<Name>, when: tcm_core::TapWhen, check: Factory) -> Tap {
        Tap {
            task: task.into(),
            when,
            check,
        }
    }

    /// The tapped task's name.
    pub fn task(&self) -> &Name {
        &self.task
    }

    /// When it checks.
    pub fn when(&self) -> tcm_core::TapWhen {
        self.when
    }
}

/// Something to spawn: a node kind, an instance name and an action.
pub struct Task {
    pub(crate) kind: NodeKind,
    pub(crate) name: Name,
    // The task's own name, once `named` renamed the instance (`None`: the instance name), so that
    // a task that is not renamed keeps one name, never compared nor cloned.
    pub(crate) task_name: Option<Name>,
    pub(crate) action: Option<Action>,
    pub(crate) constraints: tcm_core::Constraints,
    // Kept as the engine takes them (`Task::into_parts` moves them as they are).
    pub(crate) on_terminate: Vec<OnTerminate<Action>>,
    pub(crate) handlers: Vec<HandlerSpec<Factory>>,
    pub(crate) monitor: Option<Box<MonitorSpec<Factory>>>,
    pub(crate) retry: Option<Factory>,
    pub(crate) persistent: bool,
    pub(crate) args: Option<AnyArgs>,
    pub(crate) grace: Option<Duration>,
    pub(crate) wanted: Option<Box<crate::resource::Wanted>>,
    // The version of the program that defines it (`Task::version`).
    pub(crate) version: Option<Arc<str>>,
    pub(crate) durable: Option<Arc<Durable>>,
    pub(crate) describe: Option<DescribeArgs>,
}

impl Task {
    fn bare(kind: NodeKind, name: Name, action: Option<Action>) -> Task {
        Task {
            kind,
            task_name: None,
            name,
            action,
            constraints: tcm_core::Constraints::new(),
            on_terminate: Vec::new(),
            handlers: Vec::new(),
            monitor: None,
            retry: None,
            persistent: false,
            args: None,
            grace: None,
            wanted: None,
            version: None,
            durable: None,
            describe: None,
        }
    }

    /// A task of any kind.
    pub fn new<F, Fut, T>(kind: NodeKind, name: impl Into<Name>, f: F) -> Task
    where
        F: FnOnce(Ctx) -> Fut + Send + 'static,
        Fut: Future<Output = Result<T, Failure>> + Send + 'static,
        T: Any + Send,
    {
        Task::bare(kind, name.into(), Some(Action::new(f)))
    }

    /// A task whose action can run again: handlers may [`Ctx::retry`] it after a failure.
    pub fn retryable<F, Fut, T>(kind: NodeKind, name: impl Into<Name>, f: F) -> Task
    where
        F: Fn(Ctx) -> Fut + Send + Sync + 'static,
        Fut: Future<Output = Result<T, Failure>> + Send + 'static,
        T: Any + Send,
    {
        let fac = factory(f);
        let first = fac.clone();
        let mut task = Task::bare(
            kind,
            name.into(),
            Some(Action::from_fn(move |ctx: Ctx| first(ctx))),
        );
        task.retry = Some(fac);
        task
    }

    /// [`Task::retryable`] whose body ends without awaiting: its first run is a synchronous
    /// action ([`Task::new_now`]); a retry runs the same body in a future (a retry's action is made
    /// under the engine's lock, where the body cannot run). Generated TDL goals and commands whose
    /// bodies never await are these.
    pub fn retryable_now<F, T>(kind: NodeKind, name: impl Into<Name>, f: F) -> Task
    where
        F: Fn(Ctx) -> Result<T, Failure> + Send + Sync + 'static,
        T: Any + Send,
    {
        let f = Arc::new(f);
        let again = f.clone();
        let fac: Factory = Arc::new(move |ctx: Ctx| {
            let f = again.clone();
            Box::pin(async move { f(ctx).map(value) })
        });
        let mut task = Task::bare(kind, name.into(), Some(Action::now(move |ctx| f(ctx))));
        task.retry = Some(fac);
        task
    }

    /// A task whose action takes its arguments `args`, and can run again with the same or other
    /// arguments: a handler's [`Ctx::retry`] re-runs it with the failed run's arguments,
    /// [`Ctx::retry_with`] with new ones. The arguments are kept beside each node
    /// ([`Task::with_args`]), so wiretap checks read them too ([`Ctx::tapped_args`]).
    pub fn retryable_with<A, F, Fut, T>(
        kind: NodeKind,
        name: impl Into<Name>,
        args: A,
        f: F,
    ) -> Task
    where
        A: Any + Send + Sync + Clone,
        F: Fn(Ctx, A) -> Fut + Send + Sync + 'static,
        Fut: Future<Output = Result<T, Failure>> + Send + 'static,
        T: Any + Send,
    {
        let name = name.into();
        let f = Arc::new(f);
        let first = f.clone();
        let first_args = args.clone();
        let task_name = name.clone();
        let fac: Factory = Arc::new(move |ctx: Ctx| {
            // A re-run reads the arguments the host keeps for its node (`Ctx::retry_with`).
            let args = ctx.args::<A>().map(|a| A::clone(&a));
            let fut = args.map(|a| f(ctx, a));
            let task_name = task_name.clone();
            Box::pin(async move {
                match fut {
                    Some(fut) => fut.await.map(value),
                    None => Err(Failure::new(
                        "NoArgs",
                        format!(
                            "`{task_name}` re-run without arguments of type `{}`",
                            std::any::type_name::<A>()
                        ),
                    )),
                }
            })
        });
        let mut task = Task::bare(
            kind,
            name,
            Some(Action::from_fn(move |ctx: Ctx| {
                erase(first(ctx, first_args))
            })),
        );
        task.retry = Some(fac);
        task.with_args(args)
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

    /// A task whose action ends without awaiting: `f` runs to its end when the node's turn to
    /// run comes, as an async action that never awaits would, and its result is the action's.
    /// No future is made: on a current-thread runtime it costs no allocation of its own and no
    /// poll (`pump.rs`); elsewhere it runs in a task as an async action does. The trace is the
    /// one the same body written async gives, record for record.
    pub fn new_now<F, T>(kind: NodeKind, name: impl Into<Name>, f: F) -> Task
    where
        F: FnOnce(Ctx) -> Result<T, Failure> + Send + 'static,
        T: Any + Send,
    {
        Task::bare(kind, name.into(), Some(Action::now(f)))
    }

    /// A goal whose body ends without awaiting (it only spawns and constrains): see
    /// [`Task::new_now`].
    pub fn goal_now<F, T>(name: impl Into<Name>, f: F) -> Task
    where
        F: FnOnce(Ctx) -> Result<T, Failure> + Send + 'static,
        T: Any + Send,
    {
        Task::new_now(NodeKind::Goal, name, f)
    }

    /// A command whose action ends without awaiting (a simulator's step, a computed value): see
    /// [`Task::new_now`].
    pub fn command_now<F, T>(name: impl Into<Name>, f: F) -> Task
    where
        F: FnOnce(Ctx) -> Result<T, Failure> + Send + 'static,
        T: Any + Send,
    {
        Task::new_now(NodeKind::Command, name, f)
    }

    /// A task whose action blocks or computes (a planner, a blocking driver call): `f` runs on
    /// one of tokio's blocking threads, off the async workers, so it never stalls the tree or its
    /// timers (see [`Ctx::blocking`], which this is, for termination and virtual time). Its value
    /// is the node's value. TDL's `blocking command`.
    ///
    /// ```
    /// # tcm::block_on_virtual(async {
    /// use tcm::{NodeKind, Runtime, RunOutcome, Task};
    /// let plan = Task::blocking(NodeKind::Command, "plan", |ctx| {
    ///     let mut cost = 0u64;
    ///     for step in 0..1_000u64 {
    ///         if ctx.is_cancelled() {
    ///             break; // terminated: stop early, the node is terminated once this returns
    ///         }
    ///         cost += step;
    ///     }
    ///     Ok(cost)
    /// });
    /// let report = Runtime::new().run(plan).await?;
    /// assert_eq!(report.outcome, RunOutcome::Completed);
    /// # Ok::<(), tcm::Error>(())
    /// # })?;
    /// # Ok::<(), tcm::Error>(())
    /// ```
    pub fn blocking<F, T>(kind: NodeKind, name: impl Into<Name>, f: F) -> Task
    where
        F: FnOnce(Ctx) -> Result<T, Failure> + Send + 'static,
        T: Any + Send,
    {
        Task::new(kind, name, move |ctx: Ctx| ctx.blocking(f))
    }

    /// A monitor: `body` runs once per activation, as a child command node. In the body,
    /// [`Ctx::trigger`] counts a trigger and [`Ctx::activation`] tells the counts.
    pub fn monitor<F, Fut, T>(name: impl Into<Name>, params: Monitor, body: F) -> Task
    where
        F: Fn(Ctx) -> Fut + Send + Sync + 'static,
        Fut: Future<Output = Result<T, Failure>> + Send + 'static,
        T: Any + Send,
    {
        let mut task = Task::bare(NodeKind::Monitor, name.into(), None);
        task.monitor = Some(Box::new(MonitorSpec {
            body: factory(body),
            max_activations: params.max_activations,
            max_triggers: params.max_triggers,
            period: params.period,
            initial_wait: params.initial_wait,
            each: params.each,
            overrun: params.overrun,
            activation_name: params.activation_name,
        }));
        task
    }

    /// Keeps `args`, the task's arguments, beside each node of this task (as TCA kept a message's
    /// data): a wiretap check on the node reads them with [`Ctx::tapped_args`], the node's own
    /// action with [`Ctx::args`], a handler of its failure with [`Ctx::failing_args`]. Generated
    /// TDL tasks keep the tuple of their arguments (docs/language.md, "Wiretaps").
    pub fn with_args<A: Any + Send + Sync>(mut self, args: A) -> Task {
        self.args = Some(Arc::new(args));
        self
    }

    /// Tells the arguments kept with [`Task::with_args`] in each node's `spawned` record, for the
    /// viewer and `tdl trace story` (generated code tells each argument whose type is
    /// `tdl::ShowArg`). `describe` runs at the spawn, only when the run is traced; its text must
    /// be the same on every run for the same arguments, as the trace is.
    pub fn describe_args(mut self, describe: DescribeArgs) -> Task {
        self.describe = Some(describe);
        self
    }

    /// As [`Task::with_args`], already erased (`None` keeps nothing); for generated code.
    #[doc(hidden)]
    pub fn with_args_erased(mut self, args: Option<Arc<dyn Any + Send + Sync>>) -> Task {
        self.args = args;
        self
    }

    /// The instance name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The task's own name, which [`Task::named`] leaves alone (TCM's type name, TDL's task name):
    /// what [`Ctx::is_instance_of`] compares with.
    pub fn task_name(&self) -> &str {
        self.task_name.as_deref().unwrap_or(&self.name)
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
        if let Some(ot) = cleanup.into_cleanup() {
            self.on_terminate.push(ot);
        }
        self
    }

    /// Attaches a task-level exception handler. At a node, task-level handlers are tried before
    /// spawn-level ones, and within each group in the order attached (docs/semantics.md,
    /// "Exceptions and handlers").
    pub fn handler(mut self, h: Handler) -> Task {
        self.handlers.push(h.spec);
        self
    }

    /// Declares this task's action safe to run twice (a command that moves to a pose, not one that
    /// dispenses a part): when a run resumes from its journal ([`crate::Runtime::resume`]) and
    /// the action was running at the crash, it is started again; an action not so declared fails
    /// with the exception `Interrupted` instead (docs/semantics.md, "Durable runs").
    pub fn idempotent(mut self) -> Task {
        self.durable_mut().idempotent = true;
        self
    }

    /// Has a run's journal write this task's value with serde, and its replay read it back as a
    /// `T`, instead of the run's own encoder and decoder ([`crate::Runtime::journal_with`],
    /// [`crate::Runtime::replay_values`]): for a command whose value a waiting parent reads as a
    /// `T` ([`crate::Spawner::wait_value`]), so that the replay hands the parent the same type.
    pub fn journaled<T>(mut self) -> Task
    where
        T: serde::Serialize + serde::de::DeserializeOwned + Any + Send,
    {
        let d = self.durable_mut();
        d.encode = Some(Arc::new(|v: &(dyn Any + Send)| {
            v.downcast_ref::<T>()
                .and_then(|t| serde_json::to_value(t).ok())
        }));
        d.decode = Some(Arc::new(|j: serde_json::Value| {
            serde_json::from_value::<T>(j)
                .ok()
                .map(|t| Box::new(t) as Value)
        }));
        self
    }

    /// As [`Task::journaled`], with the task's own conversions to and from JSON (`None`: no
    /// value in the journal; the replay then hands `()`).
    pub fn journaled_with(
        mut self,
        encode: impl Fn(&(dyn Any + Send)) -> Option<serde_json::Value> + Send + Sync + 'static,
        decode: impl Fn(serde_json::Value) -> Option<Value> + Send + Sync + 'static,
    ) -> Task {
        let d = self.durable_mut();
        d.encode = Some(Arc::new(encode));
        d.decode = Some(Arc::new(decode));
        self
    }

    /// How a resumed run goes on with this task's action when it was running at the crash
    /// ([`crate::Runtime::resume`]): `reattach` is the node's new action, given what the action
    /// recorded in the run ([`Ctx::record`], in order; empty if it recorded nothing), instead of
    /// starting it again ([`Task::idempotent`]) or failing it with `Interrupted`. A remote task
    /// uses it to find its body on the agent that still runs it and wait for its end there
    /// (docs/semantics.md, "Durable runs").
    pub fn reattach<F, Fut, T>(mut self, reattach: F) -> Task
    where
        F: Fn(Ctx, Vec<serde_json::Value>) -> Fut + Send + Sync + 'static,
        Fut: Future<Output = Result<T, Failure>> + Send + 'static,
        T: Any + Send,
    {
        let f = Arc::new(reattach);
        self.durable_mut().reattach = Some(Arc::new(move |recorded| {
            let f = f.clone();
            Action::new(move |ctx| f(ctx, recorded))
        }));
        self
    }

    fn durable_mut(&mut self) -> &mut Durable {
        Arc::make_mut(self.durable.get_or_insert_with(Arc::default))
    }

    /// Keeps every node of this task after it completes, instead of reclaiming it (TDL's
    /// `persistent` qualifier): its state stays visible, at the cost of memory.
    pub fn persistent(mut self) -> Task {
        self.persistent = true;
        self
    }

    /// Sets the grace period of this task's action (and of its retries; of a monitor, of each
    /// activation), instead of the runtime's ([`crate::Runtime::default_grace`], one second by
    /// default). When its node is terminated while the action runs, an action that looked at its
    /// cancellation signal ([`Ctx::cancelled`], [`Ctx::is_cancelled`]) is signalled and may run
    /// this long to cancel what it started outside (a ROS 2 goal, a remote task, a motion); the
    /// node stays terminating meanwhile. The action is dropped when it returns or when the period
    /// ends (then with a warning); what it returns is ignored (the node was terminated), a panic is
    /// reported as usual. An action that never looked at the signal is dropped at once, and
    /// `Duration::ZERO` drops this one at once (docs/semantics.md, "Termination").
    pub fn grace(mut self, grace: Duration) -> Task {
        self.grace = Some(grace);
        self
    }

    /// Every node of this task uses `amount` of the resource `resource` (a name the run declared,
    /// or a [`crate::Resource`], declared on first use): it is granted, all at once with the
    /// task's other resources and those its spawn adds, before it starts, and released when its
    /// action ends (docs/semantics.md, "Resources"). TDL's task-level `uses`.
    pub fn uses(mut self, resource: impl Into<crate::ResourceRef>, amount: u32) -> Task {
        self.wanted
            .get_or_insert_with(Box::default)
            .uses
            .push((resource.into(), amount));
        self
    }

    /// The priority of this task's requests for resources (lower is granted first; 0 by
    /// default); a spawn's own priority replaces it.
    pub fn priority(mut self, priority: i32) -> Task {
        self.wanted.get_or_insert_with(Box::default).priority = Some(priority);
        self
    }

    /// Names the version of the program that defines this task (a program loaded at run time
    /// under its content hash): the node's `spawned` record carries it, so a trace in which two
    /// versions ran tells which node ran which (docs/trace-format.md).
    pub fn version(mut self, version: Arc<str>) -> Task {
        self.version = Some(version);
        self
    }

    /// Renames the instance (TDL's `name` constraint); the task name stays (see
    /// [`Task::task_name`]).
    pub fn named(mut self, name: impl Into<Name>) -> Task {
        let name = name.into();
        let own = std::mem::replace(&mut self.name, name);
        self.task_name.get_or_insert(own);
        self
    }

    /// The engine's spawn request for this task under `parent`, and what the host keeps beside
    /// the node: the task name when the instance was renamed (and differs), the arguments, the
    /// grace period and the resources it uses. Everything is moved, nothing copied.
    #[inline(always)]
    pub(crate) fn into_parts(self, parent: NodeId) -> (Spawn<Action, Factory>, Kept) {
        let task = self.task_name.filter(|t| *t != self.name);
        let kept = Kept {
            task_name: task.clone(),
            args: self.args,
            grace: self.grace,
            fail_parent: false,
            wanted: self.wanted,
            durable: self.durable,
            describe: self.describe,
        };
        let spawn = Spawn {
            parent,
            kind: self.kind,
            name: self.name,
            task,
            action: self.action,
            constraints: self.constraints,
            persistent: self.persistent,
            on_terminate: self.on_terminate,
            fulfils: None,
            monitor: self.monitor,
            handlers: self.handlers,
            retry: self.retry,
            // Resolved by name when the spawn is made (`Kept::wanted`).
            uses: None,
            version: self.version,
            // Described by the host only when the run is traced (`Inner::spawn`).
            args: None,
        };
        (spawn, kept)
    }

    /// As an on-terminate task; monitors cannot be one.
    pub(crate) fn into_cleanup(self) -> Option<OnTerminate<Action>> {
        Some(OnTerminate {
            kind: self.kind,
            name: self.name,
            action: self.action?,
            fulfils: None,
        })
    }
}

/// Makes the task that runs `name(args)` on another process, the agent `agent`. Set with
/// [`crate::Runtime::placer`]; `tcm_zenoh::Executive` is one.
pub trait Placer: Send + Sync + 'static {
    /// The task for `name(args)` on `agent`, a goal or a command as `kind` says. Its node is the
    /// tree's like any other; its action runs on the agent.
    fn place(&self, agent: &str, name: &str, kind: NodeKind, args: Json) -> Result<Task, Error>;
}

impl<P: Placer + ?Sized> Placer for Arc<P> {
    fn place(&self, agent: &str, name: &str, kind: NodeKind, args: Json) -> Result<Task, Error> {
        (**self).place(agent, name, kind, args)
    }
}
