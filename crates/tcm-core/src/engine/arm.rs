//! Constraint arming: every synchronisation constraint, applied by one code path.
//!
//! A timed or event-driven constraint is a *trigger*: when something happens ([`When`]), do something
//! ([`Then`]): enable a facet (`disable … until`), terminate the node, or activate a monitor
//! (docs/semantics.md, "Constraints"). [`Engine::arm`] applies one trigger in four steps:
//!
//! 1. What `then` needs of the node: enabling the expansion of a node that does not expand, or
//!    activating a node that is not a monitor, makes the constraint void (traced, then dropped).
//! 2. `when` is made absolute: `In(d)` becomes `At(now + d)`, and `previous`, `this` and `parent` are
//!    resolved to a node (no `previous` makes the constraint void).
//! 3. The constraint is traced as applied (`constrained`, a `trigger` record).
//! 4. If `when` has already happened, the trigger fires now (or its delay starts now); otherwise an
//!    enabling trigger blocks its facet (one count per trigger) and a *waiter* is left where the
//!    event will come from: on the watched node, in the timer queue, or on the external event.
//!
//! Waiters fire from `transition` (in `progress.rs`), timers from `handle_timeout`, external
//! events from `handle_external`. Firing is `fire_trigger`: enabling decrements the block count and
//! queues progress of the target; terminating queues a termination; activating makes an activation.
//! The shorthands (`sequential`, `serial`) are lowered to enabling triggers here too.

use super::node::Node;
use super::node::{Delay, WaitKind, Waiter};
use super::timers::TimerKind;
use super::{Effect, Engine, EngineError, WatchOutcome, Work};
use crate::NodeKind;
use crate::arena::Keep;
use crate::arena::{Fate, Lookup};
use crate::constraint::{Constraint, Event, NodeRef, Then, When};
use crate::ids::{ExternalId, NodeId, WatchToken};
use crate::time::Time;
use std::time::Duration;
use tcm_trace::{
    Facet, Outcome, Point, State, TraceConstraint, TraceEventRef, TraceKind, TraceThen, TraceWhen,
};

/// A named external event (or manual signal gate).
#[derive(Clone)]
pub(super) struct External {
    pub(super) name: String,
    pub(super) raised: bool,
    /// Latched triggers (enable, terminate): fired by the first raise, or at once once raised.
    pub(super) waiters: Vec<WaitKind>,
    /// Monitors activated on every raise.
    pub(super) activators: Vec<NodeId>,
}

/// A group trigger as given ([`Engine::trigger_group`]), kept on a reservation until its spawn.
#[derive(Clone)]
pub(crate) struct GroupTrigger {
    pub(super) members: Vec<NodeId>,
    pub(super) facet: Facet,
    pub(super) point: Point,
    pub(super) delay: Option<Duration>,
    pub(super) then: Then,
}

/// A trigger on a whole group: it fires once `remaining` members reached their event.
#[derive(Clone)]
pub(super) struct Join {
    pub(super) target: NodeId,
    pub(super) then: Then,
    pub(super) delay: Option<Duration>,
    pub(super) remaining: u32,
    // A member reached its event because it was terminating: a termination never fires.
    pub(super) never: bool,
}

impl Then {
    /// How the trace writes it.
    fn traced(self) -> TraceThen {
        match self {
            Then::Enable(f) => TraceThen::Enable(f),
            Then::Terminate => TraceThen::Terminate,
            Then::Activate => TraceThen::Activate,
        }
    }

    /// The word for it in a void constraint's reason.
    fn word(self) -> String {
        match self {
            Then::Enable(f) => f.to_string(),
            Then::Terminate => "terminate".into(),
            Then::Activate => "activate".into(),
        }
    }
}

fn nanos(d: Duration) -> u64 {
    u64::try_from(d.as_nanos()).unwrap_or(u64::MAX)
}

