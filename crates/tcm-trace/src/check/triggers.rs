//! The checker's side of triggers: every `constrained` record's trigger, the enabling ones checked
//! when their facet becomes enabled ([`Rule::Disable`]), the terminating ones owed as terminations
//! and verified when they fall due ([`Rule::Terminate`]). Activations are checked per activation
//! record ([`Rule::Activation`]), not here.

use super::{Checker, Rule, ref_text, secs};
use crate::event::{TraceConstraint, TraceEvent, TraceEventRef, TraceKind, TraceThen, TraceWhen};
use crate::replay::ReplayNode;
use crate::state::{Facet, Outcome, State, Termination};
use std::cmp::Reverse;

/// A termination that a `terminate` trigger made due.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(super) struct Owed {
    due: u64,
    // `seq` of the record that made it due (keeps the heap order deterministic).
    seq: u64,
    node: u64,
    // Whether the trace owes it even if it ends at `due` (true for terminations due at once).
    owed_at_end: bool,
}

/// A `terminate` trigger waiting for its event.
#[derive(Clone, Debug)]
pub(super) struct Watch {
    target: u64,
    facet: Facet,
    state: State,
    // `None` for `terminate at <event>`, the delay for `terminate in <delay> after <event>`.
    delay: Option<u64>,
    // For a member of a group trigger: the index of its `GroupWatch`.
    group: Option<usize>,
    // An outcome event: it happens only if the node ends with it.
    outcome: Option<Outcome>,
}

/// A `terminate` trigger on a whole group: it is owed once every member reached its event, and
/// never if one reached it because it was terminating.
#[derive(Clone, Debug)]
pub(super) struct GroupWatch {
    target: u64,
    delay: Option<u64>,
    remaining: usize,
    never: bool,
}

impl Checker {
    pub(super) fn check_constrained(
        &mut self,
        ev: &TraceEvent,
        node: u64,
        constraint: &TraceConstraint,
    ) {
        let seq = ev.seq;
        self.report.n_constraints += 1;
        let late_ok = matches!(
            constraint,
            TraceConstraint::Trigger {
                then: TraceThen::Terminate
                    | TraceThen::Activate
                    | TraceThen::Invariant
                    | TraceThen::Pause,
                ..
            }
        );
        // An enablement of a facet still disabled (a constraint statement on a node its parent's
        // body holds, after the spawn) can still take effect: it is not late.
        let still_disabled = match constraint {
            TraceConstraint::Trigger {
                then: TraceThen::Enable(facet),
                ..
            } => self
                .replay
                .node(node)
                .is_some_and(|n| n.state(*facet) == crate::state::State::Disabled),
            _ => false,
        };
        if !late_ok && !still_disabled && self.window != Some(node) {
            let msg = format!(
                "an enablement constraint ({constraint:?}) is applied to {} after its spawn records; only \
                 `terminate` and `activate` triggers may come later",
                self.name(node)
            );
            self.flag(seq, Some(node), Rule::LateConstraint, msg);
        }
        if let Some(r) = constraint.event() {
            if self.replay.node(r.node).is_none() && r.node != node {
                let msg = format!(
                    "the constraint waits for {}, a node never seen in the trace",
                    ref_text(&r)
                );
                self.flag(seq, Some(node), Rule::UnknownReference, msg);
                return;
            }
        }
        if let TraceConstraint::Trigger {
            when: TraceWhen::Condition(cond),
            then,
        } = constraint
        {
            return self.condition_applied(ev, node, cond, *then);
        }
        let TraceConstraint::Trigger {
            when,
            then: TraceThen::Terminate,
        } = constraint
        else {
            return;
        };
        match when {
            // Handled above; `on change of` only activates.
            TraceWhen::Condition(_) | TraceWhen::Changed(_) => {}
            TraceWhen::Now => self.owe(node, ev.t, true, seq),
            TraceWhen::At(at) => self.owe(node, (*at).max(ev.t), *at <= ev.t, seq),
            TraceWhen::External(name) => {
                if self.externals.contains(name) {
                    self.owe(node, ev.t, true, seq);
                } else {
                    self.external_watches
                        .entry(name.clone())
                        .or_default()
                        .push(node);
                }
            }
            TraceWhen::Event(event) => self.watch(ev, node, event, None, None),
            TraceWhen::After { delay_ns, event } => {
                self.watch(ev, node, event, Some(*delay_ns), None)
            }
            TraceWhen::All { events, delay_ns } => self.watch_group(ev, node, events, *delay_ns),
        }
    }

