//! Parsing of constraints (TDL paper Fig. 5; docs/semantics.md, "Constraints"): spawn constraints, task-level
//! constraints, tags, events and counts.
//!
//! Constraint keywords go through `keyword.rs`, so joined and synonym forms are accepted
//! everywhere. Which constraint is allowed where is mostly decided later, in `diagnose.rs`; only the
//! task-level list is narrowed here because it has its own AST type.

use proc_macro2::{Delimiter, Ident, Span, TokenTree};
use syn::ext::IdentExt;
use syn::punctuated::Punctuated;
use syn::{Token, Type};

use super::cond::{COND_HINT, parse_cond};
use super::{Cx, parse_group, parse_group_as, take_group};
use crate::ast::{
    Constraint, ConstraintKind, Count, Event, ExternalName, Facet, HandlerRef, OnTerminate,
    Persistent, Point, Priority, ResourceAmount, Tag, TagIndex, TagKind, TaskConstraint,
    TaskConstraintKind, Then, When,
};
use crate::keyword::{Word, expect_phrase, peek_phrase, peek_words, take_words};
use crate::time::{TIME_HINT, parse_rel_time, parse_time_of_day, peek_time_of_day};
use syn::parse::ParseStream;

/// Hint attached to errors in constraint lists.
pub(crate) const CONSTRAINT_HINT: &str = "constraints are comma separated, e.g. \
     `sequential execution previous`, `serial t1`, `wait`, `terminate in 30s`, \
     `disable until t1 execution completed`, `terminate at monitor_pickup completed`";

/// Hint attached to errors in an external event.
pub(crate) const EXTERNAL_HINT: &str = "an external event is named by the string the program \
     raises (`session.raise(\"go\")`): `disable until external \"go\"`, \
     `terminate at external \"stop\"`, `activate at external \"tick\"` (monitors), or \
     `external (expr)` with the name from Rust; no delay is counted from an external event";

fn facet_of(word: Option<&str>) -> Option<Facet> {
    match word? {
        "handling" => Some(Facet::Handling),
        "expansion" => Some(Facet::Expansion),
        "execution" => Some(Facet::Execution),
        _ => None,
    }
}

fn point_of(word: Option<&str>) -> Option<Point> {
    match word? {
        "enabled" => Some(Point::Enabled),
        "active" => Some(Point::Active),
        "completed" => Some(Point::Completed),
        "succeeded" => Some(Point::Succeeded),
        "failed" => Some(Point::Failed),
        "terminated" => Some(Point::Terminated),
        _ => None,
    }
}

/// Parses `c1, c2, ...`; stops before the first token that is not `,` after a constraint.
pub(crate) fn parse_constraint_list(
    input: ParseStream,
    cx: &mut Cx,
) -> syn::Result<Vec<Constraint>> {
    let mut out = vec![parse_constraint(input, cx)?];
    while input.peek(Token![,]) {
        input.parse::<Token![,]>()?;
        if input.is_empty() || input.peek(Token![;]) {
            break;
        }
        out.push(parse_constraint(input, cx)?);
    }
    Ok(out)
}

/// Parses one constraint; on an error, sets the hint to the constraint or time syntax.
pub(crate) fn parse_constraint(input: ParseStream, cx: &mut Cx) -> syn::Result<Constraint> {
    parse_constraint_inner(input, cx).inspect_err(|err| {
        let text = err.to_string();
        cx.hint = Some(if text.contains("condition") || text.contains("chain") {
            COND_HINT
        } else if text.contains("external") {
            EXTERNAL_HINT
        } else if text.contains("time") || text.contains("H:M:S") {
            TIME_HINT
        } else {
            CONSTRAINT_HINT
        });
    })
}

