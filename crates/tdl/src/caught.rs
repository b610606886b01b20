//! [`Caught`]: the exception a handler caught, as a TDL handler body sees it through its binding
//! (`handler h() handles Fault as f { … }`).

use std::any::Any;
use std::fmt;
use std::marker::PhantomData;
use std::sync::Arc;

use tcm::{Exception, Failure};

/// The exception caught by a handler of `E`, bound with `handles E as name` (docs/semantics.md,
/// "Exceptions and handlers").
///
/// A handler of `E` also catches every exception declared below `E` (`exception TerrainFault :
/// Fault`), whose value is of its own type, not an `E`. So the value is read by asking for a type:
/// [`data`](Caught::data) gives it as the handled `E` when it is one, [`downcast`](Caught::downcast)
/// as any descendant type, and [`failure`](Caught::failure) gives the name, message and ancestry of
/// whatever was caught.
pub struct Caught<E> {
    failure: Failure,
    handled: PhantomData<fn() -> E>,
}

impl<E: Any + Send + Sync> Caught<E> {
    /// Wraps the failure a handler of `E` caught.
    pub fn new(failure: Failure) -> Caught<E> {
        Caught {
            failure,
            handled: PhantomData,
        }
    }

    /// The caught value as the handled type `E`: `Some` when the exception raised was an `E`
    /// itself, `None` when it was a descendant of `E` (read that with [`downcast`](Caught::downcast)).
    pub fn data(&self) -> Option<Arc<E>> {
        self.failure.data::<E>()
    }

    /// The caught value as `T`, typically a descendant of `E`: `Some` when the raised value is a `T`.
    pub fn downcast<T: Any + Send + Sync>(&self) -> Option<Arc<T>> {
        self.failure.data::<T>()
    }

    /// Whether the caught exception is of type `T` or of a type declared below it.
    pub fn is<T: Exception>(&self) -> bool {
        self.failure.is_a(T::name())
    }

    /// The name of the exception raised (`TerrainFault` for a handler of `Fault` that caught one).
    pub fn name(&self) -> &str {
        &self.failure.exception
    }

    /// The failure itself: name, message, ancestry and the carried value.
    pub fn failure(&self) -> &Failure {
        &self.failure
    }
}

impl<E> fmt::Debug for Caught<E> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_tuple("Caught").field(&self.failure).finish()
    }
}

impl<E> fmt::Display for Caught<E> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(&self.failure, f)
    }
}
