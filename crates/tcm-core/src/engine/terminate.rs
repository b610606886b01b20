//! Termination and suspension of subtrees (docs/semantics.md, "Termination" and "Suspension").

use super::node::Node;
use super::node::{OnTerminate, Payload, WaitKind};
use super::{Effect, Engine, EngineError, Work};
use crate::NodeKind;
use crate::arena::Keep;
use crate::arena::{Fate, Lookup};
use crate::constraint::Then;
use crate::ids::NodeId;
use crate::time::Time;
use std::collections::VecDeque;
use tcm_trace::{Facet, State, Termination, TraceKind};

impl<A, F: Clone, S: Keep<Node<A, F>>> Engine<A, F, S> {
    /// Terminates a node and its subtree (docs/semantics.md, "Termination"). A node already gone
    /// (completed and reclaimed, terminated, or a dead reservation) is not an error: a warning is
    /// traced and nothing else happens, as for a node already terminating.
    pub fn terminate(&mut self, now: Time, node: NodeId) -> Result<(), EngineError> {
        self.advance(now);
        match self.lookup(node)? {
            Lookup::Gone(fate) => {
                emit!(
                    self,
                    TraceKind::Warning {
                        node: None,
                        message: format!(
                            "Trying to terminate already dead node {node} ({})",
                            match fate {
                                Fate::Completed => "completed",
                                Fate::Terminated => "terminated",
                                Fate::Dead => "never spawned",
                            }
                        ),
                    }
                );
                return Ok(());
            }
            Lookup::Live => {}
        }
        if self.node(node).kind == NodeKind::Root {
            return Err(EngineError::Root("terminated"));
        }
        self.work.push_back(Work::Terminate {
            node,
            explicit: true,
        });
        self.settle();
        Ok(())
    }

    /// Terminates every child of `node`.
    pub fn terminate_children(&mut self, now: Time, node: NodeId) -> Result<(), EngineError> {
        self.advance(now);
        self.live(node)?;
        let mut c = self.first_child(node);
        while let Some(child) = c {
            self.work.push_back(Work::Terminate {
                node: child,
                explicit: true,
            });
            c = self.next_sibling(child);
        }
        self.settle();
        Ok(())
    }

    /// Terminates every sibling of `node` (not `node` itself).
    pub fn terminate_siblings(&mut self, now: Time, node: NodeId) -> Result<(), EngineError> {
        self.advance(now);
        let parent = self
            .live(node)?
            .parent
            .ok_or(EngineError::Root("given siblings"))?;
        let mut c = self.first_child(parent);
        while let Some(child) = c {
            if child != node {
                self.work.push_back(Work::Terminate {
                    node: child,
                    explicit: true,
                });
            }
            c = self.next_sibling(child);
        }
        self.settle();
        Ok(())
    }

    /// Terminates `id` and its subtree (docs/semantics.md, "Termination", numbered as there).
    /// `explicit`: asked for by a command, not made due by a termination constraint; only an
    /// explicit termination reaches a node whose execution already completed (a persistent one).
    /// 1. each alive node goes Terminating (a node with delayed termination, an on-terminate task,
    ///    is skipped, so it runs to completion);
    /// 2. its termination waiters are dropped (they never fire), it is unsuspended;
    /// 3. a running action is asked to stop (the node is terminated once the shell reports it
    ///    stopped); a node that started and did not complete gets its on-terminate tasks as
    ///    children; an action not yet started never starts, and its handling completes once its
    ///    constraints would have let it start (delays and external events no longer hold it);
    /// 4. its reservations are dead; its children are terminated the same way;
    /// 5. progress then completes expansion and execution bottom-up, each once it is enabled, so
    ///    constraints waiting on these nodes are released in the plan's order, and each node is
    ///    Terminated once its children are.
    #[inline(never)]
    pub(super) fn do_terminate(&mut self, id: NodeId, explicit: bool) {
        let Some(n) = self.nodes.get(id) else { return };
        // The root never terminates; an on-terminate task runs to completion whatever happens.
        if n.kind == NodeKind::Root || n.immune {
            return;
        }
        let display = n.display;
        if !n.alive() {
            emit!(
                self,
                TraceKind::Warning {
                    node: Some(display),
                    message: format!(
                        "Trying to terminate already dead node {} {{{}}}",
                        n.name, display
                    ),
                }
            );
            return;
        }
        if n.state(Facet::Execution) == State::Completed && !explicit {
            return;
        }
        let mut queue = VecDeque::from([id]);
        // Nodes terminated before their handling was enabled: their delays are released below.
        let mut unstarted = Vec::new();
        while let Some(c) = queue.pop_front() {
            let Some(n) = self.nodes.get_mut(c) else {
                continue;
            };
            if !n.alive() || (c != id && n.immune) {
                continue;
            }
            n.termination = Termination::Terminating;
            n.waiters.retain(|w| !w.kind.is_termination());
            let was_suspended = std::mem::replace(&mut n.suspended, false);
            n.parked = false;
            let h = n.state(Facet::Handling);
            let completed = n.state(Facet::Execution) == State::Completed;
            let display = n.display;
            let parent = n.parent;
            if let Some(p) = parent.and_then(|p| self.nodes.get_mut(p)) {
                p.terminating_children += 1;
            }
            emit!(self, TraceKind::Terminating { node: display });
            if was_suspended {
                emit!(self, TraceKind::Unsuspended { node: display });
            }
            let action_running = h == State::Active
                && self.node(c).monitor().is_none()
                && self.node(c).taps_pending() == 0
                && !self.node(c).never_ends();
            // Wiretap checks on it run to their end in the shell, but decide nothing any more:
            // they stop counting as running now, and their reports are refused.
            let checks = self.node_mut(c).take_cold(|c| &mut c.taps_open);
            self.running -= checks.len() as u32;
            if action_running && !self.cancel_action(c) {
                self.node_mut(c).stopping = true;
            }
            if h >= State::Active && !completed {
                let cleanups = self.node_mut(c).take_cold(|c| &mut c.on_terminate);
                for ot in cleanups {
                    self.spawn_cleanup(c, ot);
                }
            }
            match h {
                State::Active | State::Enabled => {
                    // A waiting request is withdrawn, a grant goes back, unless its action is
                    // still stopping (then once it stopped).
                    if !self.node(c).stopping {
                        self.release_resources(c);
                    }
                    self.transition(c, Facet::Handling, State::Completed);
                    self.bury_reservations(c);
                }
                State::Disabled => unstarted.push(c),
                State::Completed => {}
            }
            let mut child = self.first_child(c);
            while let Some(ch) = child {
                queue.push_back(ch);
                child = self.next_sibling(ch);
            }
            self.queue_progress(c);
        }
        if !unstarted.is_empty() {
            self.release_delays(&unstarted);
        }
    }

