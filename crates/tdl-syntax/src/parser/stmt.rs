//! Parsing of task-body statements: TDL statements, the Rust control flow that contains them, and
//! plain Rust statements kept as tokens.
//!
//! A statement is recognised by its first tokens (docs/language.md): `[label:]* spawn T`,
//! `[label:]* with (...)`, `let p = spawn T`, `succeed;`, `fail ...;`, `bypass;`, `trigger;`, and
//! `bind name = expr;` and `TAG constraint;` (in Rust, `ident ident` never starts a statement). `if`, `for`, `while`,
//! `loop`, `match` and blocks are walked only when they contain a TDL statement; otherwise they
//! stay Rust tokens, so their value and typing are exactly Rust's.

use proc_macro2::{Delimiter, Ident, Span, TokenStream, TokenTree};
use syn::buffer::Cursor;
use syn::ext::IdentExt;
use syn::parse::ParseStream;
use syn::parse::discouraged::Speculative;
use syn::punctuated::Punctuated;
use syn::{Token, Type};

use super::constraint::{
    CONSTRAINT_HINT, call_args, parse_constraint, parse_constraint_list, parse_tag,
};
use super::{Cx, attempt, parse_block, parse_group, recover, take_group};
use crate::ast::{
    Arm, Bind, BindTarget, Binding, Block, ConstraintStmt, Else, ExternalName, Fail, For, If, Log,
    Loop, Match, Raise, ResourceOp, ResourceStmt, Retry, RustStmt, SetState, Spawn, Stmt, While,
    WithGroup,
};
use crate::keyword::{peek_words, starts_constraint};
use quote::ToTokens;

mod control;

use control::{control_flow, rust_stmt, tokens_between};

/// Rust keywords that can start a statement followed by an identifier, so `kw ident` is Rust.
const RUST_KEYWORDS: &[&str] = &[
    "as", "async", "await", "break", "const", "continue", "crate", "dyn", "else", "enum", "extern",
    "false", "fn", "for", "if", "impl", "in", "let", "loop", "macro", "match", "mod", "move",
    "mut", "pub", "ref", "return", "static", "struct", "super", "trait", "true", "type", "union",
    "unsafe", "use", "where", "while", "yield", "Self",
];

/// Parses statements until the end of `input`, with the identifiers each names
/// ([`Block::mentions`]); never fails.
pub(crate) fn parse_stmts(input: ParseStream, cx: &mut Cx) -> (Vec<Stmt>, Vec<Vec<String>>) {
    let mut out = Vec::new();
    let mut mentions = Vec::new();
    while !input.is_empty() {
        if input.peek(Token![;]) {
            let _ = input.parse::<Token![;]>();
            continue;
        }
        let hint = stmt_hint(input);
        cx.hint = None;
        let start = input.cursor();
        match attempt(input, cx, stmt) {
            Ok(it) => {
                out.push(it);
                mentions.push(idents(control::tokens_between(start, input.cursor())));
            }
            Err(err) => {
                let hint = cx.hint.take().or(hint);
                cx.syn_error(err, hint);
                recover(input);
            }
        }
    }
    (out, mentions)
}

/// The identifiers `tokens` name, nested groups included, and those string literals name as a
/// format string names its inline arguments, sorted and each once.
pub(crate) fn idents(tokens: TokenStream) -> Vec<String> {
    fn walk(tokens: TokenStream, out: &mut Vec<String>) {
        for tt in tokens {
            match tt {
                proc_macro2::TokenTree::Ident(i) => out.push(i.to_string()),
                proc_macro2::TokenTree::Group(g) => walk(g.stream(), out),
                proc_macro2::TokenTree::Literal(l) => {
                    if let Ok(text) = syn::parse2::<syn::LitStr>(TokenTree::Literal(l).into()) {
                        out.extend(format_names(&text.value()));
                    }
                }
                _ => {}
            }
        }
    }
    let mut out = Vec::new();
    walk(tokens, &mut out);
    out.sort();
    out.dedup();
    out
}

/// The variables a format string names inline (`{x}`, `{x:?}`), as `format!` reads it: a string
/// that is no format names none, so its names only make a clone that was not needed.
fn format_names(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut rest = text;
    while let Some(open) = rest.find('{') {
        rest = &rest[open + 1..];
        if let Some(after) = rest.strip_prefix('{') {
            rest = after;
            continue;
        }
        let end = rest.find(['}', ':']).unwrap_or(rest.len());
        let name = &rest[..end];
        if name.starts_with(|c: char| c.is_alphabetic() || c == '_')
            && name.chars().all(|c| c.is_alphanumeric() || c == '_')
        {
            out.push(name.to_string());
        }
    }
    out
}

