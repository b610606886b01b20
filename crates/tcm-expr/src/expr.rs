//! Expressions: their syntax tree, canonical text, static types and evaluation.

use crate::value::{Type, Value};
use serde::{Deserialize, Serialize};
use std::fmt;

/// A binary operator.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "snake_case")]
pub enum BinOp {
    /// `||`
    Or,
    /// `&&`
    And,
    /// `==`
    Eq,
    /// `!=`
    Ne,
    /// `<`
    Lt,
    /// `<=`
    Le,
    /// `>`
    Gt,
    /// `>=`
    Ge,
    /// `+`
    Add,
    /// `-`
    Sub,
    /// `*`
    Mul,
    /// `/`
    Div,
    /// `%`
    Rem,
}

impl BinOp {
    /// Every operator.
    pub const ALL: [BinOp; 13] = [
        BinOp::Or,
        BinOp::And,
        BinOp::Eq,
        BinOp::Ne,
        BinOp::Lt,
        BinOp::Le,
        BinOp::Gt,
        BinOp::Ge,
        BinOp::Add,
        BinOp::Sub,
        BinOp::Mul,
        BinOp::Div,
        BinOp::Rem,
    ];

    /// How TDL writes it.
    pub fn symbol(self) -> &'static str {
        match self {
            BinOp::Or => "||",
            BinOp::And => "&&",
            BinOp::Eq => "==",
            BinOp::Ne => "!=",
            BinOp::Lt => "<",
            BinOp::Le => "<=",
            BinOp::Gt => ">",
            BinOp::Ge => ">=",
            BinOp::Add => "+",
            BinOp::Sub => "-",
            BinOp::Mul => "*",
            BinOp::Div => "/",
            BinOp::Rem => "%",
        }
    }

    /// Binding strength, as in Rust: `||` 1, `&&` 2, comparisons 3, `+ -` 4, `* / %` 5.
    /// Comparisons do not chain (`a < b < c` is an error); the others associate to the left.
    pub fn precedence(self) -> u8 {
        match self {
            BinOp::Or => 1,
            BinOp::And => 2,
            BinOp::Eq | BinOp::Ne | BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge => 3,
            BinOp::Add | BinOp::Sub => 4,
            BinOp::Mul | BinOp::Div | BinOp::Rem => 5,
        }
    }

    /// Whether a comparison (gives a `bool` from two operands of one type).
    pub fn is_comparison(self) -> bool {
        self.precedence() == 3
    }
}

/// An expression over state variables: literals, variables, `!`, unary `-`, `is_known(e)` and the
/// binary operators of [`BinOp`].
///
/// In JSON (the trace, docs/trace-format.md): `{"lit": v}`, `{"var": "name"}`, `{"not": e}`,
/// `{"neg": e}`, `{"known": e}`, `{"bin": {"op": "and", "l": e, "r": e}}`.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "snake_case")]
pub enum Expr {
    /// A literal.
    Lit(Value),
    /// A state variable's current value.
    Var(String),
    /// `!e`
    Not(Box<Expr>),
    /// `-e`
    Neg(Box<Expr>),
    /// `is_known(e)`: whether `e`'s value is known (`true` or `false`, never unknown).
    Known(Box<Expr>),
    /// `l op r`
    Bin {
        /// The operator.
        op: BinOp,
        /// The left operand.
        l: Box<Expr>,
        /// The right operand.
        r: Box<Expr>,
    },
}

/// An expression that cannot be evaluated: its operands have types its operator does not take, or
/// it names a variable that does not exist. Static checking ([`Expr::type_of`]) finds all of these
/// before a run; evaluation finds them again for expressions that were not checked.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum ExprError {
    /// A variable no one declared.
    #[error("no state variable `{0}` is declared")]
    UnknownVar(String),
    /// An operator given operands it does not take.
    #[error("`{op}` cannot be applied to {found}")]
    Operands {
        /// The operator, as written.
        op: &'static str,
        /// What it was given (`int and string`).
        found: String,
    },
    /// A comparison used as an operand of another (`a < b < c`).
    #[error("comparisons do not chain: write `a < b && b < c`")]
    Chained,
    /// A literal `unknown` inside an expression.
    #[error(
        "`unknown` is not a value to compute with: to ask whether `x` is known, write `is_known(x)`"
    )]
    UnknownLiteral,
}

