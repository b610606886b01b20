//! Triggers on a whole group (TDL's `with` group, or `previous` when it was one): armed on the
//! target, one waiter per member, fired by the last member to reach its event.

use super::super::node::{Delay, Node, WaitKind, Waiter};
use super::super::{Engine, EngineError};
use super::nanos;
use crate::NodeKind;
use crate::arena::Keep;
use crate::arena::{Fate, Lookup};
use crate::constraint::Then;
use crate::ids::NodeId;
use crate::time::Time;
use std::time::Duration;
use tcm_trace::{Facet, Point, TraceConstraint, TraceWhen};

/// A group trigger as given ([`Engine::trigger_group`]), kept on a reservation until its spawn.
#[derive(Clone)]
pub(crate) struct GroupTrigger {
    pub(in crate::engine) members: Vec<NodeId>,
    pub(in crate::engine) facet: Facet,
    pub(in crate::engine) point: Point,
    pub(in crate::engine) delay: Option<Duration>,
    pub(in crate::engine) then: Then,
}

/// A trigger on a whole group: it fires once `remaining` members reached their event.
#[derive(Clone)]
pub(in crate::engine) struct Join {
    pub(in crate::engine) target: NodeId,
    pub(in crate::engine) then: Then,
    pub(in crate::engine) delay: Option<Duration>,
    pub(in crate::engine) remaining: u32,
    // A member reached its event because it was terminating: a termination never fires.
    pub(in crate::engine) never: bool,
}

impl<A, F: Clone, S: Keep<Node<A, F>>> Engine<A, F, S> {
    /// Arms a trigger on a whole group (TDL's `with` group, or `previous` when it was one): `then`
    /// happens to `target` once every member reached `point` of `facet` (after `delay`, if any),
    /// and at once when there is no member (docs/semantics.md, "Tags and forward references").
    /// As for one node, a member that reached the point only because it was terminating never
    /// fires a termination, and a member never spawned (dead) counts as reached. `then` is a
    /// termination or an activation: an enablement constraint on a group is given to each member
    /// at the spawn, which already waits for every one ([`EngineError::GroupEnable`]).
    #[allow(clippy::too_many_arguments)]
    pub fn trigger_group(
        &mut self,
        now: Time,
        target: NodeId,
        members: &[NodeId],
        facet: Facet,
        point: Point,
        delay: Option<Duration>,
        then: Then,
    ) -> Result<(), EngineError> {
        self.advance(now);
        let n = self.live(target)?;
        if n.kind == NodeKind::Root {
            return Err(EngineError::Root("constrained"));
        }
        for m in members {
            self.check_run(*m)?;
        }
        if let Then::Enable(_) = then {
            return Err(EngineError::GroupEnable);
        }
        let g = GroupTrigger {
            members: members.to_vec(),
            facet,
            point,
            delay,
            then,
        };
        if n.reserved {
            // A forward reference: armed when the spawn fulfils it, as its other constraints.
            self.node_mut(target).cold_mut().deferred_groups.push(g);
            return Ok(());
        }
        self.arm_group(target, g);
        self.queue_progress(target);
        self.settle();
        Ok(())
    }

    /// Arms a group trigger on a linked node (see [`Engine::trigger_group`]).
    pub(in crate::engine) fn arm_group(&mut self, target: NodeId, g: GroupTrigger) {
        let GroupTrigger {
            members,
            facet,
            point,
            delay,
            then,
        } = g;
        if then.activates() && self.node(target).monitor().is_none() {
            return self.void(target, || "`activate` applies to monitors only".into());
        }
        let events = members
            .iter()
            .map(|m| self.event_ref(*m, facet, point, None))
            .collect();
        self.constrained(target, || {
            let delay_ns = delay.map(nanos);
            TraceConstraint::trigger(TraceWhen::All { events, delay_ns }, then.traced())
        });
        let slot = match self.joins.iter().position(Option::is_none) {
            Some(i) => i,
            None => {
                self.joins.push(None);
                self.joins.len() - 1
            }
        };
        let join = slot as u32;
        // One count per member, and one more so it cannot fire before all are watched.
        self.joins[slot] = Some(Join {
            target,
            then,
            delay,
            remaining: members.len() as u32 + 1,
            never: false,
        });
        self.block(target, then);
        for &m in &members {
            let reached = match self.nodes.lookup(m) {
                Lookup::Gone(Fate::Terminated) => Some(true),
                Lookup::Gone(_) => Some(false),
                Lookup::Live => {
                    let w = self.node(m);
                    w.reached(facet, point).then(|| !w.alive())
                }
            };
            match reached {
                Some(by_termination) => self.join_reached(join, by_termination),
                None => self.node_mut(m).waiters.push(Waiter {
                    facet,
                    point,
                    kind: WaitKind::Join { join, then },
                    outcome: None,
                }),
            }
        }
        self.join_reached(join, false);
    }

    /// One member of group trigger `join` reached its event: the last one fires the trigger.
    pub(super) fn join_reached(&mut self, join: u32, by_termination: bool) {
        let Some(Some(j)) = self.joins.get_mut(join as usize) else {
            return;
        };
        j.never |= by_termination && j.then == Then::Terminate;
        j.remaining = j.remaining.saturating_sub(1);
        if j.remaining > 0 {
            return;
        }
        let Some(j) = self.joins[join as usize].take() else {
            return;
        };
        if j.never {
            return;
        }
        self.fire(
            WaitKind::Trigger {
                target: j.target,
                then: j.then,
                delay: Delay::of(j.delay),
            },
            false,
        );
    }
}
