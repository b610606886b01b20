//! Monitors (TDL paper, "Task Trees" and Figure 6; docs/semantics.md, "Monitors").
//!
//! A monitor is a command-like node with no action of its own. While its handling is active, each
//! *activation* inserts a child command node (`ACT-<monitor>`) that runs the monitor's body, from a
//! factory the shell gave at spawn. Activations come from a polling period, `activate` constraints,
//! external events and explicit [`Engine::activate`] calls.
//!
//! Protocol:
//! 1. The monitor's handling becomes active like any node's; instead of an action it records its
//!    start time and, if polling, activates at once (unless `initial_wait`) and arms a timer for
//!    `start + period`.
//! 2. A polling timer `k` fires at exactly `start + k * period` (absolute deadlines: no drift), makes
//!    one activation and arms `k + 1` while the monitor's handling is active.
//! 3. An activation counts itself when created; reaching `max_activations` completes the monitor's
//!    handling at once (the last activation still runs). A `trigger` from a body counts; reaching
//!    `max_triggers` completes it too. A completed monitor makes no more activations; its execution
//!    completes when its running activations' subtrees do.
//! 4. Terminating a monitor terminates its running activations with it, like any subtree.
//! 5. Its maxima and period can change after its spawn ([`Engine::set_max_activations`],
//!    [`Engine::set_max_triggers`], [`Engine::set_period`]: TDL's constraint statements), traced as
//!    a new `monitor_params` record. A maximum already reached completes the monitor's handling at
//!    once; a new period counts from the poll already due.
//! 6. A poll that falls due while the monitor's last activation has not completed its execution
//!    is an *overrun*, handled by the monitor's [`Overrun`] policy: made at once (`Burst`, the
//!    default), dropped (`Skip`), or held until that activation completes and made then, the
//!    schedule restarting from that instant (`Delay`; the polls missed meanwhile make that one
//!    activation). A held poll arms no timer; [`Engine::activation_ended`] makes it.

use super::node::Node;
use super::node::{Payload, Purpose};
use super::timers::TimerKind;
use super::{Engine, EngineError};
use crate::arena::Keep;
use crate::constraint::{Constraint, NodeRef, Then, When};
use crate::ids::NodeId;
use crate::time::Time;
use crate::{Name, NodeKind};
use std::time::Duration;
use tcm_trace::{Facet, State, TraceKind};

/// Constraints between successive activations of one monitor (docs/semantics.md, "Monitors").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EachActivation {
    /// Each activation starts (expansion and execution) after the previous one's execution completed.
    pub serial: bool,
    /// Each activation's execution waits for the previous one's execution.
    pub sequential_execution: bool,
    /// Each activation's expansion waits for the previous one's expansion.
    pub sequential_expansion: bool,
    /// `expand first` on every activation.
    pub expand_first: bool,
    /// `delay expansion` on every activation.
    pub delay_expansion: bool,
}

/// What a polling monitor does with a poll that falls due while its last activation has not
/// completed its execution (docs/semantics.md, "Monitors", rule 7). Activations made otherwise
/// (constraints, events, explicit calls) are never held or dropped.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Overrun {
    /// Every poll makes its activation when it falls due. Without `serial`, activations overlap;
    /// with it, those due while one ran wait for it, then start one after the other at the
    /// instant it completed (a catch-up burst).
    #[default]
    Burst,
    /// A poll due while the last activation runs makes no activation; the next poll comes on the
    /// schedule. Polling stays on `start + k × period` and activations never overlap: what a
    /// ticking tree does with the ticks a long tick missed.
    Skip,
    /// A poll due while the last activation runs is held until it completes, and made then (the
    /// polls missed meanwhile make that one activation); the schedule restarts from that
    /// instant, one period per poll. Activations never overlap.
    Delay,
}

/// How a monitor behaves; given at spawn (`Spawn::monitor`).
#[derive(Clone, Debug)]
pub struct MonitorSpec<F> {
    /// The body's factory, invoked once per activation.
    pub body: F,
    /// The monitor completes after this many activations.
    pub max_activations: Option<u32>,
    /// The monitor completes after this many triggers.
    pub max_triggers: Option<u32>,
    /// Polling period: one activation every period, on absolute deadlines.
    pub period: Option<Duration>,
    /// Skip the polling activation at start.
    pub initial_wait: bool,
    /// Constraints between successive activations.
    pub each: EachActivation,
    /// What a poll due while the last activation runs does. Not in the `monitor_params` record.
    pub overrun: Overrun,
    /// Name of activation nodes; default `ACT-<monitor name>`.
    pub activation_name: Option<Name>,
}

