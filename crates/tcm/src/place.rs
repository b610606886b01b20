//! Placing a task on another process: the hook a distribution layer (such as `tcm-zenoh`)
//! implements, and the context's way to use it (TDL's `on AGENT`; docs/distributed.md).
//!
//! The runtime knows nothing of agents: it asks its [`Placer`] for the task that stands for
//! `name(args)` on `agent`, and spawns that like any other, with every constraint of the spawn.
//! Arguments cross the process boundary as JSON: none is `null`, one is itself, several are an
//! array (as the tuple they are serialises).

use std::sync::Arc;

use serde::Serialize;
use serde::de::DeserializeOwned;

/// A value as it crosses to or from an agent.
pub type Json = serde_json::Value;

use crate::{Ctx, Error, NodeKind, Task};

/// Makes the task that runs `name(args)` on another process, the agent `agent`. Set with
/// [`crate::Runtime::placer`]; `tcm_zenoh::Executive` is one.
pub trait Placer: Send + Sync + 'static {
    /// The task for `name(args)` on `agent`, a goal or a command as `kind` says. Its node is the
    /// tree's like any other; its action runs on the agent.
    fn place(&self, agent: &str, name: &str, kind: NodeKind, args: Json) -> Result<Task, Error>;
}

impl<P: Placer + ?Sized> Placer for Arc<P> {
    fn place(&self, agent: &str, name: &str, kind: NodeKind, args: Json) -> Result<Task, Error> {
        (**self).place(agent, name, kind, args)
    }
}

/// Arguments as they cross to an agent: `args` serialised to JSON (TDL passes `()` for none, the
/// value itself for one, a tuple for several).
pub fn remote_args<T: Serialize + ?Sized>(
    task: &str,
    args: &T,
) -> Result<serde_json::Value, Error> {
    serde_json::to_value(args).map_err(|e| Error::Args {
        task: task.to_string(),
        reason: e.to_string(),
    })
}

/// The value a task placed on an agent returned, read as a `T` (TDL's `let v: T = spawn t(..)
/// with on "arm", wait;`).
pub fn remote_value<T: DeserializeOwned>(task: &str, value: Json) -> Result<T, Error> {
    serde_json::from_value(value).map_err(|e| Error::RemoteValue {
        task: task.to_string(),
        reason: e.to_string(),
    })
}

impl Ctx {
    /// The task that runs `name(args)` on the agent `agent`, made by the run's [`Placer`]; spawn
    /// it as any task. TDL's `spawn name(args) with on agent`. An error if the run has no placer.
    pub fn remote_task(
        &self,
        agent: &str,
        name: &str,
        kind: NodeKind,
        args: Json,
    ) -> Result<Task, Error> {
        let placer = self.shared.placer();
        match placer {
            Some(p) => p.place(agent, name, kind, args),
            None => Err(Error::NoPlacer {
                task: name.to_string(),
                agent: agent.to_string(),
            }),
        }
    }
}
