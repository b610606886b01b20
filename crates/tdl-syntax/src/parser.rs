//! The parser: token stream to [`Ast`] plus diagnostics, never failing.
//!
//! It runs on `syn`'s `ParseStream`. Each item and each statement is parsed speculatively on a fork
//! (see [`attempt`]); on an error the diagnostic is recorded and the input skips to the next item or
//! statement boundary, so one mistake gives one diagnostic and parsing goes on. Brace and paren
//! groups are parsed as fresh token streams ([`parse_group`]), so an error inside a group never
//! leaks into the enclosing parse. Statements are in `parser/stmt.rs`, constraints in
//! `parser/constraint.rs`; the static diagnosis runs afterwards in `diagnose.rs`.

mod cond;
mod constraint;
mod decls;
mod externs;
mod stmt;

pub(crate) use stmt::idents;

use proc_macro2::{Delimiter, Ident, Span, TokenStream, TokenTree};
use syn::ext::IdentExt;
use syn::parse::discouraged::Speculative;
use syn::parse::{ParseStream, Parser};
use syn::punctuated::Punctuated;
use syn::{Token, Type};

use crate::ast::{
    Allow, Arg, Ast, Block, EnvEntry, EnvTarget, EnvironmentDecl, ExceptionDecl, Field, Item,
    ResourceDecl, StateDecl, TapDecl, Task, TaskKind, state_type,
};
use crate::diagnostic::Diagnostic;

pub(crate) use constraint::parse_task_constraints;

/// Parses `tokens` as exactly one tag (the inside of `node!(…)` in Rust code).
pub fn parse_tag_tokens(tokens: TokenStream) -> syn::Result<crate::ast::Tag> {
    constraint::parse_tag.parse2(tokens)
}

/// Parsing context: the diagnostics found so far.
pub(crate) struct Cx {
    pub(crate) diags: Vec<Diagnostic>,
    /// The `#[allow(tdl::…)]` lints found so far.
    pub(crate) allows: Vec<Allow>,
    /// Hint for the error being returned, set by the innermost parser that knows one.
    pub(crate) hint: Option<&'static str>,
    /// Where "unexpected end of input" points: the closing delimiter of the group being parsed,
    /// or the last token of the file.
    eof: Option<Span>,
    /// Parsing text (not a macro's tokens): a span with no source text is the call site.
    str_mode: bool,
}

impl Cx {
    pub(crate) fn new(eof: Option<Span>) -> Cx {
        Cx {
            diags: Vec::new(),
            allows: Vec::new(),
            hint: None,
            str_mode: eof.is_some(),
            eof,
        }
    }

    /// True for the call-site span `syn` gives errors at the end of a parsed stream.
    fn is_call_site(&self, span: Span) -> bool {
        if self.str_mode {
            // Spans of parsed text always have source text; the call site has none.
            span.source_text().is_none()
        } else {
            format!("{span:?}") == format!("{:?}", Span::call_site())
        }
    }

    /// Records the TDL lints of `attrs` as allows covering `from` to `to`, and their errors.
    pub(crate) fn allow(&mut self, attrs: &[syn::Attribute], to: Span) {
        let found = crate::lint::lint_attrs(attrs);
        self.diags.extend(found.errors);
        let Some(first) = attrs.first() else {
            return;
        };
        let from = first.pound_token.span;
        self.allows
            .extend(found.allowed.into_iter().map(|(lint, span)| Allow {
                lint,
                span,
                from,
                to,
            }));
    }

    /// Records a `syn` error as diagnostics, with `hint` if given.
    pub(crate) fn syn_error(&mut self, err: syn::Error, hint: Option<&str>) {
        for part in err {
            let mut span = part.span();
            if let Some(eof) = self.eof {
                if self.is_call_site(span) {
                    span = eof;
                }
            }
            let mut diag = Diagnostic::error(span, part.to_string());
            if let Some(hint) = hint {
                diag = diag.with_hint(hint);
            }
            self.diags.push(diag);
        }
    }
}

/// Runs `f` on a fork of `input`; on success the input advances past what `f` consumed, on
/// failure nothing is consumed and the diagnostics and allows `f` pushed are dropped.
pub(crate) fn attempt<T>(
    input: ParseStream,
    cx: &mut Cx,
    f: impl FnOnce(ParseStream, &mut Cx) -> syn::Result<T>,
) -> syn::Result<T> {
    let mark = cx.diags.len();
    let allows = cx.allows.len();
    let fork = input.fork();
    match f(&fork, cx) {
        Ok(it) => {
            input.advance_to(&fork);
            Ok(it)
        }
        Err(err) => {
            cx.diags.truncate(mark);
            cx.allows.truncate(allows);
            Err(err)
        }
    }
}