    // A `terminate` trigger on a whole group: owed once every member's event happened.
    fn watch_group(
        &mut self,
        ev: &TraceEvent,
        node: u64,
        events: &[TraceEventRef],
        delay: Option<u64>,
    ) {
        let g = self.groups.len();
        self.groups.push(GroupWatch {
            target: node,
            delay,
            remaining: events.len() + 1,
            never: false,
        });
        for event in events {
            self.watch(ev, node, event, delay, Some(g));
        }
        // The extra count keeps the group from firing before all members are watched.
        self.group_reached(ev, g, false);
    }

    // One member of group `g` reached its event (`by_termination`: because it was terminating).
    fn group_reached(&mut self, ev: &TraceEvent, g: usize, by_termination: bool) {
        let Some(gw) = self.groups.get_mut(g) else {
            return;
        };
        gw.never |= by_termination;
        gw.remaining = gw.remaining.saturating_sub(1);
        if gw.remaining == 0 && !gw.never {
            let (target, d) = (gw.target, gw.delay.unwrap_or(0));
            self.owe(target, ev.t.saturating_add(d), d == 0, ev.seq);
        }
    }

    // A `terminate` trigger on `node` waiting for `event`: owed now, never, or watched. For a
    // member of a group trigger, its group counts it instead.
    fn watch(
        &mut self,
        ev: &TraceEvent,
        node: u64,
        event: &TraceEventRef,
        delay: Option<u64>,
        group: Option<usize>,
    ) {
        let delay_ns = delay.unwrap_or(0);
        let Some(r) = self.replay.node(event.node) else {
            if let Some(g) = group {
                self.group_reached(ev, g, true);
            }
            return;
        };
        let passed = r.is_dead() || r.reached_at(event.facet, event.point).is_some();
        if r.termination() != Termination::Alive && !r.is_dead() {
            // A termination whose event's node is terminating never fires (docs/semantics.md,
            // "Termination").
            if let Some(g) = group {
                self.group_reached(ev, g, true);
            }
        } else if passed && event.outcome.is_some_and(|o| o != r.outcome()) {
            // It ended otherwise: the outcome event never happens.
        } else if passed {
            match group {
                Some(g) => self.group_reached(ev, g, false),
                None => self.owe(node, ev.t.saturating_add(delay_ns), delay_ns == 0, ev.seq),
            }
        } else {
            self.watches.entry(event.node).or_default().push(Watch {
                target: node,
                facet: event.facet,
                state: event.point.state(),
                delay,
                group,
                outcome: event.outcome,
            });
        }
    }

    // Records that `node` must be terminating by the end of the records at time `due`, unless it has
    // completed its execution or is terminating already.
    fn owe(&mut self, node: u64, due: u64, owed_at_end: bool, seq: u64) {
        let Some(n) = self.replay.node(node) else {
            return;
        };
        if n.termination() != Termination::Alive || n.state(Facet::Execution) == State::Completed {
            return;
        }
        self.owed.push(Reverse(Owed {
            due,
            seq,
            node,
            owed_at_end,
        }));
    }