impl<F> MonitorSpec<F> {
    /// The `monitor_params` record of a monitor with this spec, node `display`.
    pub(crate) fn traced(&self, display: u64) -> TraceKind {
        TraceKind::MonitorParams {
            node: display,
            max_activations: self.max_activations,
            max_triggers: self.max_triggers,
            period_ns: self
                .period
                .map(|p| u64::try_from(p.as_nanos()).unwrap_or(u64::MAX)),
            initial_wait: self.initial_wait,
        }
    }

    /// Sets the period; returns the previous one.
    fn replace_period(&mut self, period: Duration) -> Option<Duration> {
        self.period.replace(period)
    }

    /// A monitor with no limits and no period: it runs until terminated, activated by constraints,
    /// events or explicit calls.
    pub fn new(body: F) -> MonitorSpec<F> {
        MonitorSpec {
            body,
            max_activations: None,
            max_triggers: None,
            period: None,
            initial_wait: false,
            each: EachActivation::default(),
            overrun: Overrun::Burst,
            activation_name: None,
        }
    }
}

#[derive(Clone)]
pub(crate) struct Monitor<F> {
    pub(crate) spec: MonitorSpec<F>,
    pub(crate) activations: u32,
    pub(crate) triggers: u32,
    pub(crate) last: Option<NodeId>,
    /// Polling schedule: poll `k` is due at `anchor.0 + (k - anchor.1) × period`. The anchor is the
    /// start (poll 0) until the period changes, then the poll that was due next.
    pub(crate) anchor: (Time, u64),
    /// The poll whose timer is armed, or the poll held (`held`).
    pub(crate) next_poll: u64,
    /// Under [`Overrun::Delay`]: poll `next_poll` fell due while the last activation ran and waits
    /// for it to complete; no poll timer is armed meanwhile.
    pub(crate) held: bool,
}

impl<F> Monitor<F> {
    pub(crate) fn new(spec: MonitorSpec<F>) -> Monitor<F> {
        Monitor {
            spec,
            activations: 0,
            triggers: 0,
            last: None,
            anchor: (Time::ZERO, 0),
            next_poll: 0,
            held: false,
        }
    }

    /// When poll `k` is due with period `p`.
    fn poll_due(&self, p: Duration, k: u64) -> Time {
        let (at, k0) = self.anchor;
        at.saturating_add(p.saturating_mul(u32::try_from(k - k0).unwrap_or(u32::MAX)))
    }
}

impl<A, F: Clone, S: Keep<Node<A, F>>> Engine<A, F, S> {
    /// Activates a monitor now. Returns the activation node, or `None` if the monitor already
    /// reached its maximum. Activating a monitor whose handling is not active is an error (and a
    /// warning in the trace).
    pub fn activate(&mut self, now: Time, monitor: NodeId) -> Result<Option<NodeId>, EngineError> {
        self.advance(now);
        let n = self.live(monitor)?;
        if n.monitor().is_none() {
            return Err(EngineError::NotAMonitor(n.display));
        }
        if n.state(Facet::Handling) != State::Active || !n.alive() {
            let display = n.display;
            self.inactive_monitor_warning(monitor);
            return Err(EngineError::InactiveMonitor(display));
        }
        let id = self.make_activation(monitor);
        self.settle();
        Ok(id)
    }

    /// Activates `monitor` when `when` happens, that activation carrying `data` (TCM's
    /// `TCM_ActivateAt(monitor, event, data)`, `TCM_ActivateIn(monitor, delay, data)`): the
    /// activation node's [`Engine::activation_data`]. `when` is an event, a time or a delay
    /// (`When::Now`, `At`, `In`, `Event`, `After`); an activation made by a condition, a change or
    /// an external event carries no data of its own, and is refused. As for a `activate`
    /// constraint otherwise: a trigger that fires after the monitor's maximum makes no activation,
    /// and one applied to a monitor that is not handling yet waits for it.
    pub fn activate_when(
        &mut self,
        now: Time,
        monitor: NodeId,
        when: When,
        data: std::sync::Arc<dyn std::any::Any + Send + Sync>,
    ) -> Result<(), EngineError> {
        // One input: `constrain` advances the engine.
        let n = self.live(monitor)?;
        if n.monitor().is_none() {
            return Err(EngineError::NotAMonitor(n.display));
        }
        if matches!(
            when,
            When::Condition(_) | When::Changed(_) | When::External(_)
        ) {
            return Err(EngineError::ActivationData(
                "an activation by a condition, a change or an external event carries no data of \
                 its own (an external event raised with data gives it to each activation)",
            ));
        }
        let payloads = &mut self.node_mut(monitor).cold_mut().payloads;
        let Ok(i) = u16::try_from(payloads.len()) else {
            return Err(EngineError::ActivationData(
                "more than 65,535 activation triggers with data on one monitor",
            ));
        };
        payloads.push(data);
        self.constrain(
            now,
            monitor,
            Constraint::Trigger(when, Then::ActivateWith(i)),
        )
    }

