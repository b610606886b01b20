//! Read-only views of the engine: node and monitor information, and the report of a stuck run.

use super::Engine;
use super::node::{Node, WaitKind};
use crate::NodeKind;
use crate::arena::Keep;
use crate::constraint::{Event, NodeRef, Then};
use crate::ids::NodeId;
use std::collections::BTreeMap;
use std::fmt;
use std::time::Duration;
use tcm_trace::{Facet, Point, State, Termination};

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

impl NodeInfo {
    /// The state of one facet.
    pub fn state(&self, facet: Facet) -> State {
        self.states[facet.index()]
    }

    /// Whether `facet` is at or past `point` (docs/semantics.md, "Events": a facet that skipped a
    /// state has passed it).
    pub fn reached(&self, facet: Facet, point: Point) -> bool {
        self.state(facet) >= point.state()
    }

    /// Whether it was asked to terminate and its subtree is still winding down.
    pub fn is_terminating(&self) -> bool {
        self.termination == Termination::Terminating
    }

    /// Whether it and its subtree are terminated.
    pub fn is_terminated(&self) -> bool {
        self.termination == Termination::Terminated
    }
}

/// A monitor's counts and parameters (TCM's `TCM_NumActivations`, `TCM_NumTriggers` and the
/// monitor getters).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MonitorInfo {
    /// The monitor (an activation node's query answers for its monitor).
    pub monitor: NodeId,
    /// Activations made so far.
    pub activations: u32,
    /// Triggers counted so far.
    pub triggers: u32,
    /// The monitor completes after this many activations.
    pub max_activations: Option<u32>,
    /// The monitor completes after this many triggers.
    pub max_triggers: Option<u32>,
    /// Polling period, if it polls.
    pub period: Option<Duration>,
    /// Whether the polling activation at start is skipped.
    pub initial_wait: bool,
    /// The constraints between its successive activations (`serial`, `sequential …`, `expand
    /// first`, `delay expansion` on each; TCM's per-activation constraints).
    pub each: super::monitor::EachActivation,
    /// What a poll due while the last activation runs does.
    pub overrun: super::monitor::Overrun,
}

/// A node that cannot progress, and what it waits for.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Blocked {
    /// Display number of the waiting node.
    pub node: u64,
    /// Its instance name.
    pub name: String,
    /// The facet that cannot move on.
    pub facet: Facet,
    /// The point the facet cannot reach: `Enabled` for a facet its constraints (or its parent) hold
    /// disabled; `Active` for an enabled handling that cannot start (its node is suspended);
    /// `Completed` for an active handling that cannot complete (its action is parked in an await on
    /// the engine, or it is a monitor that no activation can reach).
    pub point: Point,
    /// What it waits for, in words.
    pub waits_for: Vec<String>,
}

impl fmt::Display for Blocked {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let how = match self.point {
            Point::Enabled => "",
            Point::Active => " is enabled and",
            Point::Completed => " is active and",
        };
        write!(
            f,
            "{} {{{}}} {}{how} waits for {}",
            self.name,
            self.node,
            self.facet,
            self.waits_for.join(", ")
        )
    }
}

impl<A, F: Clone, S: Keep<Node<A, F>>> Engine<A, F, S> {
    /// A live node's kind and display number, without the rest of [`Engine::info`] (which copies
    /// its name); `None` once it was reclaimed.
    pub fn kind_and_display(&self, id: NodeId) -> Option<(NodeKind, u64)> {
        let n = self.query(id)?;
        Some((n.kind, n.display))
    }

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

    /// The counts and parameters of a live monitor, given the monitor or one of its activation
    /// nodes; `None` for any other node.
    pub fn monitor_info(&self, id: NodeId) -> Option<MonitorInfo> {
        let n = self.query(id)?;
        let monitor = n.activation_of().unwrap_or(id);
        let m = self.nodes.get(monitor)?.monitor()?;
        Some(MonitorInfo {
            monitor,
            activations: m.activations,
            triggers: m.triggers,
            max_activations: m.spec.max_activations,
            max_triggers: m.spec.max_triggers,
            period: m.spec.period,
            initial_wait: m.spec.initial_wait,
            each: m.spec.each,
            overrun: m.spec.overrun,
        })
    }

