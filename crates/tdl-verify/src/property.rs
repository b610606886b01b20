//! User properties: a small language over node events, parsed from `--property` or a file, and
//! followed along each explored path from the engine's trace records.
//!
//! ```text
//! property := "never" formula                 a state where the formula holds is a violation
//!           | "never" event "while" formula   the event may not happen while the formula holds
//!           | event "before" event            every second event comes after a first one
//!           | ["always"] "eventually" event   every run that ends saw the event
//! formula  := conj ("or" conj)*
//! conj     := unary ("and" unary)*
//! unary    := "not" unary | "(" formula ")" | "active" "(" NAME ")" | state
//! state    := VAR [("<" | "<=" | ">" | ">=" | "==" | "!=") LITERAL]
//! event    := ("enabled" | "active" | "completed" | "failed" | "terminated") "(" NAME ")"
//! ```
//!
//! A `state` atom reads a state variable of the program (docs/semantics.md, "State and
//! conditions"): a `bool` variable alone, or compared with a literal (`battery < 20.0`, `mode ==
//! "safe"`; the operator between spaces). It holds as the condition would: not while unknown.
//!
//! `NAME` is a node's instance name as the trace writes it: the task's name (unless a `name`
//! constraint gave another), a handler's name, `ACT-<monitor>` for a monitor's activations.
//! `active(T)` in a formula holds while some node named `T` has its handling active; as an event
//! it is the moment one becomes active. `completed(T)` is a node's execution completing (any end),
//! `failed(T)` its action failing, `terminated(T)` its termination. A file holds one property per
//! line; `#` starts a comment.

use std::sync::Arc;

use tcm_trace::{Facet, State as FacetState, TraceEvent, TraceKind};

/// A user property, parsed.
#[derive(Clone, Debug, PartialEq)]
pub struct Property {
    text: String,
    kind: Kind,
}

#[derive(Clone, Debug, PartialEq)]
enum Kind {
    Never(Formula),
    NeverWhile(Ev, Formula),
    Before(Ev, Ev),
    Eventually(Ev),
}

#[derive(Clone, Debug, PartialEq)]
enum Formula {
    Active(String),
    /// A condition over the program's state variables.
    State(tcm_core::Expr),
    Not(Box<Formula>),
    And(Box<Formula>, Box<Formula>),
    Or(Box<Formula>, Box<Formula>),
}

/// What happens to a node.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Point {
    Enabled,
    Active,
    Completed,
    Failed,
    Terminated,
}

#[derive(Clone, Debug, PartialEq)]
struct Ev {
    point: Point,
    name: String,
}

/// A property that does not parse.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{message} in `{text}`{}", hint.as_ref().map(|h| format!("\n  help: {h}")).unwrap_or_default())]
pub struct PropertyError {
    text: String,
    message: String,
    hint: Option<String>,
}

impl Property {
    /// Parses one property.
    pub fn parse(text: &str) -> Result<Property, PropertyError> {
        let words = tokens(text);
        let mut p = Parser { text, words, at: 0 };
        let kind = p.property()?;
        if p.at < p.words.len() {
            return Err(p.error(format!("unexpected `{}`", p.words[p.at]), None));
        }
        Ok(Property {
            text: text.trim().to_owned(),
            kind,
        })
    }

    /// Parses a file's properties: one per line, `#` comments and blank lines skipped. Errors
    /// name the line.
    pub fn parse_file(name: &str, text: &str) -> Result<Vec<Property>, String> {
        let mut out = Vec::new();
        for (i, line) in text.lines().enumerate() {
            let line = line.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            out.push(Property::parse(line).map_err(|e| format!("{name}:{}: {e}", i + 1))?);
        }
        Ok(out)
    }

    /// The property as written.
    pub fn text(&self) -> &str {
        &self.text
    }

