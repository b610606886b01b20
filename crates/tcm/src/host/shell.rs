//! The host's side of the [`Driver`](tcm_core::Driver) for one step ([`Host`]): each effect of the engine carried
//! out, a job's future handed to the pump or spawned as a task.

use super::{
    Aborts, DueCallback, Parking, PendingCallback, Root, Running, Shared, TaskRef, spawn_task,
};
use crate::cancel::Cancels;
use crate::ctx::Ctx;
use crate::task::{Action, AnyArgs, Factory, Launch};
use std::any::Any;
use std::collections::{BTreeMap, BTreeSet};
use std::sync::Arc;
use std::sync::atomic::Ordering;
use tcm_core::{Engine, Job, NodeId, Purpose, Shell, WatchOutcome, WatchToken};
use tcm_trace::TraceEvent;
use tokio::sync::oneshot;

/// The host's side of the [`Driver`](tcm_core::Driver), borrowed from [`Inner`](super::Inner) for
/// one step.
pub(crate) struct Host<'a> {
    pub(super) shared: &'a Arc<Shared>,
    // Whether the pump of this thread runs for this run (`pump::pumps`), looked up on the first
    // start of a step: nothing that runs while the host carries effects out enters or leaves a pump.
    pub(super) pumps: Option<bool>,
    pub(super) aborts: &'a mut Aborts,
    pub(super) launches: &'a mut Vec<(Job, Launch)>,
    pub(super) inline_cancelled: &'a mut Vec<NodeId>,
    pub(super) cancels: &'a mut Cancels,
    pub(super) checks: &'a mut BTreeSet<Job>,
    pub(super) parking: &'a mut Parking,
    pub(super) spawner: Option<&'a tokio::runtime::Handle>,
    pub(super) watchers: &'a mut BTreeMap<u64, oneshot::Sender<WatchOutcome>>,
    pub(super) roots: &'a mut Vec<Root>,
    pub(super) roots_changed: &'a mut bool,
    pub(super) callbacks: &'a mut BTreeMap<u64, PendingCallback>,
    pub(super) due: &'a mut Vec<DueCallback>,
    pub(super) activation_data: &'a mut BTreeMap<NodeId, Arc<dyn Any + Send + Sync>>,
    pub(super) args: &'a BTreeMap<NodeId, AnyArgs>,
    pub(super) trace: &'a mut Vec<TraceEvent>,
    // The values awaited, by node (`Inner::values`).
    pub(super) values: &'a mut BTreeMap<NodeId, Option<crate::task::Value>>,
    // The journal the run replays, while it does (`replay.rs`).
    pub(super) replay: Option<&'a mut crate::replay::Replay>,
}

impl Host<'_> {
    /// Runs a job's future: left to the pump of this thread if it runs for this run (`pump.rs`),
    /// else spawned as a tokio task, under the lock (the task's own end takes the lock, so its
    /// abort handle is recorded before it can finish).
    fn run(&mut self, job: Job, launch: Launch) {
        let shared = self.shared;
        let pumps = *self.pumps.get_or_insert_with(|| crate::pump::pumps(shared));
        let running = if pumps && self.cancels.aborted == 0 && crate::pump::nothing_queued(shared) {
            self.launches.push((job, launch));
            Running::Inline
        } else {
            let h = spawn_task(
                self.shared,
                self.spawner,
                job,
                launch.into_future(shared, job),
            );
            Running::Task(h.abort_handle())
        };
        if job.cancellable() {
            self.aborts.insert(job.node(), running);
        } else {
            self.checks.insert(job);
        }
    }
}

