//! Operators, comparisons, conversions and the methods of plain values, as Rust gives them on
//! the compiled program's values: integer arithmetic checked (an overflow fails the node, as it
//! panics in a debug build), integer division truncating, `%` with the dividend's sign, floats
//! as IEEE 754. An integer meets a float only where Rust's `as` would have been written; here it
//! is converted, so `f64::from(n) * 0.5` and `n as f64 * 0.5` both work.

use std::cmp::Ordering;
use std::sync::Arc;

use tdl::Failure;

use super::{Flow, Frame, R, truth};
use crate::builtin::{self, bad};
use crate::format::{self, Fmt, Piece};
use crate::ir::{Bin, Ex};
use crate::program::Shared;
use crate::ty::Ty;
use crate::value::Value;

fn fail(exception: &'static str, message: String) -> Flow {
    Flow::Fail(Failure::new(exception, message))
}

pub(super) fn not(v: &Value) -> R<Value> {
    match v {
        Value::Bool(b) => Ok(Value::Bool(!b)),
        Value::Int(i) => Ok(Value::Int(!i)),
        other => Err(Flow::Fail(bad("`!`", other))),
    }
}

pub(super) fn neg(v: &Value) -> R<Value> {
    match v {
        Value::Int(i) => i
            .checked_neg()
            .map(Value::Int)
            .ok_or_else(|| fail("Overflow", format!("-{i} overflows"))),
        Value::Float(x) => Ok(Value::Float(-x)),
        other => Err(Flow::Fail(bad("`-`", other))),
    }
}

/// `l op r`.
pub(crate) fn binary(op: Bin, l: &Value, r: &Value) -> R<Value> {
    use Value as V;
    let overflow = || fail("Overflow", format!("`{l:?} {} {r:?}` overflows", sym(op)));
    Ok(match op {
        Bin::Eq => V::Bool(l == r),
        Bin::Ne => V::Bool(l != r),
        Bin::Lt => V::Bool(compare(l, r)?.is_lt()),
        Bin::Le => V::Bool(compare(l, r)?.is_le()),
        Bin::Gt => V::Bool(compare(l, r)?.is_gt()),
        Bin::Ge => V::Bool(compare(l, r)?.is_ge()),
        _ => match (l, r) {
            (V::Int(a), V::Int(b)) => {
                let (a, b) = (*a, *b);
                V::Int(
                    match op {
                        Bin::Add => a.checked_add(b),
                        Bin::Sub => a.checked_sub(b),
                        Bin::Mul => a.checked_mul(b),
                        Bin::Div if b == 0 => {
                            return Err(fail("DivisionByZero", format!("`{a} / 0`")));
                        }
                        Bin::Div => a.checked_div(b),
                        Bin::Rem if b == 0 => {
                            return Err(fail("DivisionByZero", format!("`{a} % 0`")));
                        }
                        Bin::Rem => a.checked_rem(b),
                        Bin::BitAnd => Some(a & b),
                        Bin::BitOr => Some(a | b),
                        Bin::BitXor => Some(a ^ b),
                        Bin::Shl => u32::try_from(b).ok().and_then(|b| a.checked_shl(b)),
                        Bin::Shr => u32::try_from(b).ok().and_then(|b| a.checked_shr(b)),
                        _ => None,
                    }
                    .ok_or_else(overflow)?,
                )
            }
            (V::Bool(a), V::Bool(b)) => match op {
                Bin::BitAnd => V::Bool(a & b),
                Bin::BitOr => V::Bool(a | b),
                Bin::BitXor => V::Bool(a ^ b),
                _ => return Err(Flow::Fail(bad(sym(op), l))),
            },
            (V::Str(a), V::Str(b)) if op == Bin::Add => V::str(format!("{a}{b}")),
            (V::Duration(a), V::Duration(b)) => match op {
                Bin::Add => V::Duration(a.checked_add(*b).ok_or_else(overflow)?),
                Bin::Sub => V::Duration(a.checked_sub(*b).ok_or_else(overflow)?),
                _ => return Err(Flow::Fail(bad(sym(op), r))),
            },
            (V::Duration(d), n @ (V::Int(_) | V::Float(_))) => {
                let x = n.as_float().unwrap_or(0.0);
                match op {
                    Bin::Mul if x >= 0.0 => V::Duration(d.mul_f64(x)),
                    Bin::Div if x > 0.0 => V::Duration(d.div_f64(x)),
                    _ => return Err(Flow::Fail(bad(sym(op), r))),
                }
            }
            (a, b) => {
                let (Some(x), Some(y)) = (a.as_float(), b.as_float()) else {
                    return Err(fail(
                        "TypeMismatch",
                        format!("`{} {} {}`: no such operation", a.kind(), sym(op), b.kind()),
                    ));
                };
                V::Float(match op {
                    Bin::Add => x + y,
                    Bin::Sub => x - y,
                    Bin::Mul => x * y,
                    Bin::Div => x / y,
                    Bin::Rem => x % y,
                    _ => return Err(Flow::Fail(bad(sym(op), a))),
                })
            }
        },
    })
}