    /// Every alive node that cannot progress, with what each waits for: the report of a stuck run
    /// (docs/semantics.md, "Run outcome"). Ordered by node number. The same as
    /// [`Engine::blocked_awaiting`] with no action parked.
    pub fn blocked(&self) -> Vec<Blocked> {
        self.blocked_awaiting(&[])
    }

    /// The report of a stuck run, given the actions the shell knows are parked in an await on an
    /// engine event (`awaits`: the node whose action, or wiretap check, awaits, and the event).
    ///
    /// Every waiting node is named (docs/semantics.md, "Run outcome"): a facet held disabled, with
    /// the events, timers or gates it waits for, its parent's facet, or its parent's held children;
    /// an enabled handling of a suspended node; an active handling whose action is parked, with each
    /// event it awaits; and a monitor whose handling waits for activations, with those armed.
    /// Ordered by node number, then facet, then point.
    pub fn blocked_awaiting(&self, awaits: &[(NodeId, Event)]) -> Vec<Blocked> {
        let Reasons {
            mut enable,
            mut activate,
        } = self.reasons();
        let mut parked = self.parked(awaits);
        let mut cycles = self.resource_cycles(awaits);
        let mut out = Vec::new();
        for (id, n) in self.nodes.iter() {
            if n.reserved || n.kind == NodeKind::Root || !n.alive() {
                continue;
            }
            let mut push = |facet, point, waits_for| {
                out.push(Blocked {
                    node: n.display,
                    name: n.name.to_string(),
                    facet,
                    point,
                    waits_for,
                });
            };
            for facet in Facet::ALL {
                if n.state(facet) != State::Disabled {
                    continue;
                }
                let mut waits_for = enable.remove(&(n.display, facet)).unwrap_or_default();
                if waits_for.is_empty() {
                    match self.disabled_for(n, facet) {
                        Some(why) => waits_for.push(why),
                        None => continue,
                    }
                }
                push(facet, Point::Enabled, waits_for);
            }
            match n.state(Facet::Handling) {
                State::Enabled if n.suspended => {
                    push(
                        Facet::Handling,
                        Point::Active,
                        vec!["being unsuspended".into()],
                    );
                }
                State::Enabled if n.grant() == super::resource::Grant::Waiting => {
                    // Waiting for its resources: which, and who holds them; and the wait cycle
                    // it closes, if any (docs/semantics.md, "Resources").
                    let mut w: Vec<String> = self
                        .why_waiting(id)
                        .iter()
                        .map(|(r, why)| self.waits_for_resource(*r, why))
                        .collect();
                    if w.is_empty() {
                        w.push("its resources".into());
                    }
                    if let Some(cycle) = cycles.remove(&n.display) {
                        w.push(cycle);
                    }
                    push(Facet::Handling, Point::Active, w);
                }
                State::Active => {
                    if let Some(w) = parked.remove(&n.display) {
                        push(Facet::Handling, Point::Completed, w);
                    } else if n.monitor().is_some() {
                        let w = activate
                            .remove(&n.display)
                            .unwrap_or_else(|| vec!["an activation, and none is armed".into()]);
                        push(Facet::Handling, Point::Completed, w);
                    }
                }
                _ => {}
            }
        }
        out.sort_by_key(|b| (b.node, b.facet, b.point));
        out
    }

