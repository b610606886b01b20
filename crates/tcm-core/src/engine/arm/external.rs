//! External events (interned by name, raised as inputs, latched), watches for the shell, and
//! the inputs that change nothing but the trace (`note_placed`, `log`, `warn`).

use super::super::node::{Node, WaitKind, Waiter};
use super::super::{Effect, Engine, EngineError, WatchOutcome};
use crate::arena::Keep;
use crate::arena::{Fate, Lookup};
use crate::constraint::{Event, NodeRef};
use crate::ids::{ExternalId, NodeId, WatchToken};
use crate::time::Time;
use tcm_trace::TraceKind;

/// A named external event (or manual signal gate).
#[derive(Clone)]
pub(in crate::engine) struct External {
    pub(in crate::engine) name: String,
    pub(in crate::engine) raised: bool,
    /// Latched triggers (enable, terminate): fired by the first raise, or at once once raised.
    pub(in crate::engine) waiters: Vec<WaitKind>,
    /// Monitors activated on every raise.
    pub(in crate::engine) activators: Vec<NodeId>,
}

impl<A, F: Clone, S: Keep<Node<A, F>>> Engine<A, F, S> {
    /// Interns a named external event (or manual signal gate).
    pub fn external(&mut self, name: &str) -> ExternalId {
        if let Some(id) = self.external_ids.get(name) {
            return *id;
        }
        let id = ExternalId(self.externals.len() as u32);
        self.externals.push(External {
            name: name.to_string(),
            raised: false,
            waiters: Vec::new(),
            activators: Vec::new(),
        });
        self.external_ids.insert(name.to_string(), id);
        id
    }

    /// Input: a named external event was raised. It is latched: constraints applied later find it
    /// raised. Monitors activated by it are activated on every raise.
    pub fn handle_external(&mut self, now: Time, event: ExternalId) {
        self.handle_external_with(now, event, None);
    }

    /// Input: the external event `event` happened, carrying `data`: as
    /// [`Engine::handle_external`], and each monitor activation it makes carries the data
    /// ([`Engine::activation_data`]; TCM's external event with data).
    pub fn handle_external_with(
        &mut self,
        now: Time,
        event: ExternalId,
        data: Option<std::sync::Arc<dyn std::any::Any + Send + Sync>>,
    ) {
        self.advance(now);
        let Some(ext) = self.externals.get_mut(event.0 as usize) else {
            return;
        };
        let first = !ext.raised;
        ext.raised = true;
        let name = ext.name.clone();
        let waiters = std::mem::take(&mut ext.waiters);
        let activators = ext.activators.clone();
        self.record(|_| super::super::InputRecord::External { name: name.clone() });
        emit!(self, TraceKind::External { name });
        if first {
            for w in waiters {
                self.fire(w, false);
            }
        }
        for monitor in activators {
            let act = self.activation_due(monitor);
            if let (Some(act), Some(data)) = (act, &data) {
                self.node_mut(act).cold_mut().data = Some(data.clone());
            }
        }
        self.settle();
    }

    /// The data an activation was made with, by an external event raised with data
    /// ([`Engine::handle_external_with`]); `None` for another node, or once it is gone.
    pub fn activation_data(
        &self,
        node: NodeId,
    ) -> Option<std::sync::Arc<dyn std::any::Any + Send + Sync>> {
        self.query(node)?.cold.as_ref()?.data.clone()
    }

    /// Input: `node`'s action runs on another process of a distributed system, the agent
    /// `agent` (the shell's distribution layer says so when it sends the action there). Changes
    /// nothing but the trace: a `placed` record. Not a step of the run ([`Engine::steps`]): a
    /// command's action notes it, and a replay, which does not run commands, must count what the
    /// run counted.
    pub fn note_placed(&mut self, now: Time, node: NodeId, agent: &str) -> Result<(), EngineError> {
        let (steps, mark) = (self.steps, self.mark);
        self.advance(now);
        (self.steps, self.mark) = (steps, mark);
        let node = self.live(node)?.display;
        emit!(
            self,
            TraceKind::Placed {
                node,
                agent: agent.to_string(),
            }
        );
        Ok(())
    }

    /// Input: `node`'s body wrote `message` to the run's log (TDL's `log` statement). Changes
    /// nothing but the trace: a `log` record, stamped with `now`. A step of the run, and an input
    /// recorded for a journal whoever gives it: a replay, which does not run commands, gives a
    /// command's line from the journal.
    pub fn log(&mut self, now: Time, node: NodeId, message: String) -> Result<(), EngineError> {
        self.advance(now);
        let node = self.live(node)?.display;
        self.record(|_| super::super::InputRecord::Log {
            node,
            message: message.clone(),
        });
        emit!(self, TraceKind::Log { node, message });
        Ok(())
    }

    /// Input: something worth a person's attention that the engine cannot see (a message from an
    /// agent that arrived twice, say), about `node` while it is in the tree (else about the run:
    /// a reclaimed node is named by no later record). A `warning` record, counted as the engine's
    /// own.
    pub fn warn(&mut self, now: Time, node: Option<NodeId>, message: impl Into<String>) {
        self.advance(now);
        let node = node.and_then(|id| self.query(id)).map(|n| n.display);
        let message = message.into();
        emit!(self, TraceKind::Warning { node, message });
    }

    /// Asks to be told (by [`Effect::Notify`] with `token`) when `event` happens. If it already
    /// happened, the notification is queued at once.
    pub fn watch(&mut self, now: Time, event: Event, token: WatchToken) -> Result<(), EngineError> {
        self.advance(now);
        let NodeRef::Node(node) = event.node else {
            return Err(EngineError::RelativeRef);
        };
        match self.lookup(node)? {
            Lookup::Gone(fate) => {
                let outcome = match fate {
                    Fate::Completed => WatchOutcome::Reached,
                    Fate::Terminated => WatchOutcome::Terminated,
                    Fate::Dead => WatchOutcome::Dead,
                };
                self.effects.push_back(Effect::Notify {
                    token,
                    outcome: Box::new(outcome),
                });
            }
            Lookup::Live => {
                // The shell is told how the node ended (`WatchOutcome`): no outcome filter.
                let waiter = Waiter {
                    facet: event.facet,
                    point: event.point,
                    kind: WaitKind::Watch { token },
                    outcome: None,
                };
                if self.node(node).reached(event.facet, event.point) {
                    self.fire_now(node, waiter.kind);
                } else {
                    self.node_mut(node).waiters.push(waiter);
                }
            }
        }
        self.settle();
        Ok(())
    }
}
