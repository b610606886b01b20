//! The diagnosis of state variables and conditions (docs/language.md, "State and conditions"):
//! a declaration's name and initial value; in each body, every condition type-checked against
//! the declared types with `tcm_expr`'s own rules (`Expr::type_of`, so the front end and the
//! engine agree), the variables of `activate on change of`, `set` and `state!(…)` declared, a
//! literal `set` of the variable's type, and `raise` with a name.

use proc_macro2::{Ident, Span};
use tcm_expr::{BinOp, ExprError, Type, Value};

use crate::ast::{CondExpr, ExternalName, StateDecl};
use crate::diagnostic::Diagnostic;
use crate::hir::{BodyScope, FileScope};

/// Names a condition gives a meaning of its own.
const RESERVED: &[&str] = &["unknown", "is_known"];

/// Checks a declaration: its name, and its initial value against its type.
pub(super) fn declaration(decl: &StateDecl, diags: &mut Vec<Diagnostic>) {
    let name = decl.name.to_string();
    if RESERVED.contains(&name.as_str()) {
        diags.push(
            Diagnostic::error(
                decl.span,
                format!("`{name}` cannot name a state variable: conditions give it a meaning"),
            )
            .with_hint("rename the variable"),
        );
    }
    let (Some(ty), Some(init)) = (decl.ty(), &decl.init) else {
        return;
    };
    if let Err(mismatch) = init.value.clone().coerce(ty) {
        diags.push(
            Diagnostic::error(
                init.span,
                format!(
                    "`{}` is {}, and `{name}` is {}",
                    init.value,
                    a(mismatch.found),
                    a(ty)
                ),
            )
            .with_hint(format!(
                "give a `{ty}` value, or `unknown` (the default without `= value`)"
            )),
        );
    }
}

/// Checks an environment declaration: each variable declared, each value of its type, each
/// condition a `bool` over declared variables, `at most` at least 1, an event's name not empty.
pub(super) fn environment(
    file: &FileScope<'_>,
    env: &crate::ast::EnvironmentDecl,
    diags: &mut Vec<Diagnostic>,
) {
    for e in &env.entries {
        match &e.target {
            crate::ast::EnvTarget::State(var) => match file.state(&var.to_string()) {
                None => diags.push(unknown_var(file, var, false)),
                Some(decl) => {
                    let Some(ty) = decl.ty() else { continue };
                    for v in &e.values {
                        if let Err(mismatch) = v.value.clone().coerce(ty) {
                            diags.push(
                                Diagnostic::error(
                                    v.span,
                                    format!(
                                        "`{var}` is {}, and `{}` {}",
                                        a(ty),
                                        v.value,
                                        a(mismatch.found)
                                    ),
                                )
                                .with_label(decl.span, format!("`{var}` is declared here"))
                                .with_hint(format!(
                                    "the outside may set it to `{ty}` values, or `unknown`"
                                )),
                            );
                        }
                    }
                }
            },
            crate::ast::EnvTarget::External(name) => {
                if name.value().is_empty() {
                    diags.push(
                        Diagnostic::error(name.span(), "the name of an external event is empty")
                            .with_hint("write the name the constraints wait for"),
                    );
                }
            }
        }
        if let Some((0, span)) = e.at_most {
            diags.push(
                Diagnostic::error(span, "`at most 0`: the entry would never be used")
                    .with_hint("remove the entry, or allow at least 1"),
            );
        }
        if let Some(cond) = &e.when {
            let mut declared = true;
            for var in cond.vars() {
                if file.state(&var.to_string()).is_none() {
                    declared = false;
                    diags.push(unknown_var(file, var, false));
                }
            }
            if !declared {
                continue;
            }
            let types = |name: &str| file.state(name).and_then(StateDecl::ty);
            match check(&cond.expr, &types) {
                Ok(Type::Bool) => {}
                Ok(ty) => diags.push(Diagnostic::error(
                    cond.span,
                    format!("this condition is {}, not a `bool`", a(ty)),
                )),
                Err((span, err, fix)) => diags.push(type_error(span, &err, fix)),
            }
        }
    }
}

