//! Loading a program: its files parsed, resolved and checked as one program, exactly as `tdl
//! check` and the compiler do (`tdl_syntax::compile_program_with`); then every task lowered
//! against the registry. The diagnostics of both steps, errors refusing the program, are
//! rendered file by file with their lines, as `tdl check` prints them.

use std::collections::BTreeMap;
use std::sync::Arc;

use tdl_syntax::ast::Item;
use tdl_syntax::{Diagnostic, hir};

use crate::LoadError;
use crate::exec::Budget;
use crate::ir::TaskDef;
use crate::lower::{ProgramNames, lower_task};
use crate::program::{Program, Shared};
use crate::registry::Registry;

/// Loads the program of `files` against `registry`.
pub(crate) fn load(
    files: &[(String, String)],
    registry: &Registry,
    budget: Budget,
) -> Result<Program, LoadError> {
    if files.is_empty() {
        return Err(LoadError::NoFile);
    }
    let named: Vec<(&str, &str)> = files
        .iter()
        .map(|(n, s)| (n.as_str(), s.as_str()))
        .collect();
    tdl_syntax::compile_program_with(&named, |program, results| {
        let mut rendered = String::new();
        let mut warnings = Vec::new();
        for ((name, src), (_, diags)) in named.iter().zip(results) {
            let errors: Vec<Diagnostic> = diags.iter().filter(|d| d.is_error()).cloned().collect();
            if !errors.is_empty() {
                rendered.push_str(&tdl_syntax::render_all(&errors, name, Some(src)));
                rendered.push('\n');
            }
            let w: Vec<Diagnostic> = diags.into_iter().filter(|d| !d.is_error()).collect();
            if !w.is_empty() {
                warnings.push(tdl_syntax::render_all(&w, name, Some(src)));
            }
        }
        if !rendered.is_empty() {
            return Err(LoadError::Invalid(rendered));
        }
        build(program, &named, registry, budget)
    })
}

/// What every body may name, from the resolved program.
fn names(program: &hir::Program<'_>) -> ProgramNames {
    let mut tasks = BTreeMap::new();
    for (i, t) in program.tasks().enumerate() {
        tasks.entry(t.task.name.to_string()).or_insert(i);
    }
    let mut exceptions = BTreeMap::new();
    for (_, e) in program.exceptions() {
        let name = e.name.to_string();
        let ancestry = program
            .ancestry(&name)
            .iter()
            .map(|a| Arc::from(a.as_str()))
            .collect();
        let fields = e
            .fields
            .iter()
            .map(|f| Arc::from(f.name.to_string()))
            .collect();
        exceptions.insert(name, (ancestry, fields));
    }
    let mut states = BTreeMap::new();
    for s in program.states() {
        let ty = s.ty().unwrap_or(tcm_expr::Type::Bool);
        let var = tdl::StateVar::new(s.name.to_string(), ty, s.initial());
        states.insert(s.name.to_string(), (var, ty));
    }
    let mut externs = BTreeMap::new();
    for e in program.externs() {
        let params = e.args.iter().map(|a| crate::ty::Ty::of(&a.ty)).collect();
        let result = e.result.as_ref().map(crate::ty::Ty::of);
        externs.insert(e.name.to_string(), (params, result));
    }
    ProgramNames {
        tasks,
        exceptions,
        states,
        externs,
    }
}

fn build(
    program: &hir::Program<'_>,
    files: &[(&str, &str)],
    registry: &Registry,
    budget: Budget,
) -> Result<Program, LoadError> {
    let names = names(program);
    // What the program's bodies spawn: an extern task none spawns is only a name, the target of
    // a handler declared `for` it (a program of recovery for another program's task), and needs
    // no registry to offer it.
    let spawned: std::collections::BTreeSet<String> = program
        .tasks()
        .flat_map(|t| {
            program
                .spawned(t.task)
                .into_iter()
                .map(|n| n.to_string())
                .collect::<Vec<_>>()
        })
        .collect();
    let mut tasks: Vec<TaskDef> = Vec::new();
    let mut rendered = String::new();
    for (file, (name, src)) in program.files().iter().zip(files) {
        let mut diags = Vec::new();
        for item in &file.ast.items {
            match item {
                Item::Task(task) => {
                    tasks.push(lower_task(
                        registry,
                        &names,
                        &file.scope,
                        name,
                        task,
                        &mut diags,
                    ));
                }
                Item::Rust(item) => {
                    use syn::spanned::Spanned;
                    diags.push(
                        Diagnostic::error(
                            item.span(),
                            "a Rust item in a TDL file is not in the interpreted subset of TDL",
                        )
                        .with_hint(format!(
                            "{}; register what it defines (`Registry::function`, `Registry::constant`, ...) in the executive instead",
                            crate::lower::SUBSET_HINT
                        )),
                    );
                }
                Item::Extern(e)
                    if spawned.contains(&e.name.to_string())
                        && !registry.tasks.contains_key(&e.name.to_string()) =>
                {
                    let offered = registry.task_names();
                    diags.push(
                        Diagnostic::error(
                            e.span,
                            format!(
                                "the program declares the extern {} `{}`, which no registry offers",
                                e.kind.as_str(),
                                e.name
                            ),
                        )
                        .with_hint(if offered.is_empty() {
                            "register it (`Registry::task`), or start the agent that offers it".to_string()
                        } else {
                            format!(
                                "register it (`Registry::task`), or start the agent that offers it; offered: {}",
                                crate::lower::list(&offered)
                            )
                        }),
                    );
                }
                Item::Exception(_)
                | Item::Resource(_)
                | Item::State(_)
                | Item::Environment(_)
                | Item::Extern(_) => {}
            }
        }
        diags.sort_by_key(|d| d.start());
        if !diags.is_empty() {
            rendered.push_str(&tdl_syntax::render_all(&diags, name, Some(src)));
            rendered.push('\n');
        }
    }
    if !rendered.is_empty() {
        return Err(LoadError::Invalid(rendered));
    }
    let mut ancestry: BTreeMap<String, Vec<Arc<str>>> = registry
        .exceptions
        .iter()
        .map(|(k, v)| (k.clone(), v.iter().map(|a| Arc::from(a.as_str())).collect()))
        .collect();
    for (k, (a, _)) in &names.exceptions {
        ancestry.insert(k.clone(), a.clone());
    }
    Ok(Program {
        shared: Arc::new(Shared {
            registry: registry.clone(),
            tasks,
            by_name: names.tasks,
            yield_every: std::sync::atomic::AtomicU32::new(budget.yield_every.max(1)),
            max_steps: std::sync::atomic::AtomicU64::new(budget.max_steps),
            ancestry,
            hash: content_hash(files),
            version: std::sync::OnceLock::new(),
            successor: std::sync::RwLock::new(None),
            superseded: std::sync::atomic::AtomicBool::new(false),
        }),
    })
}

/// The program's content hash: the first 12 hex digits of the SHA-256 of its files' texts, in
/// order (their names are left out, so the same program read from another place has the same
/// hash).
fn content_hash(files: &[(&str, &str)]) -> String {
    use sha2::Digest;
    let mut h = sha2::Sha256::new();
    for (_, text) in files {
        h.update((text.len() as u64).to_le_bytes());
        h.update(text.as_bytes());
    }
    h.finalize()
        .iter()
        .take(6)
        .map(|b| format!("{b:02x}"))
        .collect()
}
