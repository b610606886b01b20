//! The one fold of a trace: the task tree and the run's history rebuilt from its records, one
//! record at a time.
//!
//! [`Replay`] is what every reader of a trace reads instead of matching on record kinds itself:
//! the TCM text log asks it for names and states, the tree dumps walk it, the viewer's model, the
//! demo's summary and `tdl trace tree`/`story` read its nodes, [`Row`]s (the moment each node
//! reached each point, its failures, handler, retry, resource request), its [`ExceptionStory`]s and
//! its [`Restriction`]s (`history.rs`). A new record kind is applied here, once.
//!
//! The checker (`check.rs`) reads only the replayed state of the tree just before each record (states,
//! parents, resources) and the aggregates kept here (open children, started descendants) to verify
//! the Figure 3 axioms in amortised constant time per record; it never reads the history. Nodes are
//! kept after they are reclaimed (flagged), so a viewer can still show them and a constraint can
//! still name them.

use crate::event::{TraceEvent, TraceKind};
use crate::state::{Facet, NodeKind, State, Termination};
use std::collections::BTreeMap;

mod error;
mod history;
mod node;
mod resources;
mod steer;
#[cfg(test)]
mod tests;

pub use error::ReplayError;
pub(crate) use error::check_value;
pub use history::{
    ExceptionStory, Failure, M_DEAD, M_FAILED, M_RECLAIMED, M_RESERVED, M_SKIPPED, M_SPAWNED,
    M_TERMINATED, M_TERMINATING, MARKS, Mark, NUMBER_SLACK, Restriction, Row, Step, m_point,
};
pub use node::{MonitorInfo, ReplayNode};
use node::{POINTS, point_index};
pub use resources::ReplayResource;

/// Display name of the implicit root, as TCM prints it.
pub const ROOT_NAME: &str = "Root Node";

/// The task tree as rebuilt from the records applied so far.
#[derive(Clone, Debug)]
pub struct Replay {
    nodes: BTreeMap<u64, ReplayNode>,
    // Declared resources, by name.
    resources: BTreeMap<String, ReplayResource>,
    // Declared state variables, by name: their type and current value.
    states: BTreeMap<String, (tcm_expr::Type, tcm_expr::Value)>,
    // What happened to each node, and when (`history.rs`).
    history: history::History,
    run: Option<u32>,
    n_records: u64,
    last_t: u64,
    // Why the run is paused, while it is (`paused` to `resumed`).
    paused: Option<String>,
    // Nodes held for approval (`held`, until `approved` or the end of their handling).
    held: std::collections::BTreeSet<u64>,
}

impl Default for Replay {
    fn default() -> Self {
        Replay::new()
    }
}

impl Replay {
    /// An empty tree: only the implicit root, node 0, with its three facets active. It keeps the
    /// tree's state, not its history: its [`rows`](Replay::rows) stay the root's alone, and it has
    /// no exception stories (see [`Replay::with_history`]).
    pub fn new() -> Replay {
        Replay::keeping(false)
    }

    /// An empty tree that also keeps the run's history: each node's [`Row`] (when it reached each
    /// point), the exception stories, the external events and the resource restrictions.
    pub fn with_history() -> Replay {
        Replay::keeping(true)
    }

    fn keeping(history: bool) -> Replay {
        let mut nodes = BTreeMap::new();
        nodes.insert(0, ReplayNode::root());
        Replay {
            nodes,
            resources: BTreeMap::new(),
            states: BTreeMap::new(),
            history: history::History::new(history),
            run: None,
            n_records: 0,
            last_t: 0,
            paused: None,
            held: std::collections::BTreeSet::new(),
        }
    }

    /// The node with display number `number`, in any condition (reserved, dead, reclaimed).
    pub fn node(&self, number: u64) -> Option<&ReplayNode> {
        self.nodes.get(&number)
    }

    /// The implicit root.
    pub fn root(&self) -> &ReplayNode {
        // Invariant: node 0 is inserted by `new` and never removed.
        match self.nodes.get(&0) {
            Some(it) => it,
            None => unreachable!("the root is never removed"),
        }
    }

    /// Every node ever seen, by display number.
    pub fn nodes(&self) -> impl Iterator<Item = &ReplayNode> {
        self.nodes.values()
    }

    /// The nodes spawned whose execution had not completed at the last record, by number: none
    /// when the run ended (every top-level task done), some when it was stuck or cut.
    pub fn unfinished(&self) -> Vec<&ReplayNode> {
        self.nodes
            .values()
            .filter(|it| {
                it.number() != 0
                    && it.is_spawned()
                    && !it.is_reclaimed()
                    && it.state(Facet::Execution) != State::Completed
            })
            .collect()
    }

