//! The Rust types written in a program (task parameters, results, annotations, exception
//! fields) as the interpreter understands them ([`Ty`]): what a value of that type looks like,
//! and how a value given for it is checked and converted ([`Ty::coerce`]), so that an integer
//! given for an `f64` parameter becomes a float, and a string for a `u32` is refused.

use std::collections::BTreeSet;
use std::sync::Arc;

use crate::value::Value;

/// A type of the program, as values of it are represented.
#[derive(Clone, Debug, PartialEq)]
pub enum Ty {
    /// `()`.
    Unit,
    /// `bool`.
    Bool,
    /// A Rust integer type, with its range.
    Int {
        /// Its name (`u32`, `i64`, ...).
        name: &'static str,
        /// Its least value.
        min: i128,
        /// Its greatest value.
        max: i128,
    },
    /// `f32` or `f64`.
    Float,
    /// `String`, `&str`, `str`.
    Str,
    /// `Vec<T>`, `[T]`, `&[T]`, `[T; N]`.
    List(Box<Ty>),
    /// `Option<T>`.
    Option(Box<Ty>),
    /// A tuple of two or more.
    Tuple(Vec<Ty>),
    /// A map with string keys (`BTreeMap<String, T>`, `HashMap<String, T>`).
    Map(Box<Ty>),
    /// `Duration`.
    Duration,
    /// `NodeId`.
    Node,
    /// `Ended<T>`: how a waited child ended.
    Ended(Box<Ty>),
    /// Any value: `serde_json::Value`, `Json`, `_`, or a type only the registry knows.
    Any,
    /// Another named type: a host type the registry declares, or a type the program cannot
    /// check (its values are taken as they come).
    Named(Arc<str>),
}

const INTS: &[(&str, i128, i128)] = &[
    ("u8", 0, u8::MAX as i128),
    ("u16", 0, u16::MAX as i128),
    ("u32", 0, u32::MAX as i128),
    ("u64", 0, i64::MAX as i128),
    ("usize", 0, i64::MAX as i128),
    ("i8", i8::MIN as i128, i8::MAX as i128),
    ("i16", i16::MIN as i128, i16::MAX as i128),
    ("i32", i32::MIN as i128, i32::MAX as i128),
    ("i64", i64::MIN as i128, i64::MAX as i128),
    ("isize", i64::MIN as i128, i64::MAX as i128),
];

impl Ty {
    /// The integer type `name`, if it is one.
    pub fn int(name: &str) -> Option<Ty> {
        INTS.iter()
            .find(|(n, ..)| *n == name)
            .map(|&(name, min, max)| Ty::Int { name, min, max })
    }

    /// The type written `ty`; a path the interpreter does not know is [`Ty::Named`] by its last
    /// segment.
    pub fn of(ty: &syn::Type) -> Ty {
        match ty {
            syn::Type::Reference(r) => Ty::of(&r.elem),
            syn::Type::Paren(p) => Ty::of(&p.elem),
            syn::Type::Group(g) => Ty::of(&g.elem),
            syn::Type::Slice(s) => Ty::List(Box::new(Ty::of(&s.elem))),
            syn::Type::Array(a) => Ty::List(Box::new(Ty::of(&a.elem))),
            syn::Type::Tuple(t) if t.elems.is_empty() => Ty::Unit,
            syn::Type::Tuple(t) if t.elems.len() == 1 => t.elems.first().map_or(Ty::Unit, Ty::of),
            syn::Type::Tuple(t) => Ty::Tuple(t.elems.iter().map(Ty::of).collect()),
            syn::Type::Infer(_) => Ty::Any,
            syn::Type::Path(p) => {
                let Some(last) = p.path.segments.last() else {
                    return Ty::Any;
                };
                let name = last.ident.to_string();
                let args: Vec<Ty> = match &last.arguments {
                    syn::PathArguments::AngleBracketed(a) => a
                        .args
                        .iter()
                        .filter_map(|it| match it {
                            syn::GenericArgument::Type(t) => Some(Ty::of(t)),
                            _ => None,
                        })
                        .collect(),
                    _ => Vec::new(),
                };
                let first = || Box::new(args.first().cloned().unwrap_or(Ty::Any));
                if let Some(int) = Ty::int(&name) {
                    return int;
                }
                match name.as_str() {
                    "bool" => Ty::Bool,
                    "f32" | "f64" => Ty::Float,
                    "String" | "str" => Ty::Str,
                    "Vec" | "VecDeque" => Ty::List(first()),
                    "Option" => Ty::Option(first()),
                    "BTreeMap" | "HashMap" => {
                        Ty::Map(Box::new(args.get(1).cloned().unwrap_or(Ty::Any)))
                    }
                    "Duration" => Ty::Duration,
                    "NodeId" => Ty::Node,
                    "Ended" => Ty::Ended(first()),
                    "Box" | "Arc" | "Rc" => *first(),
                    "Json" => Ty::Any,
                    "Value" if p.path.segments.len() > 1 => Ty::Any,
                    _ => Ty::Named(Arc::from(name.as_str())),
                }
            }
            _ => Ty::Any,
        }
    }