fn sym(op: Bin) -> &'static str {
    match op {
        Bin::Add => "+",
        Bin::Sub => "-",
        Bin::Mul => "*",
        Bin::Div => "/",
        Bin::Rem => "%",
        Bin::Eq => "==",
        Bin::Ne => "!=",
        Bin::Lt => "<",
        Bin::Le => "<=",
        Bin::Gt => ">",
        Bin::Ge => ">=",
        Bin::BitAnd => "&",
        Bin::BitOr => "|",
        Bin::BitXor => "^",
        Bin::Shl => "<<",
        Bin::Shr => ">>",
    }
}

/// How two values order, as Rust's `PartialOrd` orders them.
pub(crate) fn compare(l: &Value, r: &Value) -> Result<Ordering, Failure> {
    use Value as V;
    let unordered = || {
        Failure::new(
            "TypeMismatch",
            format!("cannot order {} `{l:?}` and {} `{r:?}`", l.kind(), r.kind()),
        )
    };
    match (l, r) {
        (V::Int(a), V::Int(b)) => Ok(a.cmp(b)),
        (V::Str(a), V::Str(b)) => Ok(a.cmp(b)),
        (V::Bool(a), V::Bool(b)) => Ok(a.cmp(b)),
        (V::Duration(a), V::Duration(b)) => Ok(a.cmp(b)),
        (V::List(a), V::List(b)) | (V::Tuple(a), V::Tuple(b)) => {
            for (x, y) in a.iter().zip(b.iter()) {
                match compare(x, y)? {
                    Ordering::Equal => {}
                    other => return Ok(other),
                }
            }
            Ok(a.len().cmp(&b.len()))
        }
        (a, b) => match (a.as_float(), b.as_float()) {
            (Some(x), Some(y)) => x.partial_cmp(&y).ok_or_else(unordered),
            _ => Err(unordered()),
        },
    }
}

/// `x?`: the value of `Ok`/`Some`, or the failure of `Err`/`None`; any other value as it is
/// (a registered function's error already failed the node).
pub(crate) fn try_value(v: Value) -> R<Value> {
    match &v {
        Value::Variant(var) if &*var.ty == "Result" => match (&*var.name, var.fields.first()) {
            ("Ok", Some(inner)) => Ok(inner.clone()),
            ("Err", Some(e)) if e.as_failure().is_some() => Err(Flow::Fail(
                e.as_failure()
                    .cloned()
                    .unwrap_or_else(|| Failure::new("Error", "")),
            )),
            ("Err", Some(other)) => Err(fail("Error", format!("{other:?}"))),
            _ => Ok(Value::Unit),
        },
        Value::Variant(var) if &*var.ty == "Option" => match var.fields.first() {
            Some(inner) => Ok(inner.clone()),
            None => Err(fail("NoneValue", "`?` on `None`".into())),
        },
        _ => Ok(v),
    }
}

pub(super) fn tuple_field(v: &Value, i: usize) -> R<Value> {
    match v {
        Value::Tuple(items) | Value::List(items) => items
            .get(i)
            .cloned()
            .ok_or_else(|| fail("IndexOutOfRange", format!("`.{i}` of `{v:?}`"))),
        Value::Variant(var) => var
            .fields
            .get(i)
            .cloned()
            .ok_or_else(|| fail("IndexOutOfRange", format!("`.{i}` of `{v:?}`"))),
        other => Err(Flow::Fail(bad(&format!("`.{i}`"), other))),
    }
}

