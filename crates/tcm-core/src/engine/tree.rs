//! Tree links: inserting nodes (spawns, reservations, the engine's own insertions) and the sibling
//! links between live nodes.
//!
//! A node is linked under its parent when it is inserted and unlinked when it is reclaimed
//! (`progress.rs`). Each parent counts its live children and its children whose expansion or
//! execution is still open, so the Figure 3 aggregates cost O(1) per transition.

use super::exception::HandlerEntry;
use super::monitor::Monitor;
use super::node::{Link, Node, Payload};
use super::{Engine, EngineError, Spawn, Work};
use crate::arena::Keep;
use crate::constraint::Constraint;
use crate::ids::NodeId;
use crate::time::Time;
use crate::{Name, NodeKind};
use tcm_trace::{Facet, State, TraceKind};

impl<A, F: Clone, S: Keep<Node<A, F>>> Engine<A, F, S> {
    /// Reserves a node under `parent` for a later spawn, so constraints can name it before it exists
    /// (a forward reference). If the parent's action ends without spawning it, it is *dead*:
    /// enablement constraints on it are void, `terminate at` it fires at once (docs/semantics.md, "Tags and forward references").
    pub fn reserve(
        &mut self,
        now: Time,
        parent: NodeId,
        name: impl Into<Name>,
    ) -> Result<NodeId, EngineError> {
        self.advance(now);
        self.check_parent_open(parent)?;
        let display = self.next_display();
        let name = name.into();
        let mut node = Node::new(display, NodeKind::Goal, name.clone(), Some(parent));
        node.reserved = true;
        let id = self.nodes.insert(node);
        let parent_display = self.node(parent).display;
        self.node_mut(parent).cold_mut().reservations.push(id);
        emit!(
            self,
            TraceKind::Reserved {
                node: display,
                parent: parent_display,
                name: name.into_owned(),
            }
        );
        Ok(id)
    }

