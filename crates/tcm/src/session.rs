//! The program's side of a run in TCM's style ([`Runtime::start`](crate::Runtime::start)): a `main`
//! that spawns several top-level tasks, processes the agenda until nothing more can run
//! ([`Session::quiescent`], TCM's `TCM_ProcessAgenda`), inspects and terminates nodes, and ends
//! the run ([`Session::finish`]).
//!
//! The driver loop is the one of [`Runtime::run`](crate::Runtime::run) (`runtime.rs`), running on
//! a task of its own. The program's calls go through a context of the root that belongs to no job,
//! so the program's own waiting never counts as a parked action.

use crate::Error;
use crate::control::Control;
use crate::control::spawn_top;
use crate::ctx::Ctx;
use crate::events::EventHandle;
use crate::host::{Shared, lock};
use crate::host::{end_run, report};
use crate::outcome::{Report, RunOutcome};
use crate::task::Task;
use std::any::Any;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Duration;
use tcm_core::{
    Constraint, Event, ExternalId, MonitorInfo, Name, NodeId, NodeInfo, Time, WatchOutcome,
};
use tokio::task::JoinHandle;

/// A run driven by the program: see [`Runtime::start`](crate::Runtime::start).
///
/// Dropping a session without [`Session::finish`] stops the run: its driver and every running
/// action are aborted.
pub struct Session {
    // A context of the root, of no job.
    ctx: Ctx,
    driver: Option<JoinHandle<Result<RunOutcome, Error>>>,
}

impl Session {
    pub(crate) fn new(
        shared: Arc<Shared>,
        root: NodeId,
        driver: JoinHandle<Result<RunOutcome, Error>>,
    ) -> Session {
        Session {
            ctx: Ctx {
                shared,
                node: root,
                purpose: None,
                job: None,
                args: None,
                signal: Default::default(),
            },
            driver: Some(driver),
        }
    }

    fn shared(&self) -> &Arc<Shared> {
        &self.ctx.shared
    }

    /// Inserts `task` as a top-level task (a child of the root); it starts at once. The run's
    /// outcome at [`Session::finish`] takes every top-level task into account.
    pub fn spawn(&self, task: Task) -> Result<NodeId, Error> {
        spawn_top(self.shared(), task)
    }

    /// A handle to control the run from other tasks and threads while it runs: top-level tasks,
    /// events, handlers and wiretaps added and removed (see [`Control`]).
    pub fn control(&self) -> Control {
        Control {
            ctx: self.ctx.clone(),
        }
    }

    /// Waits until the run is *quiescent*: nothing more can happen without input from outside the
    /// run (an event raised, a call of the program). Then no action runs except those parked in an
    /// await on the engine, nothing is ready, no timer is pending and no callback is due
    /// (docs/semantics.md, "Run outcome"). Open event handles do not count: quiescence is what the
    /// run can do by itself. An error if the run ended meanwhile (a fatal failure); then
    /// [`Session::finish`] tells how.
    pub async fn quiescent(&self) -> Result<(), Error> {
        let mut status = self.shared().status.subscribe();
        // Read under the engine's lock, under which the driver publishes: any later turn sees
        // every change this program made before.
        let seen = {
            let _inner = lock(self.shared())?;
            status.borrow_and_update().turn
        };
        self.shared().wake.notify_one();
        let now = status
            .wait_for(|s| s.ended || (s.quiet && s.turn > seen))
            .await
            .map_err(|_| Error::RunEnded)?;
        if now.ended {
            return Err(Error::RunEnded);
        }
        Ok(())
    }

    /// How a top-level task spawned by [`Session::spawn`] ended, once it did: normally, failed,
    /// handled, or terminated. `None` while it runs, or for another node.
    pub fn outcome(&self, node: NodeId) -> Result<Option<WatchOutcome>, Error> {
        let inner = lock(self.shared())?;
        Ok(inner
            .roots
            .iter()
            .find(|r| r.node == node)
            .and_then(|r| r.outcome.clone()))
    }

