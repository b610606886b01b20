//! Progress: how a node moves forward, and the engine's work loop.
//!
//! This is where "an action finished" is handled ([`Engine::handle_action_finished`]): the node's
//! handling completes (or its after-wiretaps start, or its handler bypasses), the `transition`
//! fires the waiters left by constraints (`arm.rs`), and `settle` drains the work queue: each
//! queued `progress` moves one node as far as its constraints allow, then the oldest ready node
//! starts (`start`, in `start.rs`). Timers fire here too (`handle_timeout`).
//!
//! A node's progress, in the order `progress` tries it:
//! 1. expansion, then execution, become enabled once nothing blocks them and the parent's same
//!    facet is enabled (`expand first` and `delay expansion` add their conditions);
//! 2. handling becomes enabled once its node's expansion (goal-like) or execution (command-like)
//!    is, and the node joins the ready queue (a node terminated before it started too: at its
//!    turn it completes without starting);
//! 3. expansion, then execution, complete once the handling completed and no child is open;
//! 4. a terminating node is terminated once its execution completed and its children are;
//! 5. a completed node with no children left is reclaimed, unless persistent.

use super::InputRecord;
use super::node::{Link, Node, WaitKind, Waiters};
use super::timers::TimerKind;
use super::{ChildRun, Effect, Engine, EngineError, Job, MAX_RUNS, WatchOutcome, Work};
use crate::NodeKind;
use crate::arena::Keep;
use crate::arena::{Arena, Fate};
use crate::constraint::Then;
use crate::failure::Failure;
use crate::ids::{NodeId, TapWhen};
use crate::time::Time;
use std::time::Duration;
use tcm_trace::{Facet, State, Termination, TraceKind};
use thin_vec::ThinVec;

impl<A, F: Clone, S: Keep<Node<A, F>>> Engine<A, F, S> {
    /// Input: a job the shell ran for the engine ended ([`Effect::Start`] or [`Effect::Invoke`]).
    ///
    /// For a node's action or invocation, its handling completes (failed, if `result` is a
    /// failure), unless "after" wiretaps must first approve it; a handler that asked to bypass
    /// (`request_bypass`) passes its exception on instead. For a wiretap check, see `wiretap.rs`.
    /// A job whose node was terminated meanwhile has nothing left to finish: that is not an error.
    pub fn handle_action_finished(
        &mut self,
        now: Time,
        job: impl Into<Job>,
        result: Result<(), Failure>,
    ) -> Result<(), EngineError> {
        let job = job.into();
        self.advance(now);
        let node = job.node();
        self.check_run(node)?;
        if self.inputs.is_some() {
            self.record_finished(job, &result);
        }
        if let Some(tap) = job.tap() {
            let res = self.tap_finished(node, tap, result);
            self.settle();
            return res;
        }
        // Not `ok_or`: an error built and dropped on every call costs a drop of its own.
        let Some(n) = self.nodes.get(node) else {
            return Err(EngineError::Gone(node));
        };
        if n.stopping {
            // A terminated node's action ended before it could be stopped: whatever it returned,
            // the node was terminated (docs/semantics.md, "Termination"). Part of this input: no
            // input or step of its own, so that a replay giving this end does what the run did.
            self.stopped(node);
            return Ok(());
        }
        if n.state(Facet::Handling) != State::Active
            || !n.alive()
            || n.monitor().is_some()
            || n.taps_pending() > 0
        {
            // A cancelled action may still report; the engine already finished it.
            if n.state(Facet::Handling) == State::Completed && !n.alive() {
                return Ok(());
            }
            return Err(EngineError::NotRunning(node));
        }
        self.running -= 1;
        if n.bypass_requested() {
            // What the handler's body returned does not matter: it passed the exception on.
            self.bypass(node);
        } else {
            match result {
                Err(failure) => {
                    self.fail(node, failure);
                    self.complete_handling(node);
                }
                Ok(()) => {
                    // "After" wiretaps decide whether the node succeeded.
                    if self.start_taps(node, TapWhen::After) == 0 {
                        self.complete_handling(node);
                    }
                }
            }
        }
        if self.steer.is_some() {
            self.break_at(super::BreakAt::End, node, None);
        }
        self.settle();
        Ok(())
    }