/// A delimited group taken from the input.
pub(crate) struct Group {
    /// The tokens inside the delimiters.
    pub(crate) tokens: TokenStream,
    /// Span of the whole group.
    pub(crate) span: Span,
    /// Span of the closing delimiter, where "unexpected end of input" errors point.
    pub(crate) close: Span,
}

fn is_end_of_input(err: &syn::Error) -> bool {
    err.to_string().starts_with("unexpected end of input")
}

/// Points "unexpected end of input" errors from a group's own parse at its closing delimiter
/// (`syn` only knows the call site there).
pub(crate) fn at_close(err: syn::Error, close: Span) -> syn::Error {
    let mut parts = err.into_iter().map(|part| {
        if is_end_of_input(&part) {
            syn::Error::new(close, part.to_string())
        } else {
            part
        }
    });
    let Some(mut first) = parts.next() else {
        return syn::Error::new(close, "unexpected end of input");
    };
    for part in parts {
        first.combine(part);
    }
    first
}

/// Parses a group's tokens with `f`, which must consume all of them.
pub(crate) fn parse_group<T>(
    group: Group,
    cx: &mut Cx,
    f: impl FnOnce(ParseStream, &mut Cx) -> syn::Result<T>,
) -> syn::Result<T> {
    let outer_eof = cx.eof.replace(group.close);
    let res = (|input: ParseStream| f(input, &mut *cx))
        .parse2(group.tokens)
        .map_err(|err| at_close(err, group.close));
    cx.eof = outer_eof;
    res
}

/// Parses a group's tokens as one `T`.
pub(crate) fn parse_group_as<T: syn::parse::Parse>(group: Group) -> syn::Result<T> {
    syn::parse2(group.tokens).map_err(|err| at_close(err, group.close))
}

/// Consumes a delimited group.
pub(crate) fn take_group(
    input: ParseStream,
    delimiter: Delimiter,
    what: &str,
) -> syn::Result<Group> {
    input.step(|cursor| match cursor.group(delimiter) {
        Some((inner, span, rest)) => Ok((
            Group {
                tokens: inner.token_stream(),
                span: span.join(),
                close: span.close(),
            },
            rest,
        )),
        None => Err(cursor.error(format!("expected {what}"))),
    })
}

/// Consumes one token tree.
pub(crate) fn skip_token(input: ParseStream) -> Option<TokenTree> {
    input.parse::<TokenTree>().ok()
}

/// Consumes tokens up to and including the next `;`, or up to and including a brace group (and a
/// `;` right after it), whichever comes first; always consumes at least one token.
pub(crate) fn recover(input: ParseStream) {
    while let Some(tt) = skip_token(input) {
        match tt {
            TokenTree::Punct(p) if p.as_char() == ';' => return,
            TokenTree::Group(g) if g.delimiter() == Delimiter::Brace => {
                if input.peek(Token![;]) {
                    skip_token(input);
                }
                if !input.peek(Token![else]) {
                    return;
                }
            }
            _ => {}
        }
    }
}

/// Parses a whole file.
pub(crate) fn parse_file(input: ParseStream, cx: &mut Cx) -> Ast {
    let mut items = Vec::new();
    while !input.is_empty() {
        let is_task = tdl_item_keyword(input).is_some();
        cx.hint = None;
        match attempt(input, cx, item) {
            Ok(it) => items.push(it),
            Err(err) => {
                let hint = cx.hint.take().or(is_task.then_some(TASK_HINT));
                cx.syn_error(err, hint);
                recover(input);
            }
        }
    }
    let mut allows = std::mem::take(&mut cx.allows);
    allows.sort_by_key(|it| crate::diagnostic::LineCol::start_of(it.from));
    Ast { items, allows }
}

const TASK_HINT: &str = "a task reads `goal name(arg: Type, ...) [-> Type] [with constraint, ...] { ... }`; \
     items are `goal`, `command`, `monitor`, `handler NAME(...) handles Exc [as name] [for task]`, `exception NAME;` or Rust items";