impl Expr {
    /// A variable.
    pub fn var(name: impl Into<String>) -> Expr {
        Expr::Var(name.into())
    }

    /// A literal.
    pub fn lit(v: impl Into<Value>) -> Expr {
        Expr::Lit(v.into())
    }

    /// `l op r`.
    pub fn bin(op: BinOp, l: Expr, r: Expr) -> Expr {
        Expr::Bin {
            op,
            l: Box::new(l),
            r: Box::new(r),
        }
    }

    /// `l && r`.
    pub fn and(l: Expr, r: Expr) -> Expr {
        Expr::bin(BinOp::And, l, r)
    }

    /// `l || r`.
    pub fn or(l: Expr, r: Expr) -> Expr {
        Expr::bin(BinOp::Or, l, r)
    }

    /// `!e`.
    #[allow(clippy::should_implement_trait)]
    pub fn not(e: Expr) -> Expr {
        Expr::Not(Box::new(e))
    }

    /// `is_known(e)`.
    pub fn known(e: Expr) -> Expr {
        Expr::Known(Box::new(e))
    }

    /// The variables it reads, each once, in the order they first appear.
    pub fn vars(&self) -> Vec<&str> {
        let mut out: Vec<&str> = Vec::new();
        self.each_var(&mut |v| {
            if !out.contains(&v) {
                out.push(v);
            }
        });
        out
    }

    fn each_var<'a>(&'a self, f: &mut impl FnMut(&'a str)) {
        match self {
            Expr::Lit(_) => {}
            Expr::Var(v) => f(v),
            Expr::Not(e) | Expr::Neg(e) | Expr::Known(e) => e.each_var(f),
            Expr::Bin { l, r, .. } => {
                l.each_var(f);
                r.each_var(f);
            }
        }
    }

    /// Its static type, given each variable's (`None`: no such variable). A literal `unknown` is
    /// refused: it has no type, and `x == unknown` would never be true (`is_known(x)` asks).
    pub fn type_of(&self, var: &dyn Fn(&str) -> Option<Type>) -> Result<Type, ExprError> {
        match self {
            Expr::Lit(v) => v.type_of().ok_or(ExprError::UnknownLiteral),
            Expr::Var(name) => var(name).ok_or_else(|| ExprError::UnknownVar(name.clone())),
            Expr::Not(e) => match e.type_of(var)? {
                Type::Bool => Ok(Type::Bool),
                t => Err(operands("!", &[t])),
            },
            Expr::Neg(e) => match e.type_of(var)? {
                t if t.is_number() => Ok(t),
                t => Err(operands("-", &[t])),
            },
            Expr::Known(e) => e.type_of(var).map(|_| Type::Bool),
            Expr::Bin { op, l, r } => {
                if op.is_comparison() && (l.is_comparison() || r.is_comparison()) {
                    return Err(ExprError::Chained);
                }
                let (a, b) = (l.type_of(var)?, r.type_of(var)?);
                bin_type(*op, a, b).ok_or_else(|| operands(op.symbol(), &[a, b]))
            }
        }
    }

    fn is_comparison(&self) -> bool {
        matches!(self, Expr::Bin { op, .. } if op.is_comparison())
    }

