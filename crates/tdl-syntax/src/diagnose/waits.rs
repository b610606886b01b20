//! Waits that cannot end: the body waits for a node that cannot complete before something the
//! body only does after the wait (docs/language.md, "Static checks").
//!
//! A body that waits (`spawn … with wait`, `with outcome`, a waited value, `X wait;`) stops there
//! until the node's execution completes. If that node, directly or through other nodes, waits
//! for a spawn written after the wait, it waits for a reservation that the body fulfils only
//! once it goes on, and that dies only when the body ends: neither comes (docs/semantics.md,
//! "Tags and forward references"). Likewise for a wait on the completion of the node running the
//! body. Only the constraints applied before the wait count. When the chain goes through an `if`
//! or a `match`, the wait blocks only if those branches run, and the finding is a warning; inside
//! loops, positions do not say what comes first, and nothing is reported.

use std::collections::{BTreeMap, VecDeque};

use super::flow::{Flow, Node, Shape, blocked, gate};
use crate::ast::{Facet, Tag, TagKind, TaskKind};
use crate::diagnostic::{Diagnostic, Lint};
use crate::hir::{BodyScope, SpawnId};

/// A spawn's event the wait needs, and how the search got there.
type State = (SpawnId, usize);

/// What the chain ends at.
enum End {
    /// A spawn written after the wait.
    Later(SpawnId),
    /// The node running the body.
    Parent,
}

/// One enablement constraint applied before a wait, resolved.
struct Step {
    applied: usize,
    targets: Vec<SpawnId>,
    deps: Vec<Node>,
}

/// Reports each wait of the body that cannot end.
pub(super) fn check(flow: &Flow<'_>, scope: &BodyScope<'_>, diags: &mut Vec<Diagnostic>) {
    let mut steps: Vec<Step> = Vec::new();
    for (i, applied) in flow.applied.iter().enumerate() {
        if applied.cond.looped {
            continue;
        }
        let Some(gate) = gate(&applied.constraint.kind) else {
            continue;
        };
        let Some(targets) = flow.targets(scope, applied.target, &applied.prev) else {
            continue;
        };
        let previous = Tag {
            kind: TagKind::Previous,
            span: applied.constraint.span,
        };
        let Some(deps) = flow.nodes(scope, gate.tag.unwrap_or(&previous), &applied.prev) else {
            continue;
        };
        steps.push(Step {
            applied: i,
            targets,
            deps,
        });
    }
    let parent_shape = match flow.task.kind {
        TaskKind::Goal | TaskKind::Handler => Shape::GoalLike,
        TaskKind::Command | TaskKind::Monitor => Shape::CommandLike,
    };
    for wait in &flow.waits {
        if wait.cond.looped {
            continue;
        }
        let Some(targets) = flow.targets(scope, wait.target, &wait.prev) else {
            continue;
        };
        // The search: from each waited node's execution completion, back along the waits.
        let mut came_from: BTreeMap<State, Option<(State, usize)>> = BTreeMap::new();
        let mut queue: VecDeque<State> = VecDeque::new();
        for target in targets {
            let Some(spawn) = flow.spawns.get(target) else {
                continue;
            };
            // A wait on a spawn further down is reported by the diagnosis already.
            if spawn.late || spawn.cond.looped || spawn.position > wait.position {
                continue;
            }
            let start = (target, super::flow::E_DONE.index());
            if came_from.insert(start, None).is_none() {
                queue.push_back(start);
            }
        }
        let mut found: Option<(State, usize, End)> = None;
        'search: while let Some(state @ (node, ev)) = queue.pop_front() {
            let Some(spawn) = flow.spawns.get(node) else {
                continue;
            };
            for step in &steps {
                let Some(applied) = flow.applied.get(step.applied) else {
                    continue;
                };
                if applied.position > wait.position || !step.targets.contains(&node) {
                    continue;
                }
                let Some(gate) = gate(&applied.constraint.kind) else {
                    continue;
                };
                let held = gate
                    .facets
                    .iter()
                    .flat_map(|f| blocked(spawn.shape, *f, spawn.delay_expansion))
                    .any(|it| it.index() == ev);
                if !held {
                    continue;
                }
                for dep in &step.deps {
                    match *dep {
                        Node::Parent => {
                            let never = gate.event.stage == super::flow::Stage::Completed
                                && !(gate.event.facet == Facet::Expansion
                                    && parent_shape == Shape::CommandLike);
                            if never {
                                found = Some((state, step.applied, End::Parent));
                                break 'search;
                            }
                        }
                        Node::Spawn(id) => {
                            let Some(dep) = flow.spawns.get(id) else {
                                continue;
                            };
                            if dep.late {
                                continue;
                            }
                            if dep.position > wait.position {
                                found = Some((state, step.applied, End::Later(id)));
                                break 'search;
                            }
                            if dep.cond.looped {
                                continue;
                            }
                            let next = (id, gate.event.index());
                            if let std::collections::btree_map::Entry::Vacant(slot) =
                                came_from.entry(next)
                            {
                                slot.insert(Some((state, step.applied)));
                                queue.push_back(next);
                            }
                        }
                    }
                }
            }
        }
        let Some((last, applied, end)) = found else {
            continue;
        };
        // The chain of constraints, from the waited node on.
        let mut chain: Vec<(SpawnId, usize)> = vec![(last.0, applied)];
        let mut at = last;
        while let Some(Some((before, applied))) = came_from.get(&at) {
            chain.push((before.0, *applied));
            at = *before;
        }
        chain.reverse();
        diags.push(diagnostic(flow, scope, wait, &chain, &end));
    }
}

