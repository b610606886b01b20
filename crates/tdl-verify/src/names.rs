//! The names a property may use: every instance name a node of the program can have, as the
//! checker sees it. A property that names none of them is refused ([`check_names`]): it would hold
//! vacuously, and a typo, or a task whose every spawn gives it another `name`, would pass as
//! proved.

use std::collections::BTreeSet;

use tdl_syntax::ast::TaskKind;

use crate::ir::Callee;
use crate::program::Program;
use crate::property::Property;
use crate::value::{Env, Value};

/// A property names a node no run of the program can have.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "property `{property}` names `{name}`, which no {what} of the program is named; the names are: {}",
    known.join(", ")
)]
pub struct UnknownName {
    /// What the name was taken for: `node` or `state variable`.
    pub what: &'static str,
    /// The property, as written.
    pub property: String,
    /// The name it uses that nothing has.
    pub name: String,
    /// The names nodes of the program may have, in order.
    pub known: Vec<String>,
}

/// Checks that every name `properties` use is one a node of `program` may have when `task` is
/// verified: the task itself, each spawn's instance name (its `name "…"`, else its task's name),
/// on-terminate tasks, handlers, and `ACT-<monitor>` for a monitor's activations. A spawn whose
/// name is computed in Rust may have any name: then every name is accepted.
pub fn check_names(
    program: &Program,
    task: &str,
    properties: &[Property],
) -> Result<(), UnknownName> {
    // State variables are the program's own, whatever the task.
    let vars: Vec<String> = program.states.iter().map(|s| s.name.clone()).collect();
    for p in properties {
        for var in p.state_vars() {
            if !vars.contains(&var) {
                return Err(UnknownName {
                    what: "state variable",
                    property: p.text().to_owned(),
                    name: var,
                    known: vars.clone(),
                });
            }
        }
    }
    let Some(known) = node_names(program, task) else {
        return Ok(());
    };
    for p in properties {
        for name in p.names() {
            if !known.contains(name) {
                return Err(UnknownName {
                    what: "node",
                    property: p.text().to_owned(),
                    name: name.to_owned(),
                    known: known.iter().cloned().collect(),
                });
            }
        }
    }
    Ok(())
}

/// The instance names nodes may have; `None` when some name is computed in Rust.
fn node_names(program: &Program, task: &str) -> Option<BTreeSet<String>> {
    let mut names = BTreeSet::new();
    let monitor = |names: &mut BTreeSet<String>, callee: Callee, instance: &str| {
        if let Callee::Task(id) = callee {
            if program.task(id).kind == TaskKind::Monitor {
                names.insert(format!("ACT-{instance}"));
            }
        }
    };
    names.insert(task.to_owned());
    if let Some(&id) = program.by_name.get(task) {
        monitor(&mut names, Callee::Task(id), task);
    }
    for t in &program.tasks {
        if t.kind == TaskKind::Handler {
            names.insert(t.name.to_owned());
        }
        for c in &t.on_terminate {
            names.insert(program.callee_name(c.callee).to_owned());
        }
        for s in &t.body.spawns {
            let task_name = program.callee_name(s.call.callee);
            let instance = match &s.name {
                None => task_name.to_owned(),
                Some(n) => match n.eval(&Env::default()) {
                    Value::Str(s) => s.to_string(),
                    _ => return None,
                },
            };
            monitor(&mut names, s.call.callee, &instance);
            names.insert(instance);
            for (c, _) in &s.on_terminate {
                names.insert(program.callee_name(c.callee).to_owned());
            }
        }
    }
    Some(names)
}
