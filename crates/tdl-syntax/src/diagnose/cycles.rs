//! Circular constraints within a body: spawns that wait for each other, so that none of them can
//! ever complete (docs/language.md, "Static checks").
//!
//! The graph's nodes are the events of the body's spawns and of the node running the body
//! (`parent`): an edge from event `e` of `a` to event `f` of `b` says that `e` cannot happen
//! before `f`, because a constraint holds a facet of `a` disabled until `f`, and that facet
//! keeps `e` from happening ([`blocked`]); the node running the body completes only after its
//! children. A cycle of such edges can never be satisfied. Only spawns that surely run count
//! (see `flow.rs`): a constraint inside an `if` or a loop, or on a spawn that may not run, makes
//! no edge, and neither do termination and activation constraints, which hold nothing, nor a
//! constraint statement after a wait, which may come too late and be refused.

use std::collections::BTreeSet;

use proc_macro2::Span;

use super::flow::{Ev, Flow, Node, Target, blocked, gate};
use super::graph;
use crate::ast::{Facet, TaskKind};
use crate::diagnostic::Diagnostic;
use crate::hir::{BodyScope, SpawnId};

/// Why an edge is there.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Why {
    /// The applied constraint of this number.
    Constraint(usize),
    /// The node running the body completes only after this child.
    Child(SpawnId),
}

struct Edge {
    why: Why,
    /// The waiting spawn, `None` for the node running the body.
    from: Option<SpawnId>,
    to: Node,
    event: Ev,
    span: Span,
}

/// Reports each cycle of waits among the body's spawns.
pub(super) fn check(flow: &Flow<'_>, scope: &BodyScope<'_>, diags: &mut Vec<Diagnostic>) {
    let sure = |id: SpawnId| {
        flow.spawns
            .get(id)
            .is_some_and(|s| s.cond.sure() && !s.late)
    };
    let parent_base = flow.spawns.len() * Ev::COUNT;
    let index = |node: Node, ev: Ev| match node {
        Node::Spawn(id) => id * Ev::COUNT + ev.index(),
        Node::Parent => parent_base + ev.index(),
    };
    let mut pairs: Vec<(usize, usize)> = Vec::new();
    let mut edges: Vec<Edge> = Vec::new();
    for (i, applied) in flow.applied.iter().enumerate() {
        if !applied.cond.sure() {
            continue;
        }
        let Some(gate) = gate(&applied.constraint.kind) else {
            continue;
        };
        let Some(targets) = flow.targets(scope, applied.target, &applied.prev) else {
            continue;
        };
        let deps = match gate.tag {
            Some(tag) => flow.nodes(scope, tag, &applied.prev),
            None => flow.nodes(scope, &previous(applied.constraint.span), &applied.prev),
        };
        let Some(deps) = deps else {
            continue;
        };
        for target in targets.into_iter().filter(|it| sure(*it)) {
            let Some(spawn) = flow.spawns.get(target) else {
                continue;
            };
            // A constraint statement after a wait may come once the node started: the run then
            // refuses it (docs/semantics.md, "Constraints"), and it holds nothing.
            let late = matches!(applied.target, Target::Tag(_))
                && flow
                    .waits
                    .iter()
                    .any(|w| spawn.position <= w.position && w.position < applied.position);
            if late {
                continue;
            }
            let held: BTreeSet<Ev> = gate
                .facets
                .iter()
                .flat_map(|facet| blocked(spawn.shape, *facet, spawn.delay_expansion))
                .copied()
                .collect();
            for dep in &deps {
                if let Node::Spawn(id) = dep {
                    if !sure(*id) {
                        continue;
                    }
                }
                for ev in &held {
                    pairs.push((index(Node::Spawn(target), *ev), index(*dep, gate.event)));
                    edges.push(Edge {
                        why: Why::Constraint(i),
                        from: Some(target),
                        to: *dep,
                        event: gate.event,
                        span: applied.constraint.span,
                    });
                }
            }
        }
    }
    // The node running the body completes its expansion and its execution only after its
    // children's (docs/semantics.md, "Facets and states", rule 5); a command-like node's
    // expansion is completed from the start.
    let goal_like = matches!(flow.task.kind, TaskKind::Goal | TaskKind::Handler);
    for id in (0..flow.spawns.len()).filter(|it| sure(*it)) {
        let Some(span) = Flow::span(scope, id) else {
            continue;
        };
        for facet in [Facet::Expansion, Facet::Execution] {
            if facet == Facet::Expansion && !goal_like {
                continue;
            }
            let ev = Ev {
                facet,
                stage: super::flow::Stage::Completed,
            };
            pairs.push((index(Node::Parent, ev), index(Node::Spawn(id), ev)));
            edges.push(Edge {
                why: Why::Child(id),
                from: None,
                to: Node::Spawn(id),
                event: ev,
                span,
            });
        }
    }
    let mut reported: BTreeSet<BTreeSet<Why>> = BTreeSet::new();
    for cycle in graph::cycles(parent_base + Ev::COUNT, &pairs) {
        let cycle: Vec<&Edge> = cycle.iter().filter_map(|i| edges.get(*i)).collect();
        let whys: BTreeSet<Why> = cycle.iter().map(|it| it.why).collect();
        if cycle.is_empty() || !reported.insert(whys) {
            continue;
        }
        diags.push(diagnostic(scope, &cycle));
    }
}

