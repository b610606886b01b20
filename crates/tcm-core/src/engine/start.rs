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
    #[inline(never)]
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
        // Most nodes have no cold part (no resources, not a monitor, no wiretap checks made),
        // most runs no wiretap and nobody steers them: then none of `start_checks` applies.
        let (n, how) = if n.cold.is_none() && self.taps.is_empty() && self.steer.is_none() {
            (n, How::Action)
        } else {
            let Some(how) = self.start_checks(id) else {
                return;
            };
            let Some(n) = self.nodes.get_mut(id) else {
                return;
            };
            (n, how)
        };
        let payload = n.action.take();
        if payload.is_none() && how == How::Action {
            return;
        }
        let invariants = !n.invariant_conditions().is_empty();
        let expands = n.kind.expands();
        if how == How::Action {
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
            None if how == How::Monitor => self.monitor_started(id),
            None => {}
        }
        if how == How::Injected {
            self.injected(id);
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

    /// What must happen before a node with a cold part, or of a run with wiretaps or steered,
    /// starts: its `skip if` conditions are read (it is skipped if one holds), its resources are
    /// granted (docs/semantics.md, "Resources": it waits, enabled, until then, or fails if it is
    /// refused), its "before" wiretaps approve it (it stays enabled until they report,
    /// `tap_finished`), and the run's steering lets it go (`steer.rs`: a breakpoint, an approval
    /// hold, a fault that stands for its action). Returns how it starts, or `None` if it does not
    /// start now.
    fn start_checks(&mut self, id: NodeId) -> Option<How> {
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
        let n = self.nodes.get(id)?;
        if n.action.is_none() && !is_monitor {
            return None;
        }
        let steered = self.steer.is_some() || n.cold.as_ref().is_some_and(|c| c.approval.is_some());
        let gate = if steered {
            self.start_gate(id, is_monitor)
        } else {
            super::steer::Gate::Go
        };
        match gate {
            super::steer::Gate::Stop => None,
            super::steer::Gate::Inject => {
                // A fault stands for the action (`steer.rs`, rule 4): it never runs.
                drop(self.nodes.get_mut(id)?.action.take());
                Some(How::Injected)
            }
            super::steer::Gate::Go if is_monitor => Some(How::Monitor),
            super::steer::Gate::Go => Some(How::Action),
        }
    }
}

/// How a node starts (`start_checks`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum How {
    /// Its action is handed to the shell.
    Action,
    /// A monitor: it has no action; its activations begin.
    Monitor,
    /// A fault stands for its action, which never runs (`steer.rs`, rule 4).
    Injected,
}