fn parse_constraint_inner(input: ParseStream, cx: &mut Cx) -> syn::Result<Constraint> {
    let span = input.span();
    let words = peek_words(input.cursor(), 4);
    let at = |i: usize| words.get(i).and_then(|it| it.text);
    let kind = match at(0) {
        Some("expand") => {
            expect_phrase(input, &["expand", "first"])?;
            ConstraintKind::ExpandFirst
        }
        Some("delay") => {
            expect_phrase(input, &["delay", "expansion"])?;
            ConstraintKind::DelayExpansion
        }
        Some("sequential") => {
            let Some(facet) = facet_of(at(1)) else {
                return Err(syn::Error::new(
                    span,
                    "expected `handling`, `expansion` or `execution` after `sequential`",
                ));
            };
            take_words(input, 2)?;
            let tag = optional_tag(input)?;
            ConstraintKind::Sequential { facet, tag }
        }
        Some("serial") => {
            take_words(input, 1)?;
            ConstraintKind::Serial {
                tag: optional_tag(input)?,
            }
        }
        Some("parallel") => {
            take_words(input, 1)?;
            ConstraintKind::Parallel
        }
        Some("wait") => {
            take_words(input, 1)?;
            ConstraintKind::Wait
        }
        Some("outcome") => {
            take_words(input, 1)?;
            ConstraintKind::Outcome
        }
        Some("propagate") => {
            take_words(input, 1)?;
            ConstraintKind::Propagate
        }
        Some("approval") => {
            take_words(input, 1)?;
            let within =
                if peek_words(input.cursor(), 1).first().and_then(|w| w.text) == Some("within") {
                    take_words(input, 1)?;
                    Some(parse_rel_time(input)?)
                } else {
                    None
                };
            ConstraintKind::Approval(within)
        }
        Some("disable") => disable(input, cx)?,
        Some(word @ ("terminate" | "activate")) => timed(input, cx, word == "activate")?,
        Some("maximum") => match at(1) {
            Some("activate") => {
                take_words(input, 2)?;
                ConstraintKind::MaximumActivate(parse_count(input)?)
            }
            Some("trigger") => {
                take_words(input, 2)?;
                ConstraintKind::MaximumTrigger(parse_count(input)?)
            }
            _ => {
                return Err(syn::Error::new(
                    span,
                    "expected `activate` or `trigger` after `maximum`",
                ));
            }
        },
        Some("period") => {
            take_words(input, 1)?;
            ConstraintKind::Period(parse_rel_time(input)?)
        }
        Some("exception") => {
            expect_phrase(input, &["exception", "handler"])?;
            ConstraintKind::ExceptionHandler(handler_ref(input, cx)?)
        }
        Some("handler") => {
            take_words(input, 1)?;
            ConstraintKind::ExceptionHandler(handler_ref(input, cx)?)
        }
        Some("on") if at(1) == Some("terminate") => {
            take_words(input, 2)?;
            ConstraintKind::OnTerminate(on_terminate(input, cx)?)
        }
        Some("on") => {
            take_words(input, 1)?;
            ConstraintKind::OnAgent(input.call(syn::Expr::parse_without_eager_brace)?)
        }
        Some("name") => {
            take_words(input, 1)?;
            ConstraintKind::Name(input.call(syn::Expr::parse_without_eager_brace)?)
        }
        Some("parent") => {
            take_words(input, 1)?;
            ConstraintKind::Parent(input.call(syn::Expr::parse_without_eager_brace)?)
        }
        Some("uses") => {
            take_words(input, 1)?;
            ConstraintKind::Uses(parse_uses(input)?)
        }
        Some("priority") => {
            take_words(input, 1)?;
            ConstraintKind::Priority(parse_priority(input)?)
        }
        Some("deny") => {
            expect_phrase(input, &["deny", "if", "busy"])?;
            ConstraintKind::DenyIfBusy
        }
        Some("skip") => {
            expect_phrase(input, &["skip", "if"])?;
            condition(input, Then::Skip)?
        }
        Some("invariant") => {
            take_words(input, 1)?;
            condition(input, Then::Invariant)?
        }
        Some("pause") => {
            expect_phrase(input, &["pause", "while"])?;
            condition(input, Then::Pause)?
        }
        _ => {
            let what = match input.cursor().token_tree() {
                Some((tt, _)) => format!("`{tt}`"),
                None => "end of input".to_owned(),
            };
            return Err(syn::Error::new(
                span,
                format!("expected a constraint, found {what}"),
            ));
        }
    };
    Ok(Constraint { kind, span })
}