    /// Input: a job the shell was asked to cancel ([`Effect::Cancel`]) has stopped without
    /// reporting an end (its task was dropped). Its terminated node can now be terminated for
    /// good. A report for a job that was not being stopped changes nothing.
    pub fn handle_action_stopped(&mut self, now: Time, job: impl Into<Job>) {
        let node = job.into().node();
        self.advance(now);
        self.record(|e| InputRecord::Stopped {
            node: e.display_of(node),
        });
        self.stopped(node);
    }

    /// `node`'s action no longer runs, after a cancellation.
    fn stopped(&mut self, node: NodeId) {
        let stopping =
            self.check_run(node).is_ok() && self.nodes.get(node).is_some_and(|n| n.stopping);
        if stopping {
            self.node_mut(node).stopping = false;
            self.running -= 1;
            // Its action no longer runs: what it was granted goes back (docs/semantics.md,
            // "Resources").
            self.release_resources(node);
            self.queue_progress(node);
            self.settle();
        }
    }

    /// Input: a job the shell was asked to cancel ([`Effect::Cancel`]) was given a grace period to
    /// stop by itself, and is still running when it ends: the shell drops it now. Traces a warning
    /// naming the node (an action that ignores its cancellation may leave something running on
    /// the other side, which a person should know about); the stop itself is still reported with
    /// [`Engine::handle_action_stopped`]. A job that is not being stopped changes nothing.
    pub fn handle_action_overdue(&mut self, now: Time, job: impl Into<Job>, grace: Duration) {
        let node = job.into().node();
        self.advance(now);
        self.record(|e| InputRecord::Overdue {
            node: e.display_of(node),
            grace,
        });
        if self.check_run(node).is_err() {
            return;
        }
        let Some(n) = self.nodes.get(node).filter(|n| n.stopping) else {
            return;
        };
        let (display, message) = (
            n.display,
            format!(
                "Action of {} {{{}}} did not stop within its grace period ({grace:?}) after \
                 termination: dropped",
                n.name, n.display
            ),
        );
        emit!(
            self,
            TraceKind::Warning {
                node: Some(display),
                message,
            }
        );
    }

    /// Input: the time is `now`; fires every timer due at or before it.
    pub fn handle_timeout(&mut self, now: Time) {
        // Recorded only when timers are due: a turn that finds none changes nothing.
        let due = self.inputs.is_some() && self.poll_timeout().is_some_and(|d| d <= now);
        self.advance(now);
        if due {
            self.record(|_| InputRecord::Time);
        }
        self.fire_timers(now, true);
    }

    /// Fires the live timers due before `now` (or at `now` too, if `inclusive`), in deadline order,
    /// each at its own time.
    pub(super) fn fire_timers(&mut self, now: Time, inclusive: bool) {
        loop {
            if self.halted() {
                // A paused run's timers wait (`steer.rs`, rule 1).
                break;
            }
            let nodes = &self.nodes;
            let Some((at, entry)) = self
                .timers
                .pop_due(now, inclusive, |k| timer_is_live(nodes, k))
            else {
                break;
            };
            if at > self.now {
                self.now = at;
            }
            let steps = self.steer.is_some() && self.timer_steps();
            match entry {
                TimerKind::Trigger { target, then } => self.fire_trigger(target, then, true),
                TimerKind::Poll { monitor, k } => self.poll(monitor, k),
                TimerKind::Notify { token } => self.effects.push_back(Effect::Notify {
                    token,
                    outcome: Box::new(WatchOutcome::Reached),
                }),
                TimerKind::Approval { node, after } => self.approval_timed_out(node, after),
            }
            if steps {
                self.pause_at(None, "step".into());
            }
            self.settle();
        }
    }

    /// Delivers all queued work, then starts ready nodes one at a time, until nothing is left.
    pub(super) fn settle(&mut self) {
        loop {
            while let Some(w) = self.work.pop_front() {
                // One call of `progress` (it is inlined here).
                let id = match w {
                    Work::Progress(id) => id,
                    Work::Children(run) => match self.step_children(run) {
                        Some(id) => id,
                        None => continue,
                    },
                    Work::Terminate { node, explicit } => {
                        self.do_terminate(node, explicit);
                        continue;
                    }
                };
                self.progress(id);
            }
            if self.res.dirty {
                // Room was made: waiting requests that fit now are granted and queued.
                self.scan_resources();
            }
            if self.halted() {
                // A paused run's ready nodes wait (`steer.rs`, rule 1).
                break;
            }
            match self.ready.pop_front() {
                Some(id) => self.start(id),
                None => break,
            }
        }
    }