    /// Reserves `resource` for `holder` and its subtree, as
    /// [`Ctx::reserve_resource`] does from an action.
    pub fn reserve_resource(
        &self,
        resource: impl Into<crate::ResourceRef>,
        holder: NodeId,
    ) -> Result<(), Error> {
        self.ctx.reserve_resource(resource, holder)
    }

    /// Ends the reservation of `resource`.
    pub fn unreserve_resource(&self, resource: impl Into<crate::ResourceRef>) -> Result<(), Error> {
        self.ctx.unreserve_resource(resource)
    }

    /// Locks `resource`: nobody is granted it until it is unlocked.
    pub fn lock_resource(&self, resource: impl Into<crate::ResourceRef>) -> Result<(), Error> {
        self.ctx.lock_resource(resource)
    }

    /// Unlocks `resource`.
    pub fn unlock_resource(&self, resource: impl Into<crate::ResourceRef>) -> Result<(), Error> {
        self.ctx.unlock_resource(resource)
    }

    /// The resource `name` now (`None` if not declared).
    pub fn resource_info(&self, name: &str) -> Result<Option<tcm_core::ResourceInfo>, Error> {
        self.ctx.resource_info(name)
    }

    /// Ends the run: waits, as [`Runtime::run`](crate::Runtime::run) does for its task, until every
    /// top-level task's execution completed, a failure is fatal, or the run is stuck (quiescent
    /// with no event handle open); aborts whatever still runs, and reports. The outcome is the
    /// first top-level task's, in spawn order, that did not complete normally (its action failed,
    /// or it was terminated), or completed.
    pub async fn finish(mut self) -> Result<Report, Error> {
        lock(self.shared())?.finishing = true;
        self.shared().wake.notify_one();
        let Some(driver) = self.driver.take() else {
            return Err(Error::RunEnded);
        };
        // A driver that panicked left the engine in an unknown state.
        let outcome = driver.await.map_err(|_| Error::Poisoned)??;
        report(self.shared(), outcome)
    }

    /// Virtual (or real) time since the runtime was created.
    pub fn now(&self) -> Duration {
        self.ctx.now()
    }

    /// A handle to raise external events from anywhere; while one is open, [`Session::finish`]
    /// waits for it rather than end a run with nothing else to do as stuck.
    pub fn events(&self) -> EventHandle {
        self.shared().handles.fetch_add(1, Ordering::SeqCst);
        EventHandle::new(self.shared().clone())
    }

    /// The id of a named external event, for constraints.
    pub fn external(&self, name: &str) -> Result<ExternalId, Error> {
        self.ctx.external(name)
    }

    /// Raises a named external event.
    pub fn raise(&self, name: &str) -> Result<(), Error> {
        self.ctx.raise(name)
    }

    /// Sets the state variable `name` (see [`crate::EventHandle::set_state`]).
    pub fn set_state(&self, name: &str, value: impl Into<crate::StateValue>) -> Result<(), Error> {
        self.ctx
            .with_engine(|e, now| crate::state::set_by_name(e, now, name, value.into()))
    }

    /// The value of the state variable `name`, if it is declared.
    pub fn state(&self, name: &str) -> Result<Option<crate::StateValue>, Error> {
        self.ctx.state(name)
    }

    /// Applies a constraint to an existing node (see [`Ctx::constrain`]).
    pub fn constrain(&self, node: NodeId, c: Constraint) -> Result<(), Error> {
        self.ctx.constrain(node, c)
    }

    /// Terminates `node` and its subtree.
    pub fn terminate(&self, node: NodeId) -> Result<(), Error> {
        self.ctx.terminate(node)
    }

    /// Suspends `node` and its subtree.
    pub fn suspend(&self, node: NodeId) -> Result<(), Error> {
        self.ctx.suspend(node)
    }

