//! The values an interpreted body computes with ([`Value`]): unit, booleans, integers, floats,
//! strings, lists, tuples, maps, records (an exception's data, a struct), enum variants (`Some`,
//! `None`, `Ok`, `Err`, `Ended::Succeeded`, a registered enum's), durations, nodes, the action's
//! context, and values of Rust types registered as host types ([`Host`]), which the program
//! passes around without looking inside.
//!
//! Every value prints as Rust's `Debug` prints the compiled program's value ([`Value::debug`]),
//! so that a failure's message (an exception's `Debug`) is the same text in both, and as Rust's
//! `Display` for string formatting.

use std::any::Any;
use std::collections::BTreeMap;
use std::fmt::{self, Write as _};
use std::sync::Arc;
use std::time::Duration;

use crate::ty::Ty;
use tdl::{Ctx, NodeId};

/// A value of an interpreted body.
#[derive(Clone, Default)]
pub enum Value {
    /// `()`.
    #[default]
    Unit,
    /// A boolean.
    Bool(bool),
    /// An integer of any Rust integer type.
    Int(i64),
    /// A float (`f32` or `f64`).
    Float(f64),
    /// A string (`String` or `&str`).
    Str(Arc<str>),
    /// A list (`Vec<T>`, a slice, an array).
    List(Arc<Vec<Value>>),
    /// A tuple.
    Tuple(Arc<Vec<Value>>),
    /// A map with string keys (a JSON object).
    Map(Arc<BTreeMap<String, Value>>),
    /// A record: a struct value with named fields (an exception's data).
    Record(Arc<Record>),
    /// An enum variant: `Some(x)`, `None`, `Ok(x)`, `Err(e)`, `Ended::Failed(f)`, ...
    Variant(Arc<Variant>),
    /// A `std::time::Duration`.
    Duration(Duration),
    /// A node of the run.
    Node(NodeId),
    /// The action's context (`ctx`), for functions that take it.
    Ctx(Ctx),
    /// A failure: an exception caught or a child's.
    Failure(Arc<tdl::Failure>),
    /// The error a registered function returned (`Err(e)`), as a failure that prints as the
    /// error's `Debug`.
    Error(Arc<ErrorValue>),
    /// A value of a host type: a Rust value the program holds without looking inside.
    Host(HostValue),
}

/// A struct value: its type's name and its fields in order.
#[derive(Clone, Debug)]
pub struct Record {
    /// The type's name.
    pub name: Arc<str>,
    /// The fields, in declaration order.
    pub fields: Vec<(Arc<str>, Value)>,
}

impl Record {
    /// The field `name`.
    pub fn field(&self, name: &str) -> Option<&Value> {
        self.fields
            .iter()
            .find(|(n, _)| &**n == name)
            .map(|(_, v)| v)
    }
}

/// An enum variant: its enum's name (`Option`, `Result`, `Ended`, a registered enum), its own
/// and its fields.
#[derive(Clone, Debug)]
pub struct Variant {
    /// The enum.
    pub ty: Arc<str>,
    /// The variant.
    pub name: Arc<str>,
    /// Its fields, in order.
    pub fields: Vec<Value>,
}

/// The error a registered function returned: the failure it makes, and its `Debug`.
#[derive(Clone, Debug)]
pub struct ErrorValue {
    /// The failure (`Failure::from(e)`: the error's type name, its text, the error as data).
    pub failure: tdl::Failure,
    /// How the error prints with `{:?}`.
    pub debug: String,
}