    /// The node names the property uses, in order of appearance.
    pub fn names(&self) -> Vec<&str> {
        fn formula<'a>(f: &'a Formula, out: &mut Vec<&'a str>) {
            match f {
                Formula::Active(n) => out.push(n),
                Formula::State(_) => {}
                Formula::Not(f) => formula(f, out),
                Formula::And(a, b) | Formula::Or(a, b) => {
                    formula(a, out);
                    formula(b, out);
                }
            }
        }
        let mut out = Vec::new();
        match &self.kind {
            Kind::Never(f) => formula(f, &mut out),
            Kind::NeverWhile(e, f) => {
                out.push(&e.name);
                formula(f, &mut out);
            }
            Kind::Before(a, b) => out.extend([a.name.as_str(), b.name.as_str()]),
            Kind::Eventually(e) => out.push(&e.name),
        }
        out
    }

    /// The state variables the property reads, in order of appearance.
    pub fn state_vars(&self) -> Vec<String> {
        fn formula(f: &Formula, out: &mut Vec<String>) {
            match f {
                Formula::Active(_) => {}
                Formula::State(e) => out.extend(e.vars().into_iter().map(str::to_owned)),
                Formula::Not(f) => formula(f, out),
                Formula::And(a, b) | Formula::Or(a, b) => {
                    formula(a, out);
                    formula(b, out);
                }
            }
        }
        let mut out = Vec::new();
        match &self.kind {
            Kind::Never(f) | Kind::NeverWhile(_, f) => formula(f, &mut out),
            Kind::Before(..) | Kind::Eventually(_) => {}
        }
        out
    }

    /// A liveness property (`eventually`): decided only on a state graph without cycles.
    pub fn is_liveness(&self) -> bool {
        matches!(self.kind, Kind::Eventually(_))
    }
}

fn tokens(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut word = String::new();
    for ch in text.chars() {
        if ch == '(' || ch == ')' || ch == ',' || ch.is_whitespace() {
            if !word.is_empty() {
                out.push(std::mem::take(&mut word));
            }
            if !ch.is_whitespace() {
                out.push(ch.to_string());
            }
        } else {
            word.push(ch);
        }
    }
    if !word.is_empty() {
        out.push(word);
    }
    out
}

struct Parser<'a> {
    text: &'a str,
    words: Vec<String>,
    at: usize,
}

const EXAMPLES: &str =
    "`never active(A) and active(B)`, `completed(A) before active(B)`, `eventually completed(A)`";