/// `terminate`/`activate`, optionally followed by `at WHEN`, `at external NAME` or
/// `in REL [after EVENT]`.
fn timed(input: ParseStream, cx: &mut Cx, activate: bool) -> syn::Result<ConstraintKind> {
    let then = if activate {
        Then::Activate
    } else {
        Then::Terminate
    };
    // Enough identifiers for `terminate at external`, or a tag's facet and point after `at`.
    let words = peek_words(input.cursor(), 5);
    let second = words.get(1).and_then(|it| it.text);
    let external = external_at(&words, 2).filter(|_| second == Some("at"));
    let at = |i: usize| words.get(i).and_then(|it| it.text);
    if second == Some("when") {
        take_words(input, 2)?;
        return Ok(ConstraintKind::Trigger {
            when: When::Condition(parse_cond(input)?),
            then,
        });
    }
    if activate && second == Some("on") && at(2) == Some("change") {
        take_words(input, 2)?;
        expect_phrase(input, &["change", "of"])?;
        if input.cursor().ident().is_none() {
            return Err(input.error(
                "expected a state variable after `activate on change of`, as in \
                 `activate on change of battery`",
            ));
        }
        return Ok(ConstraintKind::Trigger {
            when: When::Changed(input.call(Ident::parse_any)?),
            then,
        });
    }
    let when = match (second, external) {
        (_, Some(keyword)) => {
            // The keywords may be joined (`terminate_at_external`): taken all at once.
            take_words(input, 3)?;
            When::External(parse_external_name(input, keyword)?)
        }
        (Some(word @ ("at" | "in")), None) => {
            take_words(input, 2)?;
            parse_when(input, cx, word == "in")?
        }
        _ => {
            take_words(input, 1)?;
            When::Now
        }
    };
    Ok(ConstraintKind::Trigger { when, then })
}

/// `disable [facet]` followed by `until WHEN`, `until external NAME` or `for REL [after EVENT]`.
fn disable(input: ParseStream, cx: &mut Cx) -> syn::Result<ConstraintKind> {
    let span = input.span();
    let words = peek_words(input.cursor(), 6);
    let at = |i: usize| words.get(i).and_then(|it| it.text);
    let facet = facet_of(at(1));
    let n_words = if facet.is_some() { 3 } else { 2 };
    let relative = match at(n_words - 1) {
        Some("until") => false,
        Some("for") => true,
        _ => {
            return Err(syn::Error::new(
                span,
                "expected `until` or `for` after `disable [handling|expansion|execution]`",
            ));
        }
    };
    let external = external_at(&words, n_words).filter(|_| !relative);
    let when = if let Some(keyword) = external {
        take_words(input, n_words + 1)?;
        When::External(parse_external_name(input, keyword)?)
    } else {
        take_words(input, n_words)?;
        if !relative && is_condition(input) {
            When::Condition(parse_cond(input)?)
        } else {
            parse_when(input, cx, relative)?
        }
    };
    Ok(ConstraintKind::Trigger {
        when,
        then: Then::Enable(facet),
    })
}

/// A constraint on a condition (`skip if`, `invariant`, `pause while`), its keywords taken.
fn condition(input: ParseStream, then: Then) -> syn::Result<ConstraintKind> {
    Ok(ConstraintKind::Trigger {
        when: When::Condition(parse_cond(input)?),
        then,
    })
}