/// The TDL item keyword at the input, after attributes, visibility and qualifiers.
fn tdl_item_keyword(input: ParseStream) -> Option<String> {
    let fork = input.fork();
    let _ = fork.call(syn::Attribute::parse_outer);
    let _ = fork.parse::<syn::Visibility>();
    let mut word = fork.call(Ident::parse_any).ok()?.to_string();
    // The qualifiers, in any order.
    for _ in 0..3 {
        if word == "persistent" || word == "blocking" || word == "idempotent" {
            word = fork.call(Ident::parse_any).ok()?.to_string();
        }
    }
    // `resource NAME(…)` declares a resource; `resource!(…)` stays a Rust macro call.
    if word == "resource" {
        return fork.peek(syn::Ident).then_some(word);
    }
    // `environment { … }` declares what the outside may change.
    if word == "environment" {
        return fork.peek(syn::token::Brace).then_some(word);
    }
    // `state NAME: TYPE` declares a state variable.
    if word == "state" {
        return (fork.peek(syn::Ident) && fork.peek2(Token![:]) && !fork.peek2(Token![::]))
            .then_some(word);
    }
    // `extern goal|command NAME(…)` declares a task implemented elsewhere.
    if word == "extern" {
        let next = fork.call(Ident::parse_any).ok()?.to_string();
        return matches!(next.as_str(), "goal" | "command").then_some(word);
    }
    matches!(
        word.as_str(),
        "goal" | "command" | "monitor" | "handler" | "wiretap" | "exception"
    )
    .then_some(word)
}

fn item(input: ParseStream, cx: &mut Cx) -> syn::Result<Item> {
    if tdl_item_keyword(input).is_none() {
        if input.peek(syn::Ident)
            && input.peek2(syn::Ident)
            && input.peek3(syn::token::Paren)
            && input.fork().parse::<syn::Item>().is_err()
        {
            let ident: Ident = input.fork().call(Ident::parse_any)?;
            cx.hint = Some(TASK_HINT);
            return Err(syn::Error::new(
                ident.span(),
                format!(
                    "unknown item kind `{ident}`; a task starts with `goal`, `command`, \
                     `monitor` or `handler`"
                ),
            ));
        }
        let it = input.parse::<syn::Item>()?;
        cx.diags
            .extend(crate::lint::misplaced(rust_item_attrs(&it), "a Rust item"));
        return Ok(Item::Rust(Box::new(it)));
    }
    let attrs = input.call(syn::Attribute::parse_outer)?;
    let vis: syn::Visibility = input.parse()?;
    if input.peek(Token![extern]) {
        input.parse::<Token![extern]>()?;
        return externs::extern_decl(input, cx, attrs);
    }
    let mut persistent = false;
    let mut blocking = None;
    let mut idempotent = None;
    let mut keyword = input.call(Ident::parse_any)?;
    // The qualifiers, in any order.
    for _ in 0..3 {
        if keyword == "persistent" && !persistent {
            persistent = true;
            keyword = input.call(Ident::parse_any)?;
        } else if keyword == "blocking" && blocking.is_none() {
            blocking = Some(keyword.span());
            keyword = input.call(Ident::parse_any)?;
        } else if keyword == "idempotent" && idempotent.is_none() {
            idempotent = Some(keyword.span());
            keyword = input.call(Ident::parse_any)?;
        }
    }
    let kind = match keyword.to_string().as_str() {
        "goal" => TaskKind::Goal,
        "command" => TaskKind::Command,
        "monitor" => TaskKind::Monitor,
        "handler" => TaskKind::Handler,
        // A wiretap's body is a command's, run as a check, never spawned.
        "wiretap" => return wiretap(input, cx, attrs, vis),
        other => {
            if let Some(span) = idempotent {
                cx.diags.push(not_idempotent(span, "this"));
            }
            if let Some(span) = blocking {
                let what = match other {
                    "resource" => "a resource",
                    "state" => "a state variable",
                    "environment" => "an environment",
                    _ => "an exception",
                };
                cx.diags.push(not_blocking(span, what));
            }
            let what = match other {
                "resource" => "a resource declaration",
                "state" => "a state variable",
                "environment" => "an environment",
                _ => "an exception",
            };
            cx.diags.extend(crate::lint::misplaced(&attrs, what));
            return match other {
                "resource" => decls::resource(input, attrs, persistent, keyword.span(), cx),
                "state" => decls::state(input, attrs, persistent, keyword.span(), cx),
                "environment" => decls::environment(input, keyword.span(), cx),
                _ => exception(input, attrs, vis, persistent, keyword.span(), cx),
            };
        }
    };
    if let (Some(span), false) = (blocking, kind == TaskKind::Command) {
        cx.diags
            .push(not_blocking(span, &format!("a {}", kind.as_str())));
    }
    if let (Some(span), false) = (idempotent, kind == TaskKind::Command) {
        cx.diags
            .push(not_idempotent(span, &format!("a {}", kind.as_str())));
    }
    let qualifiers = Qualifiers {
        persistent,
        blocking,
        idempotent,
    };
    task(input, cx, attrs, vis, qualifiers, kind)
}

