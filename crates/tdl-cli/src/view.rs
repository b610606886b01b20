//! What `tdl trace tree` and `tdl trace story` print: the task tree of a whole run (reclaimed nodes
//! included), and the story of a run, one line per record with node numbers, filtered.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use tcm_trace::story::uses_text;
use tcm_trace::{Facet, Replay, ReplayNode, Termination, TraceEvent, TraceKind};

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

/// A kind of story record, for `--kind`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, clap::ValueEnum)]
pub(crate) enum Kind {
    /// Facet transitions.
    Transition,
    /// Spawns, reservations, dead reservations, reclamation, placement on an agent.
    Spawn,
    /// Constraints applied and void constraints (left out unless asked for).
    Constraint,
    /// Termination.
    Terminate,
    /// Suspension.
    Suspend,
    /// Failures.
    Fail,
    /// Handlers chosen and bypasses.
    Handler,
    /// Retries.
    Retry,
    /// Wiretap checks.
    Wiretap,
    /// Monitor parameters, activations and triggers.
    Monitor,
    /// External events and timer callbacks.
    Event,
    /// Resources: declarations, requests, grants, releases, refusals, reservations and locks.
    Resource,
    /// Warnings.
    Warning,
}

/// What `tdl trace story` keeps.
#[derive(Clone, Debug, Default)]
pub(crate) struct Filter {
    /// Only these kinds; every kind but [`Kind::Constraint`] when empty.
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

/// The story lines of `trace` that `filter` keeps: `<seconds> {id} <name> <what>`, or
/// `<seconds> <what>` for records about no node (external events, callbacks, run-wide warnings).
pub(crate) fn story(trace: &[TraceEvent], filter: &Filter) -> Vec<String> {
    let mut names: BTreeMap<u64, String> = BTreeMap::new();
    let mut parents: BTreeMap<u64, u64> = BTreeMap::new();
    let mut out = Vec::new();
    for ev in trace {
        if let TraceKind::Spawned {
            node, parent, name, ..
        }
        | TraceKind::Reserved { node, parent, name } = &ev.kind
        {
            names.insert(*node, name.clone());
            parents.insert(*node, *parent);
        }
        let Some((kind, node, what)) = describe(&ev.kind, &names) else {
            continue;
        };
        let wanted = if filter.kinds.is_empty() {
            kind != Kind::Constraint
        } else {
            filter.kinds.contains(&kind)
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
                if filter.by_node() && !keeps(filter, node, &names, &parents) {
                    continue;
                }
                let name = names.get(&node).map_or("?", String::as_str);
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
fn keeps(
    filter: &Filter,
    node: u64,
    names: &BTreeMap<u64, String>,
    parents: &BTreeMap<u64, u64>,
) -> bool {
    // The node and its ancestors up to the top-level task, nearest first.
    let mut chain = vec![node];
    let mut at = node;
    while let Some(&parent) = parents.get(&at) {
        if parent == 0 || chain.contains(&parent) {
            break;
        }
        chain.push(parent);
        at = parent;
    }
    if filter
        .name
        .as_ref()
        .is_some_and(|name| names.get(&node) != Some(name))
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
            .map(|n| names.get(n).map_or("?", String::as_str))
            .collect();
        let wanted: Vec<&str> = path.trim_matches('/').split('/').collect();
        if full.len() < wanted.len() || full[..wanted.len()] != wanted[..] {
            return false;
        }
    }
    true
}

/// The kind, node and text of a record; `None` for the run's first record.
fn describe(
    kind: &TraceKind,
    names: &BTreeMap<u64, String>,
) -> Option<(Kind, Option<u64>, String)> {
    let name = |n: &u64| names.get(n).cloned().unwrap_or_else(|| format!("#{n}"));
    Some(match kind {
        TraceKind::RunStarted { .. } => return None,
        TraceKind::Reserved { node, parent, .. } => (
            Kind::Spawn,
            Some(*node),
            format!("reserved under {{{parent}}}"),
        ),
        TraceKind::Spawned {
            node, parent, kind, ..
        } => (
            Kind::Spawn,
            Some(*node),
            format!("spawned ({kind:?}) under {{{parent}}}").to_lowercase(),
        ),
        TraceKind::Constrained { node, constraint } => (
            Kind::Constraint,
            Some(*node),
            format!("constrained {constraint:?}"),
        ),
        TraceKind::ConstraintVoid { node, reason } => (
            Kind::Constraint,
            Some(*node),
            format!("constraint void: {reason}"),
        ),
        TraceKind::Transition {
            node, facet, to, ..
        } => (Kind::Transition, Some(*node), format!("{facet} {to}")),
        TraceKind::Terminating { node } => (Kind::Terminate, Some(*node), "terminating".into()),
        TraceKind::Terminated { node } => (Kind::Terminate, Some(*node), "terminated".into()),
        TraceKind::Suspended { node } => (Kind::Suspend, Some(*node), "suspended".into()),
        TraceKind::Unsuspended { node } => (Kind::Suspend, Some(*node), "unsuspended".into()),
        TraceKind::Failed {
            node,
            exception,
            message,
        } => (
            Kind::Fail,
            Some(*node),
            format!("failed {exception}: {message}"),
        ),
        TraceKind::Dead { node } => (Kind::Spawn, Some(*node), "dead".into()),
        TraceKind::Reclaimed { node } => (Kind::Spawn, Some(*node), "reclaimed".into()),
        TraceKind::External { name } => (Kind::Event, None, format!("external event {name}")),
        TraceKind::MonitorParams {
            node,
            max_activations,
            max_triggers,
            period_ns,
            ..
        } => (
            Kind::Monitor,
            Some(*node),
            format!(
                "monitor parameters: maximum activate {}, maximum trigger {}, period {}",
                max_activations.map_or("-".into(), |it| it.to_string()),
                max_triggers.map_or("-".into(), |it| it.to_string()),
                period_ns.map_or("-".into(), |it| format!("{}s", it as f64 / 1e9)),
            ),
        ),
        TraceKind::Activated {
            monitor,
            node,
            number,
        } => (
            Kind::Monitor,
            Some(*monitor),
            format!("activation {number}: {} {{{node}}}", name(node)),
        ),
        TraceKind::Triggered { monitor, count } => (
            Kind::Monitor,
            Some(*monitor),
            format!("triggered ({count})"),
        ),
        TraceKind::HandlerChosen {
            node,
            failing,
            attached,
            exception,
            handler,
        } => (
            Kind::Handler,
            Some(*failing),
            format!(
                "handler {handler} {{{node}}} chosen for {exception} (attached to {} {{{attached}}})",
                name(attached)
            ),
        ),
        TraceKind::Bypassed { node, exception } => {
            (Kind::Handler, Some(*node), format!("bypasses {exception}"))
        }
        TraceKind::Retried { node, of } => (
            Kind::Retry,
            Some(*node),
            format!("retries {} {{{of}}}", name(of)),
        ),
        TraceKind::Tapped { node, tap, when } => (
            Kind::Wiretap,
            Some(*node),
            format!("wiretap {tap} checks {when}"),
        ),
        TraceKind::CallbackSet { name, node, .. } => {
            (Kind::Event, *node, format!("callback {name} set"))
        }
        TraceKind::CallbackRan { name, .. } => (Kind::Event, None, format!("callback {name} ran")),
        TraceKind::Resource {
            resource,
            capacity,
            pending_limit,
        } => {
            let pending = pending_limit.map_or(String::new(), |p| format!(", pending {p}"));
            let text = format!("resource {resource} capacity {capacity}{pending}");
            (Kind::Resource, None, text)
        }
        TraceKind::Requested {
            node,
            uses,
            priority,
        } => (
            Kind::Resource,
            Some(*node),
            format!("requests {} (priority {priority})", uses_text(uses)),
        ),
        TraceKind::Granted { node, uses } => (
            Kind::Resource,
            Some(*node),
            format!("granted {}", uses_text(uses)),
        ),
        TraceKind::Released { node, uses } => (
            Kind::Resource,
            Some(*node),
            format!("released {}", uses_text(uses)),
        ),
        TraceKind::Withdrawn { node } => {
            (Kind::Resource, Some(*node), "withdraws its request".into())
        }
        TraceKind::Denied { node, resource } => {
            (Kind::Resource, Some(*node), format!("denied {resource}"))
        }
        TraceKind::Dropped { node, resource } => (
            Kind::Resource,
            Some(*node),
            format!("dropped from {resource}'s queue"),
        ),
        TraceKind::ResourceReserved { resource, holder } => (
            Kind::Resource,
            Some(*holder),
            format!("reserves {resource} for its subtree"),
        ),
        TraceKind::ResourceUnreserved { resource } => {
            (Kind::Resource, None, format!("{resource} unreserved"))
        }
        TraceKind::ResourceLocked { resource } => {
            (Kind::Resource, None, format!("{resource} locked"))
        }
        TraceKind::ResourceUnlocked { resource } => {
            (Kind::Resource, None, format!("{resource} unlocked"))
        }
        TraceKind::Placed { node, agent } => {
            (Kind::Spawn, Some(*node), format!("runs on agent {agent}"))
        }
        TraceKind::Warning { node, message } => {
            (Kind::Warning, *node, format!("warning: {message}"))
        }
    })
}