    /// The run number of the `run_started` record, if one was applied.
    pub fn run(&self) -> Option<u32> {
        self.run
    }

    /// How many records were applied successfully.
    pub fn n_records(&self) -> u64 {
        self.n_records
    }

    /// A state variable's current value (after the records applied so far).
    pub fn state_value(&self, var: &str) -> Option<&tcm_expr::Value> {
        self.states.get(var).map(|(_, v)| v)
    }

    /// Every state variable declared so far: its name, type and current value, by name.
    pub fn states(&self) -> impl Iterator<Item = (&str, tcm_expr::Type, &tcm_expr::Value)> {
        self.states.iter().map(|(n, (t, v))| (n.as_str(), *t, v))
    }

    /// Evaluates `cond` on the state variables' current values.
    pub fn eval(&self, cond: &tcm_expr::Expr) -> Result<tcm_expr::Value, tcm_expr::ExprError> {
        cond.eval(&|n| self.state_value(n).cloned())
    }

    /// Time of the last record applied.
    pub fn last_t(&self) -> u64 {
        self.last_t
    }

    fn spawned(&self, node: u64) -> Result<&ReplayNode, ReplayError> {
        if node == 0 {
            return Err(ReplayError::Root);
        }
        match self.nodes.get(&node) {
            None => Err(ReplayError::UnknownNode { node }),
            Some(it) if !it.is_spawned() => Err(ReplayError::NotSpawned { node }),
            Some(it) => Ok(it),
        }
    }

    fn node_mut(&mut self, node: u64) -> Result<&mut ReplayNode, ReplayError> {
        self.spawned(node)?;
        self.nodes
            .get_mut(&node)
            .ok_or(ReplayError::UnknownNode { node })
    }

    fn check_parent(&self, node: u64, parent: u64) -> Result<(), ReplayError> {
        match self.nodes.get(&parent) {
            Some(it) if it.is_spawned() && !it.reclaimed => Ok(()),
            _ => Err(ReplayError::UnknownParent { node, parent }),
        }
    }

