//! Parsing of state declarations' literals and of conditions (docs/language.md, "State and
//! conditions"): a small Pratt parser on `syn` tokens with Rust's precedence, `||` < `&&` <
//! comparisons (which do not chain) < `+ -` < `* / %` < unary `! -`; operands are literals, state
//! variables, `is_known(e)` and parenthesised conditions. A condition ends at `,`, `;`, a `{`
//! (a task's body) or the end of its group, none of which it consumes.

use proc_macro2::{Delimiter, Ident, Span};
use syn::Token;
use syn::parse::{ParseStream, Parser};
use tcm_expr::{BinOp, Value};

use super::{at_close, take_group};
use crate::ast::{Cond, CondExpr, StateLit};

/// Hint attached to errors in a condition.
pub(crate) const COND_HINT: &str = "a condition is an expression over state variables with \
     Rust's operators, as in `battery > 20.5 && !fault` or `is_known(position)`; it ends at `,` \
     or `;`";

/// Binding strength of unary `!` and `-`, above every binary operator.
const UNARY: u8 = 6;

/// Parses a condition, up to (not including) the `,`, `;` or `{` that ends it.
pub(crate) fn parse_cond(input: ParseStream) -> syn::Result<Cond> {
    let first = input.span();
    let mut last = first;
    let expr = expr_bp(input, 0, &mut last)?;
    if !ends(input) {
        let what = match input.cursor().token_tree() {
            Some((tt, _)) => format!("`{tt}`"),
            None => "end of input".to_owned(),
        };
        return Err(input.error(format!(
            "expected an operator, `,` or `;` after the condition, found {what}"
        )));
    }
    let span = first.join(last).unwrap_or(first);
    Ok(Cond { expr, span })
}

/// Whether the condition ends here.
fn ends(input: ParseStream) -> bool {
    input.is_empty()
        || input.peek(Token![,])
        || input.peek(Token![;])
        || input.peek(syn::token::Brace)
}

/// The binary operator at the input, with the number of punctuation tokens it takes; an error
/// for `=`, `&` and `|`, which Rust would read otherwise.
fn peek_op(input: ParseStream) -> syn::Result<Option<(BinOp, usize)>> {
    let two = [
        (input.peek(Token![||]), BinOp::Or),
        (input.peek(Token![&&]), BinOp::And),
        (input.peek(Token![==]), BinOp::Eq),
        (input.peek(Token![!=]), BinOp::Ne),
        (input.peek(Token![<=]), BinOp::Le),
        (input.peek(Token![>=]), BinOp::Ge),
    ];
    if let Some((_, op)) = two.iter().find(|(found, _)| *found) {
        return Ok(Some((*op, 2)));
    }
    let wrong = [
        (
            input.peek(Token![=]),
            "`=` assigns; to compare in a condition, write `==`",
        ),
        (
            input.peek(Token![&]),
            "in a condition, write `&&` for \"and\"",
        ),
        (
            input.peek(Token![|]),
            "in a condition, write `||` for \"or\"",
        ),
    ];
    if let Some((_, msg)) = wrong.iter().find(|(found, _)| *found) {
        return Err(input.error(*msg));
    }
    let one = [
        (input.peek(Token![<]), BinOp::Lt),
        (input.peek(Token![>]), BinOp::Gt),
        (input.peek(Token![+]), BinOp::Add),
        (input.peek(Token![-]), BinOp::Sub),
        (input.peek(Token![*]), BinOp::Mul),
        (input.peek(Token![/]), BinOp::Div),
        (input.peek(Token![%]), BinOp::Rem),
    ];
    Ok(one.iter().find(|(found, _)| *found).map(|(_, op)| (*op, 1)))
}

/// Consumes `n` punctuation tokens; the span of the first.
fn take_puncts(input: ParseStream, n: usize, last: &mut Span) -> syn::Result<Span> {
    let first = input.span();
    for _ in 0..n {
        let tt: proc_macro2::TokenTree = input.parse()?;
        *last = tt.span();
    }
    Ok(first.join(*last).unwrap_or(first))
}

/// An expression whose binary operators bind at least as strongly as `min`.
fn expr_bp(input: ParseStream, min: u8, last: &mut Span) -> syn::Result<CondExpr> {
    let mut lhs = prefix(input, last)?;
    // Whether `lhs` is a comparison written without parentheses, which another cannot follow.
    let mut bare_comparison = false;
    while !ends(input) {
        let Some((op, n)) = peek_op(input)? else {
            break;
        };
        let p = op.precedence();
        if p < min {
            break;
        }
        if op.is_comparison() && bare_comparison {
            return Err(input.error("comparisons do not chain: write `a < b && b < c`"));
        }
        let span = take_puncts(input, n, last)?;
        let rhs = expr_bp(input, p + 1, last)?;
        lhs = CondExpr::Bin {
            op,
            l: Box::new(lhs),
            r: Box::new(rhs),
            span,
        };
        bare_comparison = op.is_comparison();
    }
    Ok(lhs)
}

