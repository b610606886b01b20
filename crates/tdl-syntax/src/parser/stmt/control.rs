//! Control flow in a body: an `if`, `for`, `while`, `loop`, `match` or block that holds a TDL
//! statement is parsed structurally (its branches as statements); one that holds none stays Rust.
//! A TDL statement written as a match arm's expression is refused with what to write.

use super::*;

/// True when `stmt` is or contains a TDL statement.
fn has_tdl(stmt: &Stmt) -> bool {
    fn block(it: &Block) -> bool {
        it.stmts.iter().any(has_tdl)
    }
    fn if_(it: &If) -> bool {
        block(&it.then_branch)
            || match it.else_branch.as_deref() {
                Some(Else::If(it)) => if_(it),
                Some(Else::Block(it)) => block(it),
                None => false,
            }
    }
    match stmt {
        Stmt::Rust(_) => false,
        Stmt::If(it) => if_(it),
        Stmt::For(it) => block(&it.body),
        Stmt::While(it) => block(&it.body),
        Stmt::Loop(it) => block(&it.body),
        Stmt::Match(it) => it.arms.iter().any(|arm| block(&arm.body)),
        Stmt::Block(it) => block(it),
        _ => true,
    }
}

/// Parses `if`/`for`/`while`/`loop`/`match`/`{}` structurally when it contains a TDL statement.
pub(super) fn control_flow(input: ParseStream, cx: &mut Cx) -> syn::Result<Option<Stmt>> {
    let starts = input.peek(Token![if])
        || input.peek(Token![for])
        || input.peek(Token![while])
        || input.peek(Token![loop])
        || input.peek(Token![match])
        || input.peek(syn::token::Brace)
        || (input.peek(syn::Lifetime) && input.peek2(Token![:]));
    if !starts {
        return Ok(None);
    }
    let mark = cx.diags.len();
    let fork = input.fork();
    let parsed = control_flow_structural(&fork, cx);
    match parsed {
        Ok(it) if has_tdl(&it) || cx.diags.len() > mark => {
            if fork.peek(Token![;]) {
                fork.parse::<Token![;]>()?;
            }
            input.advance_to(&fork);
            Ok(Some(it))
        }
        Ok(_) => {
            cx.diags.truncate(mark);
            Ok(None)
        }
        Err(err) => {
            cx.diags.truncate(mark);
            // A condition Rust itself cannot parse: report it from the structural parse.
            if input.fork().parse::<syn::Stmt>().is_err() {
                Err(err)
            } else {
                Ok(None)
            }
        }
    }
}

fn block(input: ParseStream, cx: &mut Cx) -> syn::Result<Block> {
    Ok(parse_block(take_group(input, Delimiter::Brace, "`{`")?, cx))
}

fn control_flow_structural(input: ParseStream, cx: &mut Cx) -> syn::Result<Stmt> {
    let label = if input.peek(syn::Lifetime) {
        let label: syn::Lifetime = input.parse()?;
        input.parse::<Token![:]>()?;
        Some(label)
    } else {
        None
    };
    let span = input.span();
    if input.peek(Token![for]) {
        input.parse::<Token![for]>()?;
        let pat = input.call(syn::Pat::parse_multi_with_leading_vert)?;
        input.parse::<Token![in]>()?;
        let expr = input.call(syn::Expr::parse_without_eager_brace)?;
        let body = block(input, cx)?;
        return Ok(Stmt::For(For {
            label,
            pat,
            expr,
            body,
            span,
        }));
    }
    if input.peek(Token![while]) {
        input.parse::<Token![while]>()?;
        let cond = input.call(syn::Expr::parse_without_eager_brace)?;
        let body = block(input, cx)?;
        return Ok(Stmt::While(While {
            label,
            cond,
            body,
            span,
        }));
    }
    if input.peek(Token![loop]) {
        input.parse::<Token![loop]>()?;
        let body = block(input, cx)?;
        return Ok(Stmt::Loop(Loop { label, body, span }));
    }
    if label.is_some() {
        return Err(input.error("expected `for`, `while` or `loop` after a loop label"));
    }
    if input.peek(Token![if]) {
        return if_stmt(input, cx).map(Stmt::If);
    }
    if input.peek(Token![match]) {
        return match_stmt(input, cx).map(Stmt::Match);
    }
    block(input, cx).map(Stmt::Block)
}

fn if_stmt(input: ParseStream, cx: &mut Cx) -> syn::Result<If> {
    let span = input.span();
    input.parse::<Token![if]>()?;
    let cond = input.call(syn::Expr::parse_without_eager_brace)?;
    let then_branch = block(input, cx)?;
    let else_branch = if input.peek(Token![else]) {
        input.parse::<Token![else]>()?;
        if input.peek(Token![if]) {
            Some(Box::new(Else::If(if_stmt(input, cx)?)))
        } else {
            Some(Box::new(Else::Block(block(input, cx)?)))
        }
    } else {
        None
    };
    Ok(If {
        cond,
        then_branch,
        else_branch,
        span,
    })
}

fn match_stmt(input: ParseStream, cx: &mut Cx) -> syn::Result<Match> {
    let span = input.span();
    input.parse::<Token![match]>()?;
    let expr = input.call(syn::Expr::parse_without_eager_brace)?;
    let group = take_group(input, Delimiter::Brace, "`{`")?;
    let arms = parse_group(group, cx, |input, cx| {
        let mut arms = Vec::new();
        while !input.is_empty() {
            arms.push(arm(input, cx)?);
        }
        Ok(arms)
    })?;
    Ok(Match { expr, arms, span })
}