fn first_ident(cursor: Cursor<'_>) -> Option<(String, Cursor<'_>)> {
    cursor
        .ident()
        .map(|(ident, rest)| (ident.to_string(), rest))
}

fn stmt_hint(input: ParseStream) -> Option<&'static str> {
    let mut cursor = input.cursor();
    while let Some((_, rest)) = cursor.ident() {
        match rest.punct() {
            Some((p, after))
                if p.as_char() == ':' && after.punct().is_none_or(|(q, _)| q.as_char() != ':') =>
            {
                cursor = after;
            }
            _ => break,
        }
    }
    match first_ident(cursor)?.0.as_str() {
        "spawn" | "let" => Some(
            "a spawn reads `[label:] spawn task(args) [with constraint, ...];`; \
             a waited spawn `let v = spawn task(args) with wait;`",
        ),
        "with" => Some("a group reads `[label:] with (constraint, ...) { ... }`"),
        "fail" => Some("write `fail;`, `fail Exc;` or `fail Exc { field: value, ... };`"),
        "bind" if is_bind(input.cursor()) => {
            Some("a binding reads `bind name = node;`, with `node` a `tdl::NodeId` expression")
        }
        _ if is_constraint_stmt(input.cursor()) => Some(CONSTRAINT_HINT),
        _ => None,
    }
}

/// True when the cursor is at `keyword` followed by an identifier.
fn is_keyword_then_ident(cursor: Cursor<'_>, keyword: &str) -> bool {
    match first_ident(cursor) {
        Some((word, rest)) => word == keyword && rest.ident().is_some(),
        None => false,
    }
}

/// True when the cursor is at `with (...)` followed by `{` or `spawn`.
fn is_with(cursor: Cursor<'_>) -> bool {
    let Some((word, rest)) = first_ident(cursor) else {
        return false;
    };
    let Some((_, _, after)) = (word == "with")
        .then(|| rest.group(Delimiter::Parenthesis))
        .flatten()
    else {
        return false;
    };
    after.group(Delimiter::Brace).is_some() || is_keyword_then_ident(after, "spawn")
}

/// True when the cursor is at `TAG constraint`: an identifier (not a Rust keyword other than
/// `self`), optional `[index]` groups, then an identifier starting a constraint.
fn is_constraint_stmt(cursor: Cursor<'_>) -> bool {
    let Some((word, mut rest)) = first_ident(cursor) else {
        return false;
    };
    if word != "self" && RUST_KEYWORDS.contains(&word.as_str()) {
        return false;
    }
    while let Some((_, _, after)) = rest.group(Delimiter::Bracket) {
        rest = after;
    }
    peek_words(rest, 1)
        .first()
        .and_then(|it| it.text)
        .is_some_and(starts_constraint)
}

/// True when the cursor is at `bind IDENT =` (not `==`).
fn is_bind(cursor: Cursor<'_>) -> bool {
    let Some((word, rest)) = first_ident(cursor) else {
        return false;
    };
    let Some((_, after)) = rest.ident().filter(|_| word == "bind") else {
        return false;
    };
    match after.punct() {
        Some((p, next)) => {
            p.as_char() == '=' && next.punct().is_none_or(|(q, _)| q.as_char() != '=')
        }
        None => false,
    }
}

/// True when the cursor is at `word ;`.
fn is_bare(cursor: Cursor<'_>, keyword: &str) -> bool {
    match first_ident(cursor) {
        Some((word, rest)) => {
            word == keyword && rest.punct().is_some_and(|(p, _)| p.as_char() == ';')
        }
        None => false,
    }
}

/// The resource statement at the cursor: `lock r;`, `unlock r;`, `reserve r;`, `unreserve r;`
/// (a keyword, an identifier and `;`, which no Rust statement is).
fn resource_op(cursor: Cursor<'_>) -> Option<ResourceOp> {
    let (word, rest) = first_ident(cursor)?;
    let op = match word.as_str() {
        "lock" => ResourceOp::Lock,
        "unlock" => ResourceOp::Unlock,
        "reserve" => ResourceOp::Reserve,
        "unreserve" => ResourceOp::Unreserve,
        _ => return None,
    };
    let (_, after) = rest.ident()?;
    after
        .punct()
        .is_some_and(|(p, _)| p.as_char() == ';')
        .then_some(op)
}

