//! The deterministic core of TCM, the task-tree runtime of TDL.
//!
//! [`Engine`] owns the task tree, the synchronisation constraints and the agenda. It does no I/O,
//! reads no clock and starts no thread: inputs come in as method calls carrying the virtual time,
//! outputs go out as [`Effect`]s (start or cancel an action, notify a watcher), timer deadlines and
//! trace records ([`tcm_trace::TraceEvent`]). The same inputs give the same trace, byte for byte.
//! The async shell that runs real actions on tokio is the `tcm` crate.
//!
//! ```
//! use tcm_core::{Constraint, Effect, Engine, NodeKind, Spawn, Time};
//!
//! let mut engine: Engine<&str> = Engine::new(1);
//! let root = engine.root();
//! let a = engine.spawn(Time::ZERO, Spawn::new(root, NodeKind::Command, "a", "run a")).unwrap();
//! let b = engine
//!     .spawn(Time::ZERO, Spawn::new(root, NodeKind::Command, "b", "run b").with(Constraint::sequential_previous()))
//!     .unwrap();
//! // Only `a` may start: `b`'s execution waits for `a`'s.
//! assert!(matches!(engine.poll_effect(), Some(Effect::Start { node, .. }) if node == a));
//! assert!(engine.poll_effect().is_none());
//! engine.handle_action_finished(Time::from_nanos(5), a, Ok(())).unwrap();
//! assert!(matches!(engine.poll_effect(), Some(Effect::Start { node, .. }) if node == b));
//! ```
//!
//! # Architecture invariants
//!
//! - No async runtime, clock, thread, socket or hash-ordered collection in this crate.
//! - Facets only move forward; every transition is one trace record, emitted before its effects.
//! - Work is queued, never recursive: the depth of the tree costs no stack.
//! - Memory is proportional to live nodes: completed subtrees are reclaimed unless persistent.

#![warn(missing_docs)]
// `Keep` bounds name the engine's private node type: the store is chosen, never implemented, outside.
#![allow(private_bounds)]

mod arena;
mod constraint;
mod driver;
mod engine;
mod failure;
mod ids;
pub mod sim;
mod time;

#[cfg(test)]
mod tests;

pub use arena::{Keep, Owned, Shared};
pub use constraint::{Constraint, Constraints, Event, NodeRef, Then, When};
pub use driver::{Driver, Next, Shell};
pub use engine::{
    Approval, ApprovalRefused, Blocked, BreakAt, Breakpoint, Canonical, EachActivation, Effect,
    Engine, EngineError, Fault, FaultOp, FaultOutcome, FaultValue, HandlerSpec, InputRecord,
    InvariantFailed, Job, Matcher, MatcherOp, MonitorInfo, MonitorSpec, NodeInfo, OnTerminate,
    Overrun, Purpose, ResourceDenied, ResourceDropped, ResourceInfo, Spawn, Stats, SteerId,
    SteerOp, Uses, WatchOutcome,
};
pub use failure::{Failure, FailurePolicy, FatalFailure, PassedOn, short_type_name};
pub use ids::{
    AttachId, CondId, ExternalId, NodeId, ResourceId, StateId, TapWhen, WatchToken, WiretapId,
};
pub use tcm_expr::{BinOp, Expr, ExprError, Type, TypeMismatch, Value};
pub use tcm_trace::{Facet, NodeKind, Outcome, Point, State, Termination};
pub use time::{Clock, Time};

/// Instance and type names: static strings cost no allocation.
pub type Name = std::borrow::Cow<'static, str>;
