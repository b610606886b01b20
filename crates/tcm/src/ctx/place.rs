//! A task placed on an agent by the run's placer (TDL's `spawn … with on AGENT`).

use super::Ctx;
use crate::place::Json;
use crate::{Error, NodeKind, Placer as _, Task};

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
