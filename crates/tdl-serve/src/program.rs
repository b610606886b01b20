//! The tasks agents offer, registered for a program to spawn (for `tdl run` and the serving
//! executive alike).

use tdl_interp::{Registry, Value};

/// Registers every task the live agents of `exec` offer, placed on the first agent offering it,
/// its arguments crossing as JSON (one argument as itself, several as an array, as the compiled
/// code sends a tuple, none as null); `kinds` gives the kind of those the program declares
/// (`extern goal`), the rest are commands. Returns what was registered, with the agent.
pub fn register_offers(
    exec: &tcm_zenoh::Executive,
    registry: &mut Registry,
    kinds: &[(String, tdl::NodeKind)],
) -> Vec<(String, String)> {
    let mut out = Vec::new();
    for (task, agents) in exec.offers() {
        let Some(agent) = agents.first().cloned() else {
            continue;
        };
        let kind = kinds
            .iter()
            .find(|(n, _)| *n == task)
            .map_or(tdl::NodeKind::Command, |(_, k)| *k);
        out.push((task.clone(), agent.clone()));
        let (e, name) = (exec.clone(), task.clone());
        registry.task_dynamic(&task, move |args: &[Value]| {
            let json: Result<Vec<serde_json::Value>, String> =
                args.iter().map(Value::to_json).collect();
            let json = json.map_err(|why| tdl::Failure::new("Args", why))?;
            let json = match json.len() {
                0 => serde_json::Value::Null,
                1 => json.into_iter().next().unwrap_or_default(),
                _ => serde_json::Value::Array(json),
            };
            tdl::Placer::place(&e, &agent, &name, kind, json).map_err(tdl::Failure::from)
        });
    }
    out
}