    /// Moves a node as far as its constraints allow (see the module documentation).
    fn progress(&mut self, id: NodeId) {
        // What the parent allows, looked up when first needed and kept while only this node's
        // own states change: a transition that ran waiters, or a completion, may have changed
        // anything, and then it is looked up again.
        let mut parent_gate: Option<ParentGate> = None;
        loop {
            let Some(n) = self.nodes.get(id) else { return };
            if n.reserved || n.kind == NodeKind::Root {
                return;
            }
            let alive = n.alive();
            let n_expands = n.kind.expands();
            let terminated = n.termination == Termination::Terminated;
            let h = n.state(Facet::Handling);
            let x = n.state(Facet::Expansion);
            let e = n.state(Facet::Execution);
            if n.blocks[Facet::Execution.index()] > 0 && e == State::Disabled && !n.kind.expands() {
                // A command whose execution waits for a constraint (`serial previous`, as every
                // node of a chain but the first when its parent lets them go): nothing below
                // applies until the constraint is satisfied.
                return;
            }
            // Children of a holding action are not enabled at all until it releases them (only
            // looked up while something is left to enable). A terminating node that had not
            // started is still enabled in the plan's order; at its turn it completes instead of
            // starting.
            let g = if !terminated
                && (h == State::Disabled || x == State::Disabled || e == State::Disabled)
            {
                *parent_gate.get_or_insert_with(|| self.parent_gate(n))
            } else {
                ParentGate::CLOSED
            };
            let can_enable = g.open;
            let has_children = n.live_children > 0;
            if can_enable
                && x == State::Disabled
                && n.blocks[Facet::Expansion.index()] == 0
                && g.expansion
                && (!n.delay_expansion || e >= State::Enabled)
            {
                // Children wait for this facet; a node with none (and whose transition ran
                // nothing that could have made one) has nothing more to do here.
                if self.transition(id, Facet::Expansion, State::Enabled) {
                    parent_gate = None;
                    self.progress_children(id);
                } else if has_children {
                    self.progress_children(id);
                }
                continue;
            }
            if can_enable
                && e == State::Disabled
                && n.blocks[Facet::Execution.index()] == 0
                && g.execution
                && (!n.expand_first || x == State::Completed)
            {
                // Children wait for this facet; a node with none (and whose transition ran
                // nothing that could have made one) has nothing more to do here.
                if self.transition(id, Facet::Execution, State::Enabled) {
                    parent_gate = None;
                    self.progress_children(id);
                    continue;
                }
                if has_children {
                    self.progress_children(id);
                }
                // A live command whose handling waits for nothing else (the usual released
                // command): the handling branch below applies at once, and once it ran without
                // firing anything, nothing else does (the next pass would find every branch
                // closed). The pass between is skipped.
                if alive
                    && !n_expands
                    && h == State::Disabled
                    && self.node(id).blocks[Facet::Handling.index()] == 0
                {
                    let fired = self.transition(id, Facet::Handling, State::Enabled);
                    self.ready.push_back(id);
                    if fired {
                        parent_gate = None;
                        continue;
                    }
                    return;
                }
                continue;
            }
            let gate = if n_expands { x } else { e };
            if can_enable
                && h == State::Disabled
                && n.blocks[Facet::Handling.index()] == 0
                && gate >= State::Enabled
            {
                if self.transition(id, Facet::Handling, State::Enabled) {
                    parent_gate = None;
                }
                // A node terminated before it started joins the queue too: it completes at its
                // turn, after the nodes released before it started (`start`).
                self.ready.push_back(id);
                continue;
            }
            if x != State::Completed
                && h == State::Completed
                && n.open_expansions == 0
                && x >= State::Enabled
                && !n.stopping
            {
                self.transition(id, Facet::Expansion, State::Completed);
                if let Some(p) = self.node(id).parent {
                    if let Some(pn) = self.nodes.get_mut(p) {
                        pn.open_expansions -= 1;
                        if pn.child_end_may_progress() {
                            self.queue_progress(p);
                        }
                    }
                }
                parent_gate = None;
                continue;
            }
            if e != State::Completed
                && h == State::Completed
                && x == State::Completed
                && n.open_executions == 0
                && e >= State::Enabled
                && !n.stopping
            {
                // Retries and reservations live in the cold part: a node without one (unless
                // its transition ran waiters) has neither to look at. A linked node's parent
                // never changes.
                let (cold, parent) = (n.cold.is_some(), n.parent);
                if cold {
                    self.note_recovery(id);
                }
                if self.transition(id, Facet::Execution, State::Completed) || cold {
                    self.bury_labels(id);
                }
                self.end_reservations_of(id);
                if let Some(p) = parent {
                    if let Some(pn) = self.nodes.get_mut(p) {
                        pn.open_executions -= 1;
                        if pn.child_end_may_progress() {
                            self.queue_progress(p);
                        }
                    }
                }
                // An activation (cold) that ended may release its monitor's held poll.
                if cold {
                    self.activation_ended(id);
                }
                // A live node whose execution completed has one branch left, its reclaim (the
                // next pass would find every other closed): taken here, without that pass.
                let Some(n) = self.nodes.get(id) else { return };
                if n.alive() {
                    if n.live_children == 0 && !n.persistent {
                        self.reclaim(id);
                    }
                    return;
                }
                parent_gate = None;
                continue;
            }
            if n.termination == Termination::Terminating
                && e == State::Completed
                && n.open_executions == 0
                && n.terminating_children == 0
                && !n.stopping
            {
                self.node_mut(id).termination = Termination::Terminated;
                let display = self.node(id).display;
                emit!(self, TraceKind::Terminated { node: display });
                if let Some(p) = self.node(id).parent {
                    if let Some(pn) = self.nodes.get_mut(p) {
                        pn.terminating_children -= 1;
                    }
                    self.queue_progress(p);
                }
                parent_gate = None;
                continue;
            }
            if e == State::Completed
                && n.termination != Termination::Terminating
                && n.live_children == 0
                && (!n.persistent || terminated)
            {
                self.reclaim(id);
            }
            return;
        }
    }

