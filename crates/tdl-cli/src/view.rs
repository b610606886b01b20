//! What `tdl trace tree` and `tdl trace story` print: the task tree of a whole run (reclaimed nodes
//! included), and the story of a run, one line per record with node numbers, filtered. Both read
//! the one fold of a trace, [`Replay`], and each record's own text ([`tcm_trace::TraceKind::describe`]).

use std::fmt::Write as _;

use tcm_trace::{Facet, RecordClass, Replay, ReplayNode, Termination, TraceEvent};

/// The tree of every node the run spawned, reclaimed ones included (marked `reclaimed`), as the
/// modern dump prints a live tree: `<indent><name> {id}  handling=.. expansion=.. execution=..`
/// and flags. Reservations that were never spawned are left out; dead ones are marked `dead`.
pub(crate) fn whole_tree(replay: &Replay) -> String {
    let mut out = String::new();
    let mut stack = vec![(replay.root(), 0usize)];
    while let Some((node, depth)) = stack.pop() {
        line(&mut out, node, depth);
        for child in node.children().iter().rev() {
            if let Some(c) = replay.node(*child) {
                if c.is_spawned() || c.is_dead() {
                    stack.push((c, depth + 1));
                }
            }
        }
    }
    out
}

fn line(out: &mut String, node: &ReplayNode, depth: usize) {
    let indent = 2 * depth;
    if !node.is_spawned() {
        let _ = writeln!(
            out,
            "{:indent$}{} {{{}}}  dead",
            "",
            node.name(),
            node.number()
        );
        return;
    }
    let _ = write!(
        out,
        "{:indent$}{} {{{}}}  handling={} expansion={} execution={}",
        "",
        node.name(),
        node.number(),
        node.state(Facet::Handling),
        node.state(Facet::Expansion),
        node.state(Facet::Execution),
    );
    match node.termination() {
        Termination::Alive => {}
        Termination::Terminating => out.push_str(" terminating"),
        Termination::Terminated => out.push_str(" terminated"),
    }
    if node.is_suspended() {
        out.push_str(" suspended");
    }
    if node.is_failed() {
        out.push_str(" failed");
    }
    if node.is_reclaimed() {
        out.push_str(" reclaimed");
    }
    out.push('\n');
}

/// A kind of story record, for `--kind`: a record class of the fold ([`RecordClass`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Kind(RecordClass);

impl clap::ValueEnum for Kind {
    fn value_variants<'a>() -> &'a [Self] {
        const ALL: [Kind; 13] = {
            let mut all = [Kind(RecordClass::Transition); 13];
            let mut i = 0;
            while i < 13 {
                all[i] = Kind(RecordClass::ALL[i]);
                i += 1;
            }
            all
        };
        &ALL
    }

    fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
        Some(clap::builder::PossibleValue::new(self.0.name()))
    }
}

/// What `tdl trace story` keeps.
#[derive(Clone, Debug, Default)]
pub(crate) struct Filter {
    /// Only these kinds; every kind but constraints when empty.
    pub(crate) kinds: Vec<Kind>,
    /// Only records about nodes of this instance name.
    pub(crate) name: Option<String>,
    /// Only records about the node at this path (instance names from the top-level task, joined by
    /// `/`) and its subtree.
    pub(crate) path: Option<String>,
    /// Only records about this node and its subtree.
    pub(crate) node: Option<u64>,
    /// Only records at or after this time (seconds since the run started).
    pub(crate) from: Option<f64>,
    /// Only records at or before this time (seconds since the run started).
    pub(crate) to: Option<f64>,
}

impl Filter {
    fn by_node(&self) -> bool {
        self.name.is_some() || self.path.is_some() || self.node.is_some()
    }
}

