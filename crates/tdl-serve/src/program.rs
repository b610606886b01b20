//! What a program needs from outside, and which task runs by default: read from its files by the
//! front end (the model `tdl check` reads), for `tdl run` and the serving executive alike. And
//! the tasks agents offer, registered for a program to spawn.

use std::collections::BTreeSet;

use tdl_interp::{Program, Registry, Value};

/// The tasks a program spawns that it does not write in TDL (its `extern` tasks included), with
/// the kind of each (`extern goal` makes a goal; anything else is a command).
pub fn outside(files: &[(String, String)]) -> Vec<(String, tdl::NodeKind)> {
    let named: Vec<(&str, &str)> = files
        .iter()
        .map(|(n, s)| (n.as_str(), s.as_str()))
        .collect();
    tdl_syntax::compile_program_with(&named, |program, _| {
        let mut out: Vec<(String, tdl::NodeKind)> = Vec::new();
        let mut seen = BTreeSet::new();
        for e in program.externs() {
            let kind = match e.kind {
                tdl_syntax::TaskKind::Goal => tdl::NodeKind::Goal,
                _ => tdl::NodeKind::Command,
            };
            if seen.insert(e.name.to_string()) {
                out.push((e.name.to_string(), kind));
            }
        }
        for t in program.tasks() {
            for name in program.spawned(t.task) {
                let name = name.to_string();
                if program.task(&name).is_none() && seen.insert(name.clone()) {
                    out.push((name, tdl::NodeKind::Command));
                }
            }
        }
        out
    })
}

/// The task to run when none is named: the program's only goal or command no task of it spawns.
pub fn default_task(program: &Program, files: &[(String, String)]) -> Result<String, String> {
    let named: Vec<(&str, &str)> = files
        .iter()
        .map(|(n, s)| (n.as_str(), s.as_str()))
        .collect();
    let spawned: BTreeSet<String> = tdl_syntax::compile_program_with(&named, |p, _| {
        p.tasks()
            .flat_map(|t| {
                p.spawned(t.task)
                    .into_iter()
                    .map(ToString::to_string)
                    .collect::<Vec<_>>()
            })
            .collect()
    });
    let roots: Vec<&str> = program
        .tasks()
        .into_iter()
        .filter(|t| !spawned.contains(*t))
        .collect();
    match roots.as_slice() {
        [one] => Ok((*one).to_string()),
        [] => Err("the program has no task to run: name one".into()),
        many => Err(format!(
            "the program has several tasks no other spawns ({}): name one",
            many.join(", ")
        )),
    }
}

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