    pub(super) fn progress_children(&mut self, id: NodeId) {
        let Some(n) = self.nodes.get(id) else { return };
        let (count, first, last) = (n.live_children, n.first_child, n.last_child);
        if count >= self.run_from && self.runs.len() < MAX_RUNS {
            self.queue_run(first, last);
            return;
        }
        let mut c = self.nodes.id_at(first);
        while let Some(child) = c {
            self.queue_progress(child);
            c = self.next_sibling(child);
        }
    }

    /// Queues the progress of the linked children from `first` to `last` as one entry
    /// (`ChildRun`); the first child's is left out if it is the last work queued, as
    /// `queue_progress` would.
    #[inline(never)]
    fn queue_run(&mut self, first: Link, last: Link) {
        let (Some(first_id), Some(last_id)) = (self.nodes.id_at(first), self.nodes.id_at(last))
        else {
            return;
        };
        let next = if self.last_queued_is(first_id) {
            self.node(first_id).next_sibling
        } else {
            first
        };
        let run = self.next_run;
        self.next_run = self.next_run.wrapping_add(1);
        self.runs.push(ChildRun {
            id: run,
            next,
            last,
            last_id,
        });
        self.work.push_back(Work::Children(run));
    }

    /// The next child of a run of children (`Work::Children`), whose progress is due now. The run
    /// goes back to the front of the queue for the children after it, so what this child's
    /// progress queues comes after them, as it would after their own entries.
    #[inline(never)]
    fn step_children(&mut self, run: u32) -> Option<NodeId> {
        let i = self.runs.iter().position(|r| r.id == run)?;
        let r = self.runs[i];
        let Some(child) = self.nodes.id_at(r.next) else {
            // Every child left in the run was unlinked: their entries were no-ops.
            self.runs.swap_remove(i);
            return None;
        };
        if r.next == r.last {
            self.runs.swap_remove(i);
        } else {
            self.runs[i].next = self.node(child).next_sibling;
            self.work.push_front(Work::Children(run));
        }
        Some(child)
    }