pub(super) fn index(base: &Value, index: &Value) -> R<Value> {
    match (base, index) {
        (Value::List(items), Value::Int(i)) => usize::try_from(*i)
            .ok()
            .and_then(|i| items.get(i))
            .cloned()
            .ok_or_else(|| {
                fail(
                    "IndexOutOfRange",
                    format!("index {i} of a list of {}", items.len()),
                )
            }),
        (Value::Map(map), Value::Str(k)) => map
            .get(&**k)
            .cloned()
            .ok_or_else(|| fail("KeyNotFound", format!("no key {k:?} in the map"))),
        (b, i) => Err(fail(
            "TypeMismatch",
            format!("cannot index {} with {}", b.kind(), i.kind()),
        )),
    }
}

/// `base.name` on a record, a map, an exception's data.
pub(super) fn field(base: &Value, name: &str) -> Result<Value, Failure> {
    match base {
        Value::Record(r) => r.field(name).cloned().ok_or_else(|| {
            Failure::new(
                "UnknownField",
                format!("`{}` has no field `{name}`", r.name),
            )
        }),
        Value::Map(map) => map
            .get(name)
            .cloned()
            .ok_or_else(|| Failure::new("UnknownField", format!("no field `{name}` in the map"))),
        Value::Failure(_) | Value::Error(_) => match base.as_failure().and_then(failure_data) {
            Some(data) => field(&data, name),
            None => Err(Failure::new(
                "UnknownField",
                format!("the exception `{}` carries no field `{name}`", base.kind()),
            )),
        },
        other => Err(bad(&format!("`.{name}`"), other)),
    }
}

pub(super) fn with_field(base: &Value, name: &str, v: Value) -> R<Value> {
    match base {
        Value::Record(r) => {
            let mut r = (**r).clone();
            match r.fields.iter_mut().find(|(n, _)| &**n == name) {
                Some((_, slot)) => *slot = v,
                None => return Err(Flow::Fail(bad(&format!("`.{name} =`"), base))),
            }
            Ok(Value::Record(Arc::new(r)))
        }
        Value::Map(map) => {
            let mut map = (**map).clone();
            map.insert(name.to_string(), v);
            Ok(Value::Map(Arc::new(map)))
        }
        other => Err(Flow::Fail(bad(&format!("`.{name} =`"), other))),
    }
}

pub(super) fn with_index(base: &Value, index: &Value, v: Value) -> R<Value> {
    match (base, index) {
        (Value::List(items), Value::Int(i)) | (Value::Tuple(items), Value::Int(i)) => {
            let mut items = (**items).clone();
            let slot = usize::try_from(*i).ok().and_then(|i| items.get_mut(i));
            match slot {
                Some(slot) => *slot = v,
                None => return Err(fail("IndexOutOfRange", format!("index {i}"))),
            }
            Ok(match base {
                Value::Tuple(_) => Value::Tuple(Arc::new(items)),
                _ => Value::List(Arc::new(items)),
            })
        }
        (Value::Map(map), Value::Str(k)) => {
            let mut map = (**map).clone();
            map.insert(k.to_string(), v);
            Ok(Value::Map(Arc::new(map)))
        }
        (b, _) => Err(Flow::Fail(bad("an indexed assignment", b))),
    }
}

pub(super) fn format(fmt: &Fmt, args: &[Value]) -> Value {
    let mut out = String::new();
    for piece in &fmt.pieces {
        match piece {
            Piece::Text(t) => out.push_str(t),
            Piece::Hole(h) => {
                let i = match h.arg {
                    format::ArgRef::Index(i) => i,
                    _ => 0,
                };
                format::write_hole(&mut out, h, args.get(i).unwrap_or(&Value::Unit));
            }
        }
    }
    Value::str(out)
}

/// A range's integers, as a list (`for` goes over a range without making it, `exec.rs`).
pub(super) fn range(lo: Option<&Value>, hi: Option<&Value>, closed: bool) -> R<Value> {
    let (Some(Value::Int(lo)), Some(Value::Int(hi))) = (lo, hi) else {
        return Err(fail(
            "TypeMismatch",
            "a range needs two integer bounds when interpreted".into(),
        ));
    };
    let hi = if closed { hi.saturating_add(1) } else { *hi };
    if hi.saturating_sub(*lo) > 10_000_000 {
        return Err(fail(
            "TooLarge",
            format!("the range {lo}..{hi} has more than 10 million integers"),
        ));
    }
    Ok(Value::list((*lo..hi).map(Value::Int)))
}

