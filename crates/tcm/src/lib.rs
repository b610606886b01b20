//! TCM, the task-tree runtime of TDL, for Rust: async actions on tokio over a deterministic core.
//!
//! A [`Task`] is a goal or a command with an async action. [`Runtime::run`] inserts it as the
//! top-level task and drives the tree until its execution completes; [`Runtime::start`] gives a
//! [`Session`] for a program in TCM's style (several top-level tasks, wait until quiescent,
//! inspect, terminate, finish). Goals spawn children through
//! their [`Ctx`], with the synchronisation constraints of the TDL paper (Figure 5) given on a
//! [`Spawner`]; commands await their hardware. Returning completes a node's handling, an error fails
//! it (this replaces TDL's POSTPONE/Resume), and a panicking action fails its node while the run
//! goes on.
//!
//! Terminating a node drops its running action at its next `.await`; an action that started
//! something outside (a ROS 2 goal, a remote job) awaits [`Ctx::cancelled`] instead, and gets a
//! bounded grace period ([`Task::grace`], [`Runtime::default_grace`]) to cancel it before its node
//! is terminated.
//!
//! Actions run truly concurrently on tokio's workers; code that blocks or computes runs as a
//! blocking body on tokio's blocking threads ([`Task::blocking`], [`Ctx::blocking`]), so it never
//! stalls the tree or its timers. On a current-thread runtime an action released by another's end
//! is polled at once on that task, and becomes a task of its own only if it awaits. Under tokio's paused clock
//! (`#[tokio::test(start_paused = true)]`, or [`block_on_virtual`]) time is virtual: a 30 s timeout
//! passes instantly, and the same program yields the same trace on every run.
//!
//! Every transition is a trace record ([`TraceEvent`]); sinks write it as JSON lines
//! ([`JsonLines`]), TCM's text log ([`TextLogSink`]) or keep it ([`Recorder`]).
//!
//! The semantics live in `tcm-core` (the engine); see its documentation and `ARCHITECTURE.md`.
#![warn(missing_docs)]

mod cancel;
mod clock;
mod control;
mod ctx;
mod events;
mod exception;
mod faults;
mod host;
mod invoke;
mod journal;
mod niced;
mod outcome;
pub mod patterns;
mod place;
mod pump;
mod query;
mod replay;
mod resource;
mod runtime;
mod session;
mod sink;
mod state;
mod task;
pub mod testing;
mod timer;

pub use cancel::DEFAULT_GRACE;
pub use control::Control;
pub use ctx::{Ctx, Ended, Spawner};
pub use events::EventHandle;
pub use exception::Exception;
pub use faults::{FaultsError, json_value, parse_faults, read_faults};
pub use journal::{ValueEncoder, json_values};
pub use outcome::Panicked;
pub use outcome::{Report, RunOutcome};
pub use place::{Json, remote_args, remote_value};
pub use replay::{INTERRUPTED, RESUMED_BY, ValueDecoder, json_decoded};
pub use resource::{Resource, ResourceDenied, ResourceDropped, ResourceRef};
pub use runtime::Runtime;
pub use session::Session;
pub use sink::{JsonLines, Recorder, TextLogSink, TraceSink, TracingSink};
pub use state::{
    BinOp, CondId, Expr, FromState, InvariantFailed, StateId, StateType, StateValue, StateVar,
};
pub use task::Placer;
pub use task::{
    Action, ActionFuture, Attached, DescribeArgs, Factory, Handler, Monitor, Tap, Task, Value,
    factory,
};
pub use tcm_core::{
    Approval, ApprovalRefused, AttachId, BreakAt, Breakpoint, EachActivation, Fault, FaultOutcome,
    FaultValue, Matcher, Outcome, Overrun, PassedOn, ResourceInfo, SteerId, TapWhen, Then, When,
    WiretapId,
};
pub use tcm_core::{
    Blocked, Constraint, EngineError, Event, ExternalId, Facet, Failure, FailurePolicy,
    FatalFailure, MonitorInfo, NodeId, NodeInfo, NodeKind, NodeRef, Point, State, Stats,
    Termination, Time, WatchOutcome,
};
pub use tcm_trace::{TraceEvent, TraceKind};

