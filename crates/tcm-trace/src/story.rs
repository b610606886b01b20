//! Stories: a compact rendering of a trace, one line per transition, that tests assert on.
//!
//! A story line reads `<seconds> <name> <what>`, e.g. `1.5 move handling active`,
//! `30 centerOnDoor terminating`, `1 plan failed NoPath`. Times are virtual seconds since the run
//! started, written as short as they go (`0`, `1.5`, `16`). Tests across the workspace (engine,
//! runtime, language, simulator) assert on the order of such lines, so they survive any change to
//! how the engine is built inside.

use crate::event::{TraceEvent, TraceKind};
use std::collections::BTreeMap;

/// Renders a trace as story lines: facet transitions, termination, failures, dead reservations,
/// suspension, timer callbacks run (`callback <name> ran`) and resources (`drive requests base,
/// arm(2)`, `drive granted …`, `drive released …`, `drive withdrawn`, `drive denied base`,
/// `drive dropped base`, `base reserved for plan`, `base unreserved`, `base locked`, `base
/// unlocked`), state variables set (`set battery_ok = false`, also to the value they had) and
/// skipped nodes (`step3 skipped`). Other records (constraints, reclamation, state variables
/// declared, …) are left out.
pub fn story(trace: &[TraceEvent]) -> Vec<String> {
    let mut names: BTreeMap<u64, String> = BTreeMap::new();
    let mut out = Vec::new();
    for ev in trace {
        let name = |names: &BTreeMap<u64, String>, n: &u64| {
            names.get(n).cloned().unwrap_or_else(|| format!("#{n}"))
        };
        let line = match &ev.kind {
            TraceKind::Spawned { node, name: nm, .. }
            | TraceKind::Reserved { node, name: nm, .. } => {
                names.insert(*node, nm.clone());
                continue;
            }
            TraceKind::Transition {
                node, facet, to, ..
            } => format!("{} {facet} {to}", name(&names, node)),
            TraceKind::Terminating { node } => format!("{} terminating", name(&names, node)),
            TraceKind::Terminated { node } => format!("{} terminated", name(&names, node)),
            TraceKind::Failed {
                node, exception, ..
            } => format!("{} failed {exception}", name(&names, node)),
            TraceKind::Dead { node } => format!("{} dead", name(&names, node)),
            TraceKind::Suspended { node } => format!("{} suspended", name(&names, node)),
            TraceKind::Unsuspended { node } => format!("{} unsuspended", name(&names, node)),
            TraceKind::CallbackRan { name, .. } => format!("callback {name} ran"),
            TraceKind::Requested { node, uses, .. } => {
                format!("{} requests {}", name(&names, node), uses_text(uses))
            }
            TraceKind::Granted { node, uses } => {
                format!("{} granted {}", name(&names, node), uses_text(uses))
            }
            TraceKind::Released { node, uses } => {
                format!("{} released {}", name(&names, node), uses_text(uses))
            }
            TraceKind::Withdrawn { node } => format!("{} withdrawn", name(&names, node)),
            TraceKind::Denied { node, resource } => {
                format!("{} denied {resource}", name(&names, node))
            }
            TraceKind::Dropped { node, resource } => {
                format!("{} dropped {resource}", name(&names, node))
            }
            TraceKind::ResourceReserved { resource, holder } => {
                format!("{resource} reserved for {}", name(&names, holder))
            }
            TraceKind::ResourceUnreserved { resource } => format!("{resource} unreserved"),
            TraceKind::ResourceLocked { resource } => format!("{resource} locked"),
            TraceKind::ResourceUnlocked { resource } => format!("{resource} unlocked"),
            TraceKind::Placed { node, agent } => {
                format!("{} runs on agent {agent}", name(&names, node))
            }
            TraceKind::Log { node, message } => {
                format!("{} logs: {message}", name(&names, node))
            }
            TraceKind::StateSet { var, value } => format!("set {var} = {value}"),
            TraceKind::Skipped { node } => format!("{} skipped", name(&names, node)),
            _ => continue,
        };
        out.push(format!("{} {line}", ev.t as f64 / 1e9));
    }
    out
}

/// `base, arm(2)`: resource uses as people write them (an amount of 1 is left out).
pub fn uses_text(uses: &[crate::event::ResourceUse]) -> String {
    let parts: Vec<String> = uses
        .iter()
        .map(|u| match u.amount {
            1 => u.resource.clone(),
            n => format!("{}({n})", u.resource),
        })
        .collect();
    parts.join(", ")
}

/// How failures were handled, in order: `handler<-Exception` for each handler chosen, `bypass` for
/// each bypass.
pub fn handler_choices(trace: &[TraceEvent]) -> Vec<String> {
    trace
        .iter()
        .filter_map(|e| match &e.kind {
            TraceKind::HandlerChosen {
                handler, exception, ..
            } => Some(format!("{handler}<-{exception}")),
            TraceKind::Bypassed { .. } => Some("bypass".into()),
            _ => None,
        })
        .collect()
}

/// The lines that contain any of `words`.
pub fn only(lines: &[String], words: &[&str]) -> Vec<String> {
    lines
        .iter()
        .filter(|l| words.iter().any(|w| l.contains(w)))
        .cloned()
        .collect()
}

/// Panics unless `needles` occur in `lines` in this order (not necessarily adjacent), printing the
/// whole story when one is missing.
#[track_caller]
pub fn assert_order(lines: &[String], needles: &[&str]) {
    let mut it = lines.iter();
    for n in needles {
        assert!(
            it.any(|l| l == n),
            "missing or out of order: {n:?}\nstory:\n{}",
            lines.join("\n")
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Facet, NodeKind, State};

    #[test]
    fn a_story_names_nodes_and_times_in_seconds() {
        let ev = |seq, t, kind| TraceEvent { seq, t, kind };
        let trace = vec![
            ev(
                0,
                0,
                TraceKind::Spawned {
                    node: 1,
                    parent: 0,
                    kind: NodeKind::Command,
                    name: "move".into(),
                    version: None,
                    args: None,
                },
            ),
            ev(
                1,
                1_500_000_000,
                TraceKind::Transition {
                    node: 1,
                    facet: Facet::Handling,
                    from: State::Enabled,
                    to: State::Active,
                },
            ),
            ev(2, 30_000_000_000, TraceKind::Terminating { node: 1 }),
            ev(3, 30_000_000_000, TraceKind::Reclaimed { node: 1 }),
        ];
        let lines = story(&trace);
        assert_eq!(lines, ["1.5 move handling active", "30 move terminating"]);
        assert_eq!(only(&lines, &["terminating"]), ["30 move terminating"]);
        assert_order(&lines, &["1.5 move handling active", "30 move terminating"]);
    }
}
