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
use crate::ids::NodeId;
use crate::time::Time;
use std::time::Duration;
use tcm_trace::{
    Facet, Outcome, Point, State, TraceConstraint, TraceEventRef, TraceKind, TraceThen, TraceWhen,
};

mod external;
mod group;

pub(super) use external::External;
pub(crate) use group::GroupTrigger;
pub(super) use group::Join;

impl Then {
    /// How the trace writes it.
    pub(super) fn traced(self) -> TraceThen {
        match self {
            Then::Enable(f) => TraceThen::Enable(f),
            Then::Terminate => TraceThen::Terminate,
            Then::Activate | Then::ActivateWith(_) => TraceThen::Activate,
            Then::Skip => TraceThen::Skip,
            Then::Invariant => TraceThen::Invariant,
            Then::Pause => TraceThen::Pause,
        }
    }

    /// The word for it in a void constraint's reason.
    fn word(self) -> String {
        match self {
            Then::Enable(f) => f.to_string(),
            Then::Terminate => "terminate".into(),
            Then::Activate | Then::ActivateWith(_) => "activate".into(),
            Then::Skip => "skip".into(),
            Then::Invariant => "invariant".into(),
            Then::Pause => "pause".into(),
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
            Constraint::Approval(_) => &[Facet::Handling],
            Constraint::Parallel
            | Constraint::Trigger(
                _,
                Then::Terminate
                | Then::Activate
                | Then::ActivateWith(_)
                | Then::Skip
                | Then::Invariant
                | Then::Pause,
            ) => &[],
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
    pub(super) fn void(&mut self, node: NodeId, reason: impl FnOnce() -> String) {
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
    pub(super) fn constrained(
        &mut self,
        node: NodeId,
        constraint: impl FnOnce() -> TraceConstraint,
    ) {
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
            Constraint::Approval(within) => self.node_mut(node).cold_mut().approval = Some(within),
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
            Then::Activate | Then::ActivateWith(_) if self.node(node).monitor().is_none() => {
                return self.void(node, || "`activate` applies to monitors only".into());
            }
            Then::ActivateWith(i)
                if matches!(
                    when,
                    When::Condition(_) | When::Changed(_) | When::External(_)
                ) || self
                    .node(node)
                    .cold
                    .as_ref()
                    .map_or(0, |c| c.payloads.len())
                    <= usize::from(i) =>
            {
                return self.void(node, || {
                    "an activation carries data only at an event or a time, through \
                     `Engine::activate_when`"
                        .into()
                });
            }
            Then::Skip | Then::Invariant | Then::Pause if !matches!(when, When::Condition(_)) => {
                return self.void(node, || {
                    format!("`{}` takes a condition over state variables", then.word())
                });
            }
            _ => {}
        }
        let traced = then.traced();
        // Steps 2 to 4, per kind of `when`.
        match when {
            When::Now => {
                self.constrained(node, || TraceConstraint::trigger(TraceWhen::Now, traced));
                if then.activates() {
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
            When::Condition(c) => self.arm_condition(node, c, then),
            When::Changed(v) => self.arm_changed(node, v, then),
            When::External(x) => {
                let Some(ext) = self.externals.get(x.0 as usize) else {
                    return self.void(node, || "unknown external event".into());
                };
                let (name, raised) = (ext.name.clone(), ext.raised);
                self.constrained(node, || {
                    TraceConstraint::trigger(TraceWhen::External(name), traced)
                });
                let ext = &mut self.externals[x.0 as usize];
                if then.activates() {
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
        if at > now || then.activates() {
            self.block(node, then);
            self.timers
                .push(at.max(now), TimerKind::Trigger { target: node, then });
        } else {
            self.fire_trigger(node, then, false);
        }
    }

    /// `when` is an event of a live node: fires now if the node already reached it, else waits.
    pub(super) fn arm_event(
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
    pub(super) fn block(&mut self, node: NodeId, then: Then) {
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
            Then::Activate => {
                self.activation_due(target);
            }
            Then::ActivateWith(i) => {
                let data = self
                    .nodes
                    .get(target)
                    .and_then(|n| n.cold.as_ref()?.payloads.get(usize::from(i)).cloned());
                if let (Some(act), Some(data)) = (self.activation_due(target), data) {
                    self.node_mut(act).cold_mut().data = Some(data);
                }
            }
            // Never armed as a waiter or a timer: `state.rs` acts on these itself.
            Then::Skip | Then::Invariant | Then::Pause => {}
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
            } else if n.skipped() {
                WatchOutcome::Skipped
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
        } else if n.skipped() {
            Outcome::Skipped
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