fn stmt(input: ParseStream, cx: &mut Cx) -> syn::Result<Stmt> {
    if input.peek(Token![#]) {
        let fork = input.fork();
        if let Ok(attrs) = fork.call(syn::Attribute::parse_outer) {
            if attrs.iter().any(crate::lint::is_tdl) {
                input.advance_to(&fork);
                return allowed_stmt(input, cx, &attrs);
            }
        }
    }
    let mut labels = Vec::new();
    while input.peek(syn::Ident) && input.peek2(Token![:]) && !input.peek2(Token![::]) {
        labels.push(input.parse::<Ident>()?);
        input.parse::<Token![:]>()?;
    }
    let cursor = input.cursor();
    if is_keyword_then_ident(cursor, "spawn") {
        return spawn(input, cx, labels, None).map(Stmt::Spawn);
    }
    if let Some((word, rest)) = first_ident(cursor) {
        let ends = rest.eof() || rest.punct().is_some_and(|(p, _)| p.as_char() == ';');
        if word == "spawn" && ends {
            return Err(input.error("expected a task name after `spawn`"));
        }
    }
    if is_with(cursor) {
        return with_group(input, cx, labels).map(Stmt::With);
    }
    if let Some(label) = labels.first() {
        return Err(syn::Error::new(
            label.span(),
            format!("expected `spawn` or `with` after the label `{label}:`"),
        ));
    }
    if input.peek(Token![let]) {
        if let Some(binding) = let_spawn(input)? {
            return spawn(input, cx, Vec::new(), Some(binding)).map(Stmt::Spawn);
        }
    }
    for (keyword, make) in [
        ("succeed", Stmt::Succeed as fn(Span) -> Stmt),
        ("bypass", Stmt::Bypass),
        ("trigger", Stmt::Trigger),
    ] {
        if is_bare(cursor, keyword) {
            let ident = input.call(Ident::parse_any)?;
            input.parse::<Token![;]>()?;
            return Ok(make(ident.span()));
        }
    }
    if let Some(binding) = assign_spawn(input)? {
        return spawn(input, cx, Vec::new(), Some(binding)).map(Stmt::Spawn);
    }
    if is_bare(cursor, "retry") || is_keyword_then_ident(cursor, "retry") {
        return retry(input).map(Stmt::Retry);
    }
    if is_bare(cursor, "fail") || is_keyword_then_ident(cursor, "fail") {
        return fail(input, cx).map(Stmt::Fail);
    }
    if is_bind(cursor) {
        return bind(input).map(Stmt::Bind);
    }
    if let Some(op) = resource_op(cursor) {
        let keyword = input.call(Ident::parse_any)?;
        let name: Ident = input.parse()?;
        input.parse::<Token![;]>()?;
        return Ok(Stmt::Resource(ResourceStmt {
            op,
            name,
            span: keyword.span(),
        }));
    }
    if is_set(cursor) {
        return set_state(input, cx).map(Stmt::Set);
    }
    if is_raise(cursor) {
        return raise(input, cx).map(Stmt::Raise);
    }
    if is_log(cursor) {
        return log(input, cx).map(Stmt::Log);
    }
    if is_constraint_stmt(cursor) {
        return constraint_stmt(input, cx).map(Stmt::Constrain);
    }
    if let Some((word, rest)) = first_ident(cursor) {
        if let (true, Some((name, _))) = (word == "raise", rest.ident()) {
            cx.hint = Some(RAISE_HINT);
            return Err(syn::Error::new(
                name.span(),
                format!("the name of an external event is a string: write `raise \"{name}\";`"),
            ));
        }
        if let (true, Some((name, _))) = (word == "log", rest.ident()) {
            cx.hint = Some(LOG_HINT);
            return Err(syn::Error::new(
                name.span(),
                format!("a log line starts with its format string: write `log \"{{{name}}}\";`"),
            ));
        }
    }
    if let Some(it) = control_flow(input, cx)? {
        return Ok(it);
    }
    rust_stmt(input, cx).map(Stmt::Rust)
}

/// The statement after `attrs`, attributes of which some name TDL lints: those lints are allowed
/// over the statement (docs/language.md, "Accepting a warning"). The other attributes stay on a
/// Rust statement; a TDL statement takes none.
fn allowed_stmt(input: ParseStream, cx: &mut Cx, attrs: &[syn::Attribute]) -> syn::Result<Stmt> {
    let Some(first) = attrs.first() else {
        return stmt(input, cx);
    };
    if input.is_empty() || input.peek(Token![;]) {
        cx.hint = Some(
            "an allow goes right before the statement whose warning it accepts, or on the task",
        );
        return Err(syn::Error::new(
            syn::spanned::Spanned::span(first),
            "expected a statement after `#[allow(tdl::…)]`",
        ));
    }
    let start = input.cursor();
    let mut it = stmt(input, cx)?;
    let covered = tokens_between(start, input.cursor());
    let to = crate::last_span(&covered).unwrap_or(first.pound_token.span);
    cx.allow(attrs, to);
    let rust = crate::lint::rust_attrs(attrs);
    match &mut it {
        Stmt::Rust(stmt) => {
            let mut tokens: TokenStream = rust.into_iter().map(|(_, it)| it).collect();
            tokens.extend(std::mem::take(&mut stmt.tokens));
            stmt.tokens = tokens;
        }
        _ => {
            if let Some((span, _)) = rust.first() {
                cx.hint = Some(
                    "a TDL statement takes no Rust attribute; only `#[allow(tdl::…)]` goes on it",
                );
                return Err(syn::Error::new(
                    *span,
                    "Rust attributes cannot go on a TDL statement",
                ));
            }
        }
    }
    Ok(it)
}

/// True when the cursor is at `set IDENT =` (not `==`).
fn is_set(cursor: Cursor<'_>) -> bool {
    let Some((word, rest)) = first_ident(cursor) else {
        return false;
    };
    let Some((_, after)) = rest.ident().filter(|_| word == "set") else {
        return false;
    };
    match after.punct() {
        Some((p, next)) => {
            p.as_char() == '=' && next.punct().is_none_or(|(q, _)| q.as_char() != '=')
        }
        None => false,
    }
}

/// True when the cursor is at `raise "name"` or `raise (…)`.
fn is_raise(cursor: Cursor<'_>) -> bool {
    let Some((word, rest)) = first_ident(cursor) else {
        return false;
    };
    word == "raise" && (rest.literal().is_some() || rest.group(Delimiter::Parenthesis).is_some())
}

const SET_HINT: &str = "a set reads `set name = value;`, the value any Rust expression \
     convertible to the variable's type (`true`, `3`, `x + 1.5`, `\"text\"`) or `unknown`";

const RAISE_HINT: &str = "a raise reads `raise \"name\";`, or `raise (expr);` with the name \
     computed in Rust; `disable until external \"name\"`, `terminate at external \"name\"` and \
     `activate at external \"name\"` wait for it";

/// `set name = expr;`.
fn set_state(input: ParseStream, cx: &mut Cx) -> syn::Result<SetState> {
    cx.hint = Some(SET_HINT);
    let keyword = input.call(Ident::parse_any)?;
    let name: Ident = input.parse()?;
    input.parse::<Token![=]>()?;
    let value: syn::Expr = input.parse()?;
    if !input.peek(Token![;]) {
        return Err(input.error("expected `;` after `set name = value`"));
    }
    input.parse::<Token![;]>()?;
    Ok(SetState {
        name,
        value,
        span: keyword.span(),
    })
}

/// `raise "name";` or `raise (expr);`.
fn raise(input: ParseStream, cx: &mut Cx) -> syn::Result<Raise> {
    cx.hint = Some(RAISE_HINT);
    let keyword = input.call(Ident::parse_any)?;
    let name = if input.peek(syn::LitStr) {
        ExternalName::Lit(input.parse()?)
    } else if input.peek(syn::token::Paren) {
        let group = take_group(input, Delimiter::Parenthesis, "`(`")?;
        ExternalName::Expr(super::parse_group_as(group)?)
    } else {
        let lit: syn::Lit = input.parse()?;
        return Err(syn::Error::new(
            lit.span(),
            format!(
                "expected the external event's name as a string, found `{}`",
                lit.to_token_stream()
            ),
        ));
    };
    if !input.peek(Token![;]) {
        return Err(input.error("expected `;` after `raise \"name\"`"));
    }
    input.parse::<Token![;]>()?;
    Ok(Raise {
        name,
        span: keyword.span(),
    })
}

/// True when the cursor is at `log "…"`.
fn is_log(cursor: Cursor<'_>) -> bool {
    let Some((word, rest)) = first_ident(cursor) else {
        return false;
    };
    word == "log"
        && rest.literal().is_some_and(|(lit, _)| {
            let text = lit.to_string();
            text.starts_with('"') || text.starts_with("r\"") || text.starts_with("r#")
        })
}

const LOG_HINT: &str = "a log reads `log \"text\";` or `log \"format\", args…;`, formatted as \
     `format!` formats (`log \"battery {:.1}%\", state!(battery);`, `log \"at {door}\";`)";

/// `log "format", args…;`.
fn log(input: ParseStream, cx: &mut Cx) -> syn::Result<Log> {
    cx.hint = Some(LOG_HINT);
    let keyword = input.call(Ident::parse_any)?;
    let format: syn::LitStr = input.parse()?;
    let mut args = Vec::new();
    while input.peek(Token![,]) {
        input.parse::<Token![,]>()?;
        if input.peek(Token![;]) {
            break;
        }
        args.push(input.parse::<syn::Expr>()?);
    }
    if !input.peek(Token![;]) {
        return Err(input.error("expected `,` and an argument, or `;`, after the log's format"));
    }
    input.parse::<Token![;]>()?;
    Ok(Log {
        format,
        args,
        span: keyword.span(),
    })
}

/// Parses `place =` when a `spawn TASK` follows (an assignment of a waited spawn's value to an
/// existing variable); otherwise consumes nothing.
fn assign_spawn(input: ParseStream) -> syn::Result<Option<Binding>> {
    let mut cursor = input.cursor();
    let mut place = TokenStream::new();
    let mut after_joint = false;
    let mut count = 0usize;
    while let Some((tt, next)) = cursor.token_tree() {
        count += 1;
        if let TokenTree::Punct(p) = &tt {
            match p.as_char() {
                ';' => return Ok(None),
                // A lone `=` (not `==`, `+=`, `=>`, `<=`) followed by `spawn task`.
                '=' if !after_joint && p.spacing() == proc_macro2::Spacing::Alone => {
                    if place.is_empty() || !is_keyword_then_ident(next, "spawn") {
                        return Ok(None);
                    }
                    let Ok(expr) = syn::parse2::<syn::Expr>(place) else {
                        return Ok(None);
                    };
                    // Past the place and the `=`.
                    input.step(|c| {
                        let mut c = *c;
                        for _ in 0..count {
                            if let Some((_, next)) = c.token_tree() {
                                c = next;
                            }
                        }
                        Ok(((), c))
                    })?;
                    return Ok(Some(Binding {
                        target: BindTarget::Assign(expr),
                        ty: None,
                    }));
                }
                _ => {}
            }
        }
        after_joint =
            matches!(&tt, TokenTree::Punct(p) if p.spacing() == proc_macro2::Spacing::Joint);
        place.extend([tt]);
        cursor = next;
    }
    Ok(None)
}

/// `retry;` or `retry with (args);`.
fn retry(input: ParseStream) -> syn::Result<Retry> {
    let span = input.call(Ident::parse_any)?.span();
    let args = if input.peek(Token![;]) {
        None
    } else {
        let with = input.call(Ident::parse_any)?;
        if with != "with" || !input.peek(syn::token::Paren) {
            return Err(syn::Error::new(
                with.span(),
                "expected `retry;` or `retry with (arguments);`",
            ));
        }
        let content;
        syn::parenthesized!(content in input);
        let args = content.parse_terminated(<syn::Expr as syn::parse::Parse>::parse, Token![,])?;
        Some(args.into_iter().collect())
    };
    input.parse::<Token![;]>()?;
    Ok(Retry { args, span })
}

/// Parses `let pat [: T] =` when a `spawn TASK` follows; otherwise consumes nothing.
fn let_spawn(input: ParseStream) -> syn::Result<Option<Binding>> {
    let fork = input.fork();
    let parsed = (|| -> syn::Result<Binding> {
        fork.parse::<Token![let]>()?;
        let pat = fork.call(syn::Pat::parse_single)?;
        let ty = if fork.peek(Token![:]) {
            fork.parse::<Token![:]>()?;
            Some(fork.parse::<Type>()?)
        } else {
            None
        };
        fork.parse::<Token![=]>()?;
        Ok(Binding {
            target: BindTarget::Let(pat),
            ty,
        })
    })();
    match parsed {
        Ok(binding) if is_keyword_then_ident(fork.cursor(), "spawn") => {
            input.advance_to(&fork);
            Ok(Some(binding))
        }
        _ => Ok(None),
    }
}

fn spawn(
    input: ParseStream,
    cx: &mut Cx,
    labels: Vec<Ident>,
    binding: Option<Binding>,
) -> syn::Result<Spawn> {
    let keyword = input.call(Ident::parse_any)?;
    let task: Ident = input.parse()?;
    let args = call_args(input, cx)?;
    let mut constraints = Vec::new();
    if first_ident(input.cursor()).is_some_and(|(word, _)| word == "with") {
        input.call(Ident::parse_any)?;
        constraints = parse_constraint_list(input, cx)?;
        if !input.peek(Token![;]) {
            return Err(input.error("expected `,` or `;` after a constraint"));
        }
    } else if !input.peek(Token![;]) {
        return Err(input.error("expected `with` or `;` after the spawned task's arguments"));
    }
    input.parse::<Token![;]>()?;
    Ok(Spawn {
        labels,
        binding,
        task,
        args,
        constraints,
        span: keyword.span(),
    })
}

fn with_group(input: ParseStream, cx: &mut Cx, labels: Vec<Ident>) -> syn::Result<WithGroup> {
    let keyword = input.call(Ident::parse_any)?;
    let group = take_group(input, Delimiter::Parenthesis, "`(`")?;
    let paren_span = group.span;
    let constraints = parse_group(group, cx, |input, cx| {
        if input.is_empty() {
            return Err(syn::Error::new(
                paren_span,
                "expected at least one constraint in `with (...)`",
            ));
        }
        let list = parse_constraint_list(input, cx)?;
        if !input.is_empty() {
            return Err(input.error("expected `,` between constraints"));
        }
        Ok(list)
    })?;
    let body = if input.peek(syn::token::Brace) {
        parse_block(take_group(input, Delimiter::Brace, "`{`")?, cx)
    } else {
        let span = input.span();
        let start = input.cursor();
        let single = spawn(input, cx, Vec::new(), None)?;
        Block {
            stmts: vec![Stmt::Spawn(single)],
            mentions: vec![idents(control::tokens_between(start, input.cursor()))],
            span,
        }
    };
    Ok(WithGroup {
        labels,
        constraints,
        body,
        span: keyword.span(),
    })
}

fn fail(input: ParseStream, cx: &mut Cx) -> syn::Result<Fail> {
    let keyword = input.call(Ident::parse_any)?;
    let mut exception = None;
    let mut fields = Vec::new();
    if !input.peek(Token![;]) {
        exception = Some(input.parse::<Ident>()?);
        if input.peek(syn::token::Brace) {
            let group = take_group(input, Delimiter::Brace, "`{`")?;
            fields = parse_group(group, cx, |input, _| {
                let list = Punctuated::<syn::FieldValue, Token![,]>::parse_terminated(input)?;
                Ok(list.into_iter().collect())
            })?;
        }
        if !input.peek(Token![;]) {
            return Err(input.error("expected `;` after `fail Exception { ... }`"));
        }
    }
    input.parse::<Token![;]>()?;
    Ok(Fail {
        exception,
        fields,
        span: keyword.span(),
    })
}

fn bind(input: ParseStream) -> syn::Result<Bind> {
    let keyword = input.call(Ident::parse_any)?;
    let name: Ident = input.parse()?;
    input.parse::<Token![=]>()?;
    let expr: syn::Expr = input.parse()?;
    if !input.peek(Token![;]) {
        return Err(input.error("expected `;` after `bind name = node`"));
    }
    input.parse::<Token![;]>()?;
    Ok(Bind {
        name,
        expr,
        span: keyword.span(),
    })
}

fn constraint_stmt(input: ParseStream, cx: &mut Cx) -> syn::Result<ConstraintStmt> {
    let span = input.span();
    let tag = parse_tag(input)?;
    let constraint = parse_constraint(input, cx)?;
    if !input.peek(Token![;]) {
        return Err(input
            .error("expected `;` after the constraint statement (one constraint per statement)"));
    }
    input.parse::<Token![;]>()?;
    Ok(ConstraintStmt {
        tag,
        constraint,
        span,
    })
}
