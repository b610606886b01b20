//! The expression language of TDL conditions (docs/language.md, "State and conditions").
//!
//! A program declares *state variables* (`state battery_ok: bool = true;`), each of one [`Type`],
//! and writes *conditions* over them: [`Expr`], built from literals, variables, comparison,
//! arithmetic and logic. The engine (`tcm-core`) evaluates a condition whenever a variable it reads
//! changes; the trace checker (`tcm-trace`) evaluates it again from the recorded values; `tdl verify`
//! evaluates it in every state it explores. All three use [`Expr::eval`], so they cannot disagree.
//!
//! Values are three-valued for logic: [`Value::Unknown`] is a value of every type (a variable
//! not yet measured), an operation on it gives unknown (except `false && x`, `true || x` and
//! `is_known(x)`), and a condition holds only when it is `true`.
//!
//! ```
//! use tcm_expr::{BinOp, Expr, Type, Value};
//!
//! // battery > 20.5 && !fault
//! let cond = Expr::and(
//!     Expr::bin(BinOp::Gt, Expr::var("battery"), Expr::lit(20.5)),
//!     Expr::not(Expr::var("fault")),
//! );
//! assert_eq!(cond.to_string(), "battery > 20.5 && !fault");
//! let types = |v: &str| match v { "battery" => Some(Type::Float), "fault" => Some(Type::Bool), _ => None };
//! assert_eq!(cond.type_of(&types), Ok(Type::Bool));
//!
//! let values = |v: &str| match v { "battery" => Some(Value::Int(50)), "fault" => Some(Value::Bool(false)), _ => None };
//! assert!(cond.holds(&values).unwrap());
//! let unmeasured = |v: &str| match v { "battery" => Some(Value::Unknown), _ => Some(Value::Bool(false)) };
//! assert_eq!(cond.eval(&unmeasured), Ok(Value::Unknown));
//! ```
#![warn(missing_docs)]

mod expr;
mod value;

pub use expr::{BinOp, Expr, ExprError};
pub use value::{Type, TypeMismatch, Value};

#[cfg(test)]
mod tests;
