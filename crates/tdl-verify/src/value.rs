//! Values the checker can follow through a body, and the small expression language it evaluates.
//!
//! A body's Rust code is not run. What the checker needs from it is the value of a condition, of a
//! loop's range or of a literal argument; so an expression is kept only if it is built from
//! literals, variables and the usual arithmetic, comparison and logic operators. Anything else
//! (a call, a field, a method) is [`VExpr::Unknown`], and so is a variable the checker could not
//! follow: an `if` on an unknown condition explores both branches (docs/verification.md).

use std::sync::Arc;

/// A variable of a body, numbered by the program ([`crate::program::Program`] interns names).
pub(crate) type Sym = u16;

/// What the checker knows of a value.
#[derive(Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub(crate) enum Value {
    /// Anything: the checker cannot tell.
    Unknown,
    Int(i64),
    Bool(bool),
    Str(Arc<str>),
    /// A floating-point number, by its bits (so that values hash).
    Float(u64),
}

impl Value {
    pub(crate) fn is_known(&self) -> bool {
        !matches!(self, Value::Unknown)
    }

    fn as_f64(&self) -> Option<f64> {
        match self {
            Value::Int(i) => Some(*i as f64),
            Value::Float(bits) => Some(f64::from_bits(*bits)),
            _ => None,
        }
    }