    /// What the waiters of every node and external event wait for, by the node they would release.
    fn reasons(&self) -> Reasons {
        let mut r = Reasons::default();
        for (_, n) in self.nodes.iter() {
            for w in n.waiters.iter() {
                let WaitKind::Trigger {
                    target,
                    then,
                    delay,
                } = w.kind
                else {
                    continue;
                };
                let Some(t) = self.nodes.get(target) else {
                    continue;
                };
                let mut what = describe(n, w.facet, w.point);
                if let Some(d) = delay.get() {
                    what = format!("{d:?} after {what}");
                }
                match then {
                    Then::Enable(facet) => {
                        r.enable.entry((t.display, facet)).or_default().push(what)
                    }
                    Then::Activate | Then::ActivateWith(_) => {
                        let what = format!("an activation when {what}");
                        r.activate.entry(t.display).or_default().push(what);
                    }
                    Then::Terminate | Then::Skip | Then::Invariant | Then::Pause => {}
                }
            }
        }
        for (target, facet, what) in self.states.waiting() {
            let Some(t) = self.nodes.get(target) else {
                continue;
            };
            match facet {
                Some(facet) => r.enable.entry((t.display, facet)).or_default().push(what),
                None => r.activate.entry(t.display).or_default().push(what),
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
                        r.enable
                            .entry((t.display, *facet))
                            .or_default()
                            .push(format!("external event `{}`", ext.name));
                    }
                }
            }
            for m in &ext.activators {
                if let Some(t) = self.nodes.get(*m) {
                    r.activate
                        .entry(t.display)
                        .or_default()
                        .push(format!("an activation on external event `{}`", ext.name));
                }
            }
        }
        r
    }

    /// What each parked action awaits, by the display number of its node, in the order given.
    fn parked(&self, awaits: &[(NodeId, Event)]) -> BTreeMap<u64, Vec<String>> {
        let mut parked: BTreeMap<u64, Vec<String>> = BTreeMap::new();
        for (node, event) in awaits {
            let Some(n) = self.query(*node) else { continue };
            let what = match event.node {
                NodeRef::Node(id) => match self.query(id) {
                    Some(e) => describe(e, event.facet, event.point),
                    None => format!("{id} {} {}", event.facet, event.point.as_str()),
                },
                other => format!("{other:?} {} {}", event.facet, event.point.as_str()),
            };
            parked
                .entry(n.display)
                .or_default()
                .push(format!("its action, which awaits {what}"));
        }
        parked
    }

    /// Why a disabled facet with no trigger left on it stays disabled, if the engine knows; `None`
    /// when it is only gated by another facet of its own node, reported there.
    fn disabled_for(&self, n: &Node<A, F>, facet: Facet) -> Option<String> {
        if n.suspended {
            return Some("being unsuspended".into());
        }
        let blocks = n.blocks[facet.index()];
        if blocks > 0 {
            return Some(format!("{blocks} timer(s) or gate(s)"));
        }
        if facet == Facet::Handling {
            // Gated by its own expansion (goal-like) or execution (command-like).
            return None;
        }
        if let Some(p) = n.parent.and_then(|p| self.nodes.get(p)) {
            if p.kind != NodeKind::Root && p.state(facet) == State::Disabled {
                return Some(format!(
                    "its parent {} {{{}}} {facet} enabled",
                    p.name, p.display
                ));
            }
            if p.holding && p.state(Facet::Handling) == State::Active {
                return Some(format!(
                    "its parent {} {{{}}} to return or wait (it holds its children)",
                    p.name, p.display
                ));
            }
        }
        if facet == Facet::Execution && n.expand_first {
            return Some("its own expansion (expand first)".into());
        }
        if facet == Facet::Expansion && n.delay_expansion {
            return Some("its own execution (delay expansion)".into());
        }
        None
    }
}

/// Why one node of a stuck run waits for another, in a wait cycle.
#[derive(Clone, Debug)]
enum Edge {
    /// Its request waits for a resource the other holds (`true`), or asked for first.
    Resource(String, bool),
    /// Its action awaits an event of the other.
    Await,
    /// Its execution waits for its child's.
    Child,
    /// A facet of it is held disabled until an event of the other.
    Event,
}