    /// Inserts a node (docs/semantics.md, "Constraints"): applies its constraints, links it under its parent,
    /// and settles. Returns its handle.
    pub fn spawn(&mut self, now: Time, spec: Spawn<A, F>) -> Result<NodeId, EngineError> {
        self.advance(now);
        let Spawn {
            parent,
            kind,
            name,
            task,
            action,
            constraints,
            persistent,
            on_terminate,
            fulfils,
            monitor,
            handlers,
            retry,
            mut uses,
            version,
            args,
        } = spec;
        self.live(parent)?;
        if let Some(u) = uses.as_mut() {
            self.validate_uses(u)?;
        }
        if (kind == NodeKind::Monitor) != monitor.is_some() {
            return Err(EngineError::NotAMonitor(self.next_display));
        }
        self.check_parent_open(parent)?;
        let pd = self.node(parent);
        let parent_suspended = pd.suspended;
        // A parent that holds its children (the usual spawn: from a running body); constraints do
        // not change it.
        let parent_holds = pd.holding;
        if constraints.len() >= 2
            && constraints.contains(&Constraint::ExpandFirst)
            && constraints.contains(&Constraint::DelayExpansion)
        {
            return Err(EngineError::Inconsistent);
        }
        let previous = pd.last_spawned;
        for c in &constraints {
            self.validate_refs(c)?;
        }
        let id = match fulfils {
            Some(r) => {
                if !self.is_reservation_of(r, parent) {
                    return Err(EngineError::NotReserved(r));
                }
                self.claim_reservation(parent, r, kind, name);
                r
            }
            None => {
                let display = self.next_display();
                self.nodes
                    .insert(Node::new(display, kind, name, Some(parent)))
            }
        };
        for r in on_terminate.iter().filter_map(|ot| ot.fulfils) {
            self.adopt_reservation(parent, id, r);
        }
        {
            let node = self.node_mut(id);
            node.action = action.map(Payload::Action);
            node.persistent = persistent;
            if task.is_some() {
                node.cold_mut().task = task;
            }
            if on_terminate.is_empty() {
                discard(on_terminate);
            } else {
                node.cold_mut().on_terminate = on_terminate.into();
            }
            node.suspended = parent_suspended;
            if let Some(m) = monitor {
                node.cold_mut().monitor = Some(Box::new(Monitor::new(*m)));
            }
            if handlers.is_empty() {
                discard(handlers);
            } else {
                node.cold_mut().handlers = handlers
                    .into_iter()
                    .map(|spec| HandlerEntry {
                        spec,
                        uses: 0,
                        attach: 0,
                    })
                    .collect();
            }
            if retry.is_some() {
                let cold = node.cold_mut();
                cold.retry = retry;
                // A retry is the same task again: it keeps the constraints on the node itself.
                cold.retry_constraints = constraints
                    .iter()
                    .filter(|c| matches!(c, Constraint::ExpandFirst | Constraint::DelayExpansion))
                    .copied()
                    .collect();
            }
            if let Some(u) = uses.filter(|u| !u.amounts.is_empty()) {
                node.cold_mut().uses = Some(u);
            }
        }
        if !self.class_handlers.is_empty() {
            // Handlers attached from outside to this node's task.
            let attached: Option<Vec<HandlerEntry<F>>> = self
                .class_handlers
                .get(self.node(id).task_name())
                .map(|specs| {
                    specs
                        .iter()
                        .map(|(id, spec)| HandlerEntry {
                            spec: spec.clone(),
                            uses: 0,
                            attach: id.0,
                        })
                        .collect()
                });
            if let Some(entries) = attached {
                self.node_mut(id).cold_mut().class_handlers = entries.into();
            }
        }
        self.link(parent, id);
        let display = self.emit_spawned(id, parent, version.as_ref(), args);
        if self.tracing {
            let n = self.node(id);
            if let Some(m) = n.monitor() {
                let record = m.spec.traced(display);
                emit!(self, record);
            }
        }
        if parent_suspended {
            emit!(self, TraceKind::Suspended { node: display });
        }
        // Only a reservation can carry constraints stated before its spawn.
        let mut later = if fulfils.is_some() {
            self.apply_deferred(id, parent)
        } else {
            Vec::new()
        };
        for &c in &constraints {
            if c.applies_after_link() {
                later.push((c, previous));
            } else {
                self.apply(id, parent, previous, c);
            }
        }
        self.node_mut(parent).last_spawned = Some(id);
        for (c, prev) in later {
            self.apply(id, parent, prev, c);
        }
        if fulfils.is_some() {
            for g in self.node_mut(id).take_cold(|c| &mut c.deferred_groups) {
                self.arm_group(id, g);
            }
        }
        if !self.node(parent).alive() && !self.node(id).immune {
            self.work.push_back(Work::Terminate {
                node: id,
                explicit: false,
            });
        }
        // Under a parent that holds its children, a new node cannot move at all until the hold
        // ends, which queues the progress of every child: unless its constraints queued work, its
        // own progress would be a no-op.
        if !(parent_holds
            && self.work.is_empty()
            && self.node(parent).state(Facet::Handling) == State::Active)
        {
            self.queue_progress(id);
        }
        self.settle();
        Ok(id)
    }

    /// A node can take children until its execution completed; a completed persistent node still
    /// can, with a warning, as in TCM (docs/semantics.md, "Persistent tasks and reclamation").
    fn check_parent_open(&mut self, parent: NodeId) -> Result<(), EngineError> {
        let pd = self.live(parent)?;
        if pd.state(Facet::Execution) != State::Completed {
            return Ok(());
        }
        if !pd.persistent || !pd.alive() {
            return Err(EngineError::ParentCompleted {
                node: pd.display,
                name: pd.name.to_string(),
            });
        }
        let display = pd.display;
        emit!(
            self,
            TraceKind::Warning {
                node: Some(display),
                message: format!(
                    "Adding a child to completed persistent node {} {{{display}}}",
                    pd.name
                ),
            }
        );
        Ok(())
    }

    /// Whether `r` is an open reservation of `parent`.
    pub(crate) fn is_reservation_of(&self, r: NodeId, parent: NodeId) -> bool {
        matches!(self.nodes.get(r), Some(n) if n.reserved && n.parent == Some(parent))
    }