/// A task's qualifiers, as parsed.
struct Qualifiers {
    persistent: bool,
    blocking: Option<Span>,
    idempotent: Option<Span>,
}

/// `idempotent` on what is not a command.
fn not_idempotent(span: Span, what: &str) -> Diagnostic {
    Diagnostic::error(span, format!("{what} cannot be `idempotent`")).with_hint(
        "only a command can be `idempotent` (safe to run twice: started again when a run resumes \
         from its journal); a goal's body runs again on a resumption anyway",
    )
}

/// The outer attributes of a Rust item.
fn rust_item_attrs(item: &syn::Item) -> &[syn::Attribute] {
    match item {
        syn::Item::Const(it) => &it.attrs,
        syn::Item::Enum(it) => &it.attrs,
        syn::Item::ExternCrate(it) => &it.attrs,
        syn::Item::Fn(it) => &it.attrs,
        syn::Item::ForeignMod(it) => &it.attrs,
        syn::Item::Impl(it) => &it.attrs,
        syn::Item::Macro(it) => &it.attrs,
        syn::Item::Mod(it) => &it.attrs,
        syn::Item::Static(it) => &it.attrs,
        syn::Item::Struct(it) => &it.attrs,
        syn::Item::Trait(it) => &it.attrs,
        syn::Item::TraitAlias(it) => &it.attrs,
        syn::Item::Type(it) => &it.attrs,
        syn::Item::Union(it) => &it.attrs,
        syn::Item::Use(it) => &it.attrs,
        _ => &[],
    }
}

/// `persistent` on `what`, which cannot be: an error, with `hint`.
fn not_persistent(cx: &mut Cx, persistent: bool, span: Span, what: &str, hint: &str) {
    if persistent {
        cx.diags.push(
            Diagnostic::error(span, format!("{what} cannot be `persistent`")).with_hint(hint),
        );
    }
}

/// `blocking` on what is not a command.
fn not_blocking(span: Span, what: &str) -> Diagnostic {
    Diagnostic::error(span, format!("{what} cannot be `blocking`")).with_hint(
        "only a command can be `blocking` (its body is plain Rust run on a blocking thread); \
         a goal that must compute spawns a `blocking command`",
    )
}

fn exception(
    input: ParseStream,
    attrs: Vec<syn::Attribute>,
    vis: syn::Visibility,
    persistent: bool,
    keyword_span: Span,
    cx: &mut Cx,
) -> syn::Result<Item> {
    not_persistent(
        cx,
        persistent,
        keyword_span,
        "an exception",
        "remove `persistent`",
    );
    let name: Ident = input.parse()?;
    let parent = if input.peek(Token![:]) {
        input.parse::<Token![:]>()?;
        Some(input.parse::<Ident>()?)
    } else {
        None
    };
    let fields = if input.peek(syn::token::Brace) {
        let group = take_group(input, Delimiter::Brace, "`{`")?;
        parse_group(group, cx, |input, _| {
            let fields = Punctuated::<Field, Token![,]>::parse_terminated_with(input, |input| {
                let name: Ident = input.parse()?;
                input.parse::<Token![:]>()?;
                let ty: Type = input.parse()?;
                Ok(Field { name, ty })
            })?;
            Ok(fields.into_iter().collect())
        })?
    } else {
        if !input.peek(Token![;]) {
            return Err(
                input.error("expected `;` or `{ field: Type, ... }` after the exception name")
            );
        }
        input.parse::<Token![;]>()?;
        Vec::new()
    };
    let span = name.span();
    Ok(Item::Exception(ExceptionDecl {
        attrs,
        vis,
        name,
        parent,
        fields,
        span,
    }))
}

/// A task's arguments in parentheses and its result type, if any.
fn signature(input: ParseStream, cx: &mut Cx) -> syn::Result<(Vec<Arg>, Option<Type>)> {
    let args_group = take_group(
        input,
        Delimiter::Parenthesis,
        "`(` and the task's arguments",
    )?;
    let args = parse_group(args_group, cx, |input, _| {
        let args = Punctuated::<Arg, Token![,]>::parse_terminated_with(input, |input| {
            let mutable = input.parse::<Option<Token![mut]>>()?.is_some();
            let name: Ident = input.parse()?;
            input.parse::<Token![:]>()?;
            let ty: Type = input.parse()?;
            Ok(Arg { mutable, name, ty })
        })?;
        Ok(args.into_iter().collect())
    })?;
    let result = if input.peek(Token![->]) {
        input.parse::<Token![->]>()?;
        Some(input.call(Type::without_plus)?)
    } else {
        None
    };
    Ok((args, result))
}