/// Whether what follows `disable [facet] until` is a condition rather than an event or a time
/// of day: a tag followed by a facet or a point is an event (`t1 completed`), a number followed
/// by `:` a time (`13:00:00`); anything else is a condition (`battery_ok`, `level > 3`,
/// `!fault`, `(a || b)`).
fn is_condition(input: ParseStream) -> bool {
    if input.peek(syn::LitInt) || input.peek(syn::LitFloat) {
        return !input.peek2(Token![:]);
    }
    if input.cursor().ident().is_none() || input.peek(syn::LitBool) {
        return true;
    }
    let fork = input.fork();
    let Ok(tag) = parse_tag(&fork) else {
        return true;
    };
    match tag.kind {
        TagKind::Named { indexes, .. } if indexes.is_empty() => {
            let next = peek_words(fork.cursor(), 1);
            let word = next.first().and_then(|it| it.text);
            facet_of(word).is_none() && point_of(word).is_none()
        }
        _ => false,
    }
}

/// The span of word `i` when it is the keyword `external`, not the tag of a task named `external`
/// (which a facet or a point follows: `external completed`).
fn external_at(words: &[Word], i: usize) -> Option<Span> {
    let word = words.get(i)?;
    let next = words.get(i + 1).and_then(|it| it.text);
    let tag = facet_of(next).is_some() || point_of(next).is_some();
    (word.text == Some("external") && !tag).then_some(word.span)
}

/// Parses the name after `external` (whose span is `keyword`): `"name"` or `(expr)`.
///
/// A delay written around an external event is refused here with its own message, since the
/// runtime counts delays only from node events.
fn parse_external_name(input: ParseStream, keyword: Span) -> syn::Result<ExternalName> {
    let name = if input.peek(syn::LitStr) {
        ExternalName::Lit(input.parse()?)
    } else if input.peek(syn::token::Paren) {
        let group = take_group(input, Delimiter::Parenthesis, "`(`")?;
        ExternalName::Expr(parse_group_as(group)?)
    } else if let Some((ident, _)) = input.cursor().ident() {
        return Err(syn::Error::new(
            ident.span(),
            format!("the name of an external event is a string: write `external \"{ident}\"`"),
        ));
    } else if let Some((lit, _)) = input.cursor().literal() {
        return Err(syn::Error::new(
            lit.span(),
            format!("expected the external event's name as a string, found `{lit}`"),
        ));
    } else {
        return Err(syn::Error::new(
            keyword,
            "`external` needs the event's name as a string, as in `external \"goal_updated\"`",
        ));
    };
    let words = peek_words(input.cursor(), 1);
    if let Some(
        word @ Word {
            text: Some("after" | "in" | "for"),
            ..
        },
    ) = words.first()
    {
        return Err(syn::Error::new(
            word.span,
            "a delay cannot follow an external event: the constraint fires when the external \
             event is raised",
        ));
    }
    Ok(name)
}

/// The "when" of a trigger after its `at`/`until` (`relative` false: an event or a time of day)
/// or its `in`/`for` (`relative` true: a delay, optionally `after EVENT`). `at external` and
/// `until external` are parsed by the caller, which takes the joined keywords with them.
fn parse_when(input: ParseStream, cx: &mut Cx, relative: bool) -> syn::Result<When> {
    if relative {
        if let Some(keyword) = external_at(&peek_words(input.cursor(), 2), 0) {
            return Err(syn::Error::new(
                keyword,
                "expected a delay: an external event follows `at` (`until` after `disable`), \
                 as in `terminate at external \"stop\"`",
            ));
        }
        let delay = parse_rel_time(input)?;
        return Ok(if peek_phrase(input, &["after"]) {
            take_words(input, 1)?;
            if let Some(keyword) = external_at(&peek_words(input.cursor(), 2), 0) {
                return Err(syn::Error::new(
                    keyword,
                    "a delay after an external event is not supported: `in`/`for … after` \
                     counts from a task's event",
                ));
            }
            When::After(delay, parse_event(input)?)
        } else {
            When::In(delay)
        });
    }
    if peek_time_of_day(input) {
        Ok(When::At(parse_time_of_day(input, &mut cx.diags)?))
    } else {
        Ok(When::Event(parse_event(input)?))
    }
}

