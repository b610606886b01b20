//! Failures of actions, as the core sees them.
//!
//! The core does not know the user's exception types: it sees a type name, the names of the type's
//! ancestors (for handler matching, exceptions issue) and a message. The shell keeps the typed value.

use crate::Name;
use std::fmt;

/// Why an action failed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Failure {
    /// The exception's type name, e.g. `NoPath`.
    pub exception: Name,
    /// A human-readable description.
    pub message: String,
}

impl Failure {
    /// A failure of the given exception type.
    pub fn new(exception: impl Into<Name>, message: impl Into<String>) -> Failure {
        Failure {
            exception: exception.into(),
            message: message.into(),
        }
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

impl<E: std::error::Error + 'static> From<E> for Failure {
    /// Any error fails the action with an exception named after the error's type, so `?` works in
    /// action bodies.
    fn from(e: E) -> Failure {
        let full = std::any::type_name::<E>();
        let short = full.rsplit("::").next().unwrap_or(full);
        Failure::new(short.to_string(), e.to_string())
    }
}
