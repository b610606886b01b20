//! Read-only views of the engine: node information and the report of a stuck run.

use super::Engine;
use super::node::WaitKind;
use crate::NodeKind;
use crate::constraint::Then;
use crate::ids::NodeId;
use std::fmt;
use tcm_trace::{Facet, State, Termination};

/// A snapshot of one node.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct NodeInfo {
    /// Display number (`{id}` in the text log).
    pub display: u64,
    /// Kind.
    pub kind: NodeKind,
    /// Instance name.
    pub name: String,
    /// States of handling, expansion and execution.
    pub states: [State; 3],
    /// Termination state.
    pub termination: Termination,
    /// Whether it is suspended.
    pub suspended: bool,
    /// Whether its action failed.
    pub failed: bool,
}

/// A node that cannot progress, and what it waits for.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Blocked {
    /// Display number of the waiting node.
    pub node: u64,
    /// Its instance name.
    pub name: String,
    /// The facet that cannot become enabled.
    pub facet: Facet,
    /// What it waits for, in words.
    pub waits_for: Vec<String>,
}

impl fmt::Display for Blocked {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} {{{}}} {} waits for {}",
            self.name,
            self.node,
            self.facet,
            self.waits_for.join(", ")
        )
    }
}

impl<A, F: Clone> Engine<A, F> {
    /// A snapshot of a live node; `None` once it was reclaimed.
    pub fn info(&self, id: NodeId) -> Option<NodeInfo> {
        let n = self.query(id)?;
        Some(NodeInfo {
            display: n.display,
            kind: n.kind,
            name: n.name.to_string(),
            states: n.states,
            termination: n.termination,
            suspended: n.suspended,
            failed: n.failure().is_some(),
        })
    }

    /// The parent of a live node.
    pub fn parent(&self, id: NodeId) -> Option<NodeId> {
        self.query(id)?.parent
    }

    /// The live children of a node, in spawn order.
    pub fn children(&self, id: NodeId) -> Vec<NodeId> {
        let mut out = Vec::new();
        if self.query(id).is_none() {
            return out;
        }
        let mut c = self.first_child(id);
        while let Some(ch) = c {
            out.push(ch);
            c = self.next_sibling(ch);
        }
        out
    }

    /// Every alive node whose facets cannot become enabled, with what each waits for: the report of a
    /// stuck run (docs/semantics.md, "Run outcome"). Ordered by node number.
    pub fn blocked(&self) -> Vec<Blocked> {
        use std::collections::BTreeMap;
        // (waiting node display, facet) -> reasons
        let mut reasons: BTreeMap<(u64, Facet), Vec<String>> = BTreeMap::new();
        for (_, n) in self.nodes.iter() {
            for w in n.waiters.iter() {
                let WaitKind::Trigger {
                    target,
                    then: Then::Enable(facet),
                    delay: after,
                } = w.kind
                else {
                    continue;
                };
                let Some(t) = self.nodes.get(target) else {
                    continue;
                };
                let mut what = format!(
                    "{} {{{}}} {} {}",
                    n.name,
                    n.display,
                    w.facet,
                    w.point.as_str()
                );
                if let Some(d) = after {
                    what = format!("{d:?} after {what}");
                }
                reasons.entry((t.display, facet)).or_default().push(what);
            }
        }
        for ext in &self.externals {
            for w in &ext.waiters {
                if let WaitKind::Trigger {
                    target,
                    then: Then::Enable(facet),
                    ..
                } = w
                {
                    if let Some(t) = self.nodes.get(*target) {
                        reasons
                            .entry((t.display, *facet))
                            .or_default()
                            .push(format!("external event `{}`", ext.name));
                    }
                }
            }
        }
        let mut out = Vec::new();
        for (_, n) in self.nodes.iter() {
            if n.reserved || n.kind == NodeKind::Root || !n.alive() {
                continue;
            }
            for facet in Facet::ALL {
                if n.state(facet) != State::Disabled {
                    continue;
                }
                let mut waits_for = reasons.remove(&(n.display, facet)).unwrap_or_default();
                if waits_for.is_empty() {
                    if n.suspended {
                        waits_for.push("being unsuspended".into());
                    } else if facet == Facet::Handling && n.blocks[0] == 0 {
                        continue; // Gated by its own expansion or execution, reported there.
                    } else if n.blocks[facet.index()] == 0 {
                        let parent_waits = n
                            .parent
                            .and_then(|p| self.nodes.get(p))
                            .is_some_and(|p| p.state(facet) == State::Disabled);
                        if parent_waits {
                            continue; // Its parent's facet is reported instead.
                        }
                        if facet == Facet::Execution && n.expand_first {
                            waits_for.push("its own expansion (expand first)".into());
                        } else if facet == Facet::Expansion && n.delay_expansion {
                            waits_for.push("its own execution (delay expansion)".into());
                        } else {
                            continue;
                        }
                    } else {
                        waits_for.push(format!("{} timer(s) or gate(s)", n.blocks[facet.index()]));
                    }
                }
                out.push(Blocked {
                    node: n.display,
                    name: n.name.to_string(),
                    facet,
                    waits_for,
                });
            }
        }
        out.sort_by_key(|b| (b.node, b.facet));
        out
    }
}