    /// Counts a trigger of the monitor of `node` (an activation node, or the monitor itself).
    pub fn trigger(&mut self, now: Time, node: NodeId) -> Result<(), EngineError> {
        self.advance(now);
        let n = self.live(node)?;
        let monitor = n.activation_of().unwrap_or(node);
        let m = self.live(monitor)?;
        let display = m.display;
        let Some(mon) = m.monitor() else {
            return Err(EngineError::NotAMonitor(display));
        };
        if m.state(Facet::Handling) != State::Active || !m.alive() {
            // A trigger after the monitor completed changes nothing.
            return Ok(());
        }
        let (count, max) = (mon.triggers + 1, mon.spec.max_triggers);
        if let Some(mon) = self.node_mut(monitor).monitor_mut() {
            mon.triggers = count;
        }
        emit!(
            self,
            TraceKind::Triggered {
                monitor: display,
                count,
            }
        );
        if max.is_some_and(|m| count >= m) {
            self.monitor_done(monitor);
        }
        self.settle();
        Ok(())
    }

    /// Activations and triggers counted so far, for a monitor or one of its activation nodes.
    pub fn monitor_counts(&self, node: NodeId) -> Option<(u32, u32)> {
        let n = self.query(node)?;
        let m = self.nodes.get(n.activation_of().unwrap_or(node))?;
        m.monitor().map(|m| (m.activations, m.triggers))
    }

    fn inactive_monitor_warning(&mut self, monitor: NodeId) {
        let n = self.node(monitor);
        let message = format!(
            "Trying to activate an inactive monitor {} {{{}}}",
            n.name, n.display
        );
        let display = n.display;
        emit!(
            self,
            TraceKind::Warning {
                node: Some(display),
                message,
            }
        );
    }

    /// An activation source fired (timer, event, external event).
    pub(crate) fn activation_due(&mut self, monitor: NodeId) -> Option<NodeId> {
        let n = self.nodes.get(monitor)?;
        if !n.alive() || n.state(Facet::Handling) == State::Completed {
            return None;
        }
        if n.state(Facet::Handling) != State::Active {
            self.inactive_monitor_warning(monitor);
            return None;
        }
        self.make_activation(monitor)
    }

    /// The monitor's handling became active (step 1 of the protocol).
    pub(crate) fn monitor_started(&mut self, monitor: NodeId) {
        let now = self.time();
        let Some(mon) = self.node_mut(monitor).monitor_mut() else {
            return;
        };
        mon.anchor = (now, 0);
        let (period, initial_wait) = (mon.spec.period, mon.spec.initial_wait);
        if let Some(p) = period {
            if !initial_wait {
                self.make_activation(monitor);
            }
            if self.node(monitor).state(Facet::Handling) == State::Active {
                self.arm_poll(monitor, now + p, 1);
            }
        }
    }

    fn arm_poll(&mut self, monitor: NodeId, at: Time, k: u64) {
        if let Some(mon) = self.node_mut(monitor).monitor_mut() {
            mon.next_poll = k;
        }
        self.timers.push(at, TimerKind::Poll { monitor, k });
    }

    /// Whether the monitor's last activation has not completed its execution (an overrun if a
    /// poll falls due now).
    fn last_activation_runs(&self, mon: &Monitor<F>) -> bool {
        mon.last
            .and_then(|a| self.nodes.get(a))
            .is_some_and(|a| a.state(Facet::Execution) != State::Completed)
    }

