//! Tree dumps of a [`Replay`]: TCM's `TCM_DisplayTree` form and a modern form
//! (docs/semantics.md, "TCM-compatible output").
//!
//! TCM's form prints one line per node, indented 3 spaces per depth, `<name> {id} [h|a|p|t]` with the
//! codes handling `uh/hg/hd`, achieving (execution) `ua/ag/ad`, planning (expansion) `up/pg/pd` and
//! terminating `al/tg/td`, in that order; the words follow the text log's mapping (`textlog.rs`), so an
//! enabled handling is `hg` and an enabled expansion is `up`. The modern form uses our words:
//! `deliver_mail {1}  handling=completed expansion=active execution=active`, followed by
//! `terminating`, `terminated`, `suspended` or `failed` when they apply. Reclaimed nodes are left out, as
//! TCM had deleted them. Both walks are iterative, so a 10,000-deep tree does not exhaust the stack.

use crate::replay::{Replay, ReplayNode};
use crate::state::{Facet, State, Termination};
use std::fmt::Write;

#[cfg(test)]
mod tests;

fn handling_code(s: State) -> &'static str {
    match s {
        State::Disabled => "uh",
        State::Enabled | State::Active => "hg",
        State::Completed => "hd",
    }
}

fn execution_code(s: State) -> &'static str {
    match s {
        State::Disabled | State::Enabled => "ua",
        State::Active => "ag",
        State::Completed => "ad",
    }
}

fn expansion_code(s: State) -> &'static str {
    match s {
        State::Disabled | State::Enabled => "up",
        State::Active => "pg",
        State::Completed => "pd",
    }
}

fn termination_code(t: Termination) -> &'static str {
    match t {
        Termination::Alive => "al",
        Termination::Terminating => "tg",
        Termination::Terminated => "td",
    }
}

// Visits the live (unreclaimed, spawned) nodes depth first in spawn order, with their depth.
fn walk(replay: &Replay, mut visit: impl FnMut(&ReplayNode, usize)) {
    let mut stack = vec![(replay.root(), 0usize)];
    while let Some((node, depth)) = stack.pop() {
        visit(node, depth);
        for child in node.children().iter().rev() {
            if let Some(c) = replay.node(*child) {
                if c.is_spawned() && !c.is_reclaimed() {
                    stack.push((c, depth + 1));
                }
            }
        }
    }
}

/// TCM's tree dump: `<indent><name> {id} [h|a|p|t]`, one line per node, each ending in a newline.
pub fn dump_tcm(replay: &Replay) -> String {
    let mut out = String::new();
    walk(replay, |node, depth| {
        let codes = if node.number() == 0 {
            // TCM's root is pre-started but never handled.
            "uh|ag|pg|al".to_string()
        } else {
            format!(
                "{}|{}|{}|{}",
                handling_code(node.state(Facet::Handling)),
                execution_code(node.state(Facet::Execution)),
                expansion_code(node.state(Facet::Expansion)),
                termination_code(node.termination())
            )
        };
        let _ = writeln!(
            out,
            "{:indent$}{} {{{}}} [{codes}]",
            "",
            node.name(),
            node.number(),
            indent = 3 * depth
        );
    });
    out
}

/// The modern dump: `<indent><name> {id}  handling=.. expansion=.. execution=..[ flags]`.
pub fn dump_modern(replay: &Replay) -> String {
    let mut out = String::new();
    walk(replay, |node, depth| {
        let _ = write!(
            out,
            "{:indent$}{} {{{}}}  handling={} expansion={} execution={}",
            "",
            node.name(),
            node.number(),
            node.state(Facet::Handling),
            node.state(Facet::Expansion),
            node.state(Facet::Execution),
            indent = 2 * depth
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
        out.push('\n');
    });
    out
}