/// `v as T`.
#[allow(
    clippy::cast_possible_truncation,
    clippy::cast_precision_loss,
    reason = "as Rust's `as`"
)]
pub(super) fn cast(v: Value, ty: &Ty) -> R<Value> {
    Ok(match (ty, &v) {
        (Ty::Float, Value::Int(i)) => Value::Float(*i as f64),
        (Ty::Float, Value::Float(_)) => v,
        (Ty::Int { min, max, .. }, Value::Float(x)) => {
            Value::Int((*x as i128).clamp(*min, *max) as i64)
        }
        (Ty::Int { min, max, .. }, Value::Int(i)) => {
            let bits = (*max - *min + 1).count_ones() == 1;
            // Wrapping as Rust's `as` does, within the target's range.
            let span = *max - *min + 1;
            let mut n = i128::from(*i);
            if bits && (n < *min || n > *max) {
                n = (n - *min).rem_euclid(span) + *min;
            }
            Value::Int(n.clamp(i128::from(i64::MIN), i128::from(i64::MAX)) as i64)
        }
        (Ty::Int { .. }, Value::Bool(b)) => Value::Int(i64::from(*b)),
        _ => ty
            .coerce(v)
            .map_err(|e| fail("TypeMismatch", format!("`as`: {e}")))?,
    })
}

/// What an expression is, for a message.
pub(super) fn what(ex: &Ex) -> &'static str {
    match ex {
        Ex::Closure(_) => "a closure",
        Ex::Index(..) => "an index",
        Ex::Range(..) => "a range",
        Ex::Cast(..) => "a cast",
        Ex::AssignOp(..) => "a compound assignment",
        _ => "this expression",
    }
}