impl Parser<'_> {
    fn error(&self, message: String, hint: Option<String>) -> PropertyError {
        PropertyError {
            text: self.text.trim().to_owned(),
            message,
            hint,
        }
    }

    fn peek(&self) -> Option<&str> {
        self.words.get(self.at).map(String::as_str)
    }

    fn eat(&mut self, w: &str) -> bool {
        if self.peek() == Some(w) {
            self.at += 1;
            true
        } else {
            false
        }
    }

    fn expect(&mut self, w: &str) -> Result<(), PropertyError> {
        if self.eat(w) {
            return Ok(());
        }
        let found = self
            .peek()
            .map_or("the end".to_owned(), |f| format!("`{f}`"));
        Err(self.error(format!("expected `{w}`, found {found}"), None))
    }

    fn property(&mut self) -> Result<Kind, PropertyError> {
        match self.peek() {
            None => Err(self.error(
                "an empty property".into(),
                Some(format!("write one of {EXAMPLES}")),
            )),
            Some("never") => {
                self.at += 1;
                let event_first = matches!(
                    self.peek(),
                    Some("enabled" | "completed" | "failed" | "terminated")
                );
                if event_first {
                    let ev = self.event()?;
                    self.expect("while")?;
                    return Ok(Kind::NeverWhile(ev, self.formula()?));
                }
                let f = self.formula()?;
                if self.eat("while") {
                    let Formula::Active(name) = f else {
                        return Err(self.error(
                            "`while` follows an event".into(),
                            Some("write `never active(T) while F`".into()),
                        ));
                    };
                    let ev = Ev {
                        point: Point::Active,
                        name,
                    };
                    return Ok(Kind::NeverWhile(ev, self.formula()?));
                }
                Ok(Kind::Never(f))
            }
            Some("always") => {
                self.at += 1;
                if !self.eat("eventually") {
                    return Err(self.error(
                        "`always` alone is `never not …`".into(),
                        Some("write `never F` for a state formula F that must never hold, or `always eventually E`".into()),
                    ));
                }
                Ok(Kind::Eventually(self.event()?))
            }
            Some("eventually") => {
                self.at += 1;
                Ok(Kind::Eventually(self.event()?))
            }
            Some(_) => {
                let first = self.event()?;
                if !self.eat("before") {
                    return Err(self.error(
                        "an event alone is not a property".into(),
                        Some(format!("write one of {EXAMPLES}")),
                    ));
                }
                Ok(Kind::Before(first, self.event()?))
            }
        }
    }

    fn event(&mut self) -> Result<Ev, PropertyError> {
        let point = match self.peek() {
            Some("enabled") => Point::Enabled,
            Some("active") => Point::Active,
            Some("completed") => Point::Completed,
            Some("failed") => Point::Failed,
            Some("terminated") => Point::Terminated,
            other => {
                let found = other.map_or("the end".to_owned(), |f| format!("`{f}`"));
                return Err(self.error(
                    format!("expected an event, found {found}"),
                    Some(
                        "events are enabled(T), active(T), completed(T), failed(T), terminated(T)"
                            .into(),
                    ),
                ));
            }
        };
        self.at += 1;
        let name = self.name()?;
        Ok(Ev { point, name })
    }

    fn name(&mut self) -> Result<String, PropertyError> {
        self.expect("(")?;
        let Some(name) = self.peek().map(str::to_owned) else {
            return Err(self.error("expected a task name".into(), None));
        };
        if name == ")" || name == "(" {
            return Err(self.error("expected a task name".into(), None));
        }
        self.at += 1;
        self.expect(")")?;
        Ok(name)
    }

    fn formula(&mut self) -> Result<Formula, PropertyError> {
        let mut left = self.conj()?;
        while self.eat("or") {
            left = Formula::Or(Box::new(left), Box::new(self.conj()?));
        }
        Ok(left)
    }

    fn conj(&mut self) -> Result<Formula, PropertyError> {
        let mut left = self.unary()?;
        while self.eat("and") {
            left = Formula::And(Box::new(left), Box::new(self.unary()?));
        }
        Ok(left)
    }

    fn unary(&mut self) -> Result<Formula, PropertyError> {
        if self.eat("not") {
            return Ok(Formula::Not(Box::new(self.unary()?)));
        }
        if self.eat("(") {
            let f = self.formula()?;
            self.expect(")")?;
            return Ok(f);
        }
        match self.peek() {
            Some("active") => {
                self.at += 1;
                Ok(Formula::Active(self.name()?))
            }
            Some(var)
                if var
                    .chars()
                    .next()
                    .is_some_and(|c| c.is_alphabetic() || c == '_')
                    && var.chars().all(|c| c.is_alphanumeric() || c == '_')
                    && !matches!(var, "and" | "or" | "not" | "while" | "before") =>
            {
                let var = tcm_core::Expr::var(var);
                self.at += 1;
                let op = match self.peek() {
                    Some("<") => tcm_core::BinOp::Lt,
                    Some("<=") => tcm_core::BinOp::Le,
                    Some(">") => tcm_core::BinOp::Gt,
                    Some(">=") => tcm_core::BinOp::Ge,
                    Some("==") => tcm_core::BinOp::Eq,
                    Some("!=") => tcm_core::BinOp::Ne,
                    _ => return Ok(Formula::State(var)),
                };
                self.at += 1;
                let lit = self.peek().and_then(literal).ok_or_else(|| {
                    self.error(
                        "expected a literal after the comparison".into(),
                        Some("a number, true, false or a \"string\", e.g. `battery < 20.0`".into()),
                    )
                })?;
                self.at += 1;
                Ok(Formula::State(tcm_core::Expr::bin(
                    op,
                    var,
                    tcm_core::Expr::Lit(lit),
                )))
            }
            other => {
                let found = other.map_or("the end".to_owned(), |f| format!("`{f}`"));
                Err(self.error(
                    format!("expected `active(T)`, a state variable, `not`, or `(`, found {found}"),
                    Some(
                        "a state formula is made of active(T), state variables (`ok`, `battery < 20.0`), and, or, not"
                            .into(),
                    ),
                ))
            }
        }
    }
}

