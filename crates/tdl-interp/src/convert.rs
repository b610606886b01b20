//! Conversions between Rust values and interpreted [`Value`]s, for what a registry offers: a
//! registered function's parameters are [`FromValue`], its result [`IntoValue`] (or a `Result`
//! of one, [`IntoOutcome`]). Plain types convert to plain values; a type of the user's becomes
//! a host value with [`host_type!`](crate::host_type), which implements both for it.

use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Duration;

use tdl::{Ctx, Failure, NodeId};

use crate::value::Value;

/// A Rust value made from an interpreted value.
pub trait FromValue: Sized {
    /// The type as a message names it.
    fn expected() -> String;
    /// The value, or `None` when it is not one of this type.
    fn from_value(v: &Value) -> Option<Self>;
}

/// A Rust value as an interpreted value.
pub trait IntoValue {
    /// The value.
    fn into_value(self) -> Value;
}

/// What a registered function returns: a value, or a `Result` whose error fails the node.
pub trait IntoOutcome {
    /// The value, or the failure.
    fn into_outcome(self) -> Result<Value, Failure>;
}

impl<T: IntoValue> IntoOutcome for T {
    fn into_outcome(self) -> Result<Value, Failure> {
        Ok(self.into_value())
    }
}

/// A `Result` is a value, `Ok(v)` or `Err(e)`, as in Rust: `?` takes the value or fails the
/// node with the error's failure, `match` looks at either.
impl<T: IntoValue, E: Into<Failure> + std::fmt::Debug> IntoOutcome for Result<T, E> {
    fn into_outcome(self) -> Result<Value, Failure> {
        Ok(match self {
            Ok(v) => Value::variant("Result", "Ok", vec![v.into_value()]),
            Err(e) => {
                let debug = format!("{e:?}");
                let failure = e.into();
                Value::variant(
                    "Result",
                    "Err",
                    vec![Value::Error(Arc::new(crate::value::ErrorValue {
                        failure,
                        debug,
                    }))],
                )
            }
        })
    }
}

impl IntoValue for Value {
    fn into_value(self) -> Value {
        self
    }
}

impl FromValue for Value {
    fn expected() -> String {
        "any value".into()
    }
    fn from_value(v: &Value) -> Option<Self> {
        Some(v.clone())
    }
}

impl IntoValue for () {
    fn into_value(self) -> Value {
        Value::Unit
    }
}

impl FromValue for () {
    fn expected() -> String {
        "()".into()
    }
    fn from_value(v: &Value) -> Option<Self> {
        matches!(v, Value::Unit).then_some(())
    }
}

impl IntoValue for bool {
    fn into_value(self) -> Value {
        Value::Bool(self)
    }
}

impl FromValue for bool {
    fn expected() -> String {
        "bool".into()
    }
    fn from_value(v: &Value) -> Option<Self> {
        v.as_bool()
    }
}

macro_rules! ints {
    ($($t:ty),*) => {$(
        impl IntoValue for $t {
            fn into_value(self) -> Value {
                Value::Int(i64::try_from(self).unwrap_or(i64::MAX))
            }
        }
        impl FromValue for $t {
            fn expected() -> String {
                stringify!($t).into()
            }
            fn from_value(v: &Value) -> Option<Self> {
                v.as_int().and_then(|i| <$t>::try_from(i).ok())
            }
        }
    )*};
}

ints!(u8, u16, u32, u64, usize, i8, i16, i32, i64, isize);

impl IntoValue for f64 {
    fn into_value(self) -> Value {
        Value::Float(self)
    }
}

impl FromValue for f64 {
    fn expected() -> String {
        "f64".into()
    }
    fn from_value(v: &Value) -> Option<Self> {
        v.as_float()
    }
}

impl IntoValue for f32 {
    fn into_value(self) -> Value {
        Value::Float(f64::from(self))
    }
}

impl FromValue for f32 {
    fn expected() -> String {
        "f32".into()
    }
    #[allow(clippy::cast_possible_truncation, reason = "as Rust's `as f32`")]
    fn from_value(v: &Value) -> Option<Self> {
        v.as_float().map(|x| x as f32)
    }
}

impl IntoValue for String {
    fn into_value(self) -> Value {
        Value::str(self)
    }
}

impl IntoValue for &str {
    fn into_value(self) -> Value {
        Value::str(self)
    }
}