/// Checks what a body says of state: its conditions, `activate on change of`, `set`, `raise`
/// and `state!(…)`.
pub(super) fn body(file: &FileScope<'_>, scope: &BodyScope<'_>, diags: &mut Vec<Diagnostic>) {
    for cond in &scope.conditions {
        let mut declared = true;
        for var in cond.vars() {
            match file.state(&var.to_string()) {
                Some(decl) => declared &= decl.ty().is_some(),
                None => {
                    declared = false;
                    let bare = matches!(&cond.expr, CondExpr::Var(_));
                    diags.push(unknown_var(file, var, bare));
                }
            }
        }
        if !declared {
            continue;
        }
        let types = |name: &str| file.state(name).and_then(StateDecl::ty);
        match check(&cond.expr, &types) {
            Ok(Type::Bool) => {}
            Ok(ty) => diags.push(
                Diagnostic::error(
                    cond.span,
                    format!("this condition is {}, not a `bool`", a(ty)),
                )
                .with_hint(
                    "a condition holds or not: compare the value, as in `battery > 20.5` or \
                     `mode == \"auto\"`",
                ),
            ),
            Err((span, err, fix)) => diags.push(type_error(span, &err, fix)),
        }
    }
    for var in &scope.changes {
        if file.state(&var.to_string()).is_none() {
            diags.push(unknown_var(file, var, false));
        }
    }
    for set in &scope.sets {
        let Some(decl) = file.state(&set.name.to_string()) else {
            diags.push(unknown_var(file, &set.name, false));
            continue;
        };
        let (Some(ty), Some((value, span))) = (decl.ty(), literal(&set.value)) else {
            continue;
        };
        if let Err(mismatch) = value.clone().coerce(ty) {
            diags.push(
                Diagnostic::error(
                    span,
                    format!(
                        "`{}` is {}, and `{value}` {}",
                        set.name,
                        a(ty),
                        a(mismatch.found)
                    ),
                )
                .with_label(decl.span, format!("`{}` is declared here", set.name))
                .with_hint(format!("set it to a `{ty}`, or to `unknown`")),
            );
        }
    }
    for raise in &scope.raises_external {
        if let ExternalName::Lit(lit) = &raise.name {
            if lit.value().is_empty() {
                diags.push(
                    Diagnostic::error(lit.span(), "the name of an external event is empty")
                        .with_hint(
                            "write the name the constraints wait for, as in `raise \"go\";` \
                             with `disable until external \"go\"`",
                        ),
                );
            }
        }
    }
    for it in &scope.state_uses {
        match &it.name {
            Err(err) => {
                diags.push(Diagnostic::error(it.span, err.to_string()).with_hint(
                    "`state!(x)` reads the state variable `x` as an `Option` of its type",
                ))
            }
            Ok(name) => {
                if file.state(&name.to_string()).is_none() {
                    diags.push(unknown_var(file, name, false));
                }
            }
        }
    }
}

/// "a `bool`", "an `int`".
fn a(ty: Type) -> String {
    match ty {
        Type::Int => "an `int`".to_owned(),
        ty => format!("a `{ty}`"),
    }
}

/// The type of `e`, or the first error with the span of the part it is in (operands first).
/// With `x == unknown`, what to write instead.
fn check(
    e: &CondExpr,
    types: &dyn Fn(&str) -> Option<Type>,
) -> Result<Type, (Span, ExprError, Option<String>)> {
    match e {
        CondExpr::Lit(_) | CondExpr::Var(_) => {}
        CondExpr::Not(inner, _) | CondExpr::Neg(inner, _) | CondExpr::Known(inner, _) => {
            check(inner, types)?;
        }
        CondExpr::Bin { op, l, r, span } => {
            // `x == unknown`: say what to write instead.
            if let (BinOp::Eq | BinOp::Ne, Some(other)) = (op, unknown_operand(l, r)) {
                let text = other.to_expr().to_string();
                let fix = match op {
                    BinOp::Eq => format!("!is_known({text})"),
                    _ => format!("is_known({text})"),
                };
                return Err((*span, ExprError::UnknownLiteral, Some(fix)));
            }
            check(l, types)?;
            check(r, types)?;
        }
    }
    e.to_expr()
        .type_of(types)
        .map_err(|err| (e.span(), err, None))
}