    /// What the parent of `n` allows its children now.
    fn parent_gate(&self, n: &Node<A, F>) -> ParentGate {
        match n.parent.and_then(|p| self.nodes.get(p)) {
            // No parent (or one gone): nothing holds the node back.
            None => ParentGate {
                open: true,
                expansion: true,
                execution: true,
            },
            Some(p) => ParentGate {
                // Children of a holding action are not enabled at all until it releases them.
                open: !(p.holding && p.state(Facet::Handling) == State::Active),
                expansion: p.state(Facet::Expansion) >= State::Enabled,
                execution: p.state(Facet::Execution) >= State::Enabled,
            },
        }
    }

    /// Moves `facet` of `id` to `to`, traces it and fires the waiters whose point is now reached.
    /// Returns whether anything beyond the state itself may have changed (waiters ran, or a
    /// record was traced).
    #[inline(always)]
    pub(super) fn transition(&mut self, id: NodeId, facet: Facet, to: State) -> bool {
        let tracing = self.tracing;
        let n = self.node_mut(id);
        let from = n.states[facet.index()];
        debug_assert!(from < to, "facets only move forward");
        n.states[facet.index()] = to;
        // Most transitions fire nothing and, with tracing off, record nothing.
        if tracing || n.waiters.iter().any(|w| w.fires_at(facet, to)) {
            self.record_and_fire(id, facet, from, to);
            return true;
        }
        false
    }

    /// The rest of `transition`: traces it and fires the waiters whose point is now reached.
    fn record_and_fire(&mut self, id: NodeId, facet: Facet, from: State, to: State) {
        let n = self.node_mut(id);
        let display = n.display;
        // Usually none or one fires: `Waiters` keeps one inline, so no allocation. Most
        // transitions of a watched node fire nothing, so its waiters are first only looked at.
        let fires = |w: &super::node::Waiter| w.fires_at(facet, to);
        // The usual waiter (`serial previous` and `sequential`): the only one, an enabling
        // trigger with neither delay nor outcome. Firing it is what `fire_now` would do with it
        // (an enablement fires even for a terminating node), without going through it.
        let direct = match n.waiters.as_slice() {
            [w] if fires(w) && w.outcome.is_none() => match w.kind {
                WaitKind::Trigger {
                    target,
                    then: crate::constraint::Then::Enable(f),
                    delay: super::node::Delay::NONE,
                } => Some((target, f)),
                _ => None,
            },
            _ => None,
        };
        let fired = if direct.is_some() {
            n.waiters.clear();
            Waiters::new()
        } else if !n.waiters.iter().any(fires) {
            Waiters::new()
        } else if n.waiters.iter().all(fires) {
            std::mem::take(&mut n.waiters)
        } else {
            let mut fired = Waiters::new();
            n.waiters.retain(|w| {
                if fires(w) {
                    fired.push(*w);
                    false
                } else {
                    true
                }
            });
            fired
        };
        emit!(
            self,
            TraceKind::Transition {
                node: display,
                facet,
                from,
                to,
            }
        );
        if let Some((target, f)) = direct {
            return self.satisfy(target, f);
        }
        if !fired.is_empty() {
            for w in fired {
                match w.outcome {
                    Some(o) if o != self.outcome_of(id) => self.impossible(w.kind),
                    _ => self.fire_now(id, w.kind),
                }
            }
        }
    }

    /// A retry whose execution completes without failing recovers the first run of its task,
    /// whose outcome becomes this run's (docs/semantics.md, "Outcomes").
    fn note_recovery(&mut self, id: NodeId) {
        let n = self.node(id);
        let Some(origin) = n.retry_of() else { return };
        if !n.alive() || n.failure().is_some() {
            return;
        }
        if let Some(o) = self.nodes.get_mut(origin) {
            o.cold_mut().recovered_by = Some(id);
        }
    }

    pub(super) fn complete_handling(&mut self, id: NodeId) {
        // Its grant goes back as its action ends; an action still stopping keeps it until it
        // stopped (`handle_action_stopped`).
        if !self.res.list.is_empty() && !self.node(id).stopping {
            self.release_resources(id);
        }
        self.transition(id, Facet::Handling, State::Completed);
        let n = self.node_mut(id);
        let (was_holding, reservations) = (
            std::mem::replace(&mut n.holding, false),
            n.holds_reservations(),
        );
        if was_holding {
            self.progress_children(id);
        }
        if reservations {
            self.bury_unspawned(id);
        }
        self.queue_progress(id);
    }

