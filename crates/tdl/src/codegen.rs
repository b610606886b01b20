//! Support for the code that `tdl!`, `tdl-build` and `tdl expand` generate. Not for direct use:
//! nothing here is covered by semver, and the names may change with the generator.
//!
//! - [`Args`]: a task's arguments kept for re-runs. Every generated goal and command is a
//!   [`Task::retryable`](crate::Task::retryable) task; its body takes its arguments from an `Args`,
//!   which clones them when they are `Clone` (so a handler's `retry` re-runs the task with the same
//!   arguments) and otherwise hands them out once (a retry then fails with `NotRetryable`). The
//!   choice is made at compile time by autoref specialisation: `(&args).tdl_args()` finds
//!   [`CloneArgs`] when the arguments are `Clone`, else [`TakeArgs`]; `(&args).tdl_args_in(&ctx)`
//!   ([`CloneArgsIn`], [`TakeArgsIn`]) reads first the arguments the host keeps for the run's node,
//!   so a handler's `Ctx::retry_with` re-runs the task with other arguments. `(&args).tdl_kept()`
//!   ([`KeepArgs`] when they are `Clone`, `Send` and `Sync`, else [`NoKeepArgs`]) gives the tuple
//!   of the arguments to keep beside each node (`Task::with_args`), for wiretap checks.
//! - [`Persistent`]: a monitor's or handler's `persistent` variable, shared by its activations.
//! - [`caught`], [`handles`], [`failing_node`], [`attached_node`]: what a handler body reads.
//! - [`count`]: a `maximum activate/trigger` count as a `u32`.
//! - [`trigger_entity`], [`no_members`]: constraints naming an *entity* of several nodes (a `with`
//!   group, `previous` after a group, an iteration set, a tag bound at run time), whose members are
//!   only known at run time (docs/semantics.md, "Tags and forward references").
//! - [`bound`]: the node of a tag bound at run time, for `node!(tag)` in Rust code.

use std::any::Any;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Duration;
use tcm::{Constraint, Ctx, Error, Event, Facet, Failure, NodeId, Point, Then, When};

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// An argument shown in a node's `spawned` record (`Task::describe_args`): as
/// [`ShowArg`](crate::ShowArg) shows it when its type is one ([`DebugShown`]), else as `…`
/// ([`NoDebugShown`]); generated code picks by borrow.
pub struct Shown<'a, T>(pub &'a T);

/// An argument whose type is [`ShowArg`](crate::ShowArg).
pub trait DebugShown {
    /// The argument as it shows.
    fn tdl_shown(&self) -> String;
}

impl<T: crate::ShowArg> DebugShown for Shown<'_, T> {
    fn tdl_shown(&self) -> String {
        let mut out = String::new();
        self.0.show_arg(&mut out);
        out
    }
}

/// An argument whose type does not print.
pub trait NoDebugShown {
    /// `…`.
    fn tdl_shown(&self) -> String;
}

impl<T> NoDebugShown for &Shown<'_, T> {
    fn tdl_shown(&self) -> String {
        "…".to_string()
    }
}

/// A task's arguments, kept by its body for re-runs (see the module docs).
pub struct Args<T>(Mutex<Option<T>>);

impl<T> Args<T> {
    /// Keeps `args`.
    pub fn new(args: T) -> Args<T> {
        Args(Mutex::new(Some(args)))
    }
}

/// The arguments of a run, when they are `Clone`: a copy each time.
pub trait CloneArgs<T> {
    /// A copy of the arguments.
    fn tdl_args(&self) -> Option<T>;
}

impl<T: Clone + 'static> CloneArgs<T> for Args<T> {
    fn tdl_args(&self) -> Option<T> {
        lock(&self.0).clone()
    }
}

/// The arguments of a run, when they are `Clone`: those the host keeps for the run's node (a
/// retry with other arguments, `Ctx::retry_with`), else a copy of the spawn's.
pub trait CloneArgsIn<T> {
    /// The run's arguments.
    fn tdl_args_in(&self, ctx: &Ctx) -> Option<T>;
}

