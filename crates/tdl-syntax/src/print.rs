//! The one canonical spelling of TDL's constraints, tags, times and the Rust fragments inside
//! them, as a user writes them (docs/language.md): what the tree dumps (`dump.rs`), `tdl graph`
//! and `tdl doc` print.
//!
//! Times of day are written with two digits each (`09:00:00`, `13:05:07.25`), durations as
//! [`crate::format_nanos`] writes them (`30s`, `1.5s`, `200ms`) or `(expr)` in seconds, Rust
//! expressions and types as rustfmt would write them on one line. A printer writes into a
//! [`Sink`]: a `String` for plain text, or a sink of its own that makes the tags and task names
//! references (the HTML docs link them).

use quote::{ToTokens, quote};

use crate::ast::{
    Cond, ConstraintKind, Count, Event, ExternalName, HandlerRef, OnTerminate, Priority, RelTime,
    ResourceAmount, StateDecl, Tag, TagIndex, TagKind, TaskConstraintKind, Then, TimeOfDay, When,
};

/// Where a printer writes.
pub trait Sink {
    /// Plain text.
    fn text(&mut self, text: &str);

    /// A tag, as written ([`tag`]).
    fn tag(&mut self, it: &Tag) {
        self.text(&tag(it));
    }

    /// `previous` as `sequential` and `serial` imply it when no tag is written: nothing, unless
    /// the sink knows what it names.
    fn implied_previous(&mut self) {}

    /// The name of a task: spawned, a handler, or an on-terminate task.
    fn task(&mut self, name: &str) {
        self.text(name);
    }
}

impl Sink for String {
    fn text(&mut self, text: &str) {
        self.push_str(text);
    }
}

/// A constraint, as written in a `with (…)` list or a constraint statement.
pub fn constraint(kind: &ConstraintKind, out: &mut impl Sink) {
    match kind {
        ConstraintKind::ExpandFirst => out.text("expand first"),
        ConstraintKind::DelayExpansion => out.text("delay expansion"),
        ConstraintKind::Sequential { facet, tag } => {
            out.text(&format!("sequential {}", facet.as_str()));
            tag_or_previous(tag.as_ref(), out);
        }
        ConstraintKind::Serial { tag } => {
            out.text("serial");
            tag_or_previous(tag.as_ref(), out);
        }
        ConstraintKind::Parallel => out.text("parallel"),
        ConstraintKind::Wait => out.text("wait"),
        ConstraintKind::Outcome => out.text("outcome"),
        ConstraintKind::Propagate => out.text("propagate"),
        ConstraintKind::Approval(None) => out.text("approval"),
        ConstraintKind::Approval(Some(t)) => out.text(&format!("approval within {}", rel_time(t))),
        ConstraintKind::Trigger { when, then } => trigger(when, *then, out),
        ConstraintKind::MaximumActivate(n) => out.text(&format!("maximum activate {}", count(n))),
        ConstraintKind::MaximumTrigger(n) => out.text(&format!("maximum trigger {}", count(n))),
        ConstraintKind::Period(t) => out.text(&format!("period {}", rel_time(t))),
        ConstraintKind::ExceptionHandler(h) => handler(h, out),
        ConstraintKind::OnTerminate(it) => on_terminate(it, out),
        ConstraintKind::Name(e) => out.text(&format!("name {}", expr(e))),
        ConstraintKind::Parent(e) => out.text(&format!("parent {}", expr(e))),
        ConstraintKind::OnAgent(e) => out.text(&format!("on {}", expr(e))),
        ConstraintKind::Uses(list) => out.text(&format!("uses {}", uses(list))),
        ConstraintKind::Priority(p) => out.text(&format!("priority {}", priority(p))),
        ConstraintKind::DenyIfBusy => out.text("deny if busy"),
    }
}

/// A task-level constraint, as written after `with` in a task's header.
pub fn task_constraint(kind: &TaskConstraintKind, out: &mut impl Sink) {
    match kind {
        TaskConstraintKind::ExpandFirst => out.text("expand first"),
        TaskConstraintKind::DelayExpansion => out.text("delay expansion"),
        TaskConstraintKind::ExceptionHandler(h) => handler(h, out),
        TaskConstraintKind::OnTerminate(it) => on_terminate(it, out),
        TaskConstraintKind::Persistent(it) => {
            let init = it
                .init
                .as_ref()
                .map(|e| format!(" = {}", expr(e)))
                .unwrap_or_default();
            out.text(&format!(
                "persistent {}: {}{init}",
                it.name,
                type_text(&it.ty)
            ));
        }
        TaskConstraintKind::MaximumActivate(n) => {
            out.text(&format!("maximum activate {}", count(n)));
        }
        TaskConstraintKind::MaximumTrigger(n) => out.text(&format!("maximum trigger {}", count(n))),
        TaskConstraintKind::Period(t) => out.text(&format!("period {}", rel_time(t))),
        TaskConstraintKind::InitialWait => out.text("initial wait"),
        TaskConstraintKind::Serial => out.text("serial"),
        TaskConstraintKind::Sequential(facet) => {
            out.text(&format!("sequential {}", facet.as_str()));
        }
        TaskConstraintKind::Uses(list) => out.text(&format!("uses {}", uses(list))),
        TaskConstraintKind::Priority(p) => out.text(&format!("priority {}", priority(p))),
    }
}