/// A value of a Rust type the program does not look inside: its type's name and the value.
#[derive(Clone)]
pub struct HostValue {
    /// The registered name of its type.
    pub ty: Arc<str>,
    /// The value.
    pub value: Arc<dyn Any + Send + Sync>,
    /// How it prints with `{:?}`.
    pub debug: fn(&(dyn Any + Send + Sync), &mut fmt::Formatter<'_>) -> fmt::Result,
}

impl HostValue {
    /// The value, if it is a `T`.
    pub fn downcast<T: Any + Send + Sync>(&self) -> Option<&T> {
        self.value.downcast_ref::<T>()
    }
}

impl fmt::Debug for Value {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Value::Unit => f.write_str("()"),
            Value::Bool(b) => fmt::Debug::fmt(b, f),
            Value::Int(i) => fmt::Debug::fmt(i, f),
            Value::Float(x) => fmt::Debug::fmt(x, f),
            Value::Str(s) => fmt::Debug::fmt(&**s, f),
            Value::List(items) => f.debug_list().entries(items.iter()).finish(),
            Value::Tuple(items) => {
                let mut t = f.debug_tuple("");
                for it in items.iter() {
                    t.field(it);
                }
                t.finish()
            }
            Value::Map(map) => f.debug_map().entries(map.iter()).finish(),
            Value::Record(r) => {
                if r.fields.is_empty() {
                    return f.write_str(&r.name);
                }
                let mut s = f.debug_struct(&r.name);
                for (name, value) in &r.fields {
                    s.field(name, value);
                }
                s.finish()
            }
            Value::Variant(v) => {
                if v.fields.is_empty() {
                    return f.write_str(&v.name);
                }
                let mut t = f.debug_tuple(&v.name);
                for it in &v.fields {
                    t.field(it);
                }
                t.finish()
            }
            Value::Duration(d) => fmt::Debug::fmt(d, f),
            Value::Node(n) => fmt::Debug::fmt(n, f),
            Value::Ctx(_) => f.write_str("Ctx"),
            Value::Failure(failure) => fmt::Debug::fmt(&**failure, f),
            Value::Error(e) => f.write_str(&e.debug),
            Value::Host(h) => (h.debug)(&*h.value, f),
        }
    }
}

impl fmt::Display for Value {
    /// As Rust's `Display` of the compiled value: strings without quotes, numbers as they are;
    /// values with no `Display` in Rust print as `Debug`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Value::Str(s) => fmt::Display::fmt(&**s, f),
            Value::Int(i) => fmt::Display::fmt(i, f),
            Value::Float(x) => fmt::Display::fmt(x, f),
            Value::Bool(b) => fmt::Display::fmt(b, f),
            Value::Failure(failure) => fmt::Display::fmt(&**failure, f),
            Value::Error(e) => f.write_str(&e.failure.message),
            other => fmt::Debug::fmt(other, f),
        }
    }
}

/// Values compare as Rust's `==` compares them; a host value equals only itself.
impl PartialEq for Value {
    fn eq(&self, other: &Value) -> bool {
        match (self, other) {
            (Value::Unit, Value::Unit) => true,
            (Value::Bool(a), Value::Bool(b)) => a == b,
            (Value::Int(a), Value::Int(b)) => a == b,
            (Value::Float(a), Value::Float(b)) => a == b,
            #[allow(clippy::cast_precision_loss, reason = "as Rust's `as f64`")]
            (Value::Int(a), Value::Float(b)) | (Value::Float(b), Value::Int(a)) => *a as f64 == *b,
            (Value::Str(a), Value::Str(b)) => a == b,
            (Value::List(a), Value::List(b)) | (Value::Tuple(a), Value::Tuple(b)) => a == b,
            (Value::Map(a), Value::Map(b)) => a == b,
            (Value::Record(a), Value::Record(b)) => {
                a.name == b.name
                    && a.fields.len() == b.fields.len()
                    && a.fields.iter().zip(&b.fields).all(|(x, y)| x == y)
            }
            (Value::Variant(a), Value::Variant(b)) => {
                a.name == b.name && a.ty == b.ty && a.fields == b.fields
            }
            (Value::Duration(a), Value::Duration(b)) => a == b,
            (Value::Node(a), Value::Node(b)) => a == b,
            (Value::Failure(a), Value::Failure(b)) => a == b,
            (Value::Error(a), Value::Error(b)) => a.failure == b.failure,
            (Value::Host(a), Value::Host(b)) => Arc::ptr_eq(&a.value, &b.value),
            _ => false,
        }
    }
}

impl Value {
    /// A string value.
    pub fn str(s: impl AsRef<str>) -> Value {
        Value::Str(Arc::from(s.as_ref()))
    }