fn arm(input: ParseStream, cx: &mut Cx) -> syn::Result<Arm> {
    // Only the TDL lints of an arm's attributes are kept: allowed over the arm.
    let attrs = input.call(syn::Attribute::parse_outer)?;
    let start = input.cursor();
    let pat = input.call(syn::Pat::parse_multi_with_leading_vert)?;
    let guard = if input.peek(Token![if]) {
        input.parse::<Token![if]>()?;
        Some(input.parse::<syn::Expr>()?)
    } else {
        None
    };
    input.parse::<Token![=>]>()?;
    if is_keyword_then_ident(input.cursor(), "spawn") {
        cx.hint = Some("write `pat => { spawn task(args); }`");
        return Err(input.error("a spawn in a match arm needs braces"));
    }
    if let Some(word) = tdl_arm_statement(input.cursor()) {
        cx.hint = Some(match word {
            "fail" => "write `pat => { fail E; }`: a TDL statement in an arm goes in braces",
            "bypass" => "write `pat => { bypass; }`",
            "retry" => "write `pat => { retry; }`",
            "succeed" => "write `pat => { succeed; }`",
            _ => "write `pat => { trigger; }`",
        });
        return Err(input.error(format!("a `{word}` in a match arm needs braces")));
    }
    let body = if input.peek(syn::token::Brace) {
        let body = block(input, cx)?;
        if input.peek(Token![,]) {
            input.parse::<Token![,]>()?;
        }
        body
    } else {
        let span = input.span();
        let fork = input.fork();
        fork.parse::<syn::Expr>()?;
        let tokens = tokens_between(input.cursor(), fork.cursor());
        input.advance_to(&fork);
        if !input.is_empty() {
            input.parse::<Token![,]>()?;
        }
        Block {
            mentions: vec![super::idents(tokens.clone())],
            stmts: vec![Stmt::Rust(RustStmt { tokens, span })],
            span,
        }
    };
    if let Some(to) = crate::last_span(&tokens_between(start, input.cursor())) {
        cx.allow(&attrs, to);
    }
    Ok(Arm { pat, guard, body })
}

/// A TDL statement written as a match arm's expression: `fail E`, `fail E { .. }`, or `fail`,
/// `bypass`, `retry`, `succeed` or `trigger` alone before the arm's `,` (or the end of the
/// arms). Those words as Rust (`fail_count`, `retry(3)`, `bypass.len()`) are left alone.
fn tdl_arm_statement(cursor: Cursor<'_>) -> Option<&'static str> {
    let (word, rest) = first_ident(cursor)?;
    let word = ["fail", "bypass", "retry", "succeed", "trigger"]
        .into_iter()
        .find(|it| word == *it)?;
    let alone = rest.eof() || rest.punct().is_some_and(|(p, _)| p.as_char() == ',');
    let fail_with = word == "fail" && rest.ident().is_some();
    (alone || fail_with).then_some(word)
}

/// The tokens from `start` up to (not including) `end`, which must come after `start` in the
/// same buffer.
pub(super) fn tokens_between(start: Cursor<'_>, end: Cursor<'_>) -> TokenStream {
    let mut out = TokenStream::new();
    let mut cursor = start;
    while cursor != end {
        let Some((tt, rest)) = cursor.token_tree() else {
            break;
        };
        out.extend([tt]);
        cursor = rest;
    }
    out
}

/// Finds `spawn IDENT` anywhere in `tokens`: a spawn hidden in a Rust expression.
fn find_spawn(tokens: TokenStream) -> Option<Span> {
    let mut prev_spawn: Option<Span> = None;
    for tt in tokens {
        match &tt {
            TokenTree::Ident(ident) => {
                if prev_spawn.is_some() {
                    return prev_spawn;
                }
                prev_spawn = (ident == "spawn").then(|| ident.span());
            }
            TokenTree::Group(group) => {
                if let Some(span) = find_spawn(group.stream()) {
                    return Some(span);
                }
                prev_spawn = None;
            }
            TokenTree::Punct(_) | TokenTree::Literal(_) => prev_spawn = None,
        }
    }
    None
}

/// The tokens from the cursor up to the next `;` at this level.
fn tokens_to_semicolon(mut cursor: Cursor<'_>) -> TokenStream {
    let mut out = TokenStream::new();
    while let Some((tt, rest)) = cursor.token_tree() {
        if matches!(&tt, TokenTree::Punct(p) if p.as_char() == ';') {
            break;
        }
        out.extend([tt]);
        cursor = rest;
    }
    out
}

/// Parses one Rust statement (or a tail expression) and keeps its tokens.
pub(super) fn rust_stmt(input: ParseStream, cx: &mut Cx) -> syn::Result<RustStmt> {
    let span = input.span();
    let fork = input.fork();
    if let Err(err) = fork.parse::<syn::Stmt>() {
        if let Some(spawn) = find_spawn(tokens_to_semicolon(input.cursor())) {
            cx.hint = Some(
                "make the spawn a statement of its own; a waited spawn that yields the child's \
                 result reads `let v = spawn task(args) with wait;`",
            );
            return Err(syn::Error::new(
                spawn,
                "`spawn` inside a Rust expression is not supported",
            ));
        }
        let tail = input.fork();
        if tail.parse::<syn::Expr>().is_err() || !tail.is_empty() {
            return Err(err);
        }
        let tokens = tokens_between(input.cursor(), tail.cursor());
        input.advance_to(&tail);
        return Ok(RustStmt { tokens, span });
    }
    let tokens = tokens_between(input.cursor(), fork.cursor());
    input.advance_to(&fork);
    Ok(RustStmt { tokens, span })
}