impl<T: Clone + 'static> CloneArgsIn<T> for Args<T> {
    fn tdl_args_in(&self, ctx: &Ctx) -> Option<T> {
        match ctx.args_ref::<T>() {
            Some(a) => Some(a.clone()),
            None => self.tdl_args(),
        }
    }
}

/// The arguments to keep beside the node (`Task::with_args`), when they are `Clone`, `Send`
/// and `Sync`: wiretap checks read them, handlers retry with changed ones.
pub trait KeepArgs {
    /// A copy of the arguments, erased.
    fn tdl_kept(&self) -> Option<Arc<dyn Any + Send + Sync>>;
}

impl<T: Clone + Send + Sync + 'static> KeepArgs for Args<T> {
    fn tdl_kept(&self) -> Option<Arc<dyn Any + Send + Sync>> {
        lock(&self.0)
            .clone()
            .map(|a| Arc::new(a) as Arc<dyn Any + Send + Sync>)
    }
}

/// Arguments that cannot be kept (not `Clone`, `Send` and `Sync`): nothing is kept.
pub trait NoKeepArgs {
    /// Nothing.
    fn tdl_kept(&self) -> Option<Arc<dyn Any + Send + Sync>>;
}

impl<T> NoKeepArgs for &Args<T> {
    fn tdl_kept(&self) -> Option<Arc<dyn Any + Send + Sync>> {
        None
    }
}

/// The arguments of a run, when they are not `Clone`: the first run takes them.
pub trait TakeArgs<T> {
    /// The arguments, the first time only.
    fn tdl_args(&self) -> Option<T>;
}

impl<T> TakeArgs<T> for &Args<T> {
    fn tdl_args(&self) -> Option<T> {
        lock(&self.0).take()
    }
}

/// As [`CloneArgs`] reading the run's own arguments first, when the arguments are not `Clone`:
/// the first run takes them.
pub trait TakeArgsIn<T> {
    /// The arguments, the first time only.
    fn tdl_args_in(&self, ctx: &Ctx) -> Option<T>;
}

impl<T> TakeArgsIn<T> for &Args<T> {
    fn tdl_args_in(&self, _: &Ctx) -> Option<T> {
        lock(&self.0).take()
    }
}

/// The failure of a re-run of a task whose arguments are not `Clone`.
pub fn not_retryable(task: &str) -> Failure {
    Failure::new(
        "NotRetryable",
        format!("`{task}` cannot run again: its arguments are not `Clone`"),
    )
}

/// A `persistent` variable of a monitor or a handler: one value per monitor instance (per spawn)
/// or per handler instance, shared by its activations. Each activation starts with a copy of the
/// value ([`Persistent::load`]) and stores its copy back when its body ends
/// ([`Persistent::store`]), however it ends.
pub struct Persistent<T>(Arc<Mutex<T>>);

impl<T> Clone for Persistent<T> {
    fn clone(&self) -> Self {
        Persistent(self.0.clone())
    }
}

impl<T: Clone> Persistent<T> {
    /// A variable with its initial value.
    pub fn new(init: T) -> Persistent<T> {
        Persistent(Arc::new(Mutex::new(init)))
    }

    /// The current value.
    pub fn load(&self) -> T {
        lock(&self.0).clone()
    }

    /// Replaces the value.
    pub fn store(&self, value: T) {
        *lock(&self.0) = value;
    }
}

/// In a handler body: the caught exception, for the binding of `handles E as name`. It reads
/// every failure a handler of `E` catches, descendants of `E` included (see [`crate::Caught`]).
pub fn caught<E: Send + Sync + 'static>(
    ctx: &Ctx,
    handler: &str,
) -> Result<crate::Caught<E>, Failure> {
    match ctx.failure() {
        Some(failure) => Ok(crate::Caught::new(failure.clone())),
        None => Err(Failure::new(
            "NotAHandler",
            format!("`{handler}` reads its caught exception outside an exception handler"),
        )),
    }
}

/// Names the Rust type of a handled exception, so that `handles X` with no type `X` in scope is a
/// compile error rather than a handler that never fires.
pub fn handles<E: ?Sized + 'static>(name: &'static str) -> &'static str {
    name
}

