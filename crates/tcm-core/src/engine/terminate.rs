//! Termination and suspension of subtrees (docs/semantics.md, "Termination" and "Suspension").

use super::node::{OnTerminate, Payload};
use super::{Effect, Engine, EngineError, Work};
use crate::NodeKind;
use crate::ids::NodeId;
use crate::time::Time;
use std::collections::VecDeque;
use tcm_trace::{Facet, State, Termination, TraceKind};

impl<A, F: Clone> Engine<A, F> {
    /// Terminates a node and its subtree (docs/semantics.md, "Termination").
    pub fn terminate(&mut self, now: Time, node: NodeId) -> Result<(), EngineError> {
        self.advance(now);
        let n = self.live(node)?;
        if n.kind == NodeKind::Root {
            return Err(EngineError::Root("terminated"));
        }
        self.work.push_back(Work::Terminate(node));
        self.settle();
        Ok(())
    }

    /// Terminates every child of `node`.
    pub fn terminate_children(&mut self, now: Time, node: NodeId) -> Result<(), EngineError> {
        self.advance(now);
        self.live(node)?;
        let mut c = self.first_child(node);
        while let Some(child) = c {
            self.work.push_back(Work::Terminate(child));
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
                self.work.push_back(Work::Terminate(child));
            }
            c = self.next_sibling(child);
        }
        self.settle();
        Ok(())
    }

    /// Terminates `id` and its subtree (docs/semantics.md, "Termination", numbered as there):
    /// 1. each alive node goes Terminating (a node with delayed termination, an on-terminate task,
    ///    is skipped, so it runs to completion);
    /// 2. its termination waiters are dropped (they never fire), it is unsuspended;
    /// 3. a running action is cancelled and its on-terminate tasks inserted as children; an action
    ///    not yet started never starts; either way the handling completes at once;
    /// 4. its reservations are dead; its children are terminated the same way;
    /// 5. progress then completes expansion and execution bottom-up, so constraints waiting on these
    ///    nodes are released, and each node is Terminated once its children are.
    pub(super) fn do_terminate(&mut self, id: NodeId) {
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
        if n.state(Facet::Execution) == State::Completed {
            return;
        }
        let mut queue = VecDeque::from([id]);
        while let Some(c) = queue.pop_front() {
            let Some(n) = self.nodes.get_mut(c) else {
                continue;
            };
            if !n.alive() || (c != id && n.immune) || n.state(Facet::Execution) == State::Completed
            {
                continue;
            }
            n.termination = Termination::Terminating;
            n.waiters.retain(|w| !w.kind.is_termination());
            let was_suspended = std::mem::replace(&mut n.suspended, false);
            n.parked = false;
            let h = n.state(Facet::Handling);
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
                && self.node(c).taps_pending() == 0;
            // Wiretap checks on it run to their end in the shell, but decide nothing any more:
            // they stop counting as running now, and their reports are refused.
            let checks = self.node_mut(c).take_cold(|c| &mut c.taps_open);
            self.running -= checks.len() as u32;
            if h == State::Active {
                if action_running {
                    self.running -= 1;
                    self.cancel_action(c);
                }
                let cleanups = self.node_mut(c).take_cold(|c| &mut c.on_terminate);
                for ot in cleanups {
                    self.spawn_cleanup(c, ot);
                }
            }
            if h != State::Completed {
                self.transition(c, Facet::Handling, State::Completed);
                self.bury_reservations(c);
            }
            let mut child = self.first_child(c);
            while let Some(ch) = child {
                queue.push_back(ch);
                child = self.next_sibling(ch);
            }
            self.work.push_back(Work::Progress(c));
        }
    }

    /// Stops the running action of `node`. If its start is still queued (the shell has not taken
    /// it yet), the start is withdrawn, so the shell never runs it; otherwise the shell is asked to
    /// cancel it. The queue is short: every shell drains it after each input.
    fn cancel_action(&mut self, node: NodeId) {
        let queued = self.effects.iter().rposition(|e| match e {
            Effect::Start { node: n, .. } => *n == node,
            Effect::Invoke { job, .. } => job.node() == node && job.cancellable(),
            _ => false,
        });
        match queued {
            Some(i) => drop(self.effects.remove(i)),
            None => self.effects.push_back(Effect::Cancel { node }),
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
        self.work.push_back(Work::Progress(id));
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
        let mut queue = VecDeque::from([id]);
        while let Some(c) = queue.pop_front() {
            let Some(n) = self.nodes.get_mut(c) else {
                continue;
            };
            if n.suspended != on && n.alive() {
                n.suspended = on;
                let display = n.display;
                let resume = !on && std::mem::replace(&mut n.parked, false);
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
            }
            let mut child = self.first_child(c);
            while let Some(ch) = child {
                queue.push_back(ch);
                child = self.next_sibling(ch);
            }
        }
        self.settle();
        Ok(())
    }
}
