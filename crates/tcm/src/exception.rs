//! The [`Exception`] trait: a Rust error type a handler can name (TDL's `exception`
//! declarations).

use tcm_core::{Failure, Name};

/// An exception type (TDL's `exception` declarations): a Rust error with an optional chain of
/// ancestor types, so that a handler for `HardwareFailure` also catches `EngineOnFire`.
pub trait Exception: std::error::Error + Send + Sync + 'static {
    /// The names of the ancestor exception types, nearest first. Default: none.
    fn ancestry() -> &'static [&'static str]
    where
        Self: Sized,
    {
        &[]
    }

    /// The exception type's name. Default: the short Rust type name.
    fn name() -> &'static str
    where
        Self: Sized,
    {
        tcm_core::short_type_name::<Self>()
    }

    /// This exception as a failure that carries it (TDL's `fail`): `return Err(e.raise())`.
    fn raise(self) -> Failure
    where
        Self: Sized,
    {
        let mut f = Failure::from(self);
        f.exception = Self::name().into();
        f.ancestry = Self::ancestry().iter().map(|a| Name::Borrowed(a)).collect();
        f
    }
}
