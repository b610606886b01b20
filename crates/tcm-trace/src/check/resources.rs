//! The checker's side of resources (docs/semantics.md, "Resources"): each resource record against
//! the resources as declared and used so far, capacity at every grant, locks and reservations,
//! grants before a requesting node goes active, and releases before its node is done.

use super::{Checker, Rule};
use crate::event::{ResourceUse, TraceEvent, TraceKind};
use crate::state::{Facet, State, Termination};

#[cfg(test)]
mod tests;

/// `base, arm(2)`: the uses as people write them.
fn uses_text(uses: &[ResourceUse]) -> String {
    let parts: Vec<String> = uses
        .iter()
        .map(|u| match u.amount {
            1 => u.resource.clone(),
            n => format!("{}({n})", u.resource),
        })
        .collect();
    parts.join(", ")
}

impl Checker {
    /// A resource record, against the state before it.
    pub(super) fn check_resource(&mut self, ev: &TraceEvent) {
        let seq = ev.seq;
        let node = ev.kind.node();
        let mut found: Vec<(Rule, String)> = Vec::new();
        let unknown = |names: &mut dyn Iterator<Item = &String>,
                       found: &mut Vec<(Rule, String)>| {
            for name in names {
                if self.replay.resource(name).is_none() {
                    found.push((
                        Rule::ResourceRequest,
                        format!("resource `{name}` was never declared"),
                    ));
                }
            }
        };
        match &ev.kind {
            TraceKind::Resource { resource, .. } if self.replay.resource(resource).is_some() => {
                found.push((
                    Rule::ResourceRequest,
                    format!("resource `{resource}` is declared twice"),
                ));
            }
            TraceKind::Requested { node, uses, .. } => {
                unknown(&mut uses.iter().map(|u| &u.resource), &mut found);
                if let Some(n) = self.replay.node(*node) {
                    if n.request().is_some() || n.grant().is_some() {
                        found.push((
                            Rule::ResourceRequest,
                            format!(
                                "{} asks for resources while it waits for or holds some",
                                self.name(*node)
                            ),
                        ));
                    }
                }
                self.pending_within_limits(seq);
            }
            TraceKind::Granted { node, uses } => {
                unknown(&mut uses.iter().map(|u| &u.resource), &mut found);
                self.check_grant(*node, uses, &mut found);
            }
            TraceKind::Released { node, uses } => {
                unknown(&mut uses.iter().map(|u| &u.resource), &mut found);
                match self.replay.node(*node).map(|n| n.grant()) {
                    Some(Some(held)) if held != uses.as_slice() => found.push((
                        Rule::ResourceRequest,
                        format!(
                            "{} releases {} but holds {}",
                            self.name(*node),
                            uses_text(uses),
                            uses_text(held)
                        ),
                    )),
                    Some(None) => found.push((
                        Rule::ResourceRequest,
                        format!(
                            "{} releases {}, which it does not hold",
                            self.name(*node),
                            uses_text(uses)
                        ),
                    )),
                    _ => {}
                }
            }
            TraceKind::Withdrawn { node }
            | TraceKind::Denied { node, .. }
            | TraceKind::Dropped { node, .. } => {
                if let TraceKind::Denied { resource, .. } | TraceKind::Dropped { resource, .. } =
                    &ev.kind
                {
                    unknown(&mut std::iter::once(resource), &mut found);
                }
                if self
                    .replay
                    .node(*node)
                    .is_some_and(|n| n.request().is_none())
                {
                    found.push((
                        Rule::ResourceRequest,
                        format!("{} has no request waiting", self.name(*node)),
                    ));
                }
            }
            TraceKind::ResourceReserved { resource, .. }
            | TraceKind::ResourceUnreserved { resource }
            | TraceKind::ResourceLocked { resource }
            | TraceKind::ResourceUnlocked { resource } => {
                unknown(&mut std::iter::once(resource), &mut found);
            }
            _ => {}
        }
        for (rule, msg) in found {
            self.flag(seq, node, rule, msg);
        }
    }

