//! Generation of state variables and conditions (docs/language.md, "State and conditions"): a
//! variable is named at each use by its declaration, a `tdl::StateVar`, which the run declares on
//! first use; a condition is registered where its constraint is applied, `ctx.condition(&[vars],
//! expr)?`, its expression built from `tdl::Expr`'s constructors; the condition constraints
//! (`Constraint::disable`, `terminate`, `activate`, `skip_if`, `invariant`, `pause_while`), `set`
//! (`ctx.set_state`), `raise` (`ctx.raise`) and `state!(x)` (`ctx.read_state::<T>`).

use proc_macro2::{Ident, Literal, TokenStream};
use quote::quote;
use tcm_expr::{BinOp, Expr, Type, Value};

use super::lower::facet;
use crate::ast::{Cond, ExternalName, Facet, Raise, SetState, StateDecl, Then, When};
use crate::hir::FileScope;

/// `::tdl::StateType::X`.
fn type_tokens(ty: Type) -> TokenStream {
    match ty {
        Type::Bool => quote!(::tdl::StateType::Bool),
        Type::Int => quote!(::tdl::StateType::Int),
        Type::Float => quote!(::tdl::StateType::Float),
        Type::Str => quote!(::tdl::StateType::Str),
    }
}

/// The Rust type `state!(x)` reads a variable of type `ty` as (inside an `Option`).
fn rust_type(ty: Type) -> TokenStream {
    match ty {
        Type::Bool => quote!(bool),
        Type::Int => quote!(i64),
        Type::Float => quote!(f64),
        Type::Str => quote!(::std::string::String),
    }
}