    /// Applies one record. On error nothing changes (but [`changed_rows`](Replay::changed_rows),
    /// which then names no row).
    pub fn apply(&mut self, ev: &TraceEvent) -> Result<(), ReplayError> {
        self.history.changed.clear();
        let t = ev.t;
        match &ev.kind {
            TraceKind::RunStarted { run, .. } => self.run = Some(*run),
            TraceKind::Reserved { node, parent, name } => {
                if *node == 0 {
                    return Err(ReplayError::Root);
                }
                if self.nodes.contains_key(node) {
                    return Err(ReplayError::Duplicate { node: *node });
                }
                self.check_parent(*node, *parent)?;
                let mut it = ReplayNode::new(*node, name.clone(), Some(*parent));
                it.reserved = true;
                self.nodes.insert(*node, it);
            }
            TraceKind::Spawned {
                node,
                parent,
                kind,
                name,
                ..
            } => self.apply_spawned(t, *node, *parent, *kind, name)?,
            TraceKind::Constrained { node, constraint } => {
                self.node_mut(*node)?.constraints.push(constraint.clone());
            }
            TraceKind::ConstraintVoid { node, .. } => {
                if !self.nodes.contains_key(node) {
                    return Err(ReplayError::UnknownNode { node: *node });
                }
            }
            TraceKind::Transition {
                node, facet, to, ..
            } => self.apply_transition(t, *node, *facet, *to)?,
            TraceKind::Terminating { node } => {
                let it = self.node_mut(*node)?;
                if it.termination != Termination::Alive {
                    return Err(ReplayError::Termination {
                        node: *node,
                        from: it.termination,
                        to: Termination::Terminating,
                    });
                }
                it.termination = Termination::Terminating;
            }
            TraceKind::Terminated { node } => self.apply_terminated(*node)?,
            TraceKind::Suspended { node } => self.node_mut(*node)?.suspended = true,
            TraceKind::Unsuspended { node } => self.node_mut(*node)?.suspended = false,
            TraceKind::Failed { node, .. } => self.node_mut(*node)?.failed = true,
            TraceKind::Dead { node } => {
                let it = self
                    .nodes
                    .get_mut(node)
                    .ok_or(ReplayError::UnknownNode { node: *node })?;
                if !it.is_reserved() {
                    return Err(ReplayError::Duplicate { node: *node });
                }
                it.dead = true;
                it.dead_t = Some(t);
            }
            TraceKind::Resource { .. }
            | TraceKind::Requested { .. }
            | TraceKind::Granted { .. }
            | TraceKind::Released { .. }
            | TraceKind::Withdrawn { .. }
            | TraceKind::Denied { .. }
            | TraceKind::Dropped { .. }
            | TraceKind::ResourceReserved { .. }
            | TraceKind::ResourceUnreserved { .. }
            | TraceKind::ResourceLocked { .. }
            | TraceKind::ResourceUnlocked { .. } => self.apply_resource(&ev.kind)?,
            TraceKind::Placed { node, agent } => {
                self.node_mut(*node)?.agent = Some(agent.clone());
            }
            TraceKind::StateDeclared { var, ty, value } => {
                if self.states.contains_key(var) {
                    return Err(ReplayError::State(format!(
                        "state variable `{var}` is declared twice"
                    )));
                }
                check_value(var, *ty, value)?;
                self.states.insert(var.clone(), (*ty, value.clone()));
            }
            TraceKind::StateSet { var, value } => {
                let Some((ty, v)) = self.states.get_mut(var) else {
                    return Err(ReplayError::State(format!(
                        "state variable `{var}` is set before it is declared"
                    )));
                };
                check_value(var, *ty, value)?;
                *v = value.clone();
            }
            TraceKind::Skipped { node } => self.node_mut(*node)?.skipped = true,
            TraceKind::External { .. }
            | TraceKind::Warning { .. }
            | TraceKind::Log { .. }
            | TraceKind::Tapped { .. }
            | TraceKind::CallbackSet { .. }
            | TraceKind::CallbackRan { .. }
            | TraceKind::HandlerAttached { .. }
            | TraceKind::HandlerDetached { .. }
            | TraceKind::TapAdded { .. }
            | TraceKind::TapRemoved { .. }
            | TraceKind::Control { .. }
            | TraceKind::Injected { .. } => {}
            TraceKind::Paused { why, .. } => self.paused = Some(why.clone()),
            TraceKind::Resumed { .. } => self.paused = None,
            TraceKind::Held { node } => {
                self.node_mut(*node)?;
                self.held.insert(*node);
            }
            TraceKind::Approved { node, .. } => {
                self.held.remove(node);
            }
            TraceKind::MonitorParams {
                node,
                max_activations,
                max_triggers,
                period_ns,
                ..
            } => {
                // Parameters changed after the spawn keep the counts so far.
                let it = self.node_mut(*node)?;
                let counts = it.monitor.unwrap_or_default();
                it.monitor = Some(MonitorInfo {
                    max_activations: *max_activations,
                    max_triggers: *max_triggers,
                    period_ns: *period_ns,
                    activations: counts.activations,
                    triggers: counts.triggers,
                });
            }
            TraceKind::Activated {
                monitor,
                node,
                number,
            } => {
                self.node_mut(*node)?.activation_of = Some(*monitor);
                if let Some(m) = self.node_mut(*monitor)?.monitor.as_mut() {
                    m.activations = *number;
                }
            }
            TraceKind::Triggered { monitor, count } => {
                if let Some(m) = self.node_mut(*monitor)?.monitor.as_mut() {
                    m.triggers = *count;
                }
            }
            TraceKind::HandlerChosen { node, failing, .. } => {
                self.node_mut(*node)?.handler_for = Some(*failing);
            }
            TraceKind::Bypassed { node, .. } => {
                self.node_mut(*node)?;
            }
            TraceKind::Retried { node, of } => {
                let origin = self.nodes.get(of).and_then(|o| o.retry_of).unwrap_or(*of);
                self.node_mut(*node)?.retry_of = Some(origin);
            }
            TraceKind::Reclaimed { node } => {
                let it = self.node_mut(*node)?;
                if it.reclaimed {
                    return Err(ReplayError::Duplicate { node: *node });
                }
                it.reclaimed = true;
                let parent = it.parent;
                if let Some(p) = parent.and_then(|p| self.nodes.get_mut(&p)) {
                    p.n_children_live = p.n_children_live.saturating_sub(1);
                }
            }
        }
        self.record_history(history::Mark { seq: ev.seq, t }, &ev.kind);
        self.n_records += 1;
        self.last_t = t;
        Ok(())
    }

    fn apply_spawned(
        &mut self,
        t: u64,
        node: u64,
        parent: u64,
        kind: NodeKind,
        name: &str,
    ) -> Result<(), ReplayError> {
        if node == 0 || kind == NodeKind::Root {
            return Err(ReplayError::Root);
        }
        if let Some(it) = self.nodes.get(&node) {
            if !it.is_reserved() {
                return Err(ReplayError::Duplicate { node });
            }
        }
        self.check_parent(node, parent)?;
        let it = self
            .nodes
            .entry(node)
            .or_insert_with(|| ReplayNode::new(node, String::new(), Some(parent)));
        it.kind = Some(kind);
        it.name = name.to_string();
        it.parent = Some(parent);
        it.spawned_t = Some(t);
        if !kind.expands() {
            // A node that does not expand has its expansion completed from the start (paper, footnote 1).
            it.facets[Facet::Expansion.index()] = State::Completed;
            it.reached_t[Facet::Expansion.index()] = [Some(t); 3];
        }
        if let Some(p) = self.nodes.get_mut(&parent) {
            p.children.push(node);
            p.n_children_exec_open += 1;
            p.n_children_unsettled += 1;
            p.n_children_live += 1;
        }
        // An absent child counted as "goals done"; the new one may not be.
        self.propagate_goals_done(node, true);
        Ok(())
    }