    /// The value as a number of seconds, for a computed time `(expr)`.
    pub(crate) fn seconds(&self) -> Option<f64> {
        self.as_f64().filter(|s| s.is_finite() && *s >= 0.0)
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Un {
    Not,
    Neg,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Bin {
    Add,
    Sub,
    Mul,
    Div,
    Rem,
    And,
    Or,
    Eq,
    Ne,
    Lt,
    Le,
    Gt,
    Ge,
}

/// An expression the checker can evaluate, or [`VExpr::Unknown`].
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum VExpr {
    Unknown,
    Lit(Value),
    Var(Sym),
    Un(Un, Box<VExpr>),
    Bin(Bin, Box<VExpr>, Box<VExpr>),
}

/// A body's variables with a known value, sorted by symbol. A variable not listed is unknown.
#[derive(Clone, Debug, Default, PartialEq, Eq, Hash)]
pub(crate) struct Env(Vec<(Sym, Value)>);

impl Env {
    pub(crate) fn get(&self, s: Sym) -> Value {
        match self.0.binary_search_by_key(&s, |(k, _)| *k) {
            Ok(i) => self.0[i].1.clone(),
            Err(_) => Value::Unknown,
        }
    }

    pub(crate) fn set(&mut self, s: Sym, v: Value) {
        match (self.0.binary_search_by_key(&s, |(k, _)| *k), v.is_known()) {
            (Ok(i), true) => self.0[i].1 = v,
            (Ok(i), false) => {
                self.0.remove(i);
            }
            (Err(i), true) => self.0.insert(i, (s, v)),
            (Err(_), false) => {}
        }
    }
}

impl VExpr {
    pub(crate) fn eval(&self, env: &Env) -> Value {
        match self {
            VExpr::Unknown => Value::Unknown,
            VExpr::Lit(v) => v.clone(),
            VExpr::Var(s) => env.get(*s),
            VExpr::Un(op, e) => match (op, e.eval(env)) {
                (Un::Not, Value::Bool(b)) => Value::Bool(!b),
                (Un::Neg, Value::Int(i)) => i.checked_neg().map_or(Value::Unknown, Value::Int),
                (Un::Neg, Value::Float(f)) => Value::Float((-f64::from_bits(f)).to_bits()),
                _ => Value::Unknown,
            },
            VExpr::Bin(op, a, b) => {
                let (a, b) = (a.eval(env), b.eval(env));
                // `false && x` and `true || x` whatever `x` is.
                match (op, &a, &b) {
                    (Bin::And, Value::Bool(false), _) | (Bin::And, _, Value::Bool(false)) => {
                        return Value::Bool(false);
                    }
                    (Bin::Or, Value::Bool(true), _) | (Bin::Or, _, Value::Bool(true)) => {
                        return Value::Bool(true);
                    }
                    _ => {}
                }
                binary(*op, &a, &b)
            }
        }
    }
}

fn binary(op: Bin, a: &Value, b: &Value) -> Value {
    use Value::{Bool, Float, Int, Str};
    match (a, b) {
        (Int(x), Int(y)) => {
            let (x, y) = (*x, *y);
            match op {
                Bin::Add => x.checked_add(y).map_or(Value::Unknown, Int),
                Bin::Sub => x.checked_sub(y).map_or(Value::Unknown, Int),
                Bin::Mul => x.checked_mul(y).map_or(Value::Unknown, Int),
                Bin::Div => x.checked_div(y).map_or(Value::Unknown, Int),
                Bin::Rem => x.checked_rem(y).map_or(Value::Unknown, Int),
                Bin::Eq => Bool(x == y),
                Bin::Ne => Bool(x != y),
                Bin::Lt => Bool(x < y),
                Bin::Le => Bool(x <= y),
                Bin::Gt => Bool(x > y),
                Bin::Ge => Bool(x >= y),
                Bin::And | Bin::Or => Value::Unknown,
            }
        }
        (Bool(x), Bool(y)) => match op {
            Bin::And => Bool(*x && *y),
            Bin::Or => Bool(*x || *y),
            Bin::Eq => Bool(x == y),
            Bin::Ne => Bool(x != y),
            _ => Value::Unknown,
        },
        (Str(x), Str(y)) => match op {
            Bin::Eq => Bool(x == y),
            Bin::Ne => Bool(x != y),
            _ => Value::Unknown,
        },
        (Int(_) | Float(_), Int(_) | Float(_)) => {
            let (Some(x), Some(y)) = (a.as_f64(), b.as_f64()) else {
                return Value::Unknown;
            };
            match op {
                Bin::Add => Float((x + y).to_bits()),
                Bin::Sub => Float((x - y).to_bits()),
                Bin::Mul => Float((x * y).to_bits()),
                Bin::Div => Float((x / y).to_bits()),
                Bin::Lt => Bool(x < y),
                Bin::Le => Bool(x <= y),
                Bin::Gt => Bool(x > y),
                Bin::Ge => Bool(x >= y),
                _ => Value::Unknown,
            }
        }
        _ => Value::Unknown,
    }
}

/// The expression language's reading of a Rust expression; `sym` interns a variable name.
pub(crate) fn lower(e: &syn::Expr, sym: &mut impl FnMut(&str) -> Sym) -> VExpr {
    match e {
        syn::Expr::Lit(l) => match &l.lit {
            syn::Lit::Int(i) => i
                .base10_parse::<i64>()
                .map_or(VExpr::Unknown, |v| VExpr::Lit(Value::Int(v))),
            syn::Lit::Float(f) => f
                .base10_parse::<f64>()
                .map_or(VExpr::Unknown, |v| VExpr::Lit(Value::Float(v.to_bits()))),
            syn::Lit::Bool(b) => VExpr::Lit(Value::Bool(b.value)),
            syn::Lit::Str(s) => VExpr::Lit(Value::Str(s.value().into())),
            _ => VExpr::Unknown,
        },
        syn::Expr::Path(p) if p.qself.is_none() => match p.path.get_ident() {
            Some(id) => VExpr::Var(sym(&id.to_string())),
            None => VExpr::Unknown,
        },
        syn::Expr::Paren(p) => lower(&p.expr, sym),
        syn::Expr::Group(g) => lower(&g.expr, sym),
        // A cast keeps the value (`x as i64`): the checker does not model overflow.
        syn::Expr::Cast(c) => lower(&c.expr, sym),
        syn::Expr::Reference(r) => lower(&r.expr, sym),
        syn::Expr::Unary(u) => {
            let op = match u.op {
                syn::UnOp::Not(_) => Un::Not,
                syn::UnOp::Neg(_) => Un::Neg,
                _ => return VExpr::Unknown,
            };
            match lower(&u.expr, sym) {
                VExpr::Unknown => VExpr::Unknown,
                inner => VExpr::Un(op, Box::new(inner)),
            }
        }
        syn::Expr::Binary(b) => {
            let op = match b.op {
                syn::BinOp::Add(_) => Bin::Add,
                syn::BinOp::Sub(_) => Bin::Sub,
                syn::BinOp::Mul(_) => Bin::Mul,
                syn::BinOp::Div(_) => Bin::Div,
                syn::BinOp::Rem(_) => Bin::Rem,
                syn::BinOp::And(_) => Bin::And,
                syn::BinOp::Or(_) => Bin::Or,
                syn::BinOp::Eq(_) => Bin::Eq,
                syn::BinOp::Ne(_) => Bin::Ne,
                syn::BinOp::Lt(_) => Bin::Lt,
                syn::BinOp::Le(_) => Bin::Le,
                syn::BinOp::Gt(_) => Bin::Gt,
                syn::BinOp::Ge(_) => Bin::Ge,
                _ => return VExpr::Unknown,
            };
            let (l, r) = (lower(&b.left, sym), lower(&b.right, sym));
            // `x && y` with one side unknown may still be decided by the other.
            if l == VExpr::Unknown && r == VExpr::Unknown {
                return VExpr::Unknown;
            }
            VExpr::Bin(op, Box::new(l), Box::new(r))
        }
        _ => VExpr::Unknown,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn eval(src: &str, env: &[(&str, Value)]) -> Value {
        let e: syn::Expr = syn::parse_str(src).expect("an expression");
        let mut names: Vec<String> = Vec::new();
        let mut sym = |n: &str| match names.iter().position(|x| x == n) {
            Some(i) => i as Sym,
            None => {
                names.push(n.to_owned());
                (names.len() - 1) as Sym
            }
        };
        let lowered = lower(&e, &mut sym);
        let mut env_v = Env::default();
        for (n, v) in env {
            env_v.set(sym(n), v.clone());
        }
        lowered.eval(&env_v)
    }

    #[test]
    fn literals_variables_and_operators_evaluate() {
        assert_eq!(eval("1 + 2 * 3", &[]), Value::Int(7));
        assert_eq!(
            eval("n - 1 > 2", &[("n", Value::Int(3))]),
            Value::Bool(false)
        );
        assert_eq!(
            eval("!(a == 0)", &[("a", Value::Int(0))]),
            Value::Bool(false)
        );
        assert_eq!(eval("1.5 * 2.0 > 2.5", &[]), Value::Bool(true));
    }

    #[test]
    fn what_the_checker_cannot_see_is_unknown() {
        assert_eq!(eval("mail_gone(room)", &[]), Value::Unknown);
        assert_eq!(eval("x != 0", &[]), Value::Unknown);
        // Decided by the side that is known.
        assert_eq!(eval("false && sensor.ok()", &[]), Value::Bool(false));
        assert_eq!(eval("x > 1 || true", &[]), Value::Bool(true));
    }
}