    /// Its value, given each variable's (`None`: no such variable). Three-valued: an operation on
    /// `unknown` gives `unknown`, except `false && x`, `true || x` and `is_known(x)`.
    pub fn eval(&self, var: &dyn Fn(&str) -> Option<Value>) -> Result<Value, ExprError> {
        Ok(match self {
            Expr::Lit(Value::Unknown) => return Err(ExprError::UnknownLiteral),
            Expr::Lit(v) => v.clone(),
            Expr::Var(name) => var(name).ok_or_else(|| ExprError::UnknownVar(name.clone()))?,
            Expr::Known(e) => Value::Bool(e.eval(var)?.is_known()),
            Expr::Not(e) => match e.eval(var)? {
                Value::Bool(b) => Value::Bool(!b),
                Value::Unknown => Value::Unknown,
                v => return Err(operands_of("!", &[&v])),
            },
            Expr::Neg(e) => match e.eval(var)? {
                Value::Int(i) => i.checked_neg().map_or(Value::Unknown, Value::Int),
                Value::Float(x) => Value::float(-x),
                Value::Unknown => Value::Unknown,
                v => return Err(operands_of("-", &[&v])),
            },
            Expr::Bin { op, l, r } => {
                let a = l.eval(var)?;
                // `&&` and `||` look at the right side even when the left decides, so a type
                // error on either side is always found.
                let b = r.eval(var)?;
                eval_bin(*op, &a, &b)?
            }
        })
    }

    /// Whether it holds (evaluates to `true`) given the variables.
    pub fn holds(&self, var: &dyn Fn(&str) -> Option<Value>) -> Result<bool, ExprError> {
        self.eval(var).map(|v| v.is_true())
    }
}

fn operands(op: &'static str, types: &[Type]) -> ExprError {
    let found = match types {
        [t] => format!("a `{t}`"),
        [a, b] => format!("`{a}` and `{b}`"),
        _ => String::new(),
    };
    ExprError::Operands { op, found }
}

fn operands_of(op: &'static str, values: &[&Value]) -> ExprError {
    let found = values
        .iter()
        .map(|v| match v.type_of() {
            Some(t) => format!("`{v}` (a `{t}`)"),
            None => "`unknown`".to_string(),
        })
        .collect::<Vec<_>>()
        .join(" and ");
    ExprError::Operands { op, found }
}

/// The type of `a op b`, if `op` takes `a` and `b`.
fn bin_type(op: BinOp, a: Type, b: Type) -> Option<Type> {
    use BinOp::*;
    let numbers = a.is_number() && b.is_number();
    match op {
        And | Or => (a == Type::Bool && b == Type::Bool).then_some(Type::Bool),
        Eq | Ne => (a == b || numbers).then_some(Type::Bool),
        Lt | Le | Gt | Ge => (numbers || (a == Type::Str && b == Type::Str)).then_some(Type::Bool),
        Add | Sub | Mul | Div | Rem if numbers => Some(if a == Type::Int && b == Type::Int {
            Type::Int
        } else {
            Type::Float
        }),
        Add if a == Type::Str && b == Type::Str => Some(Type::Str),
        _ => None,
    }
}