    fn apply_transition(
        &mut self,
        t: u64,
        node: u64,
        facet: Facet,
        to: State,
    ) -> Result<(), ReplayError> {
        // A retry that ends well recovers the first run of its task (its outcome is then
        // `succeeded`, docs/semantics.md, "Outcomes").
        if facet == Facet::Execution && to == State::Completed {
            if let Some(it) = self.nodes.get(&node) {
                if let (Some(origin), Termination::Alive, false) =
                    (it.retry_of, it.termination, it.failed)
                {
                    if let Some(o) = self.nodes.get_mut(&origin) {
                        o.recovered = true;
                    }
                }
            }
        }
        let it = self.node_mut(node)?;
        let from = it.facets[facet.index()];
        if to <= from {
            return Err(ReplayError::Backwards {
                node,
                facet,
                from,
                to,
            });
        }
        let goals_done_before = it.goals_done();
        let terminating = it.termination != Termination::Alive;
        it.facets[facet.index()] = to;
        for p in POINTS {
            if from < p.state() && p.state() <= to {
                it.reached_t[facet.index()][point_index(p)] = Some(t);
                it.reached_terminating[facet.index()][point_index(p)] = terminating;
            }
        }
        let expands = it.expands();
        let parent = it.parent;
        let exec_settled_now = facet == Facet::Execution
            && to == State::Completed
            && it.termination != Termination::Terminated;
        match facet {
            Facet::Handling => {
                if from < State::Active && State::Active <= to {
                    self.mark_started(node, expands);
                }
                if to == State::Completed && expands {
                    self.propagate_goals_done(node, goals_done_before);
                }
            }
            Facet::Execution if to == State::Completed => {
                if let Some(p) = parent.and_then(|p| self.nodes.get_mut(&p)) {
                    p.n_children_exec_open = p.n_children_exec_open.saturating_sub(1);
                    if exec_settled_now {
                        p.n_children_unsettled = p.n_children_unsettled.saturating_sub(1);
                    }
                }
            }
            _ => {}
        }
        Ok(())
    }

    fn apply_terminated(&mut self, node: u64) -> Result<(), ReplayError> {
        let it = self.node_mut(node)?;
        if it.termination != Termination::Terminating {
            return Err(ReplayError::Termination {
                node,
                from: it.termination,
                to: Termination::Terminated,
            });
        }
        it.termination = Termination::Terminated;
        let settled_now = it.facets[Facet::Execution.index()] != State::Completed;
        let parent = it.parent;
        if settled_now {
            if let Some(p) = parent.and_then(|p| self.nodes.get_mut(&p)) {
                p.n_children_unsettled = p.n_children_unsettled.saturating_sub(1);
            }
        }
        Ok(())
    }

    // Sets the "started below" flag on `node` and its ancestors. Each flag is set once, so the walk stops
    // at the first ancestor that already has it: amortised O(1) per transition.
    fn mark_started(&mut self, node: u64, goal: bool) {
        let mut cur = Some(node);
        while let Some(n) = cur {
            let Some(it) = self.nodes.get_mut(&n) else {
                return;
            };
            let flag = if goal {
                &mut it.goal_started_below
            } else {
                &mut it.command_started_below
            };
            if *flag {
                return;
            }
            *flag = true;
            cur = it.parent;
        }
    }

    // Re-evaluates `goals_done` of `node` (which was `before`) and carries a change up to the ancestors.
    // A node flips at most once per spawn or handling completion below it, so this is amortised O(1).
    fn propagate_goals_done(&mut self, node: u64, before: bool) {
        let (mut cur, mut before) = (node, before);
        loop {
            let Some(it) = self.nodes.get(&cur) else {
                return;
            };
            let after = it.goals_done();
            let Some(parent) = it.parent else {
                return;
            };
            if before == after {
                return;
            }
            let Some(p) = self.nodes.get_mut(&parent) else {
                return;
            };
            let parent_before = p.goals_done();
            if after {
                p.n_children_goals_open = p.n_children_goals_open.saturating_sub(1);
            } else {
                p.n_children_goals_open += 1;
            }
            cur = parent;
            before = parent_before;
        }
    }
}