    /// A grant: it answers the node's request, fits every capacity, and takes no locked resource
    /// nor one reserved for another subtree.
    fn check_grant(&self, node: u64, uses: &[ResourceUse], found: &mut Vec<(Rule, String)>) {
        let name = self.name(node);
        match self.replay.node(node).map(|n| n.request()) {
            Some(None) => found.push((
                Rule::ResourceRequest,
                format!("{name} is granted {} without a request", uses_text(uses)),
            )),
            Some(Some(asked)) if asked != uses => found.push((
                Rule::ResourceRequest,
                format!(
                    "{name} is granted {} but asked for {}",
                    uses_text(uses),
                    uses_text(asked)
                ),
            )),
            _ => {}
        }
        for u in uses {
            let Some(r) = self.replay.resource(&u.resource) else {
                continue;
            };
            let after = r.in_use() + u64::from(u.amount);
            if after > u64::from(r.capacity()) {
                let holders: Vec<String> = r
                    .holders()
                    .iter()
                    .map(|(n, a)| format!("{} ({a})", self.name(*n)))
                    .collect();
                found.push((
                    Rule::ResourceCapacity,
                    format!(
                        "{name} is granted {} of `{}`, which makes {after} of its capacity {} \
                         (held by {})",
                        u.amount,
                        u.resource,
                        r.capacity(),
                        holders.join(", ")
                    ),
                ));
            }
            if r.is_locked() {
                found.push((
                    Rule::ResourceLock,
                    format!("{name} is granted `{}`, which is locked", u.resource),
                ));
            }
            if let Some(holder) = r.reserved_for() {
                if !self.replay.is_in_subtree(node, holder) {
                    found.push((
                        Rule::ResourceLock,
                        format!(
                            "{name} is granted `{}`, which is reserved for {}, and {name} is not \
                             in its subtree",
                            u.resource,
                            self.name(holder)
                        ),
                    ));
                }
            }
        }
    }

    /// No resource has more requests waiting than its pending limit allows.
    pub(super) fn pending_within_limits(&mut self, seq: u64) {
        let mut over = Vec::new();
        for r in self.replay.resources() {
            if let Some(limit) = r.pending_limit() {
                if r.pending().len() > limit as usize {
                    over.push(format!(
                        "{} requests wait for `{}`, whose pending limit is {limit}",
                        r.pending().len(),
                        r.name()
                    ));
                }
            }
        }
        for msg in over {
            self.flag(seq, None, Rule::ResourcePending, msg);
        }
    }

    /// A facet transition, a termination or a reclamation of `node`, against what it holds:
    /// a node that asked goes active only with its grant; a node is done with its resources when
    /// its handling completes (unless it is terminating: its action may still be stopping), and in
    /// any case once its execution completes.
    pub(super) fn check_resource_state(&mut self, seq: u64, node: u64, record: &TraceKind) {
        let Some(n) = self.replay.node(node) else {
            return;
        };
        if !n.has_requested() {
            return;
        }
        let held = n.grant().map(uses_text);
        let waiting = n.request().map(uses_text);
        let terminating = n.termination() != Termination::Alive;
        let name = self.name(node);
        let (rule, msg) = match record {
            TraceKind::Transition {
                facet: Facet::Handling,
                to: State::Active,
                ..
            } if held.is_none() => (
                Rule::ResourceGrant,
                format!("{name} goes active without the resources it asked for"),
            ),
            TraceKind::Transition {
                facet: Facet::Handling,
                to: State::Completed,
                ..
            } if !terminating => match (held, waiting) {
                (Some(held), _) => (
                    Rule::ResourceRelease,
                    format!("{name} completes its handling still holding {held}"),
                ),
                (None, Some(waiting)) => (
                    Rule::ResourceRelease,
                    format!("{name} completes its handling with its request for {waiting} waiting"),
                ),
                (None, None) => return,
            },
            TraceKind::Transition {
                facet: Facet::Execution,
                to: State::Completed,
                ..
            }
            | TraceKind::Terminated { .. }
            | TraceKind::Reclaimed { .. } => {
                let what = match record {
                    TraceKind::Terminated { .. } => "is terminated",
                    TraceKind::Reclaimed { .. } => "is reclaimed",
                    _ => "completes its execution",
                };
                match (held, waiting) {
                    (Some(held), _) => (
                        Rule::ResourceRelease,
                        format!("{name} {what} still holding {held}"),
                    ),
                    (None, Some(waiting)) => (
                        Rule::ResourceRelease,
                        format!("{name} {what} with its request for {waiting} waiting"),
                    ),
                    (None, None) => return,
                }
            }
            _ => return,
        };
        self.flag(seq, Some(node), rule, msg);
    }
}