    /// Unsuspends `node` and its subtree.
    pub fn unsuspend(&self, node: NodeId) -> Result<(), Error> {
        self.ctx.unsuspend(node)
    }

    /// Activates a monitor now (see [`Ctx::activate`]).
    pub fn activate(&self, monitor: NodeId) -> Result<Option<NodeId>, Error> {
        self.ctx.activate(monitor)
    }

    /// Activates a monitor when `when` happens, that activation carrying `data` (see
    /// [`Ctx::activate_when`]).
    pub fn activate_when<T: Any + Send + Sync>(
        &self,
        monitor: NodeId,
        when: tcm_core::When,
        data: T,
    ) -> Result<(), Error> {
        self.ctx.activate_when(monitor, when, data)
    }

    /// Activates a monitor now with data for that activation (see [`Ctx::activate_with`]).
    pub fn activate_with<T: Any + Send + Sync>(
        &self,
        monitor: NodeId,
        data: T,
    ) -> Result<Option<NodeId>, Error> {
        self.ctx.activate_with(monitor, data)
    }

    /// A snapshot of a node (see [`Ctx::info`]).
    pub fn info(&self, node: NodeId) -> Result<Option<NodeInfo>, Error> {
        self.ctx.info(node)
    }

    /// The parent of a node (see [`Ctx::parent_of`]).
    pub fn parent_of(&self, node: NodeId) -> Result<Option<NodeId>, Error> {
        self.ctx.parent_of(node)
    }

    /// The live children of a node, in spawn order; of the root (`Session::root`), the live
    /// top-level tasks.
    pub fn children(&self, node: NodeId) -> Result<Vec<NodeId>, Error> {
        self.ctx.children(node)
    }

    /// The root node, the parent of every top-level task.
    pub fn root(&self) -> NodeId {
        self.ctx.node
    }

    /// The task a node is an instance of (see [`Ctx::task_name`]).
    pub fn task_name(&self, node: NodeId) -> Result<Option<String>, Error> {
        self.ctx.task_name(node)
    }

    /// Whether a node is an instance of the task named `task`, a monitor's activation also of its
    /// monitor's task (see [`Ctx::is_instance_of`]).
    pub fn is_instance_of(&self, node: NodeId, task: &str) -> Result<bool, Error> {
        self.ctx.is_instance_of(node, task)
    }

    /// A monitor's counts and parameters (see [`Ctx::monitor_info`]).
    pub fn monitor_info(&self, node: NodeId) -> Result<Option<MonitorInfo>, Error> {
        self.ctx.monitor_info(node)
    }

    /// Runs `f` once when `event` happens (see [`Ctx::invoke_when`]); `f` gets a context of the
    /// root.
    pub fn invoke_when<F>(&self, name: impl Into<Name>, event: Event, f: F) -> Result<(), Error>
    where
        F: FnOnce(Ctx, WatchOutcome) + Send + 'static,
    {
        self.ctx.invoke_when(name, event, f)
    }

    /// Runs `f` once after `delay` (see [`Ctx::invoke_after`]); `f` gets a context of the root.
    pub fn invoke_after<F>(&self, name: impl Into<Name>, delay: Duration, f: F) -> Result<(), Error>
    where
        F: FnOnce(Ctx) + Send + 'static,
    {
        self.ctx.invoke_after(name, delay, f)
    }

    /// Runs `f` once at the engine time `at` (see [`Ctx::invoke_at`]).
    pub fn invoke_at<F>(&self, name: impl Into<Name>, at: Time, f: F) -> Result<(), Error>
    where
        F: FnOnce(Ctx) + Send + 'static,
    {
        self.ctx.invoke_at(name, at, f)
    }
}

impl Drop for Session {
    fn drop(&mut self) {
        if let Some(driver) = self.driver.take() {
            driver.abort();
            end_run(self.shared());
        }
    }
}
