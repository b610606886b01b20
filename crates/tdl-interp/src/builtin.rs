//! What the interpreter offers of its own, without a registry: the functions a body commonly
//! calls (`Some`, `Ok`, `Err`, `f64::from`, `String::from`, `Duration::from_secs` and its
//! siblings, `tokio::time::sleep`, `std::cmp::max`), constants (`None`, `f64::MAX`, `PI`, ...),
//! and the methods of plain values (numbers, strings, lists, options, results, durations,
//! failures, how a child ended) and of `ctx`. Methods that take a closure (`map`, `filter`,
//! `is_some_and`, ...) are evaluated by `eval.rs`, which can run the closure.

use std::sync::Arc;
use std::time::Duration;

use tdl::{Ctx, Failure};

use crate::registry::Call;
use crate::value::Value;

/// A function of the interpreter's own.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Builtin {
    Some,
    Ok,
    Err,
    ToFloat,
    ToInt,
    ToStr,
    DurSecs,
    DurMillis,
    DurMicros,
    DurNanos,
    DurSecsF64,
    Sleep,
    Identity,
    EmptyList,
    EmptyStr,
    Max,
    Min,
}

/// The built-in function `path` of `arity` arguments, if there is one.
pub(crate) fn function(path: &str, arity: usize) -> Option<Builtin> {
    let last2: Vec<&str> = path.rsplit("::").take(2).collect();
    let short = match last2.as_slice() {
        [f, ty] => format!("{ty}::{f}"),
        [f] => (*f).to_string(),
        _ => return None,
    };
    let b = match (short.as_str(), arity) {
        ("Some", 1) => Builtin::Some,
        ("Ok", 1) => Builtin::Ok,
        ("Err", 1) => Builtin::Err,
        ("f64::from" | "f32::from", 1) => Builtin::ToFloat,
        (
            "i64::from" | "i32::from" | "i16::from" | "i8::from" | "u64::from" | "u32::from"
            | "u16::from" | "u8::from" | "usize::from" | "isize::from",
            1,
        ) => Builtin::ToInt,
        ("String::from" | "str::to_string", 1) => Builtin::ToStr,
        ("Duration::from_secs", 1) => Builtin::DurSecs,
        ("Duration::from_millis", 1) => Builtin::DurMillis,
        ("Duration::from_micros", 1) => Builtin::DurMicros,
        ("Duration::from_nanos", 1) => Builtin::DurNanos,
        ("Duration::from_secs_f64" | "Duration::from_secs_f32", 1) => Builtin::DurSecsF64,
        ("time::sleep", 1) if path.starts_with("tokio::") => Builtin::Sleep,
        ("Box::new" | "Arc::new" | "Rc::new", 1) => Builtin::Identity,
        ("Vec::new", 0) => Builtin::EmptyList,
        ("String::new", 0) => Builtin::EmptyStr,
        ("cmp::max", 2) => Builtin::Max,
        ("cmp::min", 2) => Builtin::Min,
        _ => return None,
    };
    Some(b)
}

/// A constant of the interpreter's own, by its path.
pub(crate) fn constant(path: &str) -> Option<Value> {
    let last2: Vec<&str> = path.rsplit("::").take(2).collect();
    let short = match last2.as_slice() {
        [c, ty] => format!("{ty}::{c}"),
        [c] => (*c).to_string(),
        _ => return None,
    };
    Some(match short.as_str() {
        "None" => Value::none(),
        "f64::MAX" => Value::Float(f64::MAX),
        "f64::MIN" => Value::Float(f64::MIN),
        "f64::INFINITY" => Value::Float(f64::INFINITY),
        "f64::NEG_INFINITY" => Value::Float(f64::NEG_INFINITY),
        "f64::EPSILON" => Value::Float(f64::EPSILON),
        "consts::PI" => Value::Float(std::f64::consts::PI),
        "consts::TAU" => Value::Float(std::f64::consts::TAU),
        "Duration::ZERO" => Value::Duration(Duration::ZERO),
        "Duration::MAX" => Value::Duration(Duration::MAX),
        other => {
            let (ty, c) = other.split_once("::")?;
            let int = crate::ty::Ty::int(ty)?;
            let crate::ty::Ty::Int { min, max, .. } = int else {
                return None;
            };
            let v = match c {
                "MAX" => max,
                "MIN" => min,
                _ => return None,
            };
            Value::Int(i64::try_from(v).unwrap_or(i64::MAX))
        }
    })
}