impl<A, F: Clone, S: Keep<Node<A, F>>> Engine<A, F, S> {
    /// The wait cycles through resources: who waits for whom (a request for the holders of what it
    /// needs, or for the earlier requests it may not overtake; a parked action for the node it
    /// awaits; a node whose own action ended for its unfinished children; a facet held disabled
    /// for the node of its event), and each cycle of that graph with at least one resource wait,
    /// in words, by the first node of the cycle that waits for a resource.
    fn resource_cycles(&self, awaits: &[(NodeId, Event)]) -> BTreeMap<u64, String> {
        let mut out = BTreeMap::new();
        if self.res.waiting.is_empty() {
            return out;
        }
        let mut edges: BTreeMap<u64, Vec<(u64, Edge)>> = BTreeMap::new();
        let mut names: BTreeMap<u64, String> = BTreeMap::new();
        for (id, n) in self.nodes.iter() {
            if n.reserved || n.kind == NodeKind::Root || !n.alive() {
                continue;
            }
            names.insert(n.display, format!("{} {{{}}}", n.name, n.display));
            let mut to: Vec<(u64, Edge)> = Vec::new();
            for (r, why) in self.why_waiting(id) {
                let name = self.res.list[r.idx as usize].name.to_string();
                let (others, held) = match why {
                    super::resource::Why::Held(h) => (h, true),
                    super::resource::Why::Behind(h) => (h, false),
                    _ => continue,
                };
                for o in others {
                    if let Some(o) = self.nodes.get(o) {
                        to.push((o.display, Edge::Resource(name.clone(), held)));
                    }
                }
            }
            if n.state(Facet::Handling) == State::Completed
                && n.state(Facet::Execution) != State::Completed
            {
                let mut c = self.first_child(id);
                while let Some(ch) = c {
                    let cn = self.node(ch);
                    if cn.state(Facet::Execution) != State::Completed {
                        to.push((cn.display, Edge::Child));
                    }
                    c = self.next_sibling(ch);
                }
            }
            for w in n.waiters.iter() {
                if let WaitKind::Trigger {
                    target,
                    then: Then::Enable(_),
                    ..
                } = w.kind
                {
                    if let Some(t) = self.nodes.get(target) {
                        edges
                            .entry(t.display)
                            .or_default()
                            .push((n.display, Edge::Event));
                    }
                }
            }
            edges.entry(n.display).or_default().extend(to);
        }
        for (node, event) in awaits {
            let (Some(n), NodeRef::Node(e)) = (self.query(*node), event.node) else {
                continue;
            };
            if let Some(e) = self.query(e) {
                edges
                    .entry(n.display)
                    .or_default()
                    .push((e.display, Edge::Await));
            }
        }
        for cycle in find_cycles(&edges) {
            let Some(start) = cycle
                .iter()
                .position(|(_, e)| matches!(e, Edge::Resource(..)))
            else {
                continue;
            };
            // Begin at the first resource wait, so the report reads from the waiting request.
            let mut steps = cycle.clone();
            steps.rotate_left(start);
            let name = |d: u64| names.get(&d).cloned().unwrap_or_else(|| format!("{{{d}}}"));
            let first = steps[0].0;
            let mut parts = Vec::new();
            for (i, (from, edge)) in steps.iter().enumerate() {
                let to = steps.get(i + 1).map_or(first, |(n, _)| *n);
                parts.push(match edge {
                    Edge::Resource(r, true) => {
                        format!("{} needs `{r}`, held by {}", name(*from), name(to))
                    }
                    Edge::Resource(r, false) => format!(
                        "{} needs `{r}`, promised first to {}",
                        name(*from),
                        name(to)
                    ),
                    Edge::Await => format!("{}'s action awaits {}", name(*from), name(to)),
                    Edge::Child => format!("{} waits for its child {}", name(*from), name(to)),
                    Edge::Event => format!("{} waits for an event of {}", name(*from), name(to)),
                });
            }
            out.entry(first)
                .or_insert_with(|| format!("in the wait cycle: {}", parts.join("; ")));
        }
        out
    }
}