    /// Turns the open reservation `r` of `parent` into a node of `kind` named `name`, not linked
    /// yet.
    fn claim_reservation(&mut self, parent: NodeId, r: NodeId, kind: NodeKind, name: Name) {
        self.node_mut(parent)
            .cold_mut()
            .reservations
            .retain(|x| *x != r);
        let node = self.node_mut(r);
        node.reserved = false;
        node.kind = kind;
        node.name = name;
        if !kind.expands() {
            node.states[Facet::Expansion.index()] = State::Completed;
        }
    }

    /// Hands the reservation `r` of `parent` over to its new child `node`, whose on-terminate task
    /// fulfils it: the reservation then dies when `node`'s execution completes, unless `node` is
    /// terminated after it started and the on-terminate task is inserted (docs/semantics.md, "Tags
    /// and forward references"). A handle that is no open reservation of `parent` is left alone.
    fn adopt_reservation(&mut self, parent: NodeId, node: NodeId, r: NodeId) {
        if !self.is_reservation_of(r, parent) {
            return;
        }
        self.node_mut(parent)
            .cold_mut()
            .reservations
            .retain(|x| *x != r);
        self.node_mut(r).parent = Some(node);
        self.node_mut(node).cold_mut().reservations.push(r);
    }

    /// Applies the constraints kept on a reservation that `id` fulfilled, except those applied once
    /// the node is linked and `previous` moved on, which it returns.
    fn apply_deferred(&mut self, id: NodeId, parent: NodeId) -> Vec<(Constraint, Option<NodeId>)> {
        let deferred = self.node_mut(id).take_cold(|c| &mut c.deferred);
        let mut later = Vec::new();
        for (c, prev) in deferred {
            if c.applies_after_link() {
                later.push((c, prev));
            } else {
                self.apply(id, parent, prev, c);
            }
        }
        later
    }

    /// Holds (or releases) the start of the children a running action spawns: while held, they are
    /// inserted and constrained but their handling is not enabled. TDL's semantics, where a task's
    /// body always ends before any child it spawned runs (unless it waits), so constraint statements
    /// after a spawn still apply. The hold ends by itself when the action returns.
    /// Returns whether it was holding before.
    pub fn hold_children(
        &mut self,
        now: Time,
        node: NodeId,
        on: bool,
    ) -> Result<bool, EngineError> {
        self.advance(now);
        let n = self.live(node)?;
        if n.kind == NodeKind::Root {
            return Err(EngineError::Root("held"));
        }
        let was = std::mem::replace(&mut self.node_mut(node).holding, on);
        if was && !on {
            self.progress_children(node);
            self.settle();
        }
        Ok(was)
    }

    fn link(&mut self, parent: NodeId, child: NodeId) {
        let p = self.node_mut(parent);
        let last = p.last_child;
        if p.first_child == Link::NONE {
            p.first_child = Link::to(child);
        }
        p.last_child = Link::to(child);
        p.live_children += 1;
        p.open_executions += 1;
        let c = self.node_mut(child);
        c.prev_sibling = last;
        c.next_sibling = Link::NONE;
        if c.state(Facet::Expansion) != State::Completed {
            self.node_mut(parent).open_expansions += 1;
        }
        if let Some(l) = self.nodes.get_mut_at(last) {
            l.next_sibling = Link::to(child);
        }
    }

    pub(super) fn unlink(&mut self, child: NodeId) {
        let (parent, prev, next) = {
            let c = self.node(child);
            (c.parent, c.prev_sibling, c.next_sibling)
        };
        let Some(parent) = parent else { return };
        let first = match self.nodes.get_mut_at(prev) {
            Some(p) => {
                p.next_sibling = next;
                false
            }
            None => true,
        };
        let last = match self.nodes.get_mut_at(next) {
            Some(n) => {
                n.prev_sibling = prev;
                false
            }
            None => true,
        };
        if !self.runs.is_empty() {
            self.step_runs_over(Link::to(child), prev, next);
        }
        let p = self.node_mut(parent);
        if first {
            p.first_child = next;
        }
        if last {
            p.last_child = prev;
        }
        p.live_children -= 1;
    }