fn optional_tag(input: ParseStream) -> syn::Result<Option<Tag>> {
    if input.cursor().ident().is_some() {
        Ok(Some(parse_tag(input)?))
    } else {
        Ok(None)
    }
}

/// Parses `TAG [handling|expansion|execution] (enabled|active|completed)` or
/// `TAG (succeeded|failed|terminated)`.
pub(crate) fn parse_event(input: ParseStream) -> syn::Result<Event> {
    let tag = parse_tag(input)?;
    let words = peek_words(input.cursor(), 2);
    let at = |i: usize| words.get(i).and_then(|it| it.text);
    let (facet, point, n_words) = match facet_of(at(0)) {
        Some(facet) => (Some(facet), point_of(at(1)), 2),
        None => (None, point_of(at(0)), 1),
    };
    let Some(point) = point else {
        return Err(input.error(
            "expected `enabled`, `active`, `completed`, `succeeded`, `failed` or `terminated` after the tag, as in `t1 execution completed` or `t1 failed`",
        ));
    };
    if let (Some(facet), true) = (facet, point.is_outcome()) {
        return Err(input.error(format!(
            "`{}` is an outcome of the whole task; it takes no facet: write `{} {}`, not `{} {}`",
            point.as_str(),
            "TAG",
            point.as_str(),
            facet.as_str(),
            point.as_str()
        )));
    }
    take_words(input, n_words)?;
    Ok(Event { tag, facet, point })
}

/// Parses a tag: a name with optional `[index]`s, `previous`, `self`/`child` or `parent`/`this`.
pub(crate) fn parse_tag(input: ParseStream) -> syn::Result<Tag> {
    let span = input.span();
    let name = input.call(Ident::parse_any)?;
    let kind = match name.to_string().as_str() {
        "previous" => TagKind::Previous,
        "self" | "child" => TagKind::Child,
        "parent" | "this" => TagKind::Parent,
        _ => {
            let mut indexes = Vec::new();
            while input.peek(syn::token::Bracket) {
                let group = take_group(input, Delimiter::Bracket, "`[`")?;
                let mut iter = group.tokens.clone().into_iter();
                let index = match (iter.next(), iter.next()) {
                    (Some(TokenTree::Punct(p)), None) if p.as_char() == '.' => TagIndex::Current,
                    _ => TagIndex::Expr(parse_group_as(group)?),
                };
                indexes.push(index);
            }
            TagKind::Named { name, indexes }
        }
    };
    if !matches!(kind, TagKind::Named { .. }) && input.peek(syn::token::Bracket) {
        return Err(input.error("only a task name or a label takes iteration indexes"));
    }
    Ok(Tag { kind, span })
}

/// Parses the list after `uses`: `name` or `name(amount)`, comma separated. The list goes on
/// after a comma while the next identifier is not a constraint keyword (`uses base, arm(2),
/// priority 1` ends before `priority`).
fn parse_uses(input: ParseStream) -> syn::Result<Vec<ResourceAmount>> {
    let mut out = vec![resource_amount(input)?];
    loop {
        let fork = input.fork();
        if fork.parse::<Token![,]>().is_err() {
            break;
        }
        let next = peek_words(fork.cursor(), 1);
        let starts = next
            .first()
            .and_then(|it| it.text)
            .is_some_and(crate::keyword::starts_constraint);
        if starts || fork.cursor().ident().is_none() {
            break;
        }
        input.parse::<Token![,]>()?;
        out.push(resource_amount(input)?);
    }
    Ok(out)
}

/// `name` or `name(amount)`.
fn resource_amount(input: ParseStream) -> syn::Result<ResourceAmount> {
    if input.cursor().ident().is_none() {
        return Err(
            input.error("expected a resource's name after `uses`, as in `uses base, arm(2)`")
        );
    }
    let name = input.call(Ident::parse_any)?;
    if !input.peek(syn::token::Paren) {
        let span = name.span();
        return Ok(ResourceAmount {
            name,
            amount: None,
            span,
        });
    }
    let group = take_group(input, Delimiter::Parenthesis, "`(`")?;
    let span = group.span;
    let expr: syn::Expr = parse_group_as(group)?;
    Ok(ResourceAmount {
        name,
        amount: Some(count_of(expr)?),
        span,
    })
}