/// A literal of a state atom: `true`, `false`, a number, a `"string"`.
fn literal(word: &str) -> Option<tcm_core::Value> {
    match word {
        "true" => return Some(true.into()),
        "false" => return Some(false.into()),
        _ => {}
    }
    if let Some(s) = word.strip_prefix('"').and_then(|w| w.strip_suffix('"')) {
        return Some(s.into());
    }
    if let Ok(i) = word.parse::<i64>() {
        return Some(i.into());
    }
    word.parse::<f64>().ok().map(Into::into)
}

impl Formula {
    fn holds(
        &self,
        active: &dyn Fn(&str) -> bool,
        state: &dyn Fn(&str) -> Option<tcm_core::Value>,
    ) -> bool {
        match self {
            Formula::Active(n) => active(n),
            Formula::State(e) => e.holds(state).unwrap_or(false),
            Formula::Not(f) => !f.holds(active, state),
            Formula::And(a, b) => a.holds(active, state) && b.holds(active, state),
            Formula::Or(a, b) => a.holds(active, state) || b.holds(active, state),
        }
    }
}

/// The properties of one verification, with the events they follow numbered.
#[derive(Clone, Debug, Default)]
pub(crate) struct Props {
    pub(crate) list: Vec<Property>,
    /// Distinct events `before` and `eventually` need to remember, by number (at most 64).
    events: Vec<Ev>,
}

/// What a path has shown the properties so far (part of the state when properties exist).
#[derive(Clone, Debug, Default)]
pub(crate) struct Watch {
    names: Vec<(u64, Arc<str>)>,
    active: Vec<u64>,
    /// The state variables' values on the path, by name.
    states: Vec<(Arc<str>, tcm_core::Value)>,
    /// Bit `i`: event `i` of [`Props`] happened on the path.
    pub(crate) seen: u64,
}

impl Watch {
    /// Whether a state formula holds on the path now.
    fn holds(&self, f: &Formula) -> bool {
        let names = &self.names;
        let active = &self.active;
        let is_active = |t: &str| {
            active.iter().any(|a| {
                names
                    .binary_search_by_key(a, |(n, _)| *n)
                    .is_ok_and(|j| &*names[j].1 == t)
            })
        };
        let state = |v: &str| {
            self.states
                .iter()
                .find(|(n, _)| &**n == v)
                .map(|(_, value)| value.clone())
        };
        f.holds(&is_active, &state)
    }
}

impl Props {
    pub(crate) fn new(list: Vec<Property>) -> Result<Props, String> {
        let mut events: Vec<Ev> = Vec::new();
        for p in &list {
            let evs: Vec<&Ev> = match &p.kind {
                Kind::Before(a, _) => vec![a],
                Kind::Eventually(e) => vec![e],
                Kind::Never(_) | Kind::NeverWhile(..) => Vec::new(),
            };
            for e in evs {
                if !events.contains(e) {
                    events.push(e.clone());
                }
            }
        }
        if events.len() > 64 {
            return Err(
                "more than 64 distinct events in `before` and `eventually` properties".into(),
            );
        }
        Ok(Props { list, events })
    }

    pub(crate) fn is_empty(&self) -> bool {
        self.list.is_empty()
    }

    fn bit(&self, e: &Ev) -> Option<u64> {
        self.events.iter().position(|x| x == e).map(|i| 1u64 << i)
    }