    /// Polling timer `k` fired (step 2), under the monitor's overrun policy (step 6).
    pub(crate) fn poll(&mut self, monitor: NodeId, k: u64) {
        let Some(mon) = self.nodes.get(monitor).and_then(Node::monitor) else {
            return;
        };
        let overrun = mon.spec.overrun;
        let runs = overrun != Overrun::Burst && self.last_activation_runs(mon);
        match (overrun, runs) {
            (Overrun::Delay, true) => {
                if let Some(mon) = self.node_mut(monitor).monitor_mut() {
                    mon.held = true;
                    mon.next_poll = k;
                }
                return;
            }
            (Overrun::Skip, true) => {}
            _ => {
                self.activation_due(monitor);
            }
        }
        let Some(n) = self.nodes.get(monitor) else {
            return;
        };
        let Some(mon) = n.monitor() else { return };
        if n.alive() && n.state(Facet::Handling) == State::Active {
            if let Some(p) = mon.spec.period {
                let next = mon.poll_due(p, k + 1);
                self.arm_poll(monitor, next, k + 1);
            }
        }
    }

    /// The execution of node `id` completed: if it is an activation and its monitor holds a poll
    /// (step 6, `Delay`) and no activation of it runs any more, the held poll makes its
    /// activation now and the schedule restarts from now.
    pub(crate) fn activation_ended(&mut self, id: NodeId) {
        let Some(monitor) = self.nodes.get(id).and_then(Node::activation_of) else {
            return;
        };
        let Some(m) = self.nodes.get(monitor) else {
            return;
        };
        let Some(mon) = m.monitor() else { return };
        if !mon.held || self.last_activation_runs(mon) {
            return;
        }
        let active = m.alive() && m.state(Facet::Handling) == State::Active;
        let now = self.time();
        let Some(mon) = self.node_mut(monitor).monitor_mut() else {
            return;
        };
        mon.held = false;
        let (k, period) = (mon.next_poll, mon.spec.period);
        mon.anchor = (now, k);
        let Some(p) = period.filter(|_| active) else {
            return;
        };
        self.make_activation(monitor);
        if self.node(monitor).state(Facet::Handling) == State::Active {
            self.arm_poll(monitor, now + p, k + 1);
        }
    }

    /// Inserts one activation node (step 3).
    fn make_activation(&mut self, monitor: NodeId) -> Option<NodeId> {
        let m = self.node(monitor);
        let mon = m.monitor()?;
        if mon
            .spec
            .max_activations
            .is_some_and(|max| mon.activations >= max)
        {
            return None;
        }
        let number = mon.activations + 1;
        let triggers = mon.triggers;
        let prev = mon.last;
        let each = mon.spec.each;
        let body = mon.spec.body.clone();
        let name: Name = match &mon.spec.activation_name {
            Some(n) => n.clone(),
            None => Name::Owned(format!("ACT-{}", m.name)),
        };
        let max = mon.spec.max_activations;
        let monitor_display = m.display;
        if let Some(mon) = self.node_mut(monitor).monitor_mut() {
            mon.activations = number;
        }
        let payload = Payload::Invoke(
            body,
            std::sync::Arc::new(Purpose::Activation {
                monitor,
                number,
                triggers,
            }),
        );
        let id = self.insert(monitor, NodeKind::Command, name, payload);
        let propagate = self.node(monitor).propagates();
        let cold = self.node_mut(id).cold_mut();
        cold.activation_of = Some(monitor);
        // A monitor whose failure fails its parent: an activation's failure is the monitor's.
        if propagate == super::node::Propagate::Parent {
            cold.propagate = propagate;
        }
        if let Some(prev) = prev {
            let r = NodeRef::Node(prev);
            let mut cs = Vec::new();
            if each.serial {
                cs.push(Constraint::Serial(r));
            }
            if each.sequential_execution {
                cs.push(Constraint::Sequential(Facet::Execution, r));
            }
            if each.sequential_expansion {
                cs.push(Constraint::Sequential(Facet::Expansion, r));
            }
            for c in cs {
                self.apply(id, monitor, Some(prev), c);
            }
        }
        if each.expand_first {
            self.apply(id, monitor, prev, Constraint::ExpandFirst);
        }
        if each.delay_expansion {
            self.apply(id, monitor, prev, Constraint::DelayExpansion);
        }
        let display = self.node(id).display;
        emit!(
            self,
            TraceKind::Activated {
                monitor: monitor_display,
                node: display,
                number,
            }
        );
        if let Some(mon) = self.node_mut(monitor).monitor_mut() {
            mon.last = Some(id);
        }
        self.node_mut(monitor).last_spawned = Some(id);
        self.queue_progress(id);
        if max.is_some_and(|max| number >= max) {
            self.monitor_done(monitor);
        }
        Some(id)
    }