impl Shell<Action, Factory> for Host<'_> {
    fn start(&mut self, engine: &mut Engine<Action, Factory>, node: NodeId, action: Action) {
        if let Some(r) = self.replay.as_mut() {
            // A command's end comes from the journal (`replay.rs`, rule 1).
            if let Some((tcm_core::NodeKind::Command, display)) = engine.kind_and_display(node) {
                r.stub(node, display, action);
                return;
            }
        }
        // The engine already holds the action's children (`Engine::hold_by_default`, set by
        // `Runtime::new`): a hand-written action holds them until it returns or waits, as
        // generated TDL does (docs/semantics.md, "Bodies and children").
        let job = Job::from(node);
        let launch = action.launch(self.shared, job, self.args.get(&node).cloned());
        self.run(job, launch);
    }

    fn invoke(
        &mut self,
        engine: &mut Engine<Action, Factory>,
        job: Job,
        body: Factory,
        p: Arc<Purpose>,
    ) {
        // A monitor's activation has the grace period its monitor's task set.
        if let Purpose::Activation { monitor, .. } = p.as_ref() {
            if let Some(grace) = self.cancels.grace_of(*monitor) {
                let engine = &*engine;
                self.cancels
                    .keep_grace(job.node(), grace, |id| engine.parent(id).is_some());
            }
        }
        // A monitor activation, a handler or a retry holds its children like any action (see
        // `start`); the engine set the hold when it handed the job out.
        let ctx = Ctx {
            shared: self.shared.clone(),
            node: job.node(),
            purpose: Some(p),
            job: Some(job),
            // A check's node is the tapped node: its arguments (`Ctx::tapped_args`).
            args: self.args.get(&job.node()).cloned(),
            signal: Default::default(),
        };
        let fut = body(ctx);
        self.run(job, Launch::Future(fut));
    }

    fn cancel(&mut self, node: NodeId) {
        if self.replay.as_mut().is_some_and(|r| r.cancel(node)) {
            // A stub: its stop comes from the journal.
            return;
        }
        // Removed from the running actions either way: an action in its grace period is never
        // parked again, so it keeps the run busy, not stuck, until it stops.
        let at_once = match self.aborts.remove(&node) {
            Some(Running::Task(h)) => {
                self.cancels
                    .cancel(self.shared, self.spawner, node, TaskRef::Task(h))
            }
            Some(Running::Parked(p)) => {
                self.cancels
                    .cancel(self.shared, self.spawner, node, TaskRef::Parked(p))
            }
            // The pump holds it: it drops it unpolled, or cancels the task it becomes.
            Some(Running::Inline) => {
                self.inline_cancelled.push(node);
                self.shared.inline_cancels.fetch_add(1, Ordering::Relaxed);
                true
            }
            None => false,
        };
        if at_once {
            if let Some(r) = self.replay.as_mut() {
                // Its stop is certain now, whenever its drop is reported (`replay.rs`, rule 3).
                r.dropped_at_once(Job::from(node));
            }
        }
        self.parking.forget_job(Job::from(node));
        self.activation_data.remove(&node);
    }

    /// A fault stands for the node's action and succeeds with `value`: kept as the node's value
    /// for whoever waits for it, as an action's returned value is (`host/ended.rs`).
    fn value(&mut self, node: NodeId, value: tcm_core::FaultValue) {
        if let Some(slot) = self.values.get_mut(&node) {
            *slot = Some(value.make());
        }
    }

    fn notify(
        &mut self,
        _: &mut Engine<Action, Factory>,
        token: WatchToken,
        outcome: WatchOutcome,
    ) {
        if let Some(tx) = self.watchers.remove(&token.0) {
            self.parking.unpark(token.0);
            let _ = tx.send(outcome);
        } else if let Some(root) = self.roots.iter_mut().find(|r| r.token == token.0) {
            root.outcome = Some(outcome);
            *self.roots_changed = true;
        } else if let Some(cb) = self.callbacks.remove(&token.0) {
            self.due.push(DueCallback {
                token,
                name: cb.name,
                node: cb.node,
                f: cb.f,
                outcome,
            });
        }
    }

    fn trace(&mut self, record: TraceEvent) {
        self.trace.push(record);
    }
}