impl<A, F: Clone, S: Keep<Node<A, F>>> Engine<A, F, S> {
    /// Applies a constraint to a node that already exists. Termination constraints apply at any time
    /// before the node completes; enablement constraints only while their facet is still disabled.
    pub fn constrain(&mut self, now: Time, node: NodeId, c: Constraint) -> Result<(), EngineError> {
        self.advance(now);
        let n = self.live(node)?;
        if n.kind == NodeKind::Root {
            return Err(EngineError::Root("constrained"));
        }
        self.validate_refs(&c)?;
        if n.reserved {
            // A constraint statement on a task spawned later (a forward reference): kept until the
            // spawn, so it is applied with the spawn's own constraints.
            let parent = n.parent.unwrap_or(self.root);
            let previous = self.nodes.get(parent).and_then(|p| p.last_spawned);
            self.node_mut(node).cold_mut().deferred.push((c, previous));
            return Ok(());
        }
        let gated: &[Facet] = match c {
            Constraint::ExpandFirst => &[Facet::Execution],
            Constraint::DelayExpansion => &[Facet::Expansion],
            Constraint::Sequential(f, _) | Constraint::Trigger(_, Then::Enable(f)) => match f {
                Facet::Handling => &[Facet::Handling],
                Facet::Expansion => &[Facet::Expansion],
                Facet::Execution => &[Facet::Execution],
            },
            Constraint::Serial(_) => &[Facet::Expansion, Facet::Execution],
            Constraint::Parallel | Constraint::Trigger(_, Then::Terminate | Then::Activate) => &[],
        };
        for &f in gated {
            if f == Facet::Expansion && !n.kind.expands() {
                continue; // Void for a node that does not expand (see `arm`).
            }
            if n.state(f) != State::Disabled || n.state(Facet::Handling) != State::Disabled {
                return Err(EngineError::TooLate {
                    node: n.display,
                    name: n.name.to_string(),
                    facet: f,
                    constraint: format!("{c:?}"),
                });
            }
        }
        let parent = n.parent.unwrap_or(self.root);
        let previous = self
            .nodes
            .get(parent)
            .and_then(|p| p.last_spawned)
            .filter(|p| *p != node);
        self.apply(node, parent, previous, c);
        self.queue_progress(node);
        self.settle();
        Ok(())
    }

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
    pub(super) fn arm_group(&mut self, target: NodeId, g: GroupTrigger) {
        let GroupTrigger {
            members,
            facet,
            point,
            delay,
            then,
        } = g;
        if then == Then::Activate && self.node(target).monitor().is_none() {
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
    fn join_reached(&mut self, join: u32, by_termination: bool) {
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
        self.advance(now);
        let Some(ext) = self.externals.get_mut(event.0 as usize) else {
            return;
        };
        let first = !ext.raised;
        ext.raised = true;
        let name = ext.name.clone();
        let waiters = std::mem::take(&mut ext.waiters);
        let activators = ext.activators.clone();
        emit!(self, TraceKind::External { name });
        if first {
            for w in waiters {
                self.fire(w, false);
            }
        }
        for monitor in activators {
            self.activation_due(monitor);
        }
        self.settle();
    }

    /// Input: `node`'s action runs on another process of a distributed system, the agent
    /// `agent` (the shell's distribution layer says so when it sends the action there). Changes
    /// nothing but the trace: a `placed` record.
    pub fn note_placed(&mut self, now: Time, node: NodeId, agent: &str) -> Result<(), EngineError> {
        self.advance(now);
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

    /// A constraint naming a node handle of another run is refused before anything is applied.
    pub(super) fn validate_refs(&self, c: &Constraint) -> Result<(), EngineError> {
        let r = match c {
            Constraint::Sequential(_, r) | Constraint::Serial(r) => Some(*r),
            Constraint::Trigger(when, _) => when.event().map(|e| e.node),
            _ => None,
        };
        if let Some(NodeRef::Node(id)) = r {
            self.check_run(id)?;
        }
        Ok(())
    }

    fn resolve(
        &self,
        r: NodeRef,
        this: NodeId,
        parent: NodeId,
        previous: Option<NodeId>,
    ) -> Option<NodeId> {
        match r {
            NodeRef::Node(id) => Some(id),
            NodeRef::Previous => previous,
            NodeRef::This => Some(this),
            NodeRef::Parent => Some(parent),
        }
    }

    /// Traces a constraint that was dropped; the reason is only built when someone reads the trace.
    fn void(&mut self, node: NodeId, reason: impl FnOnce() -> String) {
        if !self.tracing {
            return;
        }
        let display = self.node(node).display;
        emit!(
            self,
            TraceKind::ConstraintVoid {
                node: display,
                reason: reason(),
            }
        );
    }

    /// Traces a constraint as applied.
    fn constrained(&mut self, node: NodeId, constraint: impl FnOnce() -> TraceConstraint) {
        if !self.tracing {
            return;
        }
        let display = self.node(node).display;
        emit!(
            self,
            TraceKind::Constrained {
                node: display,
                constraint: constraint(),
            }
        );
    }

    /// Applies one constraint to `node` (already in the arena). `previous` is the sibling spawned
    /// just before it, for `previous` references.
    pub(super) fn apply(
        &mut self,
        node: NodeId,
        parent: NodeId,
        previous: Option<NodeId>,
        c: Constraint,
    ) {
        match c {
            Constraint::Parallel => {}
            Constraint::ExpandFirst => {
                self.node_mut(node).expand_first = true;
                self.constrained(node, || TraceConstraint::ExpandFirst);
            }
            Constraint::DelayExpansion => {
                self.node_mut(node).delay_expansion = true;
                self.constrained(node, || TraceConstraint::DelayExpansion);
            }
            Constraint::Sequential(facet, r) => {
                let when = When::Event(Event::on(r, facet, Point::Completed));
                self.arm(node, parent, previous, when, Then::Enable(facet));
            }
            Constraint::Serial(r) => {
                let when = When::Event(Event::on(r, Facet::Execution, Point::Completed));
                // On a command the expansion half is void (`arm`, step 1): only a trace would
                // tell, so it is skipped when nothing is traced.
                if self.tracing || self.node(node).kind.expands() {
                    self.arm(node, parent, previous, when, Then::Enable(Facet::Expansion));
                }
                self.arm(node, parent, previous, when, Then::Enable(Facet::Execution));
            }
            Constraint::Trigger(when, then) => self.arm(node, parent, previous, when, then),
        }
    }

    /// Arms one trigger on `node` (the module documentation's four steps).
    fn arm(
        &mut self,
        node: NodeId,
        parent: NodeId,
        previous: Option<NodeId>,
        when: When,
        then: Then,
    ) {
        // Step 1.
        match then {
            Then::Enable(Facet::Expansion) if !self.node(node).kind.expands() => {
                // A command's expansion is complete from the start (paper, footnote 1).
                return self.void(node, || {
                    "expansion of a node that does not expand is always completed".into()
                });
            }
            Then::Activate if self.node(node).monitor().is_none() => {
                return self.void(node, || "`activate` applies to monitors only".into());
            }
            _ => {}
        }
        let traced = then.traced();
        // Steps 2 to 4, per kind of `when`.
        match when {
            When::Now => {
                self.constrained(node, || TraceConstraint::trigger(TraceWhen::Now, traced));
                if then == Then::Activate {
                    // TCM's "activate at self handling active", which avoids racing the monitor's
                    // own start.
                    let event = Event::on(node, Facet::Handling, Point::Active);
                    self.arm_event(node, node, event, then, None);
                } else {
                    self.fire_trigger(node, then, false);
                }
            }
            When::At(at) => self.arm_at(node, at, then),
            When::In(d) => {
                let now = self.time();
                self.arm_at(node, now + d, then)
            }
            When::External(x) => {
                let Some(ext) = self.externals.get(x.0 as usize) else {
                    return self.void(node, || "unknown external event".into());
                };
                let (name, raised) = (ext.name.clone(), ext.raised);
                self.constrained(node, || {
                    TraceConstraint::trigger(TraceWhen::External(name), traced)
                });
                let ext = &mut self.externals[x.0 as usize];
                if then == Then::Activate {
                    // Not latched: every raise from now on activates the monitor.
                    ext.activators.push(node);
                } else if raised {
                    self.fire_trigger(node, then, false);
                } else {
                    ext.waiters.push(WaitKind::Trigger {
                        target: node,
                        then,
                        delay: Delay::NONE,
                    });
                    self.block(node, then);
                }
            }
            When::Event(ev) | When::After(_, ev) => {
                let delay = match when {
                    When::After(d, _) => Some(d),
                    _ => None,
                };
                let Some(watched) = self.resolve(ev.node, node, parent, previous) else {
                    if let Some(d) = delay {
                        // TDL: a missing `previous` drops the `after` part, the delay stays.
                        let now = self.time();
                        return self.arm_at(node, now + d, then);
                    }
                    return self.void(node, || {
                        format!(
                            "{} constraint names `previous`, but nothing was spawned before",
                            then.word()
                        )
                    });
                };
                let event = self.event_ref(watched, ev.facet, ev.point, ev.outcome);
                let passed = match self.nodes.lookup(watched) {
                    Lookup::Live => None,
                    Lookup::Gone(fate) => Some(fate),
                };
                match (passed, then) {
                    // The event is long past: an enabling trigger has nothing left to wait for.
                    (Some(_), Then::Enable(_)) => {
                        return self.void(node, || {
                            "the referenced node is already gone; its events have passed".into()
                        });
                    }
                    (Some(Fate::Terminated), Then::Terminate) => {
                        return self.void(node, || {
                            "the referenced node was terminated; its termination constraints never fire"
                                .into()
                        });
                    }
                    _ => {}
                }
                self.constrained(node, || {
                    let when = match delay {
                        Some(d) => TraceWhen::After {
                            delay_ns: nanos(d),
                            event,
                        },
                        None => TraceWhen::Event(event),
                    };
                    TraceConstraint::trigger(when, traced)
                });
                match passed {
                    Some(_) => self.fire_passed(node, then, delay),
                    None => self.arm_event(node, watched, ev, then, delay),
                }
            }
        }
    }

    /// `when` is an absolute time (step 2 made `In` one).
    fn arm_at(&mut self, node: NodeId, at: Time, then: Then) {
        self.constrained(node, || {
            TraceConstraint::trigger(TraceWhen::At(at.as_nanos()), then.traced())
        });
        // An activation due in the past still waits for the timer queue's turn, so a monitor
        // spawned with it has started by then.
        let now = self.time();
        if at > now || then == Then::Activate {
            self.block(node, then);
            self.timers
                .push(at.max(now), TimerKind::Trigger { target: node, then });
        } else {
            self.fire_trigger(node, then, false);
        }
    }

    /// `when` is an event of a live node: fires now if the node already reached it, else waits.
    fn arm_event(
        &mut self,
        node: NodeId,
        watched: NodeId,
        ev: Event,
        then: Then,
        delay: Option<Duration>,
    ) {
        let w = self.node_mut(watched);
        if then == Then::Terminate && !w.alive() {
            // Its points are reached by termination only: the constraint never fires.
            return;
        }
        if !w.reached(ev.facet, ev.point) {
            // The usual case: wait (the waiter first, while the watched node is at hand).
            w.waiters.push(Waiter {
                facet: ev.facet,
                point: ev.point,
                outcome: ev.outcome,
                kind: WaitKind::Trigger {
                    target: node,
                    then,
                    delay: Delay::of(delay),
                },
            });
            return self.block(node, then);
        }
        if ev.outcome.is_some_and(|o| o != self.outcome_of(watched)) {
            // It ended otherwise: the event never happens.
            self.block(node, then);
            return self.impossible(WaitKind::Trigger {
                target: node,
                then,
                delay: Delay::of(delay),
            });
        }
        self.fire_passed(node, then, delay);
    }

    /// The event already happened: the trigger fires now, or its delay starts now.
    fn fire_passed(&mut self, node: NodeId, then: Then, delay: Option<Duration>) {
        match delay {
            None => self.fire_trigger(node, then, false),
            Some(d) => {
                self.block(node, then);
                let now = self.time();
                self.timers
                    .push(now + d, TimerKind::Trigger { target: node, then });
            }
        }
    }

    /// An enabling trigger counts against its facet until it fires.
    fn block(&mut self, node: NodeId, then: Then) {
        if let Then::Enable(facet) = then {
            self.node_mut(node).blocks[facet.index()] += 1;
        }
    }

    /// A trigger fires. `armed`: it blocked its facet when armed (an enabling trigger fired at
    /// once never blocked it, so there is nothing to release). `by_termination`: the watched node
    /// reached the event only because it is terminating, which never fires a termination.
    pub(super) fn fire_trigger(&mut self, target: NodeId, then: Then, armed: bool) {
        match then {
            Then::Enable(facet) => {
                if armed {
                    self.satisfy(target, facet);
                }
            }
            Then::Terminate => self.work.push_back(Work::Terminate {
                node: target,
                explicit: false,
            }),
            Then::Activate => self.activation_due(target),
        }
    }

    /// One enablement constraint of `target`'s `facet` is satisfied.
    pub(super) fn satisfy(&mut self, target: NodeId, facet: Facet) {
        let Some(n) = self.nodes.get_mut(target) else {
            return;
        };
        let b = &mut n.blocks[facet.index()];
        if *b > 0 {
            *b -= 1;
        }
        self.queue_progress(target);
    }

    /// Carries out a waiter whose point was reached. `by_termination`: the watched node reached it
    /// only because it is terminating (termination constraints do not fire then; activations do,
    /// docs/semantics.md, "Termination").
    pub(super) fn fire(&mut self, kind: WaitKind, by_termination: bool) {
        match kind {
            WaitKind::Trigger {
                then: Then::Terminate,
                ..
            } if by_termination => {}
            WaitKind::Trigger {
                target,
                then,
                delay,
            } => match delay.get() {
                None => self.fire_trigger(target, then, true),
                Some(d) => {
                    // A terminating node that has not started waits for events, not for delays.
                    let forced = matches!(then, Then::Enable(_))
                        && self.nodes.get(target).is_some_and(|n| !n.alive());
                    if forced {
                        self.fire_trigger(target, then, true);
                    } else {
                        let now = self.time();
                        self.timers
                            .push(now + d, TimerKind::Trigger { target, then });
                    }
                }
            },
            WaitKind::Join { join, .. } => self.join_reached(join, by_termination),
            // Only reached through `fire_now`, which supplies the outcome.
            WaitKind::Watch { .. } => {}
        }
    }

    /// Fires a waiter of `watched` whose point has been reached.
    pub(super) fn fire_now(&mut self, watched: NodeId, kind: WaitKind) {
        let n = self.node(watched);
        let terminating = !n.alive();
        if let WaitKind::Watch { token } = kind {
            let outcome = if terminating {
                WatchOutcome::Terminated
            } else if let Some(f) = n.failure() {
                if let Some(by) = n.recovered_by() {
                    WatchOutcome::Recovered {
                        failure: f.clone(),
                        by,
                    }
                } else if n.handled() {
                    WatchOutcome::Handled(f.clone())
                } else {
                    WatchOutcome::Failed(f.clone())
                }
            } else {
                WatchOutcome::Reached
            };
            self.effects.push_back(Effect::Notify {
                token,
                outcome: Box::new(outcome),
            });
        } else {
            self.fire(kind, terminating);
        }
    }

    /// How `node` ended (or would, were its execution completing now): terminated if it is
    /// terminating, failed if its action failed and no retry recovered it, else succeeded.
    pub(super) fn outcome_of(&self, node: NodeId) -> Outcome {
        let Some(n) = self.nodes.get(node) else {
            return Outcome::Terminated;
        };
        if !n.alive() {
            Outcome::Terminated
        } else if n.failure().is_some() && n.recovered_by().is_none() {
            Outcome::Failed
        } else {
            Outcome::Succeeded
        }
    }

    /// A waiter whose outcome event can no longer happen (its node ended otherwise). An
    /// enablement would wait forever: its node is terminated instead (and the block it counted is
    /// released, so the terminated node completes without starting). A termination or an
    /// activation simply never fires.
    pub(super) fn impossible(&mut self, kind: WaitKind) {
        if let WaitKind::Trigger {
            target,
            then: Then::Enable(facet),
            ..
        } = kind
        {
            self.work.push_back(Work::Terminate {
                node: target,
                explicit: false,
            });
            self.satisfy(target, facet);
        }
    }

    fn event_ref(
        &self,
        node: NodeId,
        facet: Facet,
        point: Point,
        outcome: Option<Outcome>,
    ) -> TraceEventRef {
        TraceEventRef {
            node: self.nodes.get(node).map_or(0, |n| n.display),
            facet,
            point,
            outcome,
        }
    }
}