/// The cycles of a graph found by depth-first search from each vertex in order (each as its
/// vertices with the edge leaving each), every cycle once.
fn find_cycles(edges: &BTreeMap<u64, Vec<(u64, Edge)>>) -> Vec<Vec<(u64, Edge)>> {
    let mut out: Vec<Vec<(u64, Edge)>> = Vec::new();
    let mut seen_sets: Vec<Vec<u64>> = Vec::new();
    let mut done: std::collections::BTreeSet<u64> = std::collections::BTreeSet::new();
    for start in edges.keys() {
        if done.contains(start) {
            continue;
        }
        // The path from `start`: each vertex with the index of its next edge to try.
        let mut path: Vec<(u64, usize)> = vec![(*start, 0)];
        while let Some(&(v, i)) = path.last() {
            let next = edges.get(&v).and_then(|es| es.get(i));
            let Some((w, _)) = next else {
                done.insert(v);
                path.pop();
                continue;
            };
            if let Some(last) = path.last_mut() {
                last.1 += 1;
            }
            if let Some(at) = path.iter().position(|(p, _)| p == w) {
                // A cycle: the path from `w` on, each with the edge it left by.
                let cycle: Vec<(u64, Edge)> = path[at..]
                    .iter()
                    .filter_map(|(p, j)| {
                        edges
                            .get(p)
                            .and_then(|es| es.get(j - 1))
                            .map(|(_, e)| (*p, e.clone()))
                    })
                    .collect();
                let mut set: Vec<u64> = cycle.iter().map(|(p, _)| *p).collect();
                set.sort_unstable();
                if !seen_sets.contains(&set) {
                    seen_sets.push(set);
                    out.push(cycle);
                }
            } else if !done.contains(w) {
                path.push((*w, 0));
            }
        }
    }
    out
}

/// What waiters wait for, by the node they would release.
#[derive(Default)]
struct Reasons {
    // (waiting node display, facet) -> why its facet is held disabled.
    enable: BTreeMap<(u64, Facet), Vec<String>>,
    // Monitor display -> the armed activations that could still come.
    activate: BTreeMap<u64, Vec<String>>,
}

impl<A, F: Clone, S: Keep<Node<A, F>>> Engine<A, F, S> {
    /// What a waiting request waits for, about resource `r`, as the report writes it.
    fn waits_for_resource(&self, r: crate::ids::ResourceId, why: &super::resource::Why) -> String {
        use super::resource::Why;
        let res = &self.res.list[r.idx as usize];
        let names = |nodes: &[NodeId]| {
            let v: Vec<String> = nodes
                .iter()
                .filter_map(|n| self.nodes.get(*n))
                .map(|n| format!("{} {{{}}}", n.name, n.display))
                .collect();
            v.join(", ")
        };
        match why {
            Why::Held(holders) => format!(
                "resource `{}`, held by {} ({} of {})",
                res.name,
                names(holders),
                res.in_use,
                res.capacity
            ),
            Why::Behind(nodes) => format!(
                "resource `{}`, promised first to the earlier request(s) of {}",
                res.name,
                names(nodes)
            ),
            Why::Locked => format!("resource `{}` to be unlocked", res.name),
            Why::Reserved(h) => format!("resource `{}`, reserved for {}", res.name, names(&[*h])),
            Why::OverCapacity { .. } => self.why_text(r, why),
        }
    }
}

/// `name {display} facet point`, as the report writes an event.
fn describe<A, F>(n: &Node<A, F>, facet: Facet, point: Point) -> String {
    format!("{} {{{}}} {} {}", n.name, n.display, facet, point.as_str())
}