/// Whether `name` is a method the interpreter knows on some value.
pub(crate) fn is_method(name: &str) -> bool {
    METHODS.contains(&name) || CLOSURE_METHODS.contains(&name) || CTX_METHODS.contains(&name)
}

/// Methods that take a closure, evaluated by `eval.rs`.
pub(crate) const CLOSURE_METHODS: &[&str] = &[
    "map",
    "filter",
    "any",
    "all",
    "find",
    "position",
    "is_some_and",
    "is_none_or",
    "map_or",
    "map_or_else",
    "and_then",
    "unwrap_or_else",
    "filter_map",
    "for_each",
];

const METHODS: &[&str] = &[
    "clone",
    "to_owned",
    "to_string",
    "into",
    "as_ref",
    "as_deref",
    "as_str",
    "iter",
    "into_iter",
    "copied",
    "cloned",
    "collect",
    "abs",
    "min",
    "max",
    "pow",
    "powi",
    "powf",
    "sqrt",
    "floor",
    "ceil",
    "round",
    "trunc",
    "signum",
    "clamp",
    "is_nan",
    "is_finite",
    "len",
    "is_empty",
    "contains",
    "starts_with",
    "ends_with",
    "to_uppercase",
    "to_lowercase",
    "trim",
    "first",
    "last",
    "get",
    "join",
    "sum",
    "rev",
    "enumerate",
    "count",
    "is_some",
    "is_none",
    "unwrap",
    "expect",
    "unwrap_or",
    "unwrap_or_default",
    "ok",
    "err",
    "is_ok",
    "is_err",
    "ok_or",
    "as_secs_f64",
    "as_secs",
    "as_millis",
    "mul_f64",
    "name",
    "message",
    "exception",
    "data",
    "downcast",
    "is",
    "failure",
    "succeeded",
    "failed",
    "terminated",
    "skipped",
    "value",
    "is_a",
    "push",
    "pop",
    "insert",
    "remove",
    "clear",
    "sin",
    "cos",
    "atan2",
    "hypot",
    "to_degrees",
    "to_radians",
    "saturating_sub",
    "checked_sub",
    "zip",
];

const CTX_METHODS: &[&str] = &[
    "sleep",
    "node",
    "parent",
    "now",
    "reserve_resource",
    "unreserve_resource",
    "lock_resource",
    "unlock_resource",
    "terminate",
    "raise",
    "warn",
    "log",
    "is_cancelled",
    "activation",
    "placed",
];

/// A call of a built-in function.
pub(crate) fn call(b: Builtin, args: Vec<Value>) -> Call {
    let mut args = args.into_iter();
    let a = args.next().unwrap_or_default();
    let r = match b {
        Builtin::Some => Ok(Value::some(a)),
        Builtin::Ok => Ok(Value::variant("Result", "Ok", vec![a])),
        Builtin::Err => Ok(Value::variant("Result", "Err", vec![a])),
        Builtin::ToFloat => a
            .as_float()
            .map(Value::Float)
            .ok_or_else(|| bad("f64::from", &a)),
        Builtin::ToInt => match &a {
            Value::Int(_) => Ok(a),
            Value::Bool(b) => Ok(Value::Int(i64::from(*b))),
            _ => Err(bad("an integer conversion", &a)),
        },
        Builtin::ToStr => match &a {
            Value::Str(_) => Ok(a),
            other => Ok(Value::str(other.to_string())),
        },
        Builtin::DurSecs => int_dur(&a, Duration::from_secs),
        Builtin::DurMillis => int_dur(&a, Duration::from_millis),
        Builtin::DurMicros => int_dur(&a, Duration::from_micros),
        Builtin::DurNanos => int_dur(&a, Duration::from_nanos),
        Builtin::DurSecsF64 => match a.as_float() {
            Some(x) if x >= 0.0 && x.is_finite() => Ok(Value::Duration(Duration::from_secs_f64(x))),
            _ => Err(bad("Duration::from_secs_f64", &a)),
        },
        Builtin::Sleep => match a {
            Value::Duration(d) => {
                return Call::Pending(Box::pin(async move {
                    tokio::time::sleep(d).await;
                    Ok(Value::Unit)
                }));
            }
            other => Err(bad("tokio::time::sleep", &other)),
        },
        Builtin::Identity => Ok(a),
        Builtin::EmptyList => Ok(Value::list([])),
        Builtin::EmptyStr => Ok(Value::str("")),
        Builtin::Max | Builtin::Min => {
            let b2 = args.next().unwrap_or_default();
            let less = crate::eval::compare(&a, &b2).map(|o| o.is_lt());
            match less {
                Ok(less) => Ok(if less == (b == Builtin::Max) { b2 } else { a }),
                Err(e) => Err(e),
            }
        }
    };
    Call::Ready(r)
}

