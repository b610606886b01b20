//! A spawn being built ([`Spawner`]): its constraints, monitor parameters, handlers, resources
//! and on-terminate tasks, then started or waited for; how a waited-for child ended ([`Ended`]).

use super::Ctx;
use crate::Error;
use crate::host::lock;
use crate::task::{Action, Factory, Handler, Kept, Task, Value};
use std::time::Duration;
use tcm_core::{Constraint, Event, Facet, Failure, NodeId, NodeRef, Spawn, WatchOutcome, When};

/// A spawn being built: add constraints, then [`Spawner::start`] it or [`Spawner::wait`] for it.
#[must_use = "a spawn does nothing until `start` or `wait` is called"]
pub struct Spawner<'a> {
    pub(super) ctx: &'a Ctx,
    pub(super) spec: Spawn<Action, Factory>,
    // What the host keeps beside the node: the task's name, when `Task::named` gave the instance
    // another, and the arguments.
    pub(super) kept: Kept,
}

impl Spawner<'_> {
    /// Adds any constraint.
    #[inline]
    pub fn with(mut self, c: Constraint) -> Self {
        self.spec.constraints.push(c);
        self
    }

    /// `sequential <facet> <reference>`.
    #[inline]
    pub fn sequential(self, facet: Facet, of: impl Into<NodeRef>) -> Self {
        self.with(Constraint::Sequential(facet, of.into()))
    }

    /// `serial <reference>`.
    #[inline]
    pub fn serial(self, of: impl Into<NodeRef>) -> Self {
        self.with(Constraint::Serial(of.into()))
    }

    /// `expand first`.
    #[inline]
    pub fn expand_first(self) -> Self {
        self.with(Constraint::ExpandFirst)
    }

    /// `delay expansion`.
    #[inline]
    pub fn delay_expansion(self) -> Self {
        self.with(Constraint::DelayExpansion)
    }

    /// `disable <facet> until <event>`.
    #[inline]
    pub fn disable_until(self, facet: Facet, event: Event) -> Self {
        self.with(Constraint::disable(facet, When::Event(event)))
    }

    /// `disable <facet> for <duration>`.
    #[inline]
    pub fn disable_for(self, facet: Facet, d: Duration) -> Self {
        self.with(Constraint::disable(facet, When::In(d)))
    }

    /// `terminate at <event>`.
    #[inline]
    pub fn terminate_at(self, event: Event) -> Self {
        self.with(Constraint::terminate(When::Event(event)))
    }

    /// `terminate in <duration>`.
    #[inline]
    pub fn terminate_in(self, d: Duration) -> Self {
        self.with(Constraint::terminate(When::In(d)))
    }

    /// `activate …` (monitors).
    #[inline]
    pub fn activate(self, when: When) -> Self {
        self.with(Constraint::activate(when))
    }

    /// Overrides the monitor's maximum activations for this spawn.
    #[inline]
    pub fn max_activations(mut self, n: u32) -> Self {
        if let Some(m) = self.spec.monitor.as_mut() {
            m.max_activations = Some(n);
        }
        self
    }

    /// Overrides the monitor's maximum triggers for this spawn.
    #[inline]
    pub fn max_triggers(mut self, n: u32) -> Self {
        if let Some(m) = self.spec.monitor.as_mut() {
            m.max_triggers = Some(n);
        }
        self
    }

    /// Overrides the monitor's polling period for this spawn.
    #[inline]
    pub fn period(mut self, d: Duration) -> Self {
        if let Some(m) = self.spec.monitor.as_mut() {
            m.period = Some(d);
        }
        self
    }

    /// Attaches a spawn-level exception handler (tried after the task-level ones; among spawn-level
    /// handlers, in the order attached).
    #[inline]
    pub fn handler(mut self, h: Handler) -> Self {
        self.spec.handlers.push(h.spec);
        self
    }

    /// Sets the grace period of this node's action, as [`Task::grace`] does for every node of a
    /// task (docs/semantics.md, "Termination").
    #[inline]
    pub fn grace(mut self, grace: Duration) -> Self {
        self.kept.grace = Some(grace);
        self
    }

    /// The node uses `amount` of the resource `resource` (a name the run declared, or a
    /// [`crate::Resource`], declared on first use), besides what its task uses: all are granted
    /// at once before it starts, and released when its action ends (docs/semantics.md,
    /// "Resources"). Until then it waits, enabled; asking for more than a capacity fails it with
    /// [`crate::ResourceDenied`].
    #[inline]
    pub fn uses(mut self, resource: impl Into<crate::ResourceRef>, amount: u32) -> Self {
        self.kept
            .wanted
            .get_or_insert_with(Box::default)
            .uses
            .push((resource.into(), amount));
        self
    }

    /// The priority of the node's request for resources: lower is granted first, requests of one
    /// priority in the order they were made (0 by default).
    #[inline]
    pub fn priority(mut self, priority: i32) -> Self {
        self.kept.wanted.get_or_insert_with(Box::default).priority = Some(priority);
        self
    }

    /// If its resources cannot be granted at once, the node does not wait: it fails with
    /// [`crate::ResourceDenied`], which a handler may take (TDL's `deny if busy`).
    #[inline]
    pub fn deny_if_busy(mut self) -> Self {
        self.kept
            .wanted
            .get_or_insert_with(Box::default)
            .deny_if_busy = true;
        self
    }

    /// Holds the node at its turn to start until an operator approves it through the run's
    /// [`Control`](crate::Control) (TDL's `with approval [within T]`): refused, or not approved
    /// within `timeout`, it fails with [`crate::ApprovalRefused`] (docs/semantics.md, "Steering a
    /// run", rule 5).
    #[inline]
    pub fn approval(mut self, timeout: Option<Duration>) -> Self {
        self.spec
            .constraints
            .push(tcm_core::Constraint::Approval(timeout));
        self
    }

    /// Keep the node after it completes (not reclaimed).
    #[inline]
    pub fn persistent(mut self) -> Self {
        self.spec.persistent = true;
        self
    }

    /// `on terminate spawn <task>`: run `task` as a child if this node is terminated while its action
    /// runs; it runs to completion.
    #[inline]
    pub fn on_terminate(mut self, task: Task) -> Self {
        if let Some(ot) = task.into_cleanup() {
            self.spec.on_terminate.push(ot);
        }
        self
    }

    /// Fulfils a reservation made with [`Ctx::reserve`].
    #[inline]
    pub fn fulfils(mut self, reserved: NodeId) -> Self {
        self.spec.fulfils = Some(reserved);
        self
    }

    /// Inserts the node under another parent than the spawning action's node (TDL's `parent`).
    #[inline]
    pub fn under(mut self, parent: NodeId) -> Self {
        self.spec.parent = parent;
        self
    }

    /// Inserts the node; returns at once (TDL's non-blocking `spawn`).
    #[inline]
    pub fn start(self) -> Result<NodeId, Error> {
        let mut inner = self.ctx.shared.enter()?;
        Ok(inner.spawn(None, self.spec, self.kept)?)
    }

    /// Inserts the node and waits until its execution completes (TDL's `with wait`).
    pub async fn wait(self) -> Result<WatchOutcome, Error> {
        let ctx = self.ctx;
        let id = self.start()?;
        ctx.wait(id).await
    }

    /// Inserts the node, waits for it, and returns the value its action returned. The child's
    /// failure that no handler on the child takes is this body's: it fails with it
    /// ([`Error::ChildFailed`], whose `?` keeps the exception's type); a retry's success is the
    /// child's, and its value the value.
    pub async fn wait_value<T: 'static>(self) -> Result<T, Error> {
        match self.wait_outcome::<T>().await? {
            Ended::Succeeded(v) => Ok(v),
            Ended::Failed(f) => Err(Error::ChildFailed(tcm_core::PassedOn(f))),
            Ended::Terminated => Err(Error::ChildTerminated),
            Ended::Skipped => Err(Error::ChildSkipped),
        }
    }

    /// Inserts the node, waits for it, and returns how it ended: succeeded with its value, failed
    /// with its (typed) failure, or terminated. The failure is the caller's to look at, so no
    /// handler above the child is searched for it and it is not reported unhandled (handlers on
    /// the child, and their retries, come first: a recovered child succeeded).
    pub async fn wait_outcome<T: 'static>(self) -> Result<Ended<T>, Error> {
        match self.wait_outcome_erased().await? {
            Ended::Succeeded(value) => match value.map(|v| v.downcast::<T>()) {
                Some(Ok(v)) => Ok(Ended::Succeeded(*v)),
                _ => Err(Error::NoValue(std::any::type_name::<T>())),
            },
            Ended::Failed(f) => Ok(Ended::Failed(f)),
            Ended::Terminated => Ok(Ended::Terminated),
            Ended::Skipped => Ok(Ended::Skipped),
        }
    }

    /// As [`Spawner::wait_outcome`], the value as the action returned it, of whatever type (none
    /// when the action's value was taken already): for a caller that learns the type only from
    /// the value, as TDL's interpreter does.
    pub async fn wait_outcome_erased(
        self,
    ) -> Result<Ended<Option<Box<dyn std::any::Any + Send>>>, Error> {
        let ctx = self.ctx;
        let id = {
            let mut inner = ctx.shared.enter()?;
            let id = inner.spawn(None, self.spec, self.kept)?;
            inner.values.insert(id, None);
            inner.engine.propagate(id)?;
            id
        };
        let outcome = ctx.wait(id).await?;
        let value: Option<Value> = {
            let mut inner = lock(&ctx.shared)?;
            let first = inner.values.remove(&id).flatten();
            match &outcome {
                // A retry succeeded: its value is the task's.
                WatchOutcome::Recovered { by, .. } => inner.values.remove(by).flatten(),
                _ => first,
            }
        };
        Ok(match outcome {
            WatchOutcome::Reached | WatchOutcome::Recovered { .. } => Ended::Succeeded(value),
            WatchOutcome::Failed(f) | WatchOutcome::Handled(f) => Ended::Failed(f),
            WatchOutcome::Terminated | WatchOutcome::Dead => Ended::Terminated,
            WatchOutcome::Skipped => Ended::Skipped,
        })
    }

    /// The child's failure that no handler on it takes fails this node, the parent, as if its
    /// action had raised it (what a behaviour-tree sequence does): the parent's action stops if
    /// it still runs, its other children are terminated, and its handlers are searched, so one of
    /// them may `retry` the whole subtree (TDL's `with propagate`; docs/semantics.md, "Failing
    /// the parent"). Under the root it changes nothing.
    #[inline]
    pub fn propagate(mut self) -> Self {
        self.kept.fail_parent = true;
        self
    }
}