/// What a valid trace of a run that did not end leaves: which nodes had not completed at its
/// last record, the innermost of them (those none of whose children are unfinished) with their
/// paths and facets; empty when the run ended.
pub(crate) fn unfinished(trace: &[TraceEvent]) -> String {
    let mut replay = Replay::with_history();
    for ev in trace {
        // A valid trace: the checker said so.
        let _ = replay.apply(ev);
    }
    let unfinished = replay.unfinished();
    if unfinished.is_empty() {
        return String::new();
    }
    let open: std::collections::BTreeSet<u64> = unfinished.iter().map(|it| it.number()).collect();
    let innermost: Vec<_> = unfinished
        .iter()
        .filter(|it| !it.children().iter().any(|c| open.contains(c)))
        .collect();
    let mut out = format!(
        "the run did not end: at its last record ({:.3} s) {} node(s) had not completed; the innermost:\n",
        replay.last_t() as f64 / 1e9,
        unfinished.len()
    );
    const SHOWN: usize = 10;
    for node in innermost.iter().take(SHOWN) {
        let facets: Vec<String> = [Facet::Handling, Facet::Expansion, Facet::Execution]
            .iter()
            .map(|f| format!("{f} {}", node.state(*f)))
            .collect();
        let terminating = if node.termination() == tcm_trace::Termination::Alive {
            ""
        } else {
            ", terminating"
        };
        out.push_str(&format!(
            "  {} {{{}}}: {}{terminating}\n",
            replay.path(node.number()),
            node.number(),
            facets.join(", ")
        ));
    }
    if innermost.len() > SHOWN {
        out.push_str(&format!("  … and {} more\n", innermost.len() - SHOWN));
    }
    out
}

/// The story lines of `trace` that `filter` keeps: `<seconds> {id} <name> <what>`, or
/// `<seconds> <what>` for records about no node (external events, callbacks, run-wide warnings).
/// Names and parents are the fold's ([`Replay`]) as of each record; the text is the record's own
/// ([`tcm_trace::TraceKind::describe`]).
pub(crate) fn story(trace: &[TraceEvent], filter: &Filter) -> Vec<String> {
    let mut replay = Replay::new();
    let mut out = Vec::new();
    for ev in trace {
        // A record the fold refuses is still told, with the names known so far; `tdl trace
        // check` says what is wrong with it.
        let _ = replay.apply(ev);
        // The root has no name in a story.
        let name_of = |n: u64| {
            (n != 0)
                .then(|| replay.node(n).map(|it| it.name().to_string()))
                .flatten()
        };
        let Some((class, node, what)) = ev
            .kind
            .describe(|n| name_of(n).unwrap_or_else(|| format!("#{n}")))
        else {
            continue;
        };
        let wanted = if filter.kinds.is_empty() {
            class != RecordClass::Constraint
        } else {
            filter.kinds.contains(&Kind(class))
        };
        let secs = ev.t as f64 / 1e9;
        if !wanted
            || filter.from.is_some_and(|from| secs < from)
            || filter.to.is_some_and(|to| secs > to)
        {
            continue;
        }
        let line = match node {
            Some(node) => {
                if filter.by_node() && !keeps(filter, node, &replay) {
                    continue;
                }
                let name = name_of(node).unwrap_or_else(|| "?".to_string());
                format!("{secs} {{{node}}} {name} {what}")
            }
            None if filter.by_node() => continue,
            None => format!("{secs} {what}"),
        };
        out.push(line);
    }
    out
}

/// Whether a record about `node` passes the node filters.
fn keeps(filter: &Filter, node: u64, replay: &Replay) -> bool {
    let name = |n: u64| {
        (n != 0)
            .then(|| replay.node(n).map(ReplayNode::name))
            .flatten()
    };
    // The node and its ancestors up to the top-level task, nearest first.
    let mut chain = vec![node];
    let mut at = node;
    while let Some(parent) = replay.node(at).and_then(ReplayNode::parent) {
        if parent == 0 || chain.contains(&parent) {
            break;
        }
        chain.push(parent);
        at = parent;
    }
    if filter
        .name
        .as_ref()
        .is_some_and(|wanted| name(node) != Some(wanted.as_str()))
    {
        return false;
    }
    if filter.node.is_some_and(|wanted| !chain.contains(&wanted)) {
        return false;
    }
    if let Some(path) = &filter.path {
        let full: Vec<&str> = chain
            .iter()
            .rev()
            .map(|n| name(*n).unwrap_or("?"))
            .collect();
        let wanted: Vec<&str> = path.trim_matches('/').split('/').collect();
        if full.len() < wanted.len() || full[..wanted.len()] != wanted[..] {
            return false;
        }
    }
    true
}