    // Verifies the terminations due before `now` (all of them at the end of the trace, `now == None`).
    pub(super) fn settle_owed(&mut self, now: Option<u64>, seq: u64) {
        let end_t = self.last.map_or(0, |(_, t)| t);
        while let Some(Reverse(top)) = self.owed.peek() {
            if now.is_some_and(|t| top.due >= t) {
                return;
            }
            let Some(Reverse(owed)) = self.owed.pop() else {
                return;
            };
            let Some(n) = self.replay.node(owed.node) else {
                continue;
            };
            let done = n.termination() != Termination::Alive
                || n.state(Facet::Execution) == State::Completed
                || n.is_reclaimed();
            // At the end of the trace, a timer due at (or after) the last record's time is not owed yet.
            // In a prefix, even a termination due at once may be among the records cut at that time.
            let owed_now = now.is_some() || (owed.owed_at_end && !self.prefix) || owed.due < end_t;
            if done || owed_now {
                self.report.n_terminations_checked += 1;
            }
            if !done && owed_now {
                let msg = format!(
                    "{} should be terminating by t={} (made due by the record with seq {}), but it is still \
                     alive and its execution is {}",
                    self.name(owed.node),
                    secs(owed.due),
                    owed.seq,
                    n.state(Facet::Execution)
                );
                self.flag(seq, Some(owed.node), Rule::Terminate, msg);
            }
        }
    }

    // Whether constraint `c` of node `n` still forbade `facet` from becoming enabled at `ev`.
    pub(super) fn constraint_blocks(
        &self,
        ev: &TraceEvent,
        n: &ReplayNode,
        facet: Facet,
        c: &TraceConstraint,
    ) -> Option<(Rule, String)> {
        let problem = match c {
            TraceConstraint::Trigger {
                when,
                then: TraceThen::Enable(f),
            } if *f == facet => self.trigger_pending(
                ev,
                Some(n.number()),
                when,
                n.termination() != Termination::Alive,
            )?,
            TraceConstraint::ExpandFirst if facet == Facet::Execution => {
                return (n.state(Facet::Expansion) != State::Completed).then(|| {
                    let state = n.state(Facet::Expansion);
                    let msg = format!("`expand first`, but the expansion is {state}");
                    (Rule::ExpandFirst, msg)
                });
            }
            TraceConstraint::DelayExpansion if facet == Facet::Expansion => {
                return (n.state(Facet::Execution) < State::Enabled).then(|| {
                    let state = n.state(Facet::Execution);
                    let msg = format!("`delay expansion`, but the execution is {state}");
                    (Rule::DelayExpansion, msg)
                });
            }
            _ => return None,
        };
        Some((Rule::Disable, problem))
    }