/// How a waited child ended ([`Spawner::wait_outcome`], TDL's `let o = spawn t() with outcome;`).
#[derive(Debug)]
pub enum Ended<T> {
    /// Its execution completed and it did not fail (or a retry of it succeeded): its value.
    Succeeded(T),
    /// It failed, and no handler on it recovered it: the failure, its exception's type kept.
    Failed(Failure),
    /// It was terminated before it ended by itself.
    Terminated,
    /// It was skipped: its `skip if` condition held when its turn came (docs/semantics.md,
    /// "State and conditions"), so it has no value.
    Skipped,
}

impl<T> Ended<T> {
    /// It succeeded.
    pub fn succeeded(&self) -> bool {
        matches!(self, Ended::Succeeded(_))
    }

    /// It failed.
    pub fn failed(&self) -> bool {
        matches!(self, Ended::Failed(_))
    }

    /// It was terminated.
    pub fn terminated(&self) -> bool {
        matches!(self, Ended::Terminated)
    }

    /// It was skipped.
    pub fn skipped(&self) -> bool {
        matches!(self, Ended::Skipped)
    }

    /// Its value, if it succeeded.
    pub fn value(self) -> Option<T> {
        match self {
            Ended::Succeeded(v) => Some(v),
            _ => None,
        }
    }

