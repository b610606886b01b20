//! Cancellation that reaches the other side (docs/semantics.md, "Termination"): when a node is
//! terminated while its action runs, an action that looks at its cancellation signal
//! ([`crate::Ctx::cancelled`], [`crate::Ctx::is_cancelled`]) is signalled and keeps running for a
//! bounded grace period, to cancel what it started outside (a ROS 2 goal, a remote task, a motion);
//! it is dropped when it returns or when the period ends. An action that never looked at the
//! signal cannot react to it, so it is dropped at once, as before: a grace period would only let
//! it go on commanding hardware after its termination.
//!
//! The signal is a `tokio::sync::watch` channel of one `bool`, made on the action's first look:
//! actions that never look cost nothing (no allocation on the path every action takes), and the
//! channel latches the value, so a look after the cancellation still sees it.

use crate::host::{Shared, TaskRef};
use std::collections::{BTreeMap, BTreeSet};
use std::sync::Arc;
use std::time::Duration;
use tcm_core::NodeId;
use tokio::sync::watch;
use tokio::task::AbortHandle;

/// The grace period of an action that looks at its cancellation signal, unless its task sets its
/// own ([`crate::Task::grace`]) or the runtime another ([`crate::Runtime::default_grace`]).
///
/// One second: long enough for a cancel request to reach a server on the robot's network and be
/// acknowledged (a ROS 2 action cancel, an HTTP `DELETE`, a motor controller's stop command), short
/// enough that a cleanup hung on a lost link does not hold back, for long, what the plan ordered
/// after the terminated node. A cleanup that completes returns as soon as it is done: the period
/// bounds only the cleanups that go wrong.
pub const DEFAULT_GRACE: Duration = Duration::from_secs(1);

/// A job in its grace period: the action's task, and the timer that drops it.
struct Cancelling {
    action: TaskRef,
    timer: AbortHandle,
}

/// How often the grace periods are swept for nodes that are gone: when they are more than this,
/// and twice what the last sweep left (amortised O(1) per entry, as the host's own maps).
const SWEEP_MIN: usize = 256;

/// The cancellation state of the run's jobs, by node (cancellable jobs are one per node, as in
/// [`crate::host::Aborts`]).
pub(crate) struct Cancels {
    // The signal of each running (or cancelling) job that looked at it.
    signals: BTreeMap<NodeId, watch::Sender<bool>>,
    // The jobs signalled and running in their grace period. Invariant: each has an entry in
    // `signals` (only a job that looked is given a period).
    cancelling: BTreeMap<NodeId, Cancelling>,
    // The jobs that run a blocking body (`Ctx::blocking`): no thread can be stopped from outside,
    // so a cancelled one is only signalled, and runs until it returns. Invariant: each has an
    // entry in `signals`.
    pinned: BTreeSet<NodeId>,
    // Grace periods of nodes whose task set one (`Task::grace`), and of the activations of such a
    // monitor; kept after the job ends (a retry inherits it), swept once the node is gone.
    graces: BTreeMap<NodeId, Duration>,
    sweep_at: usize,
    // The grace period of the other jobs.
    pub(crate) default: Duration,
    // Where the pump runs (`pump.rs`): how many tasks were aborted and not yet reported stopped.
    // Tokio drops an aborted task when it next runs it, so until then it is queued, and an action
    // released meanwhile must run after it, as a task, not inline.
    pub(crate) aborted: usize,
}

impl Default for Cancels {
    fn default() -> Cancels {
        Cancels {
            signals: BTreeMap::new(),
            cancelling: BTreeMap::new(),
            pinned: BTreeSet::new(),
            graces: BTreeMap::new(),
            sweep_at: SWEEP_MIN,
            default: DEFAULT_GRACE,
            aborted: 0,
        }
    }
}

impl Cancels {
    /// A receiver of the signal of `node`'s job. `running`: whether that job runs (not yet
    /// cancelled); only then is a signal made, so a context that outlived its job leaves nothing
    /// behind. `terminated`: for such a context, whether its node was terminated (the answer it
    /// then gets, latched).
    pub(crate) fn signal(
        &mut self,
        node: NodeId,
        running: bool,
        terminated: impl FnOnce() -> bool,
    ) -> watch::Receiver<bool> {
        if let Some(tx) = self.signals.get(&node) {
            return tx.subscribe();
        }
        if running {
            let (tx, rx) = watch::channel(false);
            self.signals.insert(node, tx);
            return rx;
        }
        // The job is over: a signal that will never change (its sender is dropped at once).
        watch::channel(terminated()).1
    }

    /// `node`'s job runs a blocking body: from now on a cancellation only signals it (`signal`
    /// made it its signal), and it runs until it returns.
    pub(crate) fn pin(&mut self, node: NodeId) {
        if self.signals.contains_key(&node) {
            self.pinned.insert(node);
        }
    }

