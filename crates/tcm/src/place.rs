//! Placing a task on another process (TDL's `on AGENT`; docs/distributed.md): arguments and
//! values as they cross; the hook a distribution layer implements is [`crate::Placer`]
//! (`task.rs`), the context's way to use it `Ctx::remote_task` (`ctx/place.rs`).
//!
//! The runtime knows nothing of agents: it asks its [`Placer`] for the task that stands for
//! `name(args)` on `agent`, and spawns that like any other, with every constraint of the spawn.
//! Arguments cross the process boundary as JSON: none is `null`, one is itself, several are an
//! array (as the tuple they are serialises).

use serde::Serialize;
use serde::de::DeserializeOwned;

/// A value as it crosses to or from an agent.
pub type Json = serde_json::Value;

use crate::Error;

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