    // What an enabling trigger still waits for at `ev`, if it has not fired. A terminating node
    // that has not started waits only for other nodes' events: its delays and external events are
    // released (docs/semantics.md, "Termination").
    pub(super) fn trigger_pending(
        &self,
        ev: &TraceEvent,
        node: Option<u64>,
        when: &TraceWhen,
        terminating: bool,
    ) -> Option<String> {
        match when {
            TraceWhen::Now | TraceWhen::Changed(_) => None,
            TraceWhen::At(_) | TraceWhen::External(_) | TraceWhen::Condition(_) if terminating => {
                None
            }
            TraceWhen::Condition(cond) => self.condition_pending(node, cond),
            TraceWhen::At(at) => {
                (ev.t < *at).then(|| format!("it is disabled until t={}", secs(*at)))
            }
            TraceWhen::External(name) => (!self.externals.contains(name))
                .then(|| format!("it waits for the external event `{name}`, not raised yet")),
            TraceWhen::Event(event) => {
                let r = self.replay.node(event.node);
                let ok = r.is_some_and(|r| {
                    r.is_dead() || r.reached_at(event.facet, event.point).is_some()
                });
                let ended = r.map(|r| r.outcome());
                match event.outcome {
                    // It ended otherwise: the node can only be terminated, never started.
                    Some(o) if ok && ended != Some(o) && !terminating => Some(format!(
                        "it waits for {} to end {}, but it ended {}",
                        ref_text(event),
                        o.as_str(),
                        ended.map_or("otherwise", |e| e.as_str())
                    )),
                    _ => (!ok).then(|| {
                        format!("it waits for {}, which has not happened", ref_text(event))
                    }),
                }
            }
            TraceWhen::All { events, delay_ns } => {
                let mut last = 0;
                for event in events {
                    let since = self.replay.node(event.node).and_then(|r| {
                        r.dead_at()
                            .or_else(|| r.reached_at(event.facet, event.point))
                    });
                    match since {
                        Some(s) => last = last.max(s),
                        None => {
                            return Some(format!(
                                "it waits for every member of a group, and {} has not happened",
                                ref_text(event)
                            ));
                        }
                    }
                }
                let until = last.saturating_add(delay_ns.unwrap_or(0));
                (ev.t < until && !terminating)
                    .then(|| format!("it waits for a group's event, until t={}", secs(until)))
            }
            TraceWhen::After { delay_ns, event } => {
                let since = self.replay.node(event.node).and_then(|r| {
                    r.dead_at()
                        .or_else(|| r.reached_at(event.facet, event.point))
                });
                let delay = secs(*delay_ns);
                match since {
                    Some(_) if terminating => None,
                    None => Some(format!(
                        "it waits {delay} after {}, which has not happened",
                        ref_text(event)
                    )),
                    Some(s) if ev.t < s.saturating_add(*delay_ns) => Some(format!(
                        "it waits {delay} after {} (at t={}), until t={}",
                        ref_text(event),
                        secs(s),
                        secs(s.saturating_add(*delay_ns))
                    )),
                    Some(_) => None,
                }
            }
        }
    }

    // Fires the `terminate` triggers the record's event sets off.
    pub(super) fn after_record(&mut self, ev: &TraceEvent) {
        match &ev.kind {
            TraceKind::Transition {
                node,
                facet,
                from,
                to,
            } => {
                let Some(mut watches) = self.watches.remove(node) else {
                    return;
                };
                // Termination triggers do not fire on points reached because the node was terminating.
                let terminating = self
                    .replay
                    .node(*node)
                    .is_some_and(|n| n.termination() != Termination::Alive);
                let outcome = self.replay.node(*node).map(|n| n.outcome());
                let mut keep = Vec::new();
                for w in watches.drain(..) {
                    if w.facet == *facet && *from < w.state && w.state <= *to {
                        if w.outcome.is_some() && w.outcome != outcome {
                            // It ended otherwise: the outcome event never happens.
                            continue;
                        }
                        match w.group {
                            Some(g) => self.group_reached(ev, g, terminating),
                            None if !terminating => self.fire_watch(ev, &w),
                            None => {}
                        }
                    } else {
                        keep.push(w);
                    }
                }
                if !keep.is_empty() {
                    self.watches.insert(*node, keep);
                }
            }
            TraceKind::Dead { node } => {
                if let Some(watches) = self.watches.remove(node) {
                    for w in &watches {
                        self.fire_watch(ev, w);
                    }
                }
            }
            TraceKind::StateSet { .. } => self.state_set(ev),
            TraceKind::External { name } => {
                self.externals.insert(name.clone());
                if let Some(targets) = self.external_watches.remove(name) {
                    for target in targets {
                        self.owe(target, ev.t, true, ev.seq);
                    }
                }
            }
            _ => {}
        }
    }

    /// A termination due now, made due by record `ev`.
    pub(super) fn owe_now(&mut self, node: u64, ev: &TraceEvent) {
        self.owe(node, ev.t, true, ev.seq);
    }

    fn fire_watch(&mut self, ev: &TraceEvent, w: &Watch) {
        if let Some(g) = w.group {
            return self.group_reached(ev, g, false);
        }
        let d = w.delay.unwrap_or(0);
        self.owe(w.target, ev.t.saturating_add(d), d == 0, ev.seq);
    }
}
