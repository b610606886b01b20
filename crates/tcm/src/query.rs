//! What a body can ask about the tree (TCM's node queries: states, parent, children, the task a
//! node is an instance of, a monitor's counts and parameters) and the data a monitor activation is
//! given (TCM's `TCM_Activate(node, data)` and `TCM_ActivationData`).
//!
//! These are methods of [`Ctx`], kept here apart from the commands in `ctx.rs`; the program's
//! [`crate::Session`] offers the same queries. The engine answers from its snapshot types
//! ([`NodeInfo`], [`MonitorInfo`], `tcm-core/src/engine/report.rs`); task names and activation data
//! are kept by the host (`host.rs`), since the engine does not need them.

use crate::Error;
use crate::ctx::Ctx;
use crate::host::{Inner, lock};
use std::any::Any;
use std::sync::Arc;
use tcm_core::{MonitorInfo, NodeId, NodeInfo};

// ---- Introspection.
impl Ctx {
    /// A snapshot of `node`: kind, instance name, the state of each facet
    /// ([`NodeInfo::state`], [`NodeInfo::reached`]), termination ([`NodeInfo::is_terminating`],
    /// [`NodeInfo::is_terminated`]), suspension and failure. `None` once the node was reclaimed
    /// (its execution completed, or it was terminated, and its children were reclaimed; a
    /// [`Task::persistent`](crate::Task::persistent) node stays).
    pub fn info(&self, node: NodeId) -> Result<Option<NodeInfo>, Error> {
        Ok(lock(&self.shared)?.engine.info(node))
    }

    /// The parent of `node` (the root for a top-level task); `None` once it was reclaimed.
    pub fn parent_of(&self, node: NodeId) -> Result<Option<NodeId>, Error> {
        Ok(lock(&self.shared)?.engine.parent(node))
    }

    /// The parent of this action's node.
    pub fn parent(&self) -> Result<Option<NodeId>, Error> {
        self.parent_of(self.node)
    }

    /// The live children of `node`, in spawn order.
    pub fn children(&self, node: NodeId) -> Result<Vec<NodeId>, Error> {
        Ok(lock(&self.shared)?.engine.children(node))
    }

    /// The name of the task `node` is an instance of (TCM's type name): the task's own name, which
    /// differs from the instance name once [`Task::named`](crate::Task::named) (TDL's `name`
    /// constraint) renamed it. An activation node's is its activation name (it is an instance of
    /// its monitor's task as well, see [`Ctx::is_instance_of`]), a handler node's its handler's.
    /// `None` once the node was reclaimed.
    pub fn task_name(&self, node: NodeId) -> Result<Option<String>, Error> {
        Ok(task_name_of(&*lock(&self.shared)?, node))
    }

    /// Whether `node` is an instance of the task named `task`: its task name is `task` (see
    /// [`Ctx::task_name`]), or it is a monitor's activation and its monitor's task name is `task`.
    /// So, as in TDL, a monitor and each of its `ACT-` children are instances of the monitor's
    /// task, and an activation is also an instance of its own activation name. A reclaimed node is
    /// an instance of nothing.
    pub fn is_instance_of(&self, node: NodeId, task: &str) -> Result<bool, Error> {
        let inner = lock(&self.shared)?;
        if task_name_of(&inner, node).is_some_and(|t| t == task) {
            return Ok(true);
        }
        let monitor = inner.engine.monitor_info(node).map(|m| m.monitor);
        Ok(monitor
            .filter(|m| *m != node)
            .and_then(|m| task_name_of(&inner, m))
            .is_some_and(|t| t == task))
    }

    /// A monitor's counts (activations, triggers) and parameters (maximum activations and
    /// triggers, period, initial wait), given the monitor or one of its activation nodes; `None`
    /// for another node, or once reclaimed.
    pub fn monitor_info(&self, node: NodeId) -> Result<Option<MonitorInfo>, Error> {
        Ok(lock(&self.shared)?.engine.monitor_info(node))
    }
}

// ---- Activation data.
impl Ctx {
    /// Activates a monitor now with `data` for that activation's body, which reads it with
    /// [`Ctx::activation_data`] (TCM's `TCM_Activate(monitor, data)`). Returns the activation node,
    /// or `None` past the monitor's maximum (the data is then dropped). As [`Ctx::activate`], an
    /// error if the monitor's handling is not active.
    pub fn activate_with<T: Any + Send + Sync>(
        &self,
        monitor: NodeId,
        data: T,
    ) -> Result<Option<NodeId>, Error> {
        let mut inner = self.shared.enter()?;
        let now = inner.engine.at_clock();
        let act = inner.engine.activate(now, monitor)?;
        // Kept before this access ends, so before the activation's body can start.
        if let Some(act) = act {
            inner.keep_activation_data(act, Arc::new(data));
        }
        Ok(act)
    }

    /// Activates `monitor` when `when` happens, that activation carrying `data` for its body,
    /// which reads it with [`Ctx::activation_data`] (TCM's `TCM_ActivateAt(monitor, event, data)`,
    /// `TCM_ActivateIn(monitor, delay, data)`, `TCM_ActivateInAfter`). `when` is an event of a
    /// node, a time or a delay (`When::Now`, `At`, `In`, `Event`, `After`); a condition, a change
    /// or an external event is refused, since it makes activations of its own (an external event
    /// raised with data gives them its data). Like the constraint `activate at E`: applied to a
    /// monitor that is not handling yet, it waits for it, and past the monitor's maximum it makes
    /// no activation.
    pub fn activate_when<T: Any + Send + Sync>(
        &self,
        monitor: NodeId,
        when: tcm_core::When,
        data: T,
    ) -> Result<(), Error> {
        let mut inner = self.shared.enter()?;
        let now = inner.engine.at_clock();
        inner
            .engine
            .activate_when(now, monitor, when, Arc::new(data))?;
        Ok(())
    }

    /// In a monitor activation: the data it was activated with ([`Ctx::activate_with`], or an
    /// external event raised with data, [`EventHandle::raise_with`](crate::EventHandle::raise_with)),
    /// if it is a `T`. `None` for an activation made otherwise (a period, a constraint, an event
    /// without data).
    pub fn activation_data<T: Any + Send + Sync>(&self) -> Option<Arc<T>> {
        let inner = lock(&self.shared).ok()?;
        let data = match inner.activation_data.get(&self.node) {
            Some(d) => d.clone(),
            None => inner.engine.activation_data(self.node)?,
        };
        data.downcast::<T>().ok()
    }
}

/// The task name of `node` (see [`Ctx::task_name`]), `None` once it was reclaimed.
fn task_name_of(inner: &Inner, node: NodeId) -> Option<String> {
    let info = inner.engine.info(node)?;
    Some(match inner.task_names.get(&node) {
        Some(name) => name.to_string(),
        None => info.name,
    })
}