fn task(
    input: ParseStream,
    cx: &mut Cx,
    attrs: Vec<syn::Attribute>,
    vis: syn::Visibility,
    qualifiers: Qualifiers,
    kind: TaskKind,
) -> syn::Result<Item> {
    let Qualifiers {
        persistent,
        blocking,
        idempotent,
    } = qualifiers;
    let name: Ident = input.parse()?;
    let (args, result) = signature(input, cx)?;
    let handles = if kind == TaskKind::Handler {
        if !input.peek(syn::Ident) || input.fork().call(Ident::parse_any)? != "handles" {
            return Err(
                input.error("expected `handles ExceptionName` after the handler's arguments")
            );
        }
        input.call(Ident::parse_any)?;
        Some(input.parse::<Ident>()?)
    } else {
        None
    };
    let caught = if handles.is_some() && input.peek(Token![as]) {
        input.parse::<Token![as]>()?;
        if !input.peek(syn::Ident) {
            return Err(input.error(
                "expected a name after `as`: `handles Exception as name` binds the caught exception",
            ));
        }
        Some(input.parse::<Ident>()?)
    } else {
        None
    };
    let for_task = if handles.is_some() && input.peek(Token![for]) {
        input.parse::<Token![for]>()?;
        if !input.peek(syn::Ident) {
            return Err(input.error(
                "expected a task name after `for`: `handles Exception for task` attaches the handler to every node of that task",
            ));
        }
        Some(input.parse::<Ident>()?)
    } else {
        None
    };
    let constraints = parse_task_constraints(input, cx)?;
    let body_group = take_group(input, Delimiter::Brace, "`{` and the task body")?;
    let body_end = body_group.close;
    let body = parse_block(body_group, cx);
    cx.allow(&attrs, body_end);
    let span = name.span();
    Ok(Item::Task(Task {
        tap: None,
        attrs,
        vis,
        persistent,
        blocking: blocking.filter(|_| kind == TaskKind::Command),
        idempotent: idempotent.is_some() && kind == TaskKind::Command,
        kind,
        name,
        args,
        result,
        handles,
        caught,
        for_task,
        constraints,
        body,
        span,
    }))
}

/// Parses the inside of a brace group as a block; never fails.
pub(crate) fn parse_block(group: Group, cx: &mut Cx) -> Block {
    let span = group.span;
    let res = parse_group(group, cx, |input, cx| Ok(stmt::parse_stmts(input, cx)));
    let (stmts, mentions) = match res {
        Ok(parsed) => parsed,
        Err(err) => {
            cx.syn_error(err, None);
            (Vec::new(), Vec::new())
        }
    };
    Block {
        stmts,
        mentions,
        span,
    }
}

/// `wiretap NAME(args) before|after TASK { body }`: a check of every node of `TASK`, written as a
/// command's body (it fails the node by failing), never spawned.
fn wiretap(
    input: ParseStream,
    cx: &mut Cx,
    attrs: Vec<syn::Attribute>,
    vis: syn::Visibility,
) -> syn::Result<Item> {
    let name: Ident = input.parse()?;
    let (args, result) = signature(input, cx)?;
    let when = if input.peek(syn::Ident) {
        input.call(Ident::parse_any)?.to_string()
    } else {
        String::new()
    };
    let after = match when.as_str() {
        "before" => false,
        "after" => true,
        _ => {
            return Err(input.error(
                "expected `before TASK` or `after TASK` after the wiretap's arguments: it checks every node of TASK before its action starts or after it returned",
            ));
        }
    };
    if !input.peek(syn::Ident) {
        return Err(input.error(format!(
            "expected the name of the task the wiretap checks after `{when}`"
        )));
    }
    let target: Ident = input.parse()?;
    let body_group = take_group(input, Delimiter::Brace, "`{` and the wiretap's body")?;
    let body_end = body_group.close;
    let body = parse_block(body_group, cx);
    cx.allow(&attrs, body_end);
    let span = name.span();
    Ok(Item::Task(Task {
        tap: Some(TapDecl { after, target }),
        attrs,
        vis,
        persistent: false,
        blocking: None,
        idempotent: false,
        kind: TaskKind::Command,
        name,
        args,
        result,
        handles: None,
        caught: None,
        for_task: None,
        constraints: Vec::new(),
        body,
        span,
    }))
}