    /// Nodes terminated before they started wait only for the events of other nodes (the plan's
    /// order): their pending delays and their waits on external events and conditions are
    /// released at once.
    fn release_delays(&mut self, nodes: &[NodeId]) {
        let forced = |id: NodeId| nodes.contains(&id);
        for (target, then) in self.timers.take_enables(forced) {
            self.fire_trigger(target, then, true);
        }
        let mut released = Vec::new();
        for ext in &mut self.externals {
            ext.waiters.retain(|w| match *w {
                WaitKind::Trigger {
                    target,
                    then: then @ Then::Enable(_),
                    ..
                } if forced(target) => {
                    released.push((target, then));
                    false
                }
                _ => true,
            });
        }
        released.extend(self.states.take_enables(forced));
        for (target, then) in released {
            self.fire_trigger(target, then, true);
        }
    }

    /// Stops the running action of `node`. If its start is still queued (the shell has not taken
    /// it yet), the start is withdrawn, so the shell never runs it; otherwise the shell is asked to
    /// cancel it. The queue is short: every shell drains it after each input.
    /// Returns whether the start was withdrawn (then the action no longer counts as running).
    pub(super) fn cancel_action(&mut self, node: NodeId) -> bool {
        let queued = self.effects.iter().rposition(|e| match e {
            Effect::Start { node: n, .. } => *n == node,
            Effect::Invoke { job, .. } => job.node() == node && job.cancellable(),
            _ => false,
        });
        match queued {
            Some(i) => {
                drop(self.effects.remove(i));
                self.running -= 1;
                true
            }
            None => {
                self.effects.push_back(Effect::Cancel { node });
                false
            }
        }
    }

    fn spawn_cleanup(&mut self, parent: NodeId, ot: OnTerminate<A>) {
        let payload = Payload::Action(ot.action);
        // A labelled on-terminate task fulfils the reservation its node took over at its spawn.
        let id = match ot.fulfils.filter(|r| self.is_reservation_of(*r, parent)) {
            Some(r) => self.insert_reserved(parent, r, ot.kind, ot.name, payload),
            None => self.insert(parent, ot.kind, ot.name, payload),
        };
        // Delayed termination: the terminating parent does not take it down (see `do_terminate`).
        self.node_mut(id).immune = true;
        self.node_mut(parent).last_spawned = Some(id);
        self.queue_progress(id);
    }

    /// Suspends a node and its subtree: no action in it starts until it is unsuspended. Running
    /// actions go on. Children spawned under a suspended node start suspended.
    pub fn suspend(&mut self, now: Time, node: NodeId) -> Result<(), EngineError> {
        self.set_suspended(now, node, true)
    }

    /// Undoes [`Engine::suspend`] for the node and its subtree.
    pub fn unsuspend(&mut self, now: Time, node: NodeId) -> Result<(), EngineError> {
        self.set_suspended(now, node, false)
    }

    fn set_suspended(&mut self, now: Time, id: NodeId, on: bool) -> Result<(), EngineError> {
        self.advance(now);
        let n = self.live(id)?;
        if n.kind == NodeKind::Root {
            return Err(EngineError::Root(if on {
                "suspended"
            } else {
                "unsuspended"
            }));
        }
        self.suspend_now(id, on);
        self.settle();
        Ok(())
    }

    /// Suspends (or unsuspends) `id` and its subtree, without settling: for `suspend`, and for
    /// a pause (`state.rs`).
    pub(super) fn suspend_now(&mut self, id: NodeId, on: bool) {
        let mut queue = VecDeque::from([id]);
        while let Some(c) = queue.pop_front() {
            let Some(n) = self.nodes.get_mut(c) else {
                continue;
            };
            if n.suspended != on && n.alive() {
                n.suspended = on;
                let display = n.display;
                let resume = !on && std::mem::replace(&mut n.parked, false);
                let n_waits = n.grant() == super::resource::Grant::Waiting;
                emit!(
                    self,
                    if on {
                        TraceKind::Suspended { node: display }
                    } else {
                        TraceKind::Unsuspended { node: display }
                    }
                );
                if resume {
                    self.ready.push_back(c);
                }
                if !on && n_waits {
                    // Its waiting request may be granted now.
                    self.res.dirty = true;
                }
            }
            let mut child = self.first_child(c);
            while let Some(ch) = child {
                queue.push_back(ch);
                child = self.next_sibling(ch);
            }
        }
    }
}