/// In a handler body: the node whose action failed.
pub fn failing_node(ctx: &Ctx) -> Result<NodeId, Failure> {
    ctx.failing_node()
        .ok_or_else(|| Failure::new("NotAHandler", "`failing` outside an exception handler"))
}

/// In a handler body: the node the handler was attached to.
pub fn attached_node(ctx: &Ctx) -> Result<NodeId, Failure> {
    ctx.attached_node()
        .ok_or_else(|| Failure::new("NotAHandler", "`attached` outside an exception handler"))
}

/// What a generated goal or command declares of itself: its name and the tuple of its arguments'
/// types (the arguments a handler attached to it with `for` receives).
pub trait TaskArgs {
    /// The tuple of the argument types, in order.
    type Args;
    /// The task's name.
    const NAME: &'static str;
}

/// In a handler attached to a task with `for`: the arguments of the node it recovers.
pub fn attached_args<A: Clone + Any + Send + Sync>(
    ctx: &Ctx,
    handler: &str,
    task: &str,
) -> Result<A, Failure> {
    match ctx.attached_args::<A>() {
        Some(args) => Ok((*args).clone()),
        None => Err(Failure::new(
            "NotAttached",
            format!(
                "`{handler}` ran outside a failure of `{task}`, so it has no arguments to read"
            ),
        )),
    }
}

/// A wiretap's arguments: those of the node it checks, an instance of `task`.
pub fn tapped_args<A: Clone + Any + Send + Sync>(
    ctx: &Ctx,
    wiretap: &str,
    task: &str,
) -> Result<A, Failure> {
    match ctx.tapped_args::<A>() {
        Some(args) => Ok((*args).clone()),
        None => Err(Failure::new(
            "NotTapped",
            format!(
                "`{wiretap}` ran on a node that is no `{task}` keeping its arguments, so it has no arguments to read"
            ),
        )),
    }
}

/// A `maximum activate/trigger` count; values out of the `u32` range saturate.
pub fn count<N: TryInto<u32>>(n: N) -> u32 {
    n.try_into().unwrap_or(u32::MAX)
}

/// A `terminate` or `activate` constraint on `target` whose event names an entity: it happens when
/// every member reached `point` of `facet` (after `delay`, if any). `members` is `None` when there
/// is no entity at all (`previous` before anything was spawned): the event part is then void and
/// only a delay is kept (`terminate in D after previous` is `terminate in D`). An entity with no
/// member (a group none of whose spawns ran) is a dead reference: it fires at once, or after the
/// delay counted from now. One member is an ordinary constraint on that node.
pub fn trigger_entity(
    ctx: &Ctx,
    target: NodeId,
    members: Option<&[NodeId]>,
    facet: Facet,
    point: Point,
    delay: Option<Duration>,
    then: Then,
) -> Result<(), Error> {
    let when = match (members, delay) {
        (None, None) => return Ok(()),
        (None | Some([]), Some(d)) => When::In(d),
        (Some([]), None) => When::Now,
        (Some([one]), None) => When::Event(Event::on(*one, facet, point)),
        (Some([one]), Some(d)) => When::After(d, Event::on(*one, facet, point)),
        (Some(many), _) => return ctx.trigger_group(target, many, facet, point, delay, then),
    };
    ctx.constrain(target, Constraint::Trigger(when, then))
}

/// Whether an entity has no member, or there is none (`previous` before anything): an enablement
/// constraint `… for D after` it is then `… for D` (the `after` part of a dead or missing event
/// is dropped).
pub fn no_members(members: Option<&[NodeId]>) -> bool {
    members.is_none_or(<[NodeId]>::is_empty)
}

/// The node of a tag bound at run time (`bind name = …;`, or a spawn with `parent`), for
/// `node!(tag)` in Rust code: a failure when the statement that binds it has not run.
pub fn bound(node: Option<NodeId>, tag: &str) -> Result<NodeId, Failure> {
    node.ok_or_else(|| {
        Failure::new(
            "Unbound",
            format!("`node!({tag})`: `{tag}` is not bound yet (its `bind` or spawn has not run)"),
        )
    })
}