    /// A list value.
    pub fn list(items: impl IntoIterator<Item = Value>) -> Value {
        Value::List(Arc::new(items.into_iter().collect()))
    }

    /// A tuple value; the empty tuple is `()`.
    pub fn tuple(items: Vec<Value>) -> Value {
        if items.is_empty() {
            Value::Unit
        } else {
            Value::Tuple(Arc::new(items))
        }
    }

    /// A variant of the enum `ty`.
    pub fn variant(ty: &str, name: &str, fields: Vec<Value>) -> Value {
        Value::Variant(Arc::new(Variant {
            ty: Arc::from(ty),
            name: Arc::from(name),
            fields,
        }))
    }

    /// `Some(v)`.
    pub fn some(v: Value) -> Value {
        Value::variant("Option", "Some", vec![v])
    }

    /// `None`.
    pub fn none() -> Value {
        Value::variant("Option", "None", Vec::new())
    }

    /// `Some(v)` or `None`.
    pub fn option(v: Option<Value>) -> Value {
        v.map_or_else(Value::none, Value::some)
    }

    /// A value of a host type, printed with its `Debug`.
    pub fn host<T: Any + Send + Sync + fmt::Debug>(ty: &str, value: T) -> Value {
        fn debug<T: Any + fmt::Debug>(
            v: &(dyn Any + Send + Sync),
            f: &mut fmt::Formatter<'_>,
        ) -> fmt::Result {
            match v.downcast_ref::<T>() {
                Some(v) => fmt::Debug::fmt(v, f),
                None => f.write_str("<host value>"),
            }
        }
        Value::Host(HostValue {
            ty: Arc::from(ty),
            value: Arc::new(value),
            debug: debug::<T>,
        })
    }

    /// A value of a host type without `Debug`: it prints as its type's name.
    pub fn opaque<T: Any + Send + Sync>(ty: &str, value: T) -> Value {
        fn name(v: &(dyn Any + Send + Sync), f: &mut fmt::Formatter<'_>) -> fmt::Result {
            let _ = v;
            f.write_str("<host value>")
        }
        Value::Host(HostValue {
            ty: Arc::from(ty),
            value: Arc::new(value),
            debug: name,
        })
    }

    /// What kind of value it is, for messages: `int`, `string`, `Mission`, ...
    pub fn kind(&self) -> String {
        match self {
            Value::Unit => "()".into(),
            Value::Bool(_) => "bool".into(),
            Value::Int(_) => "integer".into(),
            Value::Float(_) => "float".into(),
            Value::Str(_) => "string".into(),
            Value::List(_) => "list".into(),
            Value::Tuple(_) => "tuple".into(),
            Value::Map(_) => "map".into(),
            Value::Record(r) => r.name.to_string(),
            Value::Variant(v) => format!("{}::{}", v.ty, v.name),
            Value::Duration(_) => "Duration".into(),
            Value::Node(_) => "NodeId".into(),
            Value::Ctx(_) => "Ctx".into(),
            Value::Failure(f) => f.exception.to_string(),
            Value::Error(e) => e.failure.exception.to_string(),
            Value::Host(h) => h.ty.to_string(),
        }
    }

    /// The value as `{:?}` prints it.
    pub fn debug(&self) -> String {
        let mut out = String::new();
        let _ = write!(out, "{self:?}");
        out
    }

    /// The failure a failure or an error value is.
    pub fn as_failure(&self) -> Option<&tdl::Failure> {
        match self {
            Value::Failure(f) => Some(f),
            Value::Error(e) => Some(&e.failure),
            _ => None,
        }
    }

    /// The value as a boolean, if it is one.
    pub fn as_bool(&self) -> Option<bool> {
        match self {
            Value::Bool(b) => Some(*b),
            _ => None,
        }
    }

    /// The value as an integer, if it is one.
    pub fn as_int(&self) -> Option<i64> {
        match self {
            Value::Int(i) => Some(*i),
            _ => None,
        }
    }