/// An operand: a unary operator and its operand, a literal, a variable, `is_known(e)`, or a
/// parenthesised condition.
fn prefix(input: ParseStream, last: &mut Span) -> syn::Result<CondExpr> {
    if input.peek(Token![!]) {
        let span = take_puncts(input, 1, last)?;
        let inner = expr_bp(input, UNARY, last)?;
        return Ok(CondExpr::Not(Box::new(inner), span));
    }
    if input.peek(Token![-]) {
        if input.peek2(syn::LitInt) || input.peek2(syn::LitFloat) {
            // A negative number is one literal (so `-9223372036854775808` is an `int`).
            let lit = parse_lit(input)?;
            *last = lit.span;
            return Ok(CondExpr::Lit(lit));
        }
        let span = take_puncts(input, 1, last)?;
        let inner = expr_bp(input, UNARY, last)?;
        return Ok(CondExpr::Neg(Box::new(inner), span));
    }
    if input.peek(syn::token::Paren) {
        let group = take_group(input, Delimiter::Parenthesis, "`(`")?;
        let close = group.close;
        let inner = group_expr(group.tokens, close)?;
        *last = close;
        return Ok(inner);
    }
    if input.peek(syn::Lit) {
        let lit = parse_lit(input)?;
        *last = lit.span;
        return Ok(CondExpr::Lit(lit));
    }
    if input.peek(syn::Ident) {
        let ident: Ident = input.parse()?;
        *last = ident.span();
        if ident == "unknown" {
            return Ok(CondExpr::Lit(StateLit {
                value: Value::Unknown,
                span: ident.span(),
            }));
        }
        if input.peek(syn::token::Paren) {
            if ident != "is_known" {
                return Err(syn::Error::new(
                    ident.span(),
                    format!(
                        "a condition cannot call `{ident}`: it reads state variables, and \
                         `is_known(x)` is its one function"
                    ),
                ));
            }
            let group = take_group(input, Delimiter::Parenthesis, "`(`")?;
            let close = group.close;
            let inner = group_expr(group.tokens, close)?;
            *last = close;
            return Ok(CondExpr::Known(Box::new(inner), ident.span()));
        }
        return Ok(CondExpr::Var(ident));
    }
    let what = match input.cursor().token_tree() {
        Some((tt, _)) => format!("`{tt}`"),
        None => "end of input".to_owned(),
    };
    Err(input.error(format!(
        "expected a condition (a state variable, a literal, `!`, `-`, `(` or `is_known(…)`), \
         found {what}"
    )))
}

/// The whole inside of a parenthesised group as one expression.
fn group_expr(tokens: proc_macro2::TokenStream, close: Span) -> syn::Result<CondExpr> {
    let parse = |input: ParseStream| {
        let mut last = close;
        let expr = expr_bp(input, 0, &mut last)?;
        if !input.is_empty() {
            return Err(input.error("expected an operator or `)` in the condition"));
        }
        Ok(expr)
    };
    parse.parse2(tokens).map_err(|err| at_close(err, close))
}

/// A literal: `true`, `false`, an integer, a float, a string, a negative number, or `unknown`.
pub(crate) fn parse_lit(input: ParseStream) -> syn::Result<StateLit> {
    let start = input.span();
    let negative = if input.peek(Token![-]) {
        input.parse::<Token![-]>()?;
        true
    } else {
        false
    };
    let lit: syn::Lit = if input.peek(syn::Ident) && !input.peek(syn::LitBool) {
        let ident: Ident = input.parse()?;
        if ident == "unknown" && !negative {
            return Ok(StateLit {
                value: Value::Unknown,
                span: ident.span(),
            });
        }
        return Err(syn::Error::new(
            ident.span(),
            format!(
                "expected a literal (`true`, `false`, a number, a string or `unknown`), found `{ident}`"
            ),
        ));
    } else {
        input.parse()?
    };
    let span = start.join(lit.span()).unwrap_or(start);
    let no_suffix = |suffix: &str, digits: &str| -> syn::Result<()> {
        if suffix.is_empty() {
            Ok(())
        } else {
            Err(syn::Error::new(
                lit.span(),
                format!("a state value takes no type suffix: write `{digits}`"),
            ))
        }
    };
    let value = match (&lit, negative) {
        (syn::Lit::Int(it), _) => {
            no_suffix(it.suffix(), it.base10_digits())?;
            let n = it.base10_parse::<i128>()?;
            let n = if negative { -n } else { n };
            Value::Int(i64::try_from(n).map_err(|_| {
                syn::Error::new(
                    span,
                    "this integer does not fit an `int` (a signed 64-bit integer)",
                )
            })?)
        }
        (syn::Lit::Float(it), _) => {
            no_suffix(it.suffix(), it.base10_digits())?;
            let x = it.base10_parse::<f64>()?;
            let x = if negative { -x } else { x };
            if !x.is_finite() {
                return Err(syn::Error::new(span, "this number does not fit a `float`"));
            }
            Value::Float(x)
        }
        (syn::Lit::Bool(it), false) => Value::Bool(it.value),
        (syn::Lit::Str(it), false) => Value::Str(it.value()),
        (_, true) => {
            return Err(syn::Error::new(span, "only a number can be negative"));
        }
        (other, false) => {
            return Err(syn::Error::new(
                other.span(),
                "expected `true`, `false`, a number, a string or `unknown`",
            ));
        }
    };
    Ok(StateLit { value, span })
}