    /// Keeps the grace period a node's task set; drops those of nodes that are gone (`live` tells
    /// which are not), now and then (a polling monitor with a grace period adds one per
    /// activation).
    pub(crate) fn keep_grace(
        &mut self,
        node: NodeId,
        grace: Duration,
        mut live: impl FnMut(NodeId) -> bool,
    ) {
        self.graces.insert(node, grace);
        if self.graces.len() > self.sweep_at {
            self.graces.retain(|id, _| live(*id));
            self.sweep_at = SWEEP_MIN.max(2 * self.graces.len());
        }
    }

    /// The grace period a node's task set, if any (a retry inherits it).
    pub(crate) fn grace_of(&self, node: NodeId) -> Option<Duration> {
        self.graces.get(&node).copied()
    }

    /// `node`'s running job is cancelled (its node was terminated): a job that looked at its signal
    /// and has a grace period is signalled and left running, with a timer on `rt` that drops it
    /// when the period ends; any other is aborted at once. Its stop is reported by its task either
    /// way (`Reporter` in `host.rs`).
    pub(crate) fn cancel(
        &mut self,
        shared: &Arc<Shared>,
        rt: Option<&tokio::runtime::Handle>,
        node: NodeId,
        action: TaskRef,
    ) -> bool {
        let grace = self.grace_of(node).unwrap_or(self.default);
        let Some(tx) = self.signals.get(&node) else {
            self.abort(shared, &action);
            return true;
        };
        // Fired even when the action is dropped at once: other tasks that hold a clone of its
        // context (and awaited the signal) learn of the cancellation too.
        tx.send_replace(true);
        if self.pinned.contains(&node) {
            // A blocking body cannot be dropped: its node is terminated once it returns.
            return false;
        }
        if grace.is_zero() {
            self.signals.remove(&node);
            self.abort(shared, &action);
            return true;
        }
        let timer = {
            let shared = shared.clone();
            // A tokio sleep: on the paused clock of a virtual-time run, the period passes in
            // virtual time, deterministically.
            let tracking = shared.clone();
            let task = async move {
                // The run's time (scaled, if the run's clock is).
                let end = shared.clock.instant(shared.now() + grace);
                tokio::time::sleep_until(end).await;
                expire(&shared, node, grace);
            };
            // Its wake-ups are counted (`pump.rs`); a new task is queued.
            let task = crate::pump::MaybeTracked::new(&tracking, Box::pin(task), true);
            match rt {
                Some(rt) => rt.spawn(task),
                None => tokio::spawn(task),
            }
        };
        self.cancelling.insert(
            node,
            Cancelling {
                action,
                timer: timer.abort_handle(),
            },
        );
        false
    }

    /// Aborts a running job's task, counting it as queued until its stop is reported.
    fn abort(&mut self, shared: &Shared, action: &TaskRef) {
        if action.abort() && shared.inline.load(std::sync::atomic::Ordering::Relaxed) {
            self.aborted += 1;
        }
    }

    /// `node`'s job returned (or panicked): its signal is no longer needed and, if it was in its
    /// grace period, the timer that would have dropped it is stopped (a pending sleep would
    /// otherwise move a paused clock for nothing).
    pub(crate) fn finished(&mut self, node: NodeId) {
        if self.signals.is_empty() {
            // The common case: no action looked at its signal.
            return;
        }
        self.signals.remove(&node);
        self.pinned.remove(&node);
        if let Some(c) = self.cancelling.remove(&node) {
            c.timer.abort();
        }
    }

    /// The run ended: every action in its grace period is dropped, every signal fires (the action
    /// is over), and nothing is left.
    pub(crate) fn end(&mut self) {
        for (_, c) in std::mem::take(&mut self.cancelling) {
            c.action.abort();
            c.timer.abort();
        }
        for (_, tx) in std::mem::take(&mut self.signals) {
            tx.send_replace(true);
        }
        self.pinned.clear();
    }
}

/// The grace period of `node`'s job ended: if the job still runs, a warning is traced and it is
/// dropped. Its task's `Reporter` then reports the stop, and the engine terminates the node.
fn expire(shared: &Arc<Shared>, node: NodeId, grace: Duration) {
    let Ok(mut inner) = shared.enter() else {
        return;
    };
    if inner.replay.as_ref().is_some_and(|r| r.active()) {
        // The journal says whether the grace period ran out (`replay.rs`, rule 2).
        return;
    }
    let Some(c) = inner.cancels.cancelling.remove(&node) else {
        // It returned meanwhile.
        return;
    };
    inner.cancels.signals.remove(&node);
    let now = inner.engine.at_clock();
    inner
        .engine
        .handle_action_overdue(now, tcm_core::Job::from(node), grace);
    // Safe under the lock: tokio drops an aborted task on its runtime, and its `Reporter` never
    // takes this lock anyway (it reports through a channel, drained by whoever takes it next).
    inner.cancels.abort(shared, &c.action);
}
