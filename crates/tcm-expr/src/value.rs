//! Values of state variables and expressions, and their types.

use serde::{Deserialize, Serialize};
use std::fmt;

/// The type of a state variable or an expression.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "snake_case")]
pub enum Type {
    /// `bool`: `true` or `false`.
    Bool,
    /// `int`: a signed 64-bit integer.
    Int,
    /// `float`: a finite 64-bit floating-point number.
    Float,
    /// `string`: text.
    Str,
}

impl Type {
    /// The type's name in TDL: `bool`, `int`, `float`, `string`.
    pub fn name(self) -> &'static str {
        match self {
            Type::Bool => "bool",
            Type::Int => "int",
            Type::Float => "float",
            Type::Str => "string",
        }
    }

    /// The type TDL names `name` (also the Rust spellings `i64`, `f64`, `String`).
    pub fn from_name(name: &str) -> Option<Type> {
        Some(match name {
            "bool" => Type::Bool,
            "int" | "i64" => Type::Int,
            "float" | "f64" => Type::Float,
            "string" | "String" | "str" => Type::Str,
            _ => return None,
        })
    }

    /// Whether `Int` and `Float` (numbers, compared and added with each other).
    pub fn is_number(self) -> bool {
        matches!(self, Type::Int | Type::Float)
    }
}

impl fmt::Display for Type {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A value: of a state variable, a literal, or what an expression evaluates to.
///
/// `Unknown` is a value of every type: a variable not yet measured (a position before the first
/// fix), or what an expression over one gives (docs/semantics.md, "State and conditions"). A
/// condition holds only when it evaluates to `true`; `unknown` does not hold, and its negation does
/// not hold either. Floats are finite: an operation whose result is not (a division by zero, an
/// overflow) gives `Unknown`.
///
/// In JSON a value is itself: `null` for unknown, `true`, `42`, `1.5`, `"text"`. A float always
/// carries a fraction or an exponent (`2.0`), so it reads back as a float.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(untagged)]
pub enum Value {
    /// Not known.
    #[default]
    Unknown,
    /// A boolean.
    Bool(bool),
    /// An integer.
    Int(i64),
    /// A finite float.
    Float(f64),
    /// Text.
    Str(String),
}

impl Value {
    /// A float value, `Unknown` if `x` is not finite.
    pub fn float(x: f64) -> Value {
        if x.is_finite() {
            Value::Float(x)
        } else {
            Value::Unknown
        }
    }

    /// Its type (`None` for `Unknown`, which has every type).
    pub fn type_of(&self) -> Option<Type> {
        match self {
            Value::Unknown => None,
            Value::Bool(_) => Some(Type::Bool),
            Value::Int(_) => Some(Type::Int),
            Value::Float(_) => Some(Type::Float),
            Value::Str(_) => Some(Type::Str),
        }
    }

    /// Whether it is known.
    pub fn is_known(&self) -> bool {
        !matches!(self, Value::Unknown)
    }

    /// Whether it is `true` (the only value for which a condition holds).
    pub fn is_true(&self) -> bool {
        matches!(self, Value::Bool(true))
    }

    /// This value as a value of type `ty`: an integer becomes a float, `Unknown` stays; any other
    /// mismatch is an error naming both types.
    pub fn coerce(self, ty: Type) -> Result<Value, TypeMismatch> {
        match (self, ty) {
            (Value::Unknown, _) => Ok(Value::Unknown),
            (Value::Int(i), Type::Float) => Ok(Value::float(i as f64)),
            (v, ty) if v.type_of() == Some(ty) => Ok(v),
            (v, ty) => Err(TypeMismatch {
                expected: ty,
                found: v.type_of().unwrap_or(ty),
                value: v.to_string(),
            }),
        }
    }

    /// The value as a float, for a number.
    pub(crate) fn as_f64(&self) -> Option<f64> {
        match *self {
            Value::Int(i) => Some(i as f64),
            Value::Float(x) => Some(x),
            _ => None,
        }
    }
}

/// A value given where another type was expected.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("expected a value of type `{expected}`, found `{value}` of type `{found}`")]
pub struct TypeMismatch {
    /// The type expected.
    pub expected: Type,
    /// The type found.
    pub found: Type,
    /// The value, as TDL writes it.
    pub value: String,
}

/// Values are equal when they are the same value of the same type (`1` and `1.0` differ here; the
/// expression `1 == 1.0` is true). Floats compare by their bits, so `Eq` holds.
impl PartialEq for Value {
    fn eq(&self, other: &Value) -> bool {
        match (self, other) {
            (Value::Unknown, Value::Unknown) => true,
            (Value::Bool(a), Value::Bool(b)) => a == b,
            (Value::Int(a), Value::Int(b)) => a == b,
            (Value::Float(a), Value::Float(b)) => a.to_bits() == b.to_bits(),
            (Value::Str(a), Value::Str(b)) => a == b,
            _ => false,
        }
    }
}

impl Eq for Value {}

impl From<bool> for Value {
    fn from(b: bool) -> Value {
        Value::Bool(b)
    }
}

impl From<i64> for Value {
    fn from(i: i64) -> Value {
        Value::Int(i)
    }
}

impl From<i32> for Value {
    fn from(i: i32) -> Value {
        Value::Int(i64::from(i))
    }
}

impl From<f64> for Value {
    fn from(x: f64) -> Value {
        Value::float(x)
    }
}

impl From<&str> for Value {
    fn from(s: &str) -> Value {
        Value::Str(s.to_string())
    }
}

impl From<String> for Value {
    fn from(s: String) -> Value {
        Value::Str(s)
    }
}

impl<T: Into<Value>> From<Option<T>> for Value {
    /// `None` is `Unknown`.
    fn from(v: Option<T>) -> Value {
        v.map_or(Value::Unknown, Into::into)
    }
}

/// As TDL writes it: `unknown`, `true`, `42`, `1.5` (always with a fraction or an exponent),
/// `"text"` (quoted, escaped as in Rust).
impl fmt::Display for Value {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Value::Unknown => f.write_str("unknown"),
            Value::Bool(b) => write!(f, "{b}"),
            Value::Int(i) => write!(f, "{i}"),
            Value::Float(x) => write!(f, "{x:?}"),
            Value::Str(s) => write!(f, "{s:?}"),
        }
    }
}