/// `priority N`: an integer literal (possibly negative) or a Rust expression.
fn parse_priority(input: ParseStream) -> syn::Result<Priority> {
    let expr = input.call(syn::Expr::parse_without_eager_brace)?;
    let literal = |lit: &syn::LitInt, negative: bool| -> syn::Result<Option<Priority>> {
        if !lit.suffix().is_empty() {
            return Ok(None);
        }
        let n = lit.base10_parse::<i64>()?;
        Ok(Some(Priority::Const(if negative { -n } else { n })))
    };
    match &expr {
        syn::Expr::Lit(syn::ExprLit {
            lit: syn::Lit::Int(lit),
            ..
        }) => {
            if let Some(p) = literal(lit, false)? {
                return Ok(p);
            }
        }
        syn::Expr::Unary(syn::ExprUnary {
            op: syn::UnOp::Neg(_),
            expr: inner,
            ..
        }) => {
            if let syn::Expr::Lit(syn::ExprLit {
                lit: syn::Lit::Int(lit),
                ..
            }) = inner.as_ref()
            {
                if let Some(p) = literal(lit, true)? {
                    return Ok(p);
                }
            }
        }
        _ => {}
    }
    Ok(Priority::Expr(expr))
}

fn parse_count(input: ParseStream) -> syn::Result<Count> {
    count_of(input.call(syn::Expr::parse_without_eager_brace)?)
}

/// A count: an integer literal without suffix, or any other expression.
fn count_of(expr: syn::Expr) -> syn::Result<Count> {
    if let syn::Expr::Lit(syn::ExprLit {
        lit: syn::Lit::Int(lit),
        ..
    }) = &expr
    {
        if lit.suffix().is_empty() {
            return Ok(Count::Const(lit.base10_parse::<u64>()?));
        }
    }
    Ok(Count::Expr(expr))
}

/// Parses `(args)` as comma-separated expressions.
pub(crate) fn call_args(input: ParseStream, cx: &mut Cx) -> syn::Result<Vec<syn::Expr>> {
    let group = take_group(input, Delimiter::Parenthesis, "`(` and the arguments")?;
    parse_group(group, cx, |input, _| {
        let args = Punctuated::<syn::Expr, Token![,]>::parse_terminated(input)?;
        Ok(args.into_iter().collect())
    })
}

fn handler_ref(input: ParseStream, cx: &mut Cx) -> syn::Result<HandlerRef> {
    let name: Ident = input.parse()?;
    let args = call_args(input, cx)?;
    let max_activate = if peek_phrase(input, &["maximum", "activate"]) {
        take_words(input, 2)?;
        Some(parse_count(input)?)
    } else {
        None
    };
    Ok(HandlerRef {
        name,
        args,
        max_activate,
    })
}

fn on_terminate(input: ParseStream, cx: &mut Cx) -> syn::Result<OnTerminate> {
    let mut labels = Vec::new();
    while input.peek(syn::Ident) && input.peek2(Token![:]) && !input.peek2(Token![::]) {
        labels.push(input.parse::<Ident>()?);
        input.parse::<Token![:]>()?;
    }
    if input.peek(syn::Ident) && input.peek2(syn::Ident) {
        let kw = input.call(Ident::parse_any)?;
        if kw != "spawn" {
            return Err(syn::Error::new(
                kw.span(),
                "expected `spawn` or a task name",
            ));
        }
    }
    let task: Ident = input.parse()?;
    let args = call_args(input, cx)?;
    Ok(OnTerminate { labels, task, args })
}