impl FromValue for String {
    fn expected() -> String {
        "String".into()
    }
    fn from_value(v: &Value) -> Option<Self> {
        v.as_str().map(str::to_string)
    }
}

impl IntoValue for Arc<str> {
    fn into_value(self) -> Value {
        Value::Str(self)
    }
}

impl FromValue for Arc<str> {
    fn expected() -> String {
        "String".into()
    }
    fn from_value(v: &Value) -> Option<Self> {
        match v {
            Value::Str(s) => Some(s.clone()),
            _ => None,
        }
    }
}

impl IntoValue for Duration {
    fn into_value(self) -> Value {
        Value::Duration(self)
    }
}

impl FromValue for Duration {
    fn expected() -> String {
        "Duration".into()
    }
    fn from_value(v: &Value) -> Option<Self> {
        match v {
            Value::Duration(d) => Some(*d),
            _ => None,
        }
    }
}

impl IntoValue for NodeId {
    fn into_value(self) -> Value {
        Value::Node(self)
    }
}

impl FromValue for NodeId {
    fn expected() -> String {
        "NodeId".into()
    }
    fn from_value(v: &Value) -> Option<Self> {
        match v {
            Value::Node(n) => Some(*n),
            _ => None,
        }
    }
}

impl FromValue for Ctx {
    fn expected() -> String {
        "the action's context (`&ctx`)".into()
    }
    fn from_value(v: &Value) -> Option<Self> {
        match v {
            Value::Ctx(ctx) => Some(ctx.clone()),
            _ => None,
        }
    }
}

impl IntoValue for Failure {
    fn into_value(self) -> Value {
        Value::Failure(Arc::new(self))
    }
}

impl FromValue for Failure {
    fn expected() -> String {
        "a failure".into()
    }
    fn from_value(v: &Value) -> Option<Self> {
        v.as_failure().cloned()
    }
}

impl<T: FromValue> FromValue for tdl::Ended<T> {
    fn expected() -> String {
        format!("Ended<{}>", T::expected())
    }
    fn from_value(v: &Value) -> Option<Self> {
        let Value::Variant(var) = v else { return None };
        if &*var.ty != "Ended" {
            return None;
        }
        Some(match &*var.name {
            "Succeeded" => tdl::Ended::Succeeded(T::from_value(var.fields.first()?)?),
            "Failed" => tdl::Ended::Failed(var.fields.first()?.as_failure()?.clone()),
            "Terminated" => tdl::Ended::Terminated,
            _ => tdl::Ended::Skipped,
        })
    }
}

impl<T: IntoValue> IntoValue for Vec<T> {
    fn into_value(self) -> Value {
        Value::list(self.into_iter().map(IntoValue::into_value))
    }
}

impl<T: FromValue> FromValue for Vec<T> {
    fn expected() -> String {
        format!("Vec<{}>", T::expected())
    }
    fn from_value(v: &Value) -> Option<Self> {
        match v {
            Value::List(items) => items.iter().map(T::from_value).collect(),
            _ => None,
        }
    }
}

impl<T: IntoValue> IntoValue for Option<T> {
    fn into_value(self) -> Value {
        Value::option(self.map(IntoValue::into_value))
    }
}

impl<T: FromValue> FromValue for Option<T> {
    fn expected() -> String {
        format!("Option<{}>", T::expected())
    }
    fn from_value(v: &Value) -> Option<Self> {
        match v {
            Value::Variant(var) if &*var.ty == "Option" => match var.fields.first() {
                Some(inner) => T::from_value(inner).map(Some),
                None => Some(None),
            },
            _ => None,
        }
    }
}

impl<T: IntoValue> IntoValue for BTreeMap<String, T> {
    fn into_value(self) -> Value {
        Value::Map(Arc::new(
            self.into_iter().map(|(k, v)| (k, v.into_value())).collect(),
        ))
    }
}

impl<T: FromValue> FromValue for BTreeMap<String, T> {
    fn expected() -> String {
        format!("BTreeMap<String, {}>", T::expected())
    }
    fn from_value(v: &Value) -> Option<Self> {
        match v {
            Value::Map(map) => map
                .iter()
                .map(|(k, v)| Some((k.clone(), T::from_value(v)?)))
                .collect(),
            _ => None,
        }
    }
}

impl IntoValue for serde_json::Value {
    fn into_value(self) -> Value {
        Value::from_json(&self)
    }
}