/// A `previous` tag at `span`, for `sequential`/`serial` written without one.
fn previous(span: Span) -> crate::ast::Tag {
    crate::ast::Tag {
        kind: crate::ast::TagKind::Previous,
        span,
    }
}

fn name(scope: &BodyScope<'_>, node: Option<Node>) -> String {
    match node {
        Some(Node::Spawn(id)) => format!("`{}`", Flow::name(scope, id)),
        Some(Node::Parent) | None => "`parent`".to_owned(),
    }
}

fn diagnostic(scope: &BodyScope<'_>, cycle: &[&Edge]) -> Diagnostic {
    // Start the story at the constraint written first.
    let first = cycle
        .iter()
        .enumerate()
        .filter(|(_, it)| matches!(it.why, Why::Constraint(_)))
        .min_by_key(|(_, it)| {
            let at = it.span.start();
            (at.line, at.column)
        })
        .map_or(0, |(i, _)| i);
    let mut ordered: Vec<&Edge> = cycle[first..].to_vec();
    ordered.extend_from_slice(&cycle[..first]);
    let from = |edge: &Edge| edge.from.map_or(Node::Parent, Node::Spawn);
    let start = name(scope, Some(from(ordered[0])));
    let message = if ordered.len() == 1 && ordered[0].to == from(ordered[0]) {
        format!("circular constraint: {start} waits for itself, so it can never complete")
    } else {
        let mut chain = format!("{start} waits for {}", name(scope, Some(ordered[0].to)));
        for edge in &ordered[1..] {
            chain.push_str(&format!(", which waits for {}", name(scope, Some(edge.to))));
        }
        format!("circular constraints: {chain}; none of them can ever complete")
    };
    let mut diag = Diagnostic::error(ordered[0].span, message);
    let mut labels: BTreeSet<(usize, usize, String)> = BTreeSet::new();
    for (i, edge) in ordered.iter().enumerate() {
        let text = match edge.why {
            Why::Constraint(_) => format!(
                "{} waits for {} {}",
                name(scope, Some(from(edge))),
                name(scope, Some(edge.to)),
                edge.event.text()
            ),
            Why::Child(_) => format!(
                "`parent` (the task running this body) completes its {} only after this child's",
                edge.event.facet.as_str()
            ),
        };
        let at = edge.span.start();
        if i > 0 && labels.insert((at.line, at.column, text.clone())) {
            diag = diag.with_label(edge.span, text);
        } else if i == 0 {
            labels.insert((at.line, at.column, text));
        }
    }
    let through_parent = ordered.iter().any(|it| matches!(it.why, Why::Child(_)));
    let hint = if ordered.len() == 1 {
        "a spawn cannot wait for its own events: name another spawn, `previous` or a label"
    } else if through_parent {
        "a child cannot wait for the completion of the task that spawns it, which completes only \
         once its children have; wait for `parent handling completed` (its body's end), or for a sibling"
    } else {
        "remove or reverse one of these constraints: each of these spawns waits for the next, so \
         none of them can complete"
    };
    diag.with_hint(hint)
}