/// The other operand when one of `l`, `r` is the literal `unknown`.
fn unknown_operand<'e>(l: &'e CondExpr, r: &'e CondExpr) -> Option<&'e CondExpr> {
    let is_unknown = |e: &CondExpr| {
        matches!(
            e,
            CondExpr::Lit(lit) if !lit.value.is_known()
        )
    };
    if is_unknown(r) {
        Some(l)
    } else if is_unknown(l) {
        Some(r)
    } else {
        None
    }
}

fn type_error(span: Span, err: &ExprError, fix: Option<String>) -> Diagnostic {
    match err {
        ExprError::UnknownLiteral => {
            Diagnostic::error(span, "`unknown` is not a value to compute or compare with")
                .with_hint(match fix {
                    Some(fix) => format!("write `{fix}`: `is_known(x)` asks whether `x` is known"),
                    None => "to ask whether `x` is known, write `is_known(x)`; whether it is not, \
                     `!is_known(x)`"
                        .to_owned(),
                })
        }
        ExprError::Chained => Diagnostic::error(span, err.to_string())
            .with_hint("a comparison gives a `bool`, which another comparison does not take"),
        _ => Diagnostic::error(span, err.to_string()).with_hint(
            "`&&`, `||` and `!` take `bool`s; comparisons take two numbers, two strings or two \
             `bool`s (`==`, `!=`); `+ - * / %` take numbers (`+` also strings); an `int` and a \
             `float` mix",
        ),
    }
}

/// "no state variable `x` is declared", with the closest declared name if one is close.
fn unknown_var(file: &FileScope<'_>, var: &Ident, bare_condition: bool) -> Diagnostic {
    let name = var.to_string();
    let close = file
        .state_names()
        .map(|it| (distance(&name, it), it))
        .filter(|(d, it)| *d <= (it.len().max(name.len()) / 3).max(1))
        .min();
    let hint = match close {
        Some((_, it)) => format!("did you mean `{it}`?"),
        None if bare_condition => format!(
            "declare it: `state {name}: bool;`; to wait for a task's event instead, name its \
             point: `{name} completed`"
        ),
        None => format!("declare it: `state {name}: bool;` (or `int`, `float`, `string`)"),
    };
    Diagnostic::error(
        var.span(),
        format!("no state variable `{name}` is declared"),
    )
    .with_hint(hint)
}

/// Levenshtein distance, for suggestions.
fn distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut prev = row[0];
        row[0] = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let cur = row[j + 1];
            row[j + 1] = if ca == *cb {
                prev
            } else {
                1 + prev.min(cur).min(row[j])
            };
            prev = cur;
        }
    }
    row[b.len()]
}

/// A `set`'s value when it is a literal (`true`, `3`, `-2.5`, `"text"`, `unknown`), with its
/// span.
fn literal(e: &syn::Expr) -> Option<(Value, Span)> {
    use syn::spanned::Spanned;
    let (negative, lit) = match e {
        syn::Expr::Lit(it) => (false, &it.lit),
        syn::Expr::Unary(syn::ExprUnary {
            op: syn::UnOp::Neg(_),
            expr,
            ..
        }) => match expr.as_ref() {
            syn::Expr::Lit(it) => (true, &it.lit),
            _ => return None,
        },
        syn::Expr::Path(p) if p.path.is_ident("unknown") => {
            return Some((Value::Unknown, e.span()));
        }
        _ => return None,
    };
    let value = match lit {
        syn::Lit::Bool(it) if !negative => Value::Bool(it.value),
        syn::Lit::Str(it) if !negative => Value::Str(it.value()),
        syn::Lit::Int(it) if it.suffix().is_empty() => {
            let n = it.base10_parse::<i64>().ok()?;
            Value::Int(if negative { -n } else { n })
        }
        syn::Lit::Float(it) if it.suffix().is_empty() => {
            let x = it.base10_parse::<f64>().ok()?;
            Value::Float(if negative { -x } else { x })
        }
        _ => return None,
    };
    Some((value, e.span()))
}