/// Parses the task-level constraints between a task's arguments and its body (docs/semantics.md, "Constraints").
pub(crate) fn parse_task_constraints(
    input: ParseStream,
    cx: &mut Cx,
) -> syn::Result<Vec<TaskConstraint>> {
    let mut out = Vec::new();
    if input.peek(syn::token::Brace) {
        return Ok(out);
    }
    if input.peek(syn::Ident) && input.fork().call(Ident::parse_any)? == "with" {
        input.call(Ident::parse_any)?;
    }
    loop {
        out.push(task_constraint(input, cx)?);
        if !input.peek(Token![,]) {
            break;
        }
        input.parse::<Token![,]>()?;
        if input.peek(syn::token::Brace) {
            break;
        }
    }
    Ok(out)
}

fn task_constraint(input: ParseStream, cx: &mut Cx) -> syn::Result<TaskConstraint> {
    let span = input.span();
    if peek_phrase(input, &["persistent"]) {
        take_words(input, 1)?;
        let name: Ident = input.parse()?;
        input.parse::<Token![:]>()?;
        let ty: Type = input.parse()?;
        let init = if input.peek(Token![=]) {
            input.parse::<Token![=]>()?;
            Some(input.call(syn::Expr::parse_without_eager_brace)?)
        } else {
            None
        };
        let kind = TaskConstraintKind::Persistent(Persistent { name, ty, init });
        return Ok(TaskConstraint { kind, span });
    }
    if peek_phrase(input, &["initial", "wait"]) {
        take_words(input, 2)?;
        let kind = TaskConstraintKind::InitialWait;
        return Ok(TaskConstraint { kind, span });
    }
    let constraint = parse_constraint(input, cx)?;
    let kind = match constraint.kind {
        ConstraintKind::ExpandFirst => TaskConstraintKind::ExpandFirst,
        ConstraintKind::DelayExpansion => TaskConstraintKind::DelayExpansion,
        ConstraintKind::ExceptionHandler(it) => TaskConstraintKind::ExceptionHandler(it),
        ConstraintKind::OnTerminate(it) => TaskConstraintKind::OnTerminate(it),
        ConstraintKind::MaximumActivate(it) => TaskConstraintKind::MaximumActivate(it),
        ConstraintKind::MaximumTrigger(it) => TaskConstraintKind::MaximumTrigger(it),
        ConstraintKind::Period(it) => TaskConstraintKind::Period(it),
        ConstraintKind::Serial { tag: None } => TaskConstraintKind::Serial,
        ConstraintKind::Sequential { facet, tag: None } => TaskConstraintKind::Sequential(facet),
        ConstraintKind::Uses(it) => TaskConstraintKind::Uses(it),
        ConstraintKind::Priority(it) => TaskConstraintKind::Priority(it),
        ConstraintKind::Trigger {
            when: when @ (When::Condition(_) | When::Changed(_)),
            then,
        } => {
            let form = match (when, then) {
                (When::Changed(_), _) => "activate on change of",
                (_, Then::Enable(_)) => "disable until",
                (_, Then::Terminate) => "terminate when",
                (_, Then::Activate) => "activate when",
                (_, Then::Skip) => "skip if",
                (_, Then::Invariant) => "invariant",
                (_, Then::Pause) => "pause while",
            };
            cx.hint = Some(
                "a condition constrains each node where it is spawned: `spawn step() with \
                 pause while !healthy;`, in a `with (...)` group, or in a constraint statement \
                 `step skip if done;`",
            );
            return Err(syn::Error::new(
                span,
                format!(
                    "`{form}` goes on a spawn, a `with` group or a constraint statement, not on \
                     a task definition"
                ),
            ));
        }
        _ => {
            return Err(syn::Error::new(
                span,
                "this constraint only applies to a spawn; a task definition takes `expand first`, \
                 `delay expansion`, `exception handler`, `on terminate`, `persistent` and, for \
                 monitors, `maximum activate`, `maximum trigger`, `period`, `initial wait`, \
                 `serial`, `sequential expansion|execution`",
            ));
        }
    };
    Ok(TaskConstraint {
        kind,
        span: constraint.span,
    })
}