fn tag_or_previous(it: Option<&Tag>, out: &mut impl Sink) {
    match it {
        Some(it) => {
            out.text(" ");
            out.tag(it);
        }
        None => out.implied_previous(),
    }
}

/// A trigger: `disable [facet] until|for …`, `terminate [at|in …]`, `activate [at|in …]`, with
/// `external "name"` after `until` or `at` for an external event; on a condition, `disable
/// [facet] until COND`, `terminate when COND`, `activate when COND`, `activate on change of VAR`,
/// `skip if COND`, `invariant COND` and `pause while COND`.
pub fn trigger(when: &When, then: Then, out: &mut impl Sink) {
    let (head, at, within) = match then {
        Then::Enable(facet) => {
            let facet = facet
                .map(|it| format!(" {}", it.as_str()))
                .unwrap_or_default();
            (format!("disable{facet}"), "until", "for")
        }
        Then::Terminate => ("terminate".to_owned(), "at", "in"),
        Then::Activate => ("activate".to_owned(), "at", "in"),
        Then::Skip => ("skip".to_owned(), "if", "in"),
        Then::Invariant => ("invariant".to_owned(), "", "in"),
        Then::Pause => ("pause".to_owned(), "while", "in"),
    };
    out.text(&head);
    match when {
        When::Now => {}
        When::At(time) => out.text(&format!(" {at} {}", time_of_day(time))),
        When::Event(it) => {
            out.text(&format!(" {at} "));
            event(it, out);
        }
        When::In(delay) => out.text(&format!(" {within} {}", rel_time(delay))),
        When::After(delay, it) => {
            out.text(&format!(" {within} {} after ", rel_time(delay)));
            event(it, out);
        }
        When::External(name) => out.text(&format!(" {at} external {}", external(name))),
        When::Condition(c) => {
            let word = match then {
                Then::Terminate | Then::Activate => " when ".to_owned(),
                Then::Invariant => " ".to_owned(),
                _ => format!(" {at} "),
            };
            out.text(&word);
            out.text(&condition(c));
        }
        When::Changed(var) => out.text(&format!(" on change of {var}")),
    }
}

/// A state variable's declaration, without its `;`: `state battery: float = 100.0`, the value
/// as the variable holds it (an integer given to a `float` is a float).
pub fn state_decl(it: &StateDecl) -> String {
    let init = match &it.init {
        Some(_) => format!(" = {}", it.initial()),
        None => String::new(),
    };
    format!("state {}: {}{init}", it.name, it.ty_name)
}

/// An environment entry, without its `;`: `battery: 100.0, 15.0 at most 2 when !docked`,
/// `external "go" at most 3`.
pub fn env_entry(it: &crate::ast::EnvEntry) -> String {
    let mut out = match &it.target {
        crate::ast::EnvTarget::State(v) => {
            let values: Vec<String> = it.values.iter().map(|l| l.value.to_string()).collect();
            format!("{v}: {}", values.join(", "))
        }
        crate::ast::EnvTarget::External(name) => format!("external {:?}", name.value()),
    };
    if let Some((n, _)) = it.at_most {
        out.push_str(&format!(" at most {n}"));
    }
    if let Some(c) = &it.when {
        out.push_str(&format!(" when {}", condition(c)));
    }
    out
}

/// A condition in its canonical text (`tcm_expr`'s: `battery > 20.5 && !fault`), the one the
/// engine, the trace and the checker show.
pub fn condition(it: &Cond) -> String {
    it.to_expr().to_string()
}

/// An event: `tag [facet] point`.
pub fn event(it: &Event, out: &mut impl Sink) {
    out.tag(&it.tag);
    let facet = it
        .facet
        .map(|it| format!(" {}", it.as_str()))
        .unwrap_or_default();
    out.text(&format!("{facet} {}", it.point.as_str()));
}

fn handler(it: &HandlerRef, out: &mut impl Sink) {
    out.text("exception handler ");
    out.task(&it.name.to_string());
    out.text(&format!("({})", exprs(&it.args)));
    if let Some(n) = &it.max_activate {
        out.text(&format!(" maximum activate {}", count(n)));
    }
}