    /// The body of `id` ended: reservations it never spawned are dead (docs/semantics.md, "Tags and
    /// forward references"). The labels of its own on-terminate tasks stay until its execution
    /// completes: a termination before then still inserts those tasks.
    #[inline]
    pub(super) fn bury_reservations(&mut self, id: NodeId) {
        if self.node(id).holds_reservations() {
            self.bury_unspawned(id);
        }
    }

    fn bury_unspawned(&mut self, id: NodeId) {
        let n = self.node_mut(id);
        let labels = n.on_terminate_labels();
        let mut reservations = n.take_cold(|c| &mut c.reservations);
        if !labels.is_empty() {
            let (kept, dead) = reservations.into_iter().partition(|r| labels.contains(r));
            n.cold_mut().reservations = kept;
            reservations = dead;
        }
        self.bury(reservations);
    }

    /// The execution of `id` completed: every reservation it still holds is dead.
    fn bury_labels(&mut self, id: NodeId) {
        if !self.node(id).holds_reservations() {
            return;
        }
        let reservations = self.node_mut(id).take_cold(|c| &mut c.reservations);
        self.bury(reservations);
    }

    fn bury(&mut self, reservations: ThinVec<NodeId>) {
        for r in reservations {
            let Some(node) = self.nodes.remove(r, Fate::Dead) else {
                continue;
            };
            emit!(self, TraceKind::Dead { node: node.display });
            for w in node.waiters {
                match w.kind {
                    WaitKind::Watch { token } => self.effects.push_back(Effect::Notify {
                        token,
                        outcome: Box::new(WatchOutcome::Dead),
                    }),
                    // A dead event fires termination at once and drops the `after` part's event.
                    other => self.fire(other, false),
                }
            }
        }
    }

    fn reclaim(&mut self, id: NodeId) {
        let n = self.node(id);
        let fate = if n.termination == Termination::Terminated {
            Fate::Terminated
        } else {
            Fate::Completed
        };
        let (parent, display) = (n.parent, n.display);
        self.unlink(id);
        self.nodes.discard(id, fate);
        emit!(self, TraceKind::Reclaimed { node: display });
        if let Some(p) = parent
            && self
                .nodes
                .get(p)
                .is_some_and(|pn| pn.child_end_may_progress())
        {
            self.queue_progress(p);
        }
    }
}

/// Whether a timer still matters when it surfaces (stale ones are skipped, see `timers.rs`).
pub(super) fn timer_is_live<A, F, S: Keep<Node<A, F>>>(
    nodes: &Arena<A, F, S>,
    kind: &TimerKind,
) -> bool {
    match *kind {
        // A terminating node that has not started still needs its enabling timers.
        TimerKind::Trigger { target, then } => nodes.get(target).is_some_and(|n| match then {
            Then::Enable(facet) => n.state(facet) == State::Disabled,
            Then::Terminate => n.alive() && n.state(Facet::Execution) != State::Completed,
            Then::Activate | Then::ActivateWith(_) => {
                n.alive() && n.state(Facet::Handling) != State::Completed
            }
            // Never timers.
            Then::Skip | Then::Invariant | Then::Pause => false,
        }),
        TimerKind::Poll { monitor, .. } => nodes
            .get(monitor)
            .is_some_and(|n| n.alive() && n.state(Facet::Handling) == State::Active),
        // A timer callback belongs to no node: it matters until it fires.
        TimerKind::Notify { .. } => true,
        TimerKind::Approval { node, .. } => nodes
            .get(node)
            .is_some_and(|n| n.alive() && n.state(Facet::Handling) == State::Enabled),
    }
}

/// What a parent allows its children, as `progress` reads it.
#[derive(Clone, Copy)]
struct ParentGate {
    // The parent does not hold its children (an action holding them while it runs).
    open: bool,
    // The parent's expansion, and execution, is enabled (or there is no parent).
    expansion: bool,
    execution: bool,
}

impl ParentGate {
    /// For a node with nothing left to enable: the parent is not looked at.
    const CLOSED: ParentGate = ParentGate {
        open: false,
        expansion: false,
        execution: false,
    };
}
