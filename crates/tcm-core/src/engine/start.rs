//! Starting a ready node: its `skip if` conditions read (it may be skipped instead), its
//! resources granted and its "before" wiretaps approved, then its handling active (with its
//! ancestors' expansion or execution, Figure 3) and its action handed to the shell; an invariant
//! already false fails it at once. Called by `settle` (`progress.rs`) for the oldest ready node;
//! a node terminated before it started completes there, at its turn, without starting.

use super::node::{Node, Payload};
use super::{Effect, Engine, Job};
use crate::NodeKind;
use crate::arena::Keep;
use crate::ids::NodeId;
use tcm_trace::{Facet, State, TraceKind};

impl<A, F: Clone, S: Keep<Node<A, F>>> Engine<A, F, S> {
    pub(super) fn start(&mut self, id: NodeId) {
        let Some(n) = self.nodes.get_mut(id) else {
            return;
        };
        if n.state(Facet::Handling) != State::Enabled {
            return;
        }
        if !n.alive() {
            self.complete_unstarted(id);
            return;
        }
        if n.suspended {
            n.parked = true;
            // A grant it could not use yet goes back; it asks again once unsuspended.
            if n.grant() == super::resource::Grant::Held {
                self.release_resources(id);
            }
            return;
        }
        // Most nodes have no cold part (no resources, not a monitor, no wiretap checks made) and
        // most runs no wiretap: then none of `start_checks` applies.
        let (n, is_monitor) = if n.cold.is_none() && self.taps.is_empty() {
            (n, false)
        } else {
            let Some(is_monitor) = self.start_checks(id) else {
                return;
            };
            let Some(n) = self.nodes.get_mut(id) else {
                return;
            };
            (n, is_monitor)
        };
        if n.action.is_none() && !is_monitor {
            return;
        }
        let gate = if self.steer.is_some() || n.cold.as_ref().is_some_and(|c| c.approval.is_some())
        {
            match self.start_gate(id, is_monitor) {
                super::steer::Gate::Stop => return,
                super::steer::Gate::Go => None,
                super::steer::Gate::Inject(outcome) => Some(outcome),
            }
        } else {
            None
        };
        let Some(n) = self.nodes.get_mut(id) else {
            return;
        };
        let mut payload = n.action.take();
        if gate.is_some() {
            // A fault stands for the action (`steer.rs`, rule 4): it never runs.
            payload = None;
        }
        let invariants = !n.invariant_conditions().is_empty();
        let expands = n.kind.expands();
        if !is_monitor && gate.is_none() {
            self.running += 1;
            n.holding = self.hold_default;
        }
        self.transition(id, Facet::Handling, State::Active);
        // Figure 3: the expansion (goals) or execution (commands) of the node and of every ancestor
        // is active once some node of the right kind in the subtree is active.
        let facet = if expands {
            Facet::Expansion
        } else {
            Facet::Execution
        };
        let mut cur = Some(id);
        while let Some(c) = cur {
            let n = self.node(c);
            if n.kind == NodeKind::Root || n.state(facet) != State::Enabled {
                break;
            }
            let parent = n.parent;
            self.transition(c, facet, State::Active);
            cur = parent;
        }
        match payload {
            Some(Payload::Action(action)) => {
                self.effects.push_back(Effect::Start { node: id, action })
            }
            Some(Payload::Invoke(body, purpose)) => {
                self.effects.push_back(Effect::Invoke {
                    job: Job::from(id),
                    body,
                    purpose,
                });
            }
            None if is_monitor => self.monitor_started(id),
            None => {}
        }
        if let Some(outcome) = gate {
            self.injected(id, outcome);
        }
        if invariants {
            self.check_invariants(id);
        }
        if self.steer.is_some() {
            self.after_start();
        }
    }

    /// The turn of a node terminated before it started came: its handling completes without
    /// running, after the nodes released before it started, as TCM marked such a node handled at
    /// its turn on the agenda (docs/semantics.md, "Termination", step 4).
    fn complete_unstarted(&mut self, id: NodeId) {
        self.transition(id, Facet::Handling, State::Completed);
        self.bury_reservations(id);
        self.queue_progress(id);
    }

    /// The node's turn came while a `skip if` condition holds: it completes without running, its
    /// handling going from enabled to completed (docs/semantics.md, "State and conditions").
    fn skip(&mut self, id: NodeId) {
        let display = self.node(id).display;
        emit!(self, TraceKind::Skipped { node: display });
        let n = self.node_mut(id);
        n.cold_mut().skipped = true;
        n.action = None;
        self.transition(id, Facet::Handling, State::Completed);
        self.bury_reservations(id);
        self.queue_progress(id);
    }

    /// What must happen before a node with a cold part starts: its `skip if` conditions are
    /// read (it is skipped if one holds), its resources are granted
    /// (docs/semantics.md, "Resources": it waits, enabled, until then, or fails if it is refused),
    /// and its "before" wiretaps approve it (it stays enabled until they report,
    /// `tap_finished`). Returns whether it is a monitor, or `None` if it does not start now.
    fn start_checks(&mut self, id: NodeId) -> Option<bool> {
        let n = self.nodes.get(id)?;
        if !n.skip_conditions().is_empty() && self.skips(id) {
            self.skip(id);
            return None;
        }
        let n = self.nodes.get(id)?;
        if n.uses().is_some()
            && n.grant() != super::resource::Grant::Held
            && !self.request_resources(id)
        {
            return None;
        }
        let n = self.nodes.get_mut(id)?;
        let is_monitor = n.monitor().is_some();
        let tapped = n.tapped_before();
        if !is_monitor && !tapped && !self.taps.is_empty() {
            n.cold_mut().tapped_before = true;
            if self.start_taps(id, crate::ids::TapWhen::Before) > 0 {
                return None;
            }
        }
        Some(is_monitor)
    }
}
