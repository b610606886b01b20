//! Failures of actions, as the core sees them.
//!
//! The core does not know the user's exception types: it sees a type name, the names of the type's
//! ancestors (for handler matching, exceptions issue) and a message. The shell keeps the typed value.

use crate::Name;
use std::any::Any;
use std::fmt;
use std::sync::Arc;

/// Why an action failed.
#[derive(Clone)]
pub struct Failure {
    /// The exception's type name, e.g. `NoPath`.
    pub exception: Name,
    /// A human-readable description.
    pub message: String,
    /// The exception type's ancestors, nearest first (`EngineOnFire` : `EngineFailure` :
    /// `HardwareFailure` gives `["EngineFailure", "HardwareFailure"]`): a handler of any of them
    /// takes this failure.
    pub ancestry: Vec<Name>,
    /// The exception value itself, for handlers to read (the core never looks inside).
    pub data: Option<Arc<dyn Any + Send + Sync>>,
}

impl fmt::Debug for Failure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Failure")
            .field("exception", &self.exception)
            .field("message", &self.message)
            .field("ancestry", &self.ancestry)
            .field("data", &self.data.as_ref().map(|_| ".."))
            .finish()
    }
}

/// Failures compare by type, message and ancestry; the carried value is not compared.
impl PartialEq for Failure {
    fn eq(&self, other: &Failure) -> bool {
        self.exception == other.exception
            && self.message == other.message
            && self.ancestry == other.ancestry
    }
}

impl Eq for Failure {}

impl Failure {
    /// A failure of the given exception type.
    pub fn new(exception: impl Into<Name>, message: impl Into<String>) -> Failure {
        Failure {
            exception: exception.into(),
            message: message.into(),
            ancestry: Vec::new(),
            data: None,
        }
    }

    /// The carried exception value, if it is an `E`.
    pub fn data<E: Any + Send + Sync>(&self) -> Option<Arc<E>> {
        self.data.clone().and_then(|d| d.downcast::<E>().ok())
    }

    /// Sets the exception type's ancestors, nearest first.
    pub fn with_ancestry(mut self, ancestry: Vec<Name>) -> Failure {
        self.ancestry = ancestry;
        self
    }

    /// Whether this failure is of exception type `name` or of a type derived from it.
    pub fn is_a(&self, name: &str) -> bool {
        self.exception == name || self.ancestry.iter().any(|a| a == name)
    }
}

impl fmt::Display for Failure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.exception, self.message)
    }
}

/// What the engine does with a failure no handler takes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FailurePolicy {
    /// TCM's behaviour: the node is marked failed, a warning is traced, the run goes on.
    #[default]
    Warn,
    /// The run ends with an error naming the exception, the node and its path.
    Fatal,
}

/// An unhandled failure under [`FailurePolicy::Fatal`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FatalFailure {
    /// The failure.
    pub failure: Failure,
    /// Display number of the failing node.
    pub node: u64,
    /// Path of instance names from the top-level task to the failing node, joined by `/`.
    pub path: String,
}

impl fmt::Display for FatalFailure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "unhandled exception {} in {} {{{}}}: {}",
            self.failure.exception, self.path, self.node, self.failure.message
        )
    }
}

/// The short name of a type: `NoPath` for `robot::errors::NoPath`.
pub fn short_type_name<T: ?Sized>() -> &'static str {
    let full = std::any::type_name::<T>();
    let base = full.split('<').next().unwrap_or(full);
    base.rsplit("::").next().unwrap_or(base)
}

/// A failure passed on as an error's source: an error whose source chain holds one becomes that
/// failure again, type and data included, when `?` turns it into a [`Failure`] (a waiter failing
/// because the child it waited for failed fails with the child's exception).
#[derive(Clone, Debug)]
pub struct PassedOn(pub Failure);

impl fmt::Display for PassedOn {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(&self.0, f)
    }
}

impl std::error::Error for PassedOn {}

impl<E: std::error::Error + Send + Sync + 'static> From<E> for Failure {
    /// Any error fails the action with an exception named after the error's type and carrying the
    /// error, so `?` works in action bodies; an error carrying a [`PassedOn`] failure in its
    /// source chain is that failure.
    fn from(e: E) -> Failure {
        let mut source: Option<&(dyn std::error::Error + 'static)> = Some(&e);
        while let Some(s) = source {
            if let Some(PassedOn(failure)) = s.downcast_ref::<PassedOn>() {
                return failure.clone();
            }
            source = s.source();
        }
        let mut f = Failure::new(short_type_name::<E>(), e.to_string());
        f.data = Some(Arc::new(e));
        f
    }
}