fn diagnostic(
    flow: &Flow<'_>,
    scope: &BodyScope<'_>,
    wait: &super::flow::WaitPoint<'_>,
    chain: &[(SpawnId, usize)],
    end: &End,
) -> Diagnostic {
    let approximate = wait.cond.branch
        || chain.iter().any(|(id, applied)| {
            flow.spawns.get(*id).is_some_and(|it| it.cond.branch)
                || flow.applied.get(*applied).is_some_and(|it| it.cond.branch)
        });
    let end_name = match end {
        End::Later(id) => format!("`{}`", Flow::name(scope, *id)),
        End::Parent => "`parent`".to_owned(),
    };
    let mut story = String::new();
    for (i, (id, _)) in chain.iter().enumerate() {
        let name = Flow::name(scope, *id);
        if i == 0 {
            story.push_str(&format!("`{name}` waits for "));
        } else {
            story.push_str(&format!("`{name}`, which waits for "));
        }
    }
    story.push_str(&end_name);
    let why = match end {
        End::Later(_) => "spawned only after this wait",
        End::Parent => "the task running this body, which cannot complete while its body waits",
    };
    let message = if approximate {
        format!("this wait never ends if these branches run: {story}, {why}")
    } else {
        format!("this wait can never end: {story}, {why}")
    };
    let mut diag = if approximate {
        Diagnostic::warning(Lint::WaitMayNotEnd, wait.span, message)
    } else {
        Diagnostic::error(wait.span, message)
    };
    for (i, (id, applied)) in chain.iter().enumerate() {
        let Some(applied) = flow.applied.get(*applied) else {
            continue;
        };
        let waited = match chain.get(i + 1) {
            Some((next, _)) => format!("`{}`", Flow::name(scope, *next)),
            None => end_name.clone(),
        };
        let event = gate(&applied.constraint.kind).map_or_else(String::new, |g| g.event.text());
        diag = diag.with_label(
            applied.constraint.span,
            format!("`{}` waits for {waited} {event}", Flow::name(scope, *id)),
        );
    }
    let hint = match end {
        End::Later(id) => {
            if let Some(span) = Flow::span(scope, *id) {
                diag = diag.with_label(span, "spawned here, after the wait");
            }
            format!(
                "spawn {end_name} before this wait, or wait after its spawn: the body stops at the wait, and {end_name} is only spawned when the body goes on"
            )
        }
        End::Parent => "wait for a sibling instead of `parent`, or do not wait here: the task running this body completes only after its body".to_owned(),
    };
    diag.with_hint(hint)
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_wait_on_a_node_waiting_for_a_later_spawn_is_an_error() {
        let src = "goal g() { a: spawn x() with serial b; a wait; b: spawn y(); }";
        let parse = crate::parse_str("g.tdl", src);
        assert!(parse.has_errors(), "{}", parse.render("g.tdl", Some(src)));
        let src = "goal g() { a: spawn x() with serial b; b: spawn y(); a wait; }";
        let parse = crate::parse_str("g.tdl", src);
        assert!(
            parse.diagnostics.is_empty(),
            "{}",
            parse.render("g.tdl", Some(src))
        );
    }
}