    /// A pending run of children steps over the child at `at`, being unlinked from between `prev`
    /// and `next` (`ChildRun`).
    #[cold]
    fn step_runs_over(&mut self, at: Link, prev: Link, next: Link) {
        for r in &mut self.runs {
            if r.next == at && r.last == at {
                r.next = Link::NONE;
            } else if r.next == at {
                r.next = next;
            } else if r.last == at && r.next != Link::NONE {
                r.last = prev;
            }
        }
    }

    /// The first linked child of a live node.
    pub(crate) fn first_child(&self, id: NodeId) -> Option<NodeId> {
        self.nodes
            .get(id)
            .and_then(|n| self.nodes.id_at(n.first_child))
    }

    /// The next linked sibling of a live node.
    pub(crate) fn next_sibling(&self, id: NodeId) -> Option<NodeId> {
        self.nodes
            .get(id)
            .and_then(|n| self.nodes.id_at(n.next_sibling))
    }

    /// Allocates, links and traces a new node under `parent` with the given payload (activations,
    /// handler nodes, retries, on-terminate tasks). The caller queues its progress.
    pub(crate) fn insert(
        &mut self,
        parent: NodeId,
        kind: NodeKind,
        name: Name,
        payload: Payload<A, F>,
    ) -> NodeId {
        let display = self.next_display();
        let mut node = Node::new(display, kind, name, Some(parent));
        node.action = Some(payload);
        node.suspended = self.node(parent).suspended;
        let id = self.nodes.insert(node);
        self.link(parent, id);
        self.emit_spawned(id, parent, None, None);
        if self.node(id).suspended {
            emit!(self, TraceKind::Suspended { node: display });
        }
        if !self.node(parent).alive() {
            self.work.push_back(Work::Terminate {
                node: id,
                explicit: false,
            });
        }
        id
    }

    /// Like [`Engine::insert`], but the node fulfils the open reservation `r` of `parent`, whose
    /// kept constraints apply now (an on-terminate task with a label). The caller queues its
    /// progress.
    pub(crate) fn insert_reserved(
        &mut self,
        parent: NodeId,
        r: NodeId,
        kind: NodeKind,
        name: Name,
        payload: Payload<A, F>,
    ) -> NodeId {
        self.claim_reservation(parent, r, kind, name);
        let suspended = self.node(parent).suspended;
        let node = self.node_mut(r);
        node.action = Some(payload);
        node.suspended = suspended;
        self.link(parent, r);
        let display = self.emit_spawned(r, parent, None, None);
        if suspended {
            emit!(self, TraceKind::Suspended { node: display });
        }
        let later = self.apply_deferred(r, parent);
        self.node_mut(parent).last_spawned = Some(r);
        for (c, prev) in later {
            self.apply(r, parent, prev, c);
        }
        for g in self.node_mut(r).take_cold(|c| &mut c.deferred_groups) {
            self.arm_group(r, g);
        }
        if !self.node(parent).alive() {
            self.work.push_back(Work::Terminate {
                node: r,
                explicit: false,
            });
        }
        r
    }

    /// Traces a node's insertion under `parent`; returns its display number.
    #[inline(always)]
    fn emit_spawned(
        &mut self,
        id: NodeId,
        parent: NodeId,
        version: Option<&std::sync::Arc<str>>,
        args: Option<Box<str>>,
    ) -> u64 {
        let display = self.node(id).display;
        // The record (and its copy of the name) is only built when someone reads the trace.
        if self.tracing {
            let kind = self.node(id).kind;
            let parent = self.node(parent).display;
            let name = self.node(id).name.to_string();
            self.push_trace(TraceKind::Spawned {
                node: display,
                parent,
                kind,
                name,
                version: version.map(ToString::to_string),
                args: args.map(String::from),
            });
        }
        display
    }
}

/// Drops a list a spawn did not use. Most are empty and never allocated: those own nothing, so
/// they are forgotten rather than handed to their drop glue, a call the compiler does not inline
/// (an empty list of a type with drop glue still goes through it).
#[inline(always)]
fn discard<T>(list: Vec<T>) {
    if list.capacity() == 0 {
        std::mem::forget(list);
    }
}