    /// Its failure, if it failed.
    pub fn failure(&self) -> Option<&Failure> {
        match self {
            Ended::Failed(f) => Some(f),
            _ => None,
        }
    }

    /// It failed with an exception of type `E` or of a descendant of `E`.
    pub fn failed_with<E: crate::Exception>(&self) -> bool {
        self.failure().is_some_and(|f| f.is_a(E::name()))
    }

    /// The outcome's point (`X succeeded`, `X failed`, `X terminated`, `X skipped`).
    pub fn outcome(&self) -> tcm_core::Outcome {
        match self {
            Ended::Succeeded(_) => tcm_core::Outcome::Succeeded,
            Ended::Failed(_) => tcm_core::Outcome::Failed,
            Ended::Terminated => tcm_core::Outcome::Terminated,
            Ended::Skipped => tcm_core::Outcome::Skipped,
        }
    }
}

// ---- On-terminate labels set from a body (`on terminate label: spawn …`).

impl Spawner<'_> {
    /// `on terminate label: spawn <task>`: as [`Spawner::on_terminate`], and the on-terminate node,
    /// if it is ever inserted, fulfils `reserved` (a reservation of the spawning node, made with
    /// [`Ctx::reserve`]). The spawned node takes the reservation over, so it dies when that node's
    /// handling completes without being terminated while running (docs/semantics.md, "Tags and
    /// forward references").
    pub fn on_terminate_fulfils(mut self, task: Task, reserved: NodeId) -> Self {
        if let Some(mut ot) = task.into_cleanup() {
            ot.fulfils = Some(reserved);
            self.spec.on_terminate.push(ot);
        }
        self
    }
}