    /// The same type, each name `n` replaced by `f(n)` where that gives one.
    pub fn rename(self, f: &dyn Fn(&str) -> Option<String>) -> Ty {
        match self {
            Ty::Named(n) => match f(&n) {
                Some(to) => Ty::Named(Arc::from(to.as_str())),
                None => Ty::Named(n),
            },
            Ty::List(t) => Ty::List(Box::new(t.rename(f))),
            Ty::Option(t) => Ty::Option(Box::new(t.rename(f))),
            Ty::Map(t) => Ty::Map(Box::new(t.rename(f))),
            Ty::Ended(t) => Ty::Ended(Box::new(t.rename(f))),
            Ty::Tuple(ts) => Ty::Tuple(ts.into_iter().map(|t| t.rename(f)).collect()),
            other => other,
        }
    }

    /// The named types it mentions: host types the registry must know.
    pub fn named(&self, out: &mut BTreeSet<Arc<str>>) {
        match self {
            Ty::Named(n) => {
                out.insert(n.clone());
            }
            Ty::List(t) | Ty::Option(t) | Ty::Map(t) | Ty::Ended(t) => t.named(out),
            Ty::Tuple(ts) => ts.iter().for_each(|t| t.named(out)),
            _ => {}
        }
    }

    /// How the type is written in a message.
    pub fn describe(&self) -> String {
        match self {
            Ty::Unit => "()".into(),
            Ty::Bool => "bool".into(),
            Ty::Int { name, .. } => (*name).into(),
            Ty::Float => "f64".into(),
            Ty::Str => "String".into(),
            Ty::List(t) => format!("Vec<{}>", t.describe()),
            Ty::Option(t) => format!("Option<{}>", t.describe()),
            Ty::Tuple(ts) => format!(
                "({})",
                ts.iter().map(Ty::describe).collect::<Vec<_>>().join(", ")
            ),
            Ty::Map(t) => format!("BTreeMap<String, {}>", t.describe()),
            Ty::Duration => "Duration".into(),
            Ty::Node => "NodeId".into(),
            Ty::Ended(t) => format!("Ended<{}>", t.describe()),
            Ty::Any => "any value".into(),
            Ty::Named(n) => n.to_string(),
        }
    }