    /// The value as a float: a float, or an integer converted.
    pub fn as_float(&self) -> Option<f64> {
        match self {
            Value::Float(x) => Some(*x),
            #[allow(clippy::cast_precision_loss, reason = "as Rust's `f64::from`")]
            Value::Int(i) => Some(*i as f64),
            _ => None,
        }
    }

    /// The value as a string, if it is one.
    pub fn as_str(&self) -> Option<&str> {
        match self {
            Value::Str(s) => Some(s),
            _ => None,
        }
    }

    /// The value as a JSON value: what crosses to an agent, or comes back from one. Host values,
    /// contexts and failures have no JSON form.
    pub fn to_json(&self) -> Result<serde_json::Value, String> {
        use serde_json::Value as J;
        Ok(match self {
            Value::Unit => J::Null,
            Value::Bool(b) => J::Bool(*b),
            Value::Int(i) => J::from(*i),
            Value::Float(x) => serde_json::Number::from_f64(*x)
                .map(J::Number)
                .ok_or_else(|| format!("the float {x} has no JSON form"))?,
            Value::Str(s) => J::String(s.to_string()),
            Value::List(items) | Value::Tuple(items) => {
                J::Array(items.iter().map(Value::to_json).collect::<Result<_, _>>()?)
            }
            Value::Map(map) => J::Object(
                map.iter()
                    .map(|(k, v)| Ok((k.clone(), v.to_json()?)))
                    .collect::<Result<_, String>>()?,
            ),
            Value::Record(r) => J::Object(
                r.fields
                    .iter()
                    .map(|(k, v)| Ok((k.to_string(), v.to_json()?)))
                    .collect::<Result<_, String>>()?,
            ),
            Value::Variant(v) if &*v.ty == "Option" => match v.fields.first() {
                Some(inner) => inner.to_json()?,
                None => J::Null,
            },
            Value::Variant(v) => match v.fields.as_slice() {
                [] => J::String(v.name.to_string()),
                [one] => J::Object([(v.name.to_string(), one.to_json()?)].into_iter().collect()),
                many => J::Object(
                    [(
                        v.name.to_string(),
                        J::Array(many.iter().map(Value::to_json).collect::<Result<_, _>>()?),
                    )]
                    .into_iter()
                    .collect(),
                ),
            },
            Value::Duration(d) => J::from(d.as_secs_f64()),
            Value::Node(_)
            | Value::Ctx(_)
            | Value::Failure(_)
            | Value::Error(_)
            | Value::Host(_) => {
                return Err(format!("a {} has no JSON form", self.kind()));
            }
        })
    }

    /// A value read from JSON, without a type to say more: numbers with no fraction are
    /// integers, objects maps, `null` unit.
    pub fn from_json(json: &serde_json::Value) -> Value {
        use serde_json::Value as J;
        match json {
            J::Null => Value::Unit,
            J::Bool(b) => Value::Bool(*b),
            J::Number(n) => match n.as_i64() {
                Some(i) => Value::Int(i),
                None => Value::Float(n.as_f64().unwrap_or(f64::NAN)),
            },
            J::String(s) => Value::str(s),
            J::Array(items) => Value::list(items.iter().map(Value::from_json)),
            J::Object(map) => Value::Map(Arc::new(
                map.iter()
                    .map(|(k, v)| (k.clone(), Value::from_json(v)))
                    .collect(),
            )),
        }
    }
}

/// The arguments of an interpreted goal or command, kept beside its node (`Task::with_args`): a
/// handler's `retry with` replaces them, wiretap checks and attached handlers read them. With
/// their parameters (names and types), when known, for the node's `spawned` record
/// ([`Args::describe`]).
#[derive(Clone, Debug, Default)]
pub struct Args(pub Vec<Value>, pub(crate) Option<Params>);

/// A task's parameters, names and declared types, in order.
pub(crate) type Params = Arc<[(Arc<str>, Ty)]>;