/// A method of a plain value.
pub(super) fn method(
    recv: &Value,
    name: &str,
    args: &[Value],
    turbofish: Option<&str>,
    shared: &Shared,
) -> Result<Value, Failure> {
    use Value as V;
    let arg = |i: usize| args.get(i).cloned().unwrap_or_default();
    let float = |f: fn(f64) -> f64| match recv.as_float() {
        Some(x) => Ok(V::Float(f(x))),
        None => Err(bad(&format!("`.{name}()`"), recv)),
    };
    let list = || builtin::items(recv).ok_or_else(|| bad(&format!("`.{name}()`"), recv));
    match (name, recv) {
        (
            "clone" | "to_owned" | "into" | "as_ref" | "as_deref" | "as_str" | "iter" | "into_iter"
            | "copied" | "cloned" | "collect",
            _,
        ) => Ok(recv.clone()),
        ("to_string", v) => Ok(V::str(v.to_string())),
        ("abs", V::Int(i)) => i
            .checked_abs()
            .map(V::Int)
            .ok_or_else(|| Failure::new("Overflow", format!("`{i}.abs()`"))),
        ("abs", _) => float(f64::abs),
        ("sqrt", _) => float(f64::sqrt),
        ("floor", _) => float(f64::floor),
        ("ceil", _) => float(f64::ceil),
        ("round", _) => float(f64::round),
        ("trunc", _) => float(f64::trunc),
        ("sin", _) => float(f64::sin),
        ("cos", _) => float(f64::cos),
        ("to_degrees", _) => float(f64::to_degrees),
        ("to_radians", _) => float(f64::to_radians),
        ("signum", V::Int(i)) => Ok(V::Int(i.signum())),
        ("signum", _) => float(f64::signum),
        ("is_nan", _) => Ok(V::Bool(recv.as_float().is_some_and(f64::is_nan))),
        ("is_finite", _) => Ok(V::Bool(recv.as_float().is_some_and(f64::is_finite))),
        ("min" | "max", _) => {
            let other = arg(0);
            let less = compare(recv, &other)?.is_lt();
            Ok(if less == (name == "min") {
                recv.clone()
            } else {
                other
            })
        }
        ("clamp", _) => {
            let (lo, hi) = (arg(0), arg(1));
            if compare(recv, &lo)?.is_lt() {
                Ok(lo)
            } else if compare(recv, &hi)?.is_gt() {
                Ok(hi)
            } else {
                Ok(recv.clone())
            }
        }
        ("pow", V::Int(i)) => {
            let e = arg(0).as_int().and_then(|e| u32::try_from(e).ok());
            e.and_then(|e| i.checked_pow(e))
                .map(V::Int)
                .ok_or_else(|| Failure::new("Overflow", format!("`{i}.pow(..)`")))
        }
        ("powi" | "powf", _) => match (recv.as_float(), arg(0).as_float()) {
            (Some(x), Some(e)) => Ok(V::Float(x.powf(e))),
            _ => Err(bad(&format!("`.{name}()`"), recv)),
        },
        ("atan2" | "hypot", _) => match (recv.as_float(), arg(0).as_float()) {
            (Some(y), Some(x)) if name == "atan2" => Ok(V::Float(y.atan2(x))),
            (Some(a), Some(b)) => Ok(V::Float(a.hypot(b))),
            _ => Err(bad(&format!("`.{name}()`"), recv)),
        },
        ("saturating_sub", V::Int(a)) => Ok(V::Int(
            a.saturating_sub(arg(0).as_int().unwrap_or(0)).max(0),
        )),
        ("len", V::Str(s)) => Ok(V::Int(i64::try_from(s.len()).unwrap_or(i64::MAX))),
        ("len" | "count", _) => Ok(V::Int(i64::try_from(list()?.len()).unwrap_or(i64::MAX))),
        ("is_empty", V::Str(s)) => Ok(V::Bool(s.is_empty())),
        ("is_empty", _) => Ok(V::Bool(list()?.is_empty())),
        ("contains", V::Str(s)) => Ok(V::Bool(arg(0).as_str().is_some_and(|p| s.contains(p)))),
        ("contains", _) => Ok(V::Bool(list()?.contains(&arg(0)))),
        ("starts_with", V::Str(s)) => {
            Ok(V::Bool(arg(0).as_str().is_some_and(|p| s.starts_with(p))))
        }
        ("ends_with", V::Str(s)) => Ok(V::Bool(arg(0).as_str().is_some_and(|p| s.ends_with(p)))),
        ("to_uppercase", V::Str(s)) => Ok(V::str(s.to_uppercase())),
        ("to_lowercase", V::Str(s)) => Ok(V::str(s.to_lowercase())),
        ("trim", V::Str(s)) => Ok(V::str(s.trim())),
        ("first", _) => Ok(V::option(list()?.first().cloned())),
        ("last", _) => Ok(V::option(list()?.last().cloned())),
        ("get", V::Map(m)) => Ok(V::option(arg(0).as_str().and_then(|k| m.get(k)).cloned())),
        ("get", _) => Ok(V::option(
            arg(0)
                .as_int()
                .and_then(|i| usize::try_from(i).ok())
                .and_then(|i| list().ok()?.get(i).cloned()),
        )),
        ("join", _) => {
            let sep = arg(0).to_string();
            let parts: Vec<String> = list()?.iter().map(ToString::to_string).collect();
            Ok(V::str(parts.join(&sep)))
        }
        ("sum", _) => {
            let items = list()?;
            let mut acc = V::Int(0);
            for it in items.iter() {
                acc = binary(Bin::Add, &acc, it).map_err(flow_failure)?;
            }
            Ok(acc)
        }
        ("rev", _) => Ok(V::list(list()?.iter().rev().cloned())),
        ("enumerate", _) => Ok(V::list(list()?.iter().enumerate().map(|(i, v)| {
            V::tuple(vec![
                V::Int(i64::try_from(i).unwrap_or(i64::MAX)),
                v.clone(),
            ])
        }))),
        ("zip", _) => {
            let other = builtin::items(&arg(0)).ok_or_else(|| bad("`.zip()`", &arg(0)))?;
            Ok(V::list(
                list()?
                    .iter()
                    .zip(other.iter())
                    .map(|(a, b)| V::tuple(vec![a.clone(), b.clone()])),
            ))
        }
        (
            "is_some" | "is_none" | "unwrap" | "expect" | "unwrap_or" | "unwrap_or_default"
            | "ok_or",
            V::Variant(v),
        ) if &*v.ty == "Option" => {
            let inner = v.fields.first().cloned();
            match name {
                "is_some" => Ok(V::Bool(inner.is_some())),
                "is_none" => Ok(V::Bool(inner.is_none())),
                "unwrap" | "expect" => {
                    inner.ok_or_else(|| Failure::new("NoneValue", format!("`.{name}()` on `None`")))
                }
                "unwrap_or" => Ok(inner.unwrap_or_else(|| arg(0))),
                "ok_or" => Ok(match inner {
                    Some(x) => V::variant("Result", "Ok", vec![x]),
                    None => V::variant("Result", "Err", vec![arg(0)]),
                }),
                _ => Ok(inner.unwrap_or_default()),
            }
        }
        ("is_ok" | "is_err" | "ok" | "err" | "unwrap" | "expect", V::Variant(v))
            if &*v.ty == "Result" =>
        {
            let ok = &*v.name == "Ok";
            let inner = v.fields.first().cloned().unwrap_or_default();
            match name {
                "is_ok" => Ok(V::Bool(ok)),
                "is_err" => Ok(V::Bool(!ok)),
                "ok" => Ok(V::option(ok.then_some(inner))),
                "err" => Ok(V::option((!ok).then_some(inner))),
                _ if ok => Ok(inner),
                _ => Err(match inner {
                    V::Failure(f) => (*f).clone(),
                    other => Failure::new("Error", format!("{other:?}")),
                }),
            }
        }
        (
            "succeeded" | "failed" | "terminated" | "skipped" | "value" | "failure",
            V::Variant(v),
        ) if &*v.ty == "Ended" => Ok(match name {
            "value" => V::option(
                (&*v.name == "Succeeded").then(|| v.fields.first().cloned().unwrap_or_default()),
            ),
            "failure" => V::option(v.fields.first().filter(|_| &*v.name == "Failed").cloned()),
            _ => {
                let want = match name {
                    "succeeded" => "Succeeded",
                    "failed" => "Failed",
                    "terminated" => "Terminated",
                    _ => "Skipped",
                };
                V::Bool(&*v.name == want)
            }
        }),
        ("as_secs_f64", V::Duration(d)) => Ok(V::Float(d.as_secs_f64())),
        ("as_secs", V::Duration(d)) => Ok(V::Int(i64::try_from(d.as_secs()).unwrap_or(i64::MAX))),
        ("as_millis", V::Duration(d)) => {
            Ok(V::Int(i64::try_from(d.as_millis()).unwrap_or(i64::MAX)))
        }
        ("mul_f64", V::Duration(d)) => match arg(0).as_float() {
            Some(x) if x >= 0.0 => Ok(V::Duration(d.mul_f64(x))),
            _ => Err(bad("`.mul_f64()`", &arg(0))),
        },
        ("name" | "exception" | "message" | "data" | "is_a" | "downcast" | "is", v)
            if v.as_failure().is_some() =>
        {
            let Some(f) = v.as_failure() else {
                return Err(bad(name, v));
            };
            failure_method(f, name, &arg(0), turbofish, shared)
        }
        _ => Err(Failure::new(
            "UnknownMethod",
            format!("{} `{recv:?}` has no method `{name}`", recv.kind()),
        )),
    }
}