impl FromValue for serde_json::Value {
    fn expected() -> String {
        "a value with a JSON form".into()
    }
    fn from_value(v: &Value) -> Option<Self> {
        v.to_json().ok()
    }
}

macro_rules! tuples {
    ($(($($t:ident $i:tt),+)),*) => {$(
        impl<$($t: IntoValue),+> IntoValue for ($($t,)+) {
            fn into_value(self) -> Value {
                Value::tuple(vec![$(self.$i.into_value()),+])
            }
        }
        impl<$($t: FromValue),+> FromValue for ($($t,)+) {
            fn expected() -> String {
                let parts: Vec<String> = vec![$($t::expected()),+];
                format!("({})", parts.join(", "))
            }
            fn from_value(v: &Value) -> Option<Self> {
                match v {
                    Value::Tuple(items) | Value::List(items) => {
                        Some(($($t::from_value(items.get($i)?)?,)+))
                    }
                    _ => None,
                }
            }
        }
    )*};
}

tuples!((A 0, B 1), (A 0, B 1, C 2), (A 0, B 1, C 2, D 3));

/// A value of any Rust type, crossing into a program as a host value named by its type's short
/// name (`Walker` for `ambler::world::Walker`), printed as that name, and back out by
/// downcasting: for a registered function's parameters and results, from any crate. Register
/// the name too ([`Registry::host_type`](crate::Registry::host_type)) so that the program may
/// name the type.
#[derive(Clone, Debug)]
pub struct Host<T>(pub T);

impl<T: Clone + Send + Sync + 'static> IntoValue for Host<T> {
    fn into_value(self) -> Value {
        Value::opaque(short_name::<T>(), self.0)
    }
}

impl<T: Clone + Send + Sync + 'static> FromValue for Host<T> {
    fn expected() -> String {
        short_name::<T>().to_string()
    }
    fn from_value(v: &Value) -> Option<Self> {
        match v {
            Value::Host(h) => h.downcast::<T>().cloned().map(Host),
            // A failure carrying a `T` (an error a registered function returned).
            other => other
                .as_failure()
                .and_then(|f| f.data::<T>())
                .map(|t| Host((*t).clone())),
        }
    }
}

/// `Ok(v)`, as a value.
pub fn ok(v: impl IntoValue) -> Value {
    Value::variant("Result", "Ok", vec![v.into_value()])
}

/// `Err(e)` for an error of a type that is not a Rust error (an enum of error codes): the
/// failure `?` raises is named after the type, its message is its `Debug`, and it carries `e`
/// (so [`Host<E>`] reads it back, and a registered method of `E` takes it).
pub fn host_err<E: Clone + std::fmt::Debug + Send + Sync + 'static>(e: E) -> Value {
    let debug = format!("{e:?}");
    let mut failure = Failure::new(short_name::<E>(), debug.clone());
    failure.data = Some(Arc::new(e));
    Value::variant(
        "Result",
        "Err",
        vec![Value::Error(Arc::new(crate::value::ErrorValue {
            failure,
            debug,
        }))],
    )
}

/// The short name of a type: `Walker` for `ambler::world::Walker`.
pub(crate) fn short_name<T: ?Sized>() -> &'static str {
    let full = std::any::type_name::<T>();
    let base = full.split('<').next().unwrap_or(full);
    base.rsplit("::").next().unwrap_or(base)
}

/// Makes a Rust type of the user's a host type: its values cross into a program as host values
/// of that name (printed with its `Debug`, compared by identity), and back out by downcasting.
/// The type must be `Clone + Debug + Send + Sync + 'static`; register it too
/// ([`Registry::host_type`](crate::Registry::host_type)) so that the program may name it.
///
/// ```ignore
/// tdl_interp::host_type!(Robot);
/// ```
#[macro_export]
macro_rules! host_type {
    ($t:ty) => {
        $crate::host_type!($t, stringify!($t));
    };
    ($t:ty, $name:expr) => {
        impl $crate::IntoValue for $t {
            fn into_value(self) -> $crate::Value {
                $crate::Value::host($name, self)
            }
        }
        impl $crate::FromValue for $t {
            fn expected() -> ::std::string::String {
                ::std::string::String::from($name)
            }
            fn from_value(v: &$crate::Value) -> ::core::option::Option<Self> {
                match v {
                    $crate::Value::Host(h) => h.downcast::<$t>().cloned(),
                    _ => ::core::option::Option::None,
                }
            }
        }
    };
}