impl Args {
    /// The arguments as a node's `spawned` record tells them, `name = value, …`, each value as
    /// the compiled program's `tdl::ShowArg` shows it, by the parameter's declared type: a
    /// bool, number, string, duration, unit, or an option or list of those, as Rust's `Debug`
    /// prints them (a list cut after `tdl::SHOWN_ITEMS` items); a value of another type as `…`
    /// (so a host type the compiled program shows with its own `ShowArg` shows as `…` here).
    /// `None` without the parameters (a `retry with`'s).
    pub fn describe(args: &(dyn std::any::Any + Send + Sync)) -> Option<String> {
        let args = args.downcast_ref::<Args>()?;
        let params = args.1.as_ref()?;
        let mut out = String::new();
        for (i, ((name, ty), value)) in params.iter().zip(&args.0).enumerate() {
            if i > 0 {
                out.push_str(", ");
            }
            out.push_str(name);
            out.push_str(" = ");
            if shown(ty) {
                show(value, &mut out);
            } else {
                out.push('…');
            }
        }
        Some(out)
    }
}

/// Whether the compiled program's `tdl::ShowArg` shows values of `ty`.
fn shown(ty: &Ty) -> bool {
    match ty {
        Ty::Unit | Ty::Bool | Ty::Int { .. } | Ty::Float | Ty::Str | Ty::Duration => true,
        Ty::List(t) | Ty::Option(t) => shown(t),
        _ => false,
    }
}

/// A value of a shown type as `tdl::ShowArg` shows the compiled one (see [`Args::describe`]).
fn show(value: &Value, out: &mut String) {
    match value {
        Value::Unit
        | Value::Bool(_)
        | Value::Int(_)
        | Value::Float(_)
        | Value::Str(_)
        | Value::Duration(_) => {
            let _ = write!(out, "{value:?}");
        }
        Value::List(items) => {
            out.push('[');
            for (i, it) in items.iter().take(tdl::SHOWN_ITEMS).enumerate() {
                if i > 0 {
                    out.push_str(", ");
                }
                show(it, out);
            }
            if items.len() > tdl::SHOWN_ITEMS {
                out.push_str(", …");
            }
            out.push(']');
        }
        Value::Variant(v) if &*v.ty == "Option" && v.fields.is_empty() => out.push_str("None"),
        Value::Variant(v) if &*v.ty == "Option" && v.fields.len() == 1 => {
            out.push_str("Some(");
            show(&v.fields[0], out);
            out.push(')');
        }
        _ => out.push('…'),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_print_as_rust_prints_the_compiled_ones() {
        let rec = Value::Record(Arc::new(Record {
            name: Arc::from("DoorLocked"),
            fields: vec![
                (Arc::from("room"), Value::Int(1)),
                (Arc::from("height"), Value::Float(1.0)),
                (Arc::from("why"), Value::str("stuck")),
            ],
        }));
        assert_eq!(
            rec.debug(),
            format!(
                "{:?}",
                DoorLocked {
                    room: 1,
                    height: 1.0,
                    why: "stuck".into()
                }
            )
        );
        let unit = Value::Record(Arc::new(Record {
            name: Arc::from("Blocked"),
            fields: Vec::new(),
        }));
        assert_eq!(unit.debug(), format!("{:?}", Blocked {}));
        assert_eq!(Value::some(Value::Int(3)).debug(), format!("{:?}", Some(3)));
        assert_eq!(
            Value::list([Value::Float(0.5), Value::Float(2.0)]).debug(),
            format!("{:?}", vec![0.5, 2.0])
        );
        assert_eq!(
            Value::tuple(vec![Value::Int(1), Value::str("a")]).debug(),
            format!("{:?}", (1, "a"))
        );
        assert_eq!(Value::str("a\"b").to_string(), "a\"b");
    }

    #[allow(dead_code)]
    #[derive(Debug)]
    struct DoorLocked {
        room: u32,
        height: f64,
        why: String,
    }

    #[derive(Debug)]
    struct Blocked {}

    #[test]
    fn json_round_trips_plain_values() {
        let v = Value::list([
            Value::Int(1),
            Value::Float(1.5),
            Value::str("x"),
            Value::Bool(true),
        ]);
        let json = v.to_json().expect("has a JSON form");
        assert_eq!(Value::from_json(&json), v);
        assert!(Value::host("Robot", 1_u8).to_json().is_err());
    }
}