    /// `value` as a value of this type: an integer for a float becomes a float, a JSON map for
    /// a tuple or list is refused, an integer out of range is refused; a value of a named type
    /// must be a host or record value of that name (or, for a type the registry does not know,
    /// anything).
    pub fn coerce(&self, value: Value) -> Result<Value, String> {
        let wrong = |v: &Value| {
            Err(format!(
                "expected {}, found {} `{v:?}`",
                self.describe(),
                v.kind()
            ))
        };
        match (self, value) {
            (Ty::Any, v) => Ok(v),
            (Ty::Unit, Value::Unit) => Ok(Value::Unit),
            (Ty::Bool, v @ Value::Bool(_)) => Ok(v),
            (Ty::Int { min, max, name }, Value::Int(i)) => {
                if i128::from(i) < *min || i128::from(i) > *max {
                    Err(format!("{i} does not fit a `{name}`"))
                } else {
                    Ok(Value::Int(i))
                }
            }
            (Ty::Float, Value::Float(x)) => Ok(Value::Float(x)),
            #[allow(clippy::cast_precision_loss, reason = "a literal given for a float")]
            (Ty::Float, Value::Int(i)) => Ok(Value::Float(i as f64)),
            (Ty::Str, v @ Value::Str(_)) => Ok(v),
            (Ty::List(t), Value::List(items)) => {
                if matches!(**t, Ty::Any) {
                    return Ok(Value::List(items));
                }
                let items: Result<Vec<Value>, String> =
                    items.iter().map(|it| t.coerce(it.clone())).collect();
                Ok(Value::List(Arc::new(items?)))
            }
            (Ty::Option(t), Value::Variant(v)) if &*v.ty == "Option" => match v.fields.first() {
                Some(inner) => Ok(Value::some(t.coerce(inner.clone())?)),
                None => Ok(Value::none()),
            },
            // JSON gives `null` for `None` and the value itself for `Some`.
            (Ty::Option(_), Value::Unit) => Ok(Value::none()),
            (Ty::Option(t), v) => Ok(Value::some(t.coerce(v)?)),
            (Ty::Tuple(ts), Value::Tuple(items)) | (Ty::Tuple(ts), Value::List(items))
                if ts.len() == items.len() =>
            {
                let items: Result<Vec<Value>, String> = ts
                    .iter()
                    .zip(items.iter())
                    .map(|(t, it)| t.coerce(it.clone()))
                    .collect();
                Ok(Value::Tuple(Arc::new(items?)))
            }
            (Ty::Map(t), Value::Map(map)) => {
                let map: Result<_, String> = map
                    .iter()
                    .map(|(k, v)| Ok((k.clone(), t.coerce(v.clone())?)))
                    .collect();
                Ok(Value::Map(Arc::new(map?)))
            }
            (Ty::Duration, v @ Value::Duration(_)) => Ok(v),
            (Ty::Duration, Value::Float(x)) if x >= 0.0 && x.is_finite() => {
                Ok(Value::Duration(std::time::Duration::from_secs_f64(x)))
            }
            (Ty::Duration, Value::Int(i)) if i >= 0 => Ok(Value::Duration(
                std::time::Duration::from_secs(i.unsigned_abs()),
            )),
            (Ty::Node, v @ Value::Node(_)) => Ok(v),
            (Ty::Ended(_), v @ Value::Variant(_)) => Ok(v),
            (Ty::Named(n), v) => match &v {
                Value::Host(h) if h.ty == *n => Ok(v),
                Value::Record(r) if r.name == *n => Ok(v),
                Value::Variant(var) if var.ty == *n => Ok(v),
                Value::Host(_) | Value::Record(_) | Value::Variant(_) => wrong(&v),
                // A plain value for a type the program cannot look into: taken as it comes (a
                // registered function converts it, or refuses it).
                _ => Ok(v),
            },
            (_, v) => wrong(&v),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ty(s: &str) -> Ty {
        Ty::of(&syn::parse_str::<syn::Type>(s).expect("a type"))
    }

    #[test]
    fn types_read_as_their_values() {
        assert_eq!(ty("u32"), Ty::int("u32").expect("an int"));
        assert_eq!(ty("&[f64]"), Ty::List(Box::new(Ty::Float)));
        assert_eq!(ty("Option<String>"), Ty::Option(Box::new(Ty::Str)));
        assert_eq!(
            ty("(u8, bool)"),
            Ty::Tuple(vec![Ty::int("u8").expect("int"), Ty::Bool])
        );
        assert_eq!(ty("std::time::Duration"), Ty::Duration);
        assert_eq!(ty("Mission"), Ty::Named(Arc::from("Mission")));
    }

    #[test]
    fn coercion_converts_or_refuses() {
        assert_eq!(ty("f64").coerce(Value::Int(2)), Ok(Value::Float(2.0)));
        assert!(ty("u8").coerce(Value::Int(300)).is_err());
        assert!(ty("u32").coerce(Value::str("3")).is_err());
        assert_eq!(
            ty("Vec<f64>").coerce(Value::list([Value::Int(1)])),
            Ok(Value::list([Value::Float(1.0)]))
        );
        assert_eq!(ty("Option<u32>").coerce(Value::Unit), Ok(Value::none()));
    }
}