fn eval_bin(op: BinOp, a: &Value, b: &Value) -> Result<Value, ExprError> {
    use BinOp::*;
    let (ta, tb) = (a.type_of(), b.type_of());
    // Types first (an unknown has every type), so `1 < "x"` is an error even when unknown.
    if let (Some(x), Some(y)) = (ta, tb) {
        if bin_type(op, x, y).is_none() {
            return Err(operands_of(op.symbol(), &[a, b]));
        }
    } else if let Some(t) = ta.or(tb) {
        let takes = match op {
            And | Or => t == Type::Bool,
            Eq | Ne => true,
            Lt | Le | Gt | Ge => t.is_number() || t == Type::Str,
            Add => t.is_number() || t == Type::Str,
            Sub | Mul | Div | Rem => t.is_number(),
        };
        if !takes {
            return Err(operands_of(op.symbol(), &[a, b]));
        }
    }
    Ok(match op {
        And => match (a, b) {
            (Value::Bool(false), _) | (_, Value::Bool(false)) => Value::Bool(false),
            (Value::Bool(true), Value::Bool(true)) => Value::Bool(true),
            _ => Value::Unknown,
        },
        Or => match (a, b) {
            (Value::Bool(true), _) | (_, Value::Bool(true)) => Value::Bool(true),
            (Value::Bool(false), Value::Bool(false)) => Value::Bool(false),
            _ => Value::Unknown,
        },
        _ if !a.is_known() || !b.is_known() => Value::Unknown,
        Eq | Ne | Lt | Le | Gt | Ge => {
            let ord = match (a, b) {
                (Value::Int(x), Value::Int(y)) => Some(x.cmp(y)),
                (Value::Str(x), Value::Str(y)) => Some(x.cmp(y)),
                (Value::Bool(x), Value::Bool(y)) => Some(x.cmp(y)),
                _ => match (a.as_f64(), b.as_f64()) {
                    (Some(x), Some(y)) => x.partial_cmp(&y),
                    _ => None,
                },
            };
            let Some(ord) = ord else {
                return Ok(Value::Unknown);
            };
            Value::Bool(match op {
                Eq => ord.is_eq(),
                Ne => ord.is_ne(),
                Lt => ord.is_lt(),
                Le => ord.is_le(),
                Gt => ord.is_gt(),
                _ => ord.is_ge(),
            })
        }
        Add | Sub | Mul | Div | Rem => match (a, b) {
            (Value::Str(x), Value::Str(y)) => Value::Str(format!("{x}{y}")),
            (Value::Int(x), Value::Int(y)) => match op {
                Add => x.checked_add(*y),
                Sub => x.checked_sub(*y),
                Mul => x.checked_mul(*y),
                Div => x.checked_div(*y),
                _ => x.checked_rem(*y),
            }
            .map_or(Value::Unknown, Value::Int),
            _ => match (a.as_f64(), b.as_f64()) {
                (Some(x), Some(y)) => Value::float(match op {
                    Add => x + y,
                    Sub => x - y,
                    Mul => x * y,
                    Div => x / y,
                    _ => x % y,
                }),
                _ => Value::Unknown,
            },
        },
    })
}

/// The canonical text, with the fewest parentheses that keep its meaning: `a && (b || c)`,
/// `!(x > 3)`, `-(a + b)`.
impl fmt::Display for Expr {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write_expr(self, f, 0)
    }
}

fn write_expr(e: &Expr, f: &mut fmt::Formatter<'_>, outer: u8) -> fmt::Result {
    match e {
        Expr::Lit(v) => write!(f, "{v}"),
        Expr::Var(v) => f.write_str(v),
        Expr::Known(e) => {
            f.write_str("is_known(")?;
            write_expr(e, f, 0)?;
            f.write_str(")")
        }
        Expr::Not(inner) | Expr::Neg(inner) => {
            f.write_str(if matches!(e, Expr::Not(_)) { "!" } else { "-" })?;
            // The operand binds tighter than any binary operator (`write_expr` parenthesises a
            // binary one); `-(-x)` and `-(-3)` keep theirs so the text never shows `--`.
            let paren = match inner.as_ref() {
                Expr::Neg(_) => true,
                Expr::Lit(Value::Int(i)) => *i < 0,
                Expr::Lit(Value::Float(x)) => x.is_sign_negative(),
                _ => false,
            };
            if paren {
                f.write_str("(")?;
            }
            write_expr(inner, f, 6)?;
            if paren {
                f.write_str(")")?;
            }
            Ok(())
        }
        Expr::Bin { op, l, r } => {
            let p = op.precedence();
            let paren = p < outer;
            if paren {
                f.write_str("(")?;
            }
            write_expr(l, f, if op.is_comparison() { p + 1 } else { p })?;
            write!(f, " {} ", op.symbol())?;
            write_expr(r, f, p + 1)?;
            if paren {
                f.write_str(")")?;
            }
            Ok(())
        }
    }
}