    /// The monitor reached a maximum: its handling completes; no more activations.
    pub(crate) fn monitor_done(&mut self, monitor: NodeId) {
        let Some(n) = self.nodes.get(monitor) else {
            return;
        };
        if n.state(Facet::Handling) != State::Active {
            return;
        }
        self.release_resources(monitor);
        self.transition(monitor, Facet::Handling, State::Completed);
        self.bury_reservations(monitor);
        self.queue_progress(monitor);
    }

    // ---- Limits changed after the spawn (protocol step 5).

    /// Sets a monitor's maximum activations (TDL's `maximum activate N` in a constraint statement),
    /// replacing the one it was spawned with. If the monitor's handling is active and it already
    /// made `n` activations, its handling completes now, as at a maximum reached normally
    /// (docs/semantics.md, "Monitors"). A monitor that completed, was terminated or was reclaimed
    /// is left alone.
    pub fn set_max_activations(
        &mut self,
        now: Time,
        monitor: NodeId,
        n: u32,
    ) -> Result<(), EngineError> {
        self.set_monitor_param(now, monitor, |mon, _| {
            mon.spec.max_activations = Some(n);
            None
        })
    }

    /// Sets a monitor's maximum triggers (TDL's `maximum trigger N` in a constraint statement),
    /// as [`Engine::set_max_activations`] does the maximum activations.
    pub fn set_max_triggers(
        &mut self,
        now: Time,
        monitor: NodeId,
        n: u32,
    ) -> Result<(), EngineError> {
        self.set_monitor_param(now, monitor, |mon, _| {
            mon.spec.max_triggers = Some(n);
            None
        })
    }

    /// Sets a monitor's polling period (TDL's `period T` in a constraint statement). Before the
    /// monitor starts, it simply replaces the one it was spawned with. Once it polls, the poll
    /// already due keeps its time and the following ones come every `period` after it; a running
    /// monitor that did not poll polls first one `period` from now. A monitor that completed, was
    /// terminated or was reclaimed is left alone.
    pub fn set_period(
        &mut self,
        now: Time,
        monitor: NodeId,
        period: Duration,
    ) -> Result<(), EngineError> {
        self.set_monitor_param(now, monitor, |mon, active| {
            let old = mon.spec.replace_period(period);
            match (active, old) {
                (false, _) => None,
                (true, Some(old)) => {
                    mon.anchor = (mon.poll_due(old, mon.next_poll), mon.next_poll);
                    None
                }
                (true, None) => {
                    mon.anchor = (now, 0);
                    Some(now + period)
                }
            }
        })
    }

    /// Changes the spec of the monitor `monitor` with `change` (given whether its handling is
    /// active; it returns when to arm poll 1, for a monitor that starts polling now), traces the
    /// new parameters, and completes the monitor's handling if a maximum is now reached.
    fn set_monitor_param(
        &mut self,
        now: Time,
        monitor: NodeId,
        change: impl FnOnce(&mut Monitor<F>, bool) -> Option<Time>,
    ) -> Result<(), EngineError> {
        self.advance(now);
        self.check_run(monitor)?;
        // A reclaimed monitor's limits no longer matter.
        let Some(n) = self.nodes.get(monitor) else {
            return Ok(());
        };
        let display = n.display;
        if n.monitor().is_none() {
            return Err(EngineError::NotAMonitor(display));
        }
        let handling = n.state(Facet::Handling);
        if !n.alive() || handling == State::Completed {
            return Ok(());
        }
        let active = handling == State::Active;
        let Some(mon) = self.node_mut(monitor).monitor_mut() else {
            return Ok(());
        };
        let poll = change(mon, active);
        let spec = &mon.spec;
        let reached = spec.max_activations.is_some_and(|m| mon.activations >= m)
            || spec.max_triggers.is_some_and(|m| mon.triggers >= m);
        let record = spec.traced(display);
        emit!(self, record);
        if let Some(at) = poll {
            self.arm_poll(monitor, at, 1);
        }
        if active && reached {
            self.monitor_done(monitor);
        }
        self.settle();
        Ok(())
    }
}