/// An `i64` literal, `i64::MIN` included.
fn int_tokens(i: i64) -> TokenStream {
    if i == i64::MIN {
        return quote!(::core::primitive::i64::MIN);
    }
    let lit = Literal::i64_suffixed(i.abs());
    if i < 0 { quote!(-#lit) } else { quote!(#lit) }
}

/// An `f64` literal (finite, as every value is).
fn float_tokens(x: f64) -> TokenStream {
    let lit = Literal::f64_suffixed(x.abs());
    if x.is_sign_negative() {
        quote!(-#lit)
    } else {
        quote!(#lit)
    }
}

/// A `::tdl::StateValue`.
pub(super) fn value_tokens(v: &Value) -> TokenStream {
    match v {
        Value::Unknown => quote!(::tdl::StateValue::Unknown),
        Value::Bool(b) => quote!(::tdl::StateValue::Bool(#b)),
        Value::Int(i) => {
            let i = int_tokens(*i);
            quote!(::tdl::StateValue::Int(#i))
        }
        Value::Float(x) => {
            let x = float_tokens(*x);
            quote!(::tdl::StateValue::Float(#x))
        }
        Value::Str(s) => quote!(::tdl::StateValue::Str(::std::string::String::from(#s))),
    }
}

/// The declaration of a variable: `::tdl::StateVar::new("name", type, initial)`.
pub(super) fn state_var(decl: &StateDecl) -> TokenStream {
    let name = decl.name.to_string();
    let ty = type_tokens(decl.ty().unwrap_or(Type::Bool));
    let initial = value_tokens(&decl.initial());
    quote!(::tdl::StateVar::new(#name, #ty, #initial))
}

/// The declaration of the variable `name`, if the program declares it (the diagnosis reports
/// one it does not).
fn var_of(file: &FileScope<'_>, name: &str) -> Option<TokenStream> {
    file.state(name).map(state_var)
}

/// `::tdl::BinOp::X`.
fn op_tokens(op: BinOp) -> TokenStream {
    match op {
        BinOp::Or => quote!(::tdl::BinOp::Or),
        BinOp::And => quote!(::tdl::BinOp::And),
        BinOp::Eq => quote!(::tdl::BinOp::Eq),
        BinOp::Ne => quote!(::tdl::BinOp::Ne),
        BinOp::Lt => quote!(::tdl::BinOp::Lt),
        BinOp::Le => quote!(::tdl::BinOp::Le),
        BinOp::Gt => quote!(::tdl::BinOp::Gt),
        BinOp::Ge => quote!(::tdl::BinOp::Ge),
        BinOp::Add => quote!(::tdl::BinOp::Add),
        BinOp::Sub => quote!(::tdl::BinOp::Sub),
        BinOp::Mul => quote!(::tdl::BinOp::Mul),
        BinOp::Div => quote!(::tdl::BinOp::Div),
        BinOp::Rem => quote!(::tdl::BinOp::Rem),
    }
}

/// A `::tdl::Expr` built from its constructors.
pub(super) fn expr_tokens(e: &Expr) -> TokenStream {
    match e {
        Expr::Lit(v) => {
            let v = match v {
                Value::Unknown => quote!(::tdl::StateValue::Unknown),
                Value::Bool(b) => quote!(#b),
                Value::Int(i) => int_tokens(*i),
                Value::Float(x) => float_tokens(*x),
                Value::Str(s) => quote!(#s),
            };
            quote!(::tdl::Expr::lit(#v))
        }
        Expr::Var(name) => quote!(::tdl::Expr::var(#name)),
        Expr::Not(e) => {
            let e = expr_tokens(e);
            quote!(::tdl::Expr::not(#e))
        }
        Expr::Neg(e) => {
            let e = expr_tokens(e);
            quote!(::tdl::Expr::Neg(::std::boxed::Box::new(#e)))
        }
        Expr::Known(e) => {
            let e = expr_tokens(e);
            quote!(::tdl::Expr::known(#e))
        }
        Expr::Bin { op, l, r } => {
            let (op, l, r) = (op_tokens(*op), expr_tokens(l), expr_tokens(r));
            quote!(::tdl::Expr::bin(#op, #l, #r))
        }
    }
}

/// The condition registered on the run: `ctx.condition(&[vars], expr)?`, a `::tdl::CondId`.
pub(super) fn condition(file: &FileScope<'_>, cond: &Cond) -> TokenStream {
    let vars = cond
        .vars()
        .into_iter()
        .filter_map(|v| var_of(file, &v.to_string()));
    let expr = expr_tokens(&cond.to_expr());
    quote!(ctx.condition(&[#(#vars),*], #expr)?)
}

/// A trigger on a condition or on a variable's change, as a `::tdl::Constraint` value.
pub(super) fn constraint(file: &FileScope<'_>, when: &When, then: Then) -> TokenStream {
    match when {
        When::Changed(var) => {
            let var = var_of(file, &var.to_string()).unwrap_or_else(|| {
                quote!(::tdl::StateVar::new(
                    "",
                    ::tdl::StateType::Bool,
                    ::tdl::StateValue::Unknown
                ))
            });
            let when = quote!(::tdl::When::Changed(ctx.state_var(&#var)?));
            match then {
                Then::Terminate => quote!(::tdl::Constraint::terminate(#when)),
                Then::Enable(f) => {
                    let f = facet(f.unwrap_or(Facet::Handling));
                    quote!(::tdl::Constraint::disable(#f, #when))
                }
                _ => quote!(::tdl::Constraint::activate(#when)),
            }
        }
        When::Condition(cond) => {
            let c = condition(file, cond);
            match then {
                Then::Enable(f) => {
                    let f = facet(f.unwrap_or(Facet::Handling));
                    quote!(::tdl::Constraint::disable(#f, ::tdl::When::Condition(#c)))
                }
                Then::Terminate => quote!(::tdl::Constraint::terminate(::tdl::When::Condition(#c))),
                Then::Activate => quote!(::tdl::Constraint::activate(::tdl::When::Condition(#c))),
                Then::Skip => quote!(::tdl::Constraint::skip_if(#c)),
                Then::Invariant => quote!(::tdl::Constraint::invariant(#c)),
                Then::Pause => quote!(::tdl::Constraint::pause_while(#c)),
            }
        }
        // The other triggers are lowered by `lower::trigger`.
        _ => TokenStream::new(),
    }
}

/// `set x = expr;`: `ctx.set_state(&var, expr)?;` (`unknown` is `StateValue::Unknown`).
pub(super) fn set(file: &FileScope<'_>, it: &SetState) -> TokenStream {
    let Some(var) = var_of(file, &it.name.to_string()) else {
        return TokenStream::new();
    };
    let value = &it.value;
    let is_unknown = matches!(value, syn::Expr::Path(p) if p.path.is_ident("unknown"));
    if is_unknown {
        quote!(ctx.set_state(&#var, ::tdl::StateValue::Unknown)?;)
    } else {
        quote!(ctx.set_state(&#var, #value)?;)
    }
}

/// `raise "name";`: `ctx.raise("name")?;`; a name computed in Rust is borrowed, as for
/// `external (expr)`.
pub(super) fn raise(it: &Raise) -> TokenStream {
    match &it.name {
        ExternalName::Lit(lit) => quote!(ctx.raise(#lit)?;),
        ExternalName::Expr(expr) => {
            quote!(ctx.raise(::core::convert::AsRef::<str>::as_ref(&(#expr)))?;)
        }
    }
}

/// `state!(x)`: `ctx.read_state::<T>(&var)?`, an `Option<T>` typed by the declaration.
pub(super) fn read(file: &FileScope<'_>, name: &Ident) -> Option<TokenStream> {
    let decl = file.state(&name.to_string())?;
    let ty = rust_type(decl.ty()?);
    let var = state_var(decl);
    Some(quote!(ctx.read_state::<#ty>(&#var)?))
}
