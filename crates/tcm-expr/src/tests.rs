//! Tests of the expression language: three-valued logic, numbers, type errors, the canonical
//! text, the JSON form, and properties over generated expressions.

use crate::{BinOp, Expr, ExprError, Type, Value};
use proptest::prelude::*;

fn vars(name: &str) -> Option<Value> {
    Some(match name {
        "b" => Value::Bool(true),
        "f" => Value::Bool(false),
        "i" => Value::Int(7),
        "x" => Value::Float(2.5),
        "s" => Value::Str("dock".into()),
        "u" => Value::Unknown,
        _ => return None,
    })
}

fn types(name: &str) -> Option<Type> {
    Some(match name {
        "b" | "f" | "u" => Type::Bool,
        "i" => Type::Int,
        "x" => Type::Float,
        "s" => Type::Str,
        _ => return None,
    })
}

#[test]
fn three_valued_logic() {
    let u = || Expr::var("u");
    let eval = |e: Expr| e.eval(&vars).expect("no error");
    assert_eq!(eval(Expr::and(u(), Expr::var("f"))), Value::Bool(false));
    assert_eq!(eval(Expr::and(u(), Expr::var("b"))), Value::Unknown);
    assert_eq!(eval(Expr::or(Expr::var("b"), u())), Value::Bool(true));
    assert_eq!(eval(Expr::or(Expr::var("f"), u())), Value::Unknown);
    assert_eq!(eval(Expr::not(u())), Value::Unknown);
    assert_eq!(eval(Expr::known(u())), Value::Bool(false));
    assert_eq!(eval(Expr::known(Expr::var("i"))), Value::Bool(true));
    // Neither a condition nor its negation holds while it is unknown.
    assert!(!Expr::not(u()).holds(&vars).expect("no error"));
    assert!(!u().holds(&vars).expect("no error"));
}

#[test]
fn numbers_mix_and_overflow_is_unknown() {
    let eval = |e: Expr| e.eval(&vars).expect("no error");
    assert_eq!(
        eval(Expr::bin(BinOp::Add, Expr::var("i"), Expr::var("x"))),
        Value::Float(9.5)
    );
    assert_eq!(
        eval(Expr::bin(BinOp::Eq, Expr::lit(1), Expr::lit(1.0))),
        Value::Bool(true)
    );
    assert_eq!(
        eval(Expr::bin(BinOp::Div, Expr::var("i"), Expr::lit(0))),
        Value::Unknown
    );
    assert_eq!(
        eval(Expr::bin(BinOp::Div, Expr::var("x"), Expr::lit(0.0))),
        Value::Unknown
    );
    assert_eq!(
        eval(Expr::bin(BinOp::Mul, Expr::lit(i64::MAX), Expr::lit(2))),
        Value::Unknown
    );
    assert_eq!(
        eval(Expr::Neg(Box::new(Expr::lit(i64::MIN)))),
        Value::Unknown
    );
    assert_eq!(
        eval(Expr::bin(BinOp::Rem, Expr::lit(7), Expr::lit(3))),
        Value::Int(1)
    );
    assert_eq!(
        eval(Expr::bin(BinOp::Add, Expr::var("s"), Expr::lit("_2"))),
        Value::Str("dock_2".into())
    );
}

#[test]
fn type_errors_are_named() {
    let e = Expr::bin(BinOp::Lt, Expr::var("i"), Expr::var("s"));
    assert_eq!(
        e.type_of(&types).expect_err("an error").to_string(),
        "`<` cannot be applied to `int` and `string`"
    );
    assert!(matches!(
        e.eval(&vars),
        Err(ExprError::Operands { op: "<", .. })
    ));
    let chained = Expr::bin(
        BinOp::Lt,
        Expr::bin(BinOp::Lt, Expr::var("i"), Expr::lit(3)),
        Expr::var("b"),
    );
    assert_eq!(chained.type_of(&types), Err(ExprError::Chained));
    assert_eq!(
        Expr::var("nope").type_of(&types),
        Err(ExprError::UnknownVar("nope".into()))
    );
    assert_eq!(
        Expr::bin(BinOp::Eq, Expr::var("u"), Expr::Lit(Value::Unknown)).type_of(&types),
        Err(ExprError::UnknownLiteral)
    );
    // An unknown operand is still checked against the operator's other operand.
    let e = Expr::bin(BinOp::Sub, Expr::var("s"), Expr::var("u"));
    assert!(matches!(
        e.eval(&vars),
        Err(ExprError::Operands { op: "-", .. })
    ));
}

