//! What a program needs from outside, and which task runs by default: read from its files by the
//! front end (the model `tdl check` reads), for `tdl run` and the serving executive alike.

use std::collections::BTreeSet;

use crate::Program;

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