fn on_terminate(it: &OnTerminate, out: &mut impl Sink) {
    out.text("on terminate ");
    if !it.labels.is_empty() {
        let labels: String = it.labels.iter().map(|l| format!("{l}: ")).collect();
        out.text(&format!("{labels}spawn "));
    }
    out.task(&it.task.to_string());
    out.text(&format!("({})", exprs(&it.args)));
}

/// A tag as written: a name with its iteration indexes (`move_by[i][.]`), `previous`, `self` or
/// `parent`.
pub fn tag(it: &Tag) -> String {
    match &it.kind {
        TagKind::Named { name, indexes } => {
            let mut text = name.to_string();
            for index in indexes {
                match index {
                    TagIndex::Expr(e) => text.push_str(&format!("[{}]", expr(e))),
                    TagIndex::Current => text.push_str("[.]"),
                }
            }
            text
        }
        TagKind::Previous => "previous".to_owned(),
        TagKind::Child => "self".to_owned(),
        TagKind::Parent => "parent".to_owned(),
    }
}

/// A time of day: `09:00:00`, `13:05:07.25`.
pub fn time_of_day(it: &TimeOfDay) -> String {
    let frac = if it.nanos == 0 {
        String::new()
    } else {
        format!(".{:09}", it.nanos).trim_end_matches('0').to_owned()
    };
    format!("{:02}:{:02}:{:02}{frac}", it.hour, it.minute, it.second)
}

/// A duration: `30s`, `1.5s`, `200ms`, or `(expr)` in seconds.
pub fn rel_time(it: &RelTime) -> String {
    match it {
        RelTime::Nanos(nanos) => crate::format_nanos(*nanos),
        RelTime::Seconds(e) => paren(e),
    }
}

/// A count: `3`, or `(expr)`.
pub fn count(it: &Count) -> String {
    match it {
        Count::Const(n) => n.to_string(),
        Count::Expr(e) => paren(e),
    }
}

/// An expression in parentheses (once).
fn paren(e: &syn::Expr) -> String {
    match e {
        syn::Expr::Paren(_) => expr(e),
        _ => format!("({})", expr(e)),
    }
}

/// Resources and amounts: `base, arm(2)`.
pub fn uses(list: &[ResourceAmount]) -> String {
    let parts: Vec<String> = list
        .iter()
        .map(|r| match &r.amount {
            Some(n) => format!("{}({})", r.name, count_bare(n)),
            None => r.name.to_string(),
        })
        .collect();
    parts.join(", ")
}

/// A count inside parentheses already: `2`, or the expression.
fn count_bare(it: &Count) -> String {
    match it {
        Count::Const(n) => n.to_string(),
        Count::Expr(e) => expr(e),
    }
}

/// A priority: `3`, or `(expr)`.
pub fn priority(it: &Priority) -> String {
    match it {
        Priority::Const(n) => n.to_string(),
        Priority::Expr(e) => paren(e),
    }
}

/// An external event's name: `"name"`, or `(expr)`.
pub fn external(it: &ExternalName) -> String {
    match it {
        // The literal's value, escaped as Rust would write it.
        ExternalName::Lit(lit) => format!("{:?}", lit.value()),
        ExternalName::Expr(e) => paren(e),
    }
}

/// A Rust type as rustfmt would write it, on one line.
pub fn type_text(ty: &impl ToTokens) -> String {
    let formatted = squash(&crate::pretty(&quote!(type T = #ty;)));
    formatted
        .strip_prefix("type T = ")
        .and_then(|s| s.strip_suffix(';'))
        .map_or_else(|| squash(&ty.to_token_stream().to_string()), str::to_string)
}

/// A Rust expression as rustfmt would write it, on one line.
pub fn expr(e: &impl ToTokens) -> String {
    exprs(std::slice::from_ref(e))
}

/// Arguments as rustfmt would write them, on one line, without the parentheses.
pub fn exprs<E: ToTokens>(args: &[E]) -> String {
    if args.is_empty() {
        return String::new();
    }
    let formatted = squash(&crate::pretty(&quote!(fn f() { g(#(#args),*); })));
    formatted
        .strip_prefix("fn f() { g(")
        .and_then(|s| s.strip_suffix("); }"))
        .map(|s| s.trim_end_matches([',', ' ']).to_string())
        .unwrap_or_else(|| {
            args.iter()
                .map(|a| squash(&a.to_token_stream().to_string()))
                .collect::<Vec<_>>()
                .join(", ")
        })
}

/// Whitespace runs made one space; no space just inside brackets.
fn squash(s: &str) -> String {
    let one = s.split_whitespace().collect::<Vec<_>>().join(" ");
    one.replace("( ", "(")
        .replace(" )", ")")
        .replace(",)", ")")
        .replace("[ ", "[")
        .replace(" ]", "]")
}

#[cfg(test)]
mod tests;