fn int_dur(a: &Value, f: fn(u64) -> Duration) -> Result<Value, Failure> {
    match a {
        Value::Int(i) if *i >= 0 => Ok(Value::Duration(f(i.unsigned_abs()))),
        other => Err(bad("a duration of whole units", other)),
    }
}

/// The failure of a value of the wrong kind.
pub(crate) fn bad(what: &str, v: &Value) -> Failure {
    Failure::new(
        "TypeMismatch",
        format!("{what}: unexpected {} `{v:?}`", v.kind()),
    )
}

/// A method of `ctx`.
pub(crate) fn ctx_method(ctx: &Ctx, name: &str, args: &[Value]) -> Option<Call> {
    let arg = |i: usize| args.get(i).cloned().unwrap_or_default();
    let node = |v: Value| match v {
        Value::Node(n) => Ok(n),
        other => Err(bad(&format!("ctx.{name}"), &other)),
    };
    let res = |v: &Value| match v {
        Value::Str(s) => Ok(s.to_string()),
        other => Err(bad(&format!("ctx.{name}"), other)),
    };
    // What returns a `Result` in Rust is a `Result` value here: `?` takes it apart.
    let result = |r: Result<Value, tdl::Error>| match r {
        Ok(v) => Ok(Value::variant("Result", "Ok", vec![v])),
        Err(e) => Ok(Value::variant(
            "Result",
            "Err",
            vec![Value::Failure(Arc::new(Failure::from(e)))],
        )),
    };
    let done = |r: Result<(), tdl::Error>| result(r.map(|()| Value::Unit));
    let r: Result<Value, Failure> = match name {
        "sleep" => {
            let ctx = ctx.clone();
            return Some(match arg(0) {
                Value::Duration(d) => Call::Pending(Box::pin(async move {
                    ctx.sleep(d).await;
                    Ok(Value::Unit)
                })),
                other => Call::Ready(Err(bad("ctx.sleep", &other))),
            });
        }
        "node" => Ok(Value::Node(ctx.node())),
        "parent" => result(ctx.parent().map(|p| Value::option(p.map(Value::Node)))),
        "now" => Ok(Value::Duration(ctx.now())),
        "reserve_resource" => res(&arg(0)).and_then(|r| {
            let n = node(arg(1))?;
            done(ctx.reserve_resource(r, n))
        }),
        "unreserve_resource" => res(&arg(0)).and_then(|r| done(ctx.unreserve_resource(r))),
        "lock_resource" => res(&arg(0)).and_then(|r| done(ctx.lock_resource(r))),
        "unlock_resource" => res(&arg(0)).and_then(|r| done(ctx.unlock_resource(r))),
        "terminate" => node(arg(0)).and_then(|n| done(ctx.terminate(n))),
        "raise" => res(&arg(0)).and_then(|r| done(ctx.raise(&r))),
        "warn" => done(ctx.warn(arg(0).to_string())),
        "log" => done(ctx.log(arg(0).to_string())),
        "placed" => res(&arg(0)).and_then(|r| done(ctx.placed(&r))),
        "is_cancelled" => Ok(Value::Bool(ctx.is_cancelled())),
        "activation" => Ok(Value::option(ctx.activation().map(|(a, t)| {
            Value::tuple(vec![Value::Int(i64::from(a)), Value::Int(i64::from(t))])
        }))),
        _ => return None,
    };
    Some(Call::Ready(r))
}

/// A list's items, a string's characters as strings, a range's integers: what `for` and the
/// iterator methods go over.
pub(crate) fn items(v: &Value) -> Option<Arc<Vec<Value>>> {
    match v {
        Value::List(items) | Value::Tuple(items) => Some(items.clone()),
        Value::Map(map) => Some(Arc::new(
            map.iter()
                .map(|(k, v)| Value::tuple(vec![Value::str(k), v.clone()]))
                .collect(),
        )),
        Value::Variant(var) if &*var.ty == "Option" => Some(Arc::new(var.fields.clone())),
        _ => None,
    }
}