/// Errors of the runtime API. Inside an action, `?` turns them into a failure of the node.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The engine refused the request (bad handle, too late for a constraint, …).
    #[error(transparent)]
    Engine(#[from] EngineError),
    /// The run ended before the awaited node finished.
    #[error("the run ended before the awaited node finished")]
    RunEnded,
    /// The run is replaying its journal (a resumed run, before it goes on live): an operation from
    /// outside would come among the journal's inputs, so it waits until the run goes live
    /// (`Control::replaying`).
    #[error("the run is replaying its journal: steer it once it goes on live")]
    Replaying,
    /// A panic inside the engine poisoned the runtime; the run cannot go on.
    #[error("the runtime was poisoned by a panic inside the engine")]
    Poisoned,
    /// The awaited child failed, with this failure (finally: after its handlers and retries).
    /// Turned into a [`Failure`] by `?` in a body, it is the child's failure itself, so handlers
    /// of the child's exception type take the waiter's failure.
    #[error("the awaited child failed: {0}")]
    ChildFailed(#[source] tcm_core::PassedOn),
    /// The awaited child was terminated (or never spawned).
    #[error("the awaited child was terminated before it completed")]
    ChildTerminated,
    /// The awaited child was skipped (its `skip if` condition held): it has no value.
    #[error("the awaited child was skipped: it has no value")]
    ChildSkipped,
    /// The precise timer's thread could not be started.
    #[error("cannot start the precise timer thread: {0}")]
    Timer(std::io::Error),
    /// The awaited child returned no value of the expected type.
    #[error("the awaited child returned no value of type {0}")]
    NoValue(&'static str),
    /// `Ctx::retry_with` was given arguments of another type than the failed task keeps (or the
    /// task keeps none).
    #[error("the failed task keeps no arguments of type {0}")]
    ArgsType(&'static str),
    /// `Runtime::start` (or `EventHandle::spawn`) was called outside a tokio runtime.
    #[error("`Runtime::start` and `EventHandle::spawn` must be called inside a tokio runtime")]
    NoRuntime,
    /// [`block_on_virtual`] could not build its tokio runtime.
    #[error("cannot start the tokio runtime: {0}")]
    Runtime(#[from] std::io::Error),
    /// A task was placed on an agent (TDL's `on AGENT`), but the run has no distribution layer.
    #[error(
        "task `{task}` is placed on agent `{agent}`, but this run has no distribution layer: give the runtime one with `Runtime::placer` (a `tcm_zenoh::Executive`), or remove `on {agent}`"
    )]
    NoPlacer {
        /// The task.
        task: String,
        /// The agent it was placed on.
        agent: String,
    },
    /// The value a task placed on an agent returned is not of the type the program expects.
    #[error("the value `{task}` returned from its agent is not of the expected type: {reason}")]
    RemoteValue {
        /// The task.
        task: String,
        /// Why.
        reason: String,
    },
    /// The arguments of a task placed on an agent cannot be sent as JSON.
    #[error("the arguments of `{task}` cannot be sent to an agent: {reason}")]
    Args {
        /// The task.
        task: String,
        /// Why.
        reason: String,
    },
}

/// The tokio this crate runs on, for programs that depend on `tcm` (or `tdl`) alone:
/// `tcm::tokio::time::sleep`. Its attribute macros need the path: `#[tcm::tokio::main(crate =
/// "tcm::tokio")]`.
#[doc(no_inline)]
pub use tokio;

/// Runs `fut`, a run or anything else returning a `Result`, on a new single-threaded tokio
/// runtime whose clock is paused: virtual time, which jumps to the next timer whenever every task
/// waits. For simulations and demos. One `Result`: the future's own error, or the error of
/// building the runtime converted into it ([`Error::Runtime`] for the runtime's [`Error`]).
///
/// ```
/// use tcm::{Runtime, RunOutcome, Task};
/// let beep = Task::command("beep", |_| async {
///     tcm::tokio::time::sleep(std::time::Duration::from_secs(60)).await;
///     Ok(())
/// });
/// // Made inside, the runtime's time zero is on the paused clock.
/// let report = tcm::block_on_virtual(async { Runtime::new().run(beep).await })?;
/// assert_eq!(report.outcome, RunOutcome::Completed);
/// assert_eq!(report.elapsed, std::time::Duration::from_secs(60));
/// # Ok::<(), tcm::Error>(())
/// ```
pub fn block_on_virtual<F, T, E>(fut: F) -> Result<T, E>
where
    F: std::future::Future<Output = Result<T, E>>,
    E: From<std::io::Error>,
{
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_time()
        .start_paused(true)
        .build()?;
    rt.block_on(fut)
}