/// A method of a failure (a caught exception, a child's failure, an error).
fn failure_method(
    f: &Failure,
    name: &str,
    arg: &Value,
    turbofish: Option<&str>,
    shared: &Shared,
) -> Result<Value, Failure> {
    use Value as V;
    match name {
        "name" | "exception" => Ok(V::str(&*f.exception)),
        "message" => Ok(V::str(&f.message)),
        "data" => Ok(V::option(failure_data(f))),
        "is_a" => Ok(V::Bool(arg.as_str().is_some_and(|n| f.is_a(n)))),
        _ => {
            let Some(ty) = turbofish else {
                return Err(Failure::new(
                    "Interpreter",
                    format!("`.{name}` needs its type: `.{name}::<E>()`"),
                ));
            };
            let matches = f.is_a(ty) || shared.is_descendant(&f.exception, ty);
            if name == "is" {
                return Ok(V::Bool(matches));
            }
            Ok(V::option(failure_data(f).filter(|_| matches)))
        }
    }
}

fn flow_failure(f: Flow) -> Failure {
    match f {
        Flow::Fail(f) => f,
        _ => Failure::new("Interpreter", "unexpected control flow in an operator"),
    }
}

/// A method that calls a closure: `apply` runs it on its arguments.
pub(super) fn with_closure(
    frame: &mut Frame,
    recv: &Value,
    name: &str,
    args: &[Value],
    apply: &mut dyn FnMut(&mut Frame, &[Value]) -> R<Value>,
) -> R<Value> {
    use Value as V;
    let arg = |i: usize| args.get(i).cloned().unwrap_or_default();
    if let V::Variant(v) = recv {
        if &*v.ty == "Option" || &*v.ty == "Result" {
            let ok = matches!(&*v.name, "Some" | "Ok");
            let inner = v.fields.first().cloned().unwrap_or_default();
            return Ok(match name {
                "is_some_and" => V::Bool(ok && truth(&apply(frame, &[inner])?)?),
                "is_none_or" => V::Bool(!ok || truth(&apply(frame, &[inner])?)?),
                "map" if ok => {
                    let out = apply(frame, &[inner])?;
                    V::variant(&v.ty, &v.name, vec![out])
                }
                "map" => recv.clone(),
                "map_or" if ok => apply(frame, &[inner])?,
                "map_or" => arg(0),
                "and_then" if ok => apply(frame, &[inner])?,
                "and_then" => recv.clone(),
                "unwrap_or_else" if ok => inner,
                "unwrap_or_else" => apply(frame, &[])?,
                "filter" if ok && truth(&apply(frame, &[inner])?)? => recv.clone(),
                "filter" => V::none(),
                _ => {
                    return Err(Flow::Fail(Failure::new(
                        "UnknownMethod",
                        format!("`{}` has no method `{name}` taking a closure", v.ty),
                    )));
                }
            });
        }
    }
    let items = builtin::items(recv)
        .ok_or_else(|| Flow::Fail(bad(&format!("`.{name}(|..| ..)`"), recv)))?;
    let mut out = Vec::new();
    for it in items.iter() {
        match name {
            "map" => out.push(apply(frame, std::slice::from_ref(it))?),
            "filter" => {
                if truth(&apply(frame, std::slice::from_ref(it))?)? {
                    out.push(it.clone());
                }
            }
            "filter_map" => {
                if let V::Variant(v) = apply(frame, std::slice::from_ref(it))? {
                    if let Some(x) = v.fields.first() {
                        out.push(x.clone());
                    }
                }
            }
            "for_each" => {
                apply(frame, std::slice::from_ref(it))?;
            }
            "any" if truth(&apply(frame, std::slice::from_ref(it))?)? => return Ok(V::Bool(true)),
            "all" if !truth(&apply(frame, std::slice::from_ref(it))?)? => {
                return Ok(V::Bool(false));
            }
            "find" if truth(&apply(frame, std::slice::from_ref(it))?)? => {
                return Ok(V::some(it.clone()));
            }
            "position" if truth(&apply(frame, std::slice::from_ref(it))?)? => {
                let i = i64::try_from(out.len()).unwrap_or(i64::MAX);
                return Ok(V::some(V::Int(i)));
            }
            "position" => out.push(V::Unit),
            "any" | "all" | "find" => {}
            _ => {
                return Err(Flow::Fail(Failure::new(
                    "UnknownMethod",
                    format!("a list has no method `{name}` taking a closure"),
                )));
            }
        }
    }
    Ok(match name {
        "any" | "find" | "position" => match name {
            "any" => V::Bool(false),
            _ => V::none(),
        },
        "all" => V::Bool(true),
        "for_each" => V::Unit,
        _ => V::list(out),
    })
}

/// The data an exception carries, as a value: the record `fail E { … }` gave it, or the JSON a
/// fault gave it (a faults file's or the viewer's `data`; docs/semantics.md, "Steering a run").
fn failure_data(f: &Failure) -> Option<Value> {
    match f.data::<Value>() {
        Some(d) => Some((*d).clone()),
        None => f.data::<serde_json::Value>().map(|j| Value::from_json(&j)),
    }
}