#[test]
fn canonical_text_keeps_only_needed_parentheses() {
    let a = || Expr::var("a");
    let b = || Expr::var("b");
    let c = || Expr::var("c");
    let text = |e: Expr| e.to_string();
    assert_eq!(text(Expr::and(a(), Expr::or(b(), c()))), "a && (b || c)");
    assert_eq!(text(Expr::or(Expr::and(a(), b()), c())), "a && b || c");
    assert_eq!(
        text(Expr::bin(BinOp::Sub, a(), Expr::bin(BinOp::Sub, b(), c()))),
        "a - (b - c)"
    );
    assert_eq!(
        text(Expr::bin(BinOp::Sub, Expr::bin(BinOp::Sub, a(), b()), c())),
        "a - b - c"
    );
    assert_eq!(
        text(Expr::not(Expr::bin(BinOp::Gt, a(), Expr::lit(62.0)))),
        "!(a > 62.0)"
    );
    assert_eq!(text(Expr::Neg(Box::new(Expr::lit(-3)))), "-(-3)");
    assert_eq!(
        text(Expr::known(Expr::bin(BinOp::Add, a(), b()))),
        "is_known(a + b)"
    );
    assert_eq!(
        text(Expr::bin(BinOp::Eq, a(), Expr::lit("x\"y"))),
        "a == \"x\\\"y\""
    );
}

#[test]
fn json_form() {
    let e = Expr::and(
        Expr::var("ok"),
        Expr::bin(BinOp::Ge, Expr::var("t"), Expr::lit(2.0)),
    );
    let json = serde_json::to_string(&e).expect("no error");
    assert_eq!(
        json,
        r#"{"bin":{"op":"and","l":{"var":"ok"},"r":{"bin":{"op":"ge","l":{"var":"t"},"r":{"lit":2.0}}}}}"#
    );
    assert_eq!(serde_json::from_str::<Expr>(&json).expect("no error"), e);
    let values: Vec<Value> =
        serde_json::from_str(r#"[null, true, 3, 3.0, "s"]"#).expect("no error");
    assert_eq!(
        values,
        [
            Value::Unknown,
            Value::Bool(true),
            Value::Int(3),
            Value::Float(3.0),
            Value::Str("s".into())
        ]
    );
}

#[test]
fn coercion() {
    assert_eq!(Value::Int(3).coerce(Type::Float), Ok(Value::Float(3.0)));
    assert_eq!(Value::Unknown.coerce(Type::Str), Ok(Value::Unknown));
    let err = Value::Str("x".into())
        .coerce(Type::Bool)
        .expect_err("an error");
    assert_eq!(
        err.to_string(),
        "expected a value of type `bool`, found `\"x\"` of type `string`"
    );
    assert_eq!(Value::float(f64::NAN), Value::Unknown);
}

fn leaf() -> impl Strategy<Value = Expr> {
    prop_oneof![
        prop::sample::select(vec!["b", "f", "i", "x", "s", "u"]).prop_map(Expr::var),
        any::<bool>().prop_map(Expr::lit),
        (-5i64..5).prop_map(Expr::lit),
        (-5.0f64..5.0).prop_map(Expr::lit),
        Just(Expr::lit("dock")),
    ]
}

fn expr() -> impl Strategy<Value = Expr> {
    leaf().prop_recursive(5, 40, 2, |inner| {
        prop_oneof![
            inner.clone().prop_map(Expr::not),
            inner.clone().prop_map(|e| Expr::Neg(Box::new(e))),
            inner.clone().prop_map(Expr::known),
            (
                prop::sample::select(BinOp::ALL.to_vec()),
                inner.clone(),
                inner
            )
                .prop_map(|(op, l, r)| Expr::bin(op, l, r)),
        ]
    })
}

proptest! {
    /// A statically well-typed expression never fails to evaluate, whatever the values (unknowns
    /// included), and its value has the static type or is unknown.
    #[test]
    fn well_typed_expressions_evaluate(e in expr(), unknown in any::<bool>()) {
        if let Ok(ty) = e.type_of(&types) {
            let values = |n: &str| if unknown && n != "s" { Some(Value::Unknown) } else { vars(n) };
            let v = e.eval(&values);
            prop_assert!(v.is_ok(), "{e} failed: {v:?}");
            let v = v.unwrap_or_default();
            prop_assert!(v.type_of().is_none_or(|t| t == ty), "{e}: {v} is not a {ty}");
        }
    }

    /// The JSON form reads back as the same expression.
    #[test]
    fn json_round_trip(e in expr()) {
        let json = serde_json::to_string(&e).unwrap_or_default();
        prop_assert_eq!(serde_json::from_str::<Expr>(&json).ok(), Some(e));
    }

    /// `&&` and `||` are commutative in three-valued logic.
    #[test]
    fn logic_commutes(a in prop::sample::select(vec!["b", "f", "u"]), b in prop::sample::select(vec!["b", "f", "u"])) {
        let (x, y) = (Expr::var(a), Expr::var(b));
        prop_assert_eq!(Expr::and(x.clone(), y.clone()).eval(&vars), Expr::and(y.clone(), x.clone()).eval(&vars));
        prop_assert_eq!(Expr::or(x.clone(), y.clone()).eval(&vars), Expr::or(y, x).eval(&vars));
    }
}