    /// Follows one transition's records; returns the first property they break.
    pub(crate) fn follow(&self, w: &mut Watch, records: &[TraceEvent]) -> Option<usize> {
        let mut broken = None;
        for r in records {
            let (point, node) = match &r.kind {
                TraceKind::StateDeclared { var, value, .. }
                | TraceKind::StateSet { var, value } => {
                    match w.states.iter_mut().find(|(n, _)| &**n == var.as_str()) {
                        Some(slot) => slot.1 = value.clone(),
                        None => w.states.push((Arc::from(var.as_str()), value.clone())),
                    }
                    // A state formula may hold from here.
                    if broken.is_none() {
                        broken = self.never_holds(w);
                    }
                    continue;
                }
                TraceKind::Spawned { node, name, .. } | TraceKind::Reserved { node, name, .. } => {
                    match w.names.binary_search_by_key(node, |(n, _)| *n) {
                        Ok(i) => w.names[i].1 = Arc::from(name.as_str()),
                        Err(i) => w.names.insert(i, (*node, Arc::from(name.as_str()))),
                    }
                    continue;
                }
                TraceKind::Reclaimed { node } | TraceKind::Dead { node } => {
                    if let Ok(i) = w.names.binary_search_by_key(node, |(n, _)| *n) {
                        w.names.remove(i);
                    }
                    w.active.retain(|a| a != node);
                    continue;
                }
                TraceKind::Transition {
                    node,
                    facet: Facet::Handling,
                    to,
                    from,
                } => {
                    if *from == FacetState::Active {
                        w.active.retain(|a| a != node);
                    }
                    match to {
                        FacetState::Enabled => (Point::Enabled, *node),
                        FacetState::Active => {
                            w.active.push(*node);
                            (Point::Active, *node)
                        }
                        _ => continue,
                    }
                }
                TraceKind::Transition {
                    node,
                    facet: Facet::Execution,
                    to: FacetState::Completed,
                    ..
                } => (Point::Completed, *node),
                TraceKind::Failed { node, .. } => (Point::Failed, *node),
                TraceKind::Terminated { node } => (Point::Terminated, *node),
                _ => continue,
            };
            let Ok(i) = w.names.binary_search_by_key(&node, |(n, _)| *n) else {
                continue;
            };
            let name = w.names[i].1.clone();
            let ev = Ev {
                point,
                name: name.to_string(),
            };
            for (k, p) in self.list.iter().enumerate() {
                match &p.kind {
                    Kind::Before(first, second) if *second == ev => {
                        let seen = self.bit(first).is_some_and(|b| w.seen & b != 0);
                        if !seen && broken.is_none() {
                            broken = Some(k);
                        }
                    }
                    Kind::Never(f) if point == Point::Active && broken.is_none() && w.holds(f) => {
                        broken = Some(k);
                    }
                    Kind::NeverWhile(e, f) if *e == ev && broken.is_none() && w.holds(f) => {
                        broken = Some(k);
                    }
                    _ => {}
                }
            }
            if let Some(b) = self.bit(&ev) {
                w.seen |= b;
            }
        }
        broken
    }

    /// The first `never` property whose formula holds now.
    fn never_holds(&self, w: &Watch) -> Option<usize> {
        self.list
            .iter()
            .position(|p| matches!(&p.kind, Kind::Never(f) if w.holds(f)))
    }

    /// At the end of a run: the first `eventually` property whose event it never saw.
    pub(crate) fn at_end(&self, w: &Watch) -> Option<usize> {
        self.list.iter().position(|p| match &p.kind {
            Kind::Eventually(e) => self.bit(e).is_some_and(|b| w.seen & b == 0),
            _ => false,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_forms_parse() {
        let p = Property::parse("never active(turn) and active(guarded_move)").expect("parses");
        assert_eq!(
            p.kind,
            Kind::Never(Formula::And(
                Box::new(Formula::Active("turn".into())),
                Box::new(Formula::Active("guarded_move".into()))
            ))
        );
        assert_eq!(p.names(), ["turn", "guarded_move"]);
        let p = Property::parse("completed(plan) before active(move)").expect("parses");
        assert!(matches!(p.kind, Kind::Before(..)));
        assert_eq!(p.names(), ["plan", "move"]);
        assert!(
            Property::parse("always eventually completed(deliver_mail)")
                .expect("parses")
                .is_liveness()
        );
    }

    #[test]
    fn mistakes_are_explained() {
        let e = Property::parse("never active(a) nand active(b)").expect_err("does not parse");
        assert_eq!(
            e.to_string(),
            "unexpected `nand` in `never active(a) nand active(b)`"
        );
        let e = Property::parse("completed(a)").expect_err("does not parse");
        assert!(
            e.to_string()
                .starts_with("an event alone is not a property")
        );
        let e = Property::parse_file("p.txt", "# motion\nnever active(x)\nbogus(y)\n")
            .expect_err("line 3 is wrong");
        assert!(
            e.starts_with("p.txt:3: expected an event, found `bogus`"),
            "{e}"
        );
    }
}
