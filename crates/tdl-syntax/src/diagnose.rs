//! The static diagnosis of a parsed [`Ast`] (docs/semantics.md, "Tags and forward references"): what is wrong with a source, as
//! diagnostics, before any code is generated. It runs as part of parsing.
//!
//! It reads the resolved program of `hir` (`hir.rs`) and words what they found: duplicate tasks, exceptions and
//! labels; unknown and ambiguous tags, wrong iteration index counts, forward references to `with`
//! groups, `[.]` outside the loop it counts. It also finds, by itself: unknown exceptions
//! (only when the file declares exceptions, since others may come from Rust), which task-level
//! constraints each task kind allows, `wait` on a forward reference, circular constraints on
//! `self`, monitor-only constraints on other tasks, constraints that only go on a spawn, misused
//! `node!(tag)`, `bind` and `parent`, and the statements that only handlers or monitors may use.
//!
//! Its submodules check the program as a whole (docs/language.md, "Static checks"): circular
//! constraints (`cycles.rs`) and waits that cannot end (`waits.rs`) in each body, on the model of
//! its waits in `flow.rs`; exceptions no handler handles (`raises.rs`) and recursion without a
//! base case (`recursion.rs`) over every file of the program; `graph.rs` finds the cycles. What
//! is found in one task body (its statements, spawns, constraints and tags) is in `body.rs`; this
//! file checks the names of the program and each task's header.

mod body;
mod caught;
mod cycles;
mod flow;
mod graph;
mod raises;
mod recursion;
mod waits;

use proc_macro2::{Ident, Span};
use quote::ToTokens;

use crate::ast::{Ast, Item, Task, TaskConstraintKind, TaskKind};
use crate::diagnostic::Diagnostic;

mod resources;
mod state;

use crate::hir::{Duplicate, FileScope};

/// Diagnoses `ast` and appends the findings to `diags`.
pub(crate) fn diagnose(ast: &Ast, diags: &mut Vec<Diagnostic>) {
    diagnose_in(&FileScope::new(ast), ast, diags);
}

/// Diagnoses `ast`, one file of a program whose names `file` resolves, and appends the findings
/// to `diags`.
pub(crate) fn diagnose_in(file: &FileScope<'_>, ast: &Ast, diags: &mut Vec<Diagnostic>) {
    for it in &file.elsewhere {
        let name = it.name;
        diags.push(
            Diagnostic::error(
                name.span(),
                format!("`{name}` is also declared in {}", it.file),
            )
            .with_label_in(it.file, it.first, "first declared here")
            .with_hint("the files of a program share one name space: rename one of them"),
        );
    }
    for duplicate in &file.duplicates {
        diags.push(match duplicate {
            Duplicate::Task(task, first) => {
                Diagnostic::error(task.span, format!("duplicate task `{}`", task.name))
                    .with_label(first.span, "first defined here")
                    .with_hint("rename one of the tasks")
            }
            Duplicate::Exception(exc, first) => {
                Diagnostic::error(exc.span, format!("duplicate exception `{}`", exc.name))
                    .with_label(first.span, "first declared here")
                    .with_hint("rename one of the exceptions")
            }
            Duplicate::Resource(r, first) => {
                Diagnostic::error(r.span, format!("duplicate resource `{}`", r.name))
                    .with_label(first.span, "first declared here")
                    .with_hint("rename one of the resources")
            }
            Duplicate::State(v, first) => {
                Diagnostic::error(v.span, format!("duplicate state variable `{}`", v.name))
                    .with_label(first.span, "first declared here")
                    .with_hint("a state variable is declared once per program: remove one")
            }
        });
    }
    for item in &ast.items {
        match item {
            Item::Task(task) => {
                task_header(file, task, diags);
                let body = body::Body {
                    file,
                    task,
                    scope: file.body(task),
                };
                body.diagnose(diags);
                state::body(file, body.scope, diags);
                let flow = flow::Flow::new(file, task, body.scope);
                cycles::check(&flow, body.scope, diags);
                waits::check(&flow, body.scope, diags);
            }
            Item::Exception(exc) => {
                if let Some(parent) = &exc.parent {
                    exception(file, parent, diags);
                }
            }
            Item::Resource(_) | Item::Rust(_) => {}
            Item::Extern(decl) => externs(file, decl, diags),
            Item::State(decl) => state::declaration(decl, diags),
            Item::Environment(env) => state::environment(file, env, diags),
        }
    }
    raises::check(file, ast, diags);
    recursion::check(file, ast, diags);
    resources::diagnose(file, ast, diags);
}

/// Reports `name` when the program declares exceptions and `name` is not one of them.
fn exception(file: &FileScope<'_>, name: &Ident, diags: &mut Vec<Diagnostic>) {
    let known: Vec<&str> = file.exception_names().collect();
    if known.is_empty() || file.declares_exception(&name.to_string()) {
        return;
    }
    diags.push(
        Diagnostic::error(name.span(), format!("unknown exception `{name}`")).with_hint(format!(
            "declare it with `exception {name};` or use one of: {}",
            known.join(", ")
        )),
    );
}

/// Reports a handler reference that names a known task which is not a handler, or a handler
/// attached to a task with `for`.
fn handler(file: &FileScope<'_>, name: &Ident, diags: &mut Vec<Diagnostic>) {
    if let Some(target) = file
        .task(&name.to_string())
        .and_then(|t| t.for_task.as_ref())
    {
        diags.push(
            Diagnostic::error(
                name.span(),
                format!("`{name}` is attached to every `{target}` (`for {target}`); it cannot also be given here"),
            )
            .with_hint(format!(
                "attach it on the runtime with `.attach({name}())`, or remove `for {target}` from its definition to give it at a spawn"
            )),
        );
        return;
    }
    if let Some(kind) = file.kind_of(&name.to_string()) {
        if kind != TaskKind::Handler {
            diags.push(
                Diagnostic::error(
                    name.span(),
                    format!("`{name}` is a {}, not an exception handler", kind.as_str()),
                )
                .with_hint("define it with `handler NAME(args) handles Exception { ... }`"),
            );
        }
    }
}

/// Checks `handler h(args) handles E for target`: `target` is a goal or command of the program,
/// and `h` takes none or all of its arguments.
fn attached_to(file: &FileScope<'_>, task: &Task, target: &Ident, diags: &mut Vec<Diagnostic>) {
    // How the declaration names its target, for the hints.
    let (how, what) = match &task.tap {
        Some(tap) if tap.after => ("after", "wiretap"),
        Some(_) => ("before", "wiretap"),
        None => ("for", "handler"),
    };
    let name = target.to_string();
    // A task written elsewhere and declared `extern` takes handlers too (a program of recovery
    // loaded beside the one it recovers).
    let (kind, args) = match (file.task(&name), file.extern_decl(&name)) {
        (Some(found), _) => (found.kind, &found.args),
        (None, Some(e)) => (e.kind, &e.args),
        (None, None) => {
            diags.push(
                Diagnostic::error(target.span(), format!("unknown task `{target}`"))
                    .with_hint(format!(
                        "`{how} {target}` attaches the {what} to a goal or command of the program (or one it declares `extern`); attach one to a task written in Rust with `Runtime::handler_for` or `Runtime::wiretap`"
                    )),
            );
            return;
        }
    };
    if !matches!(kind, TaskKind::Goal | TaskKind::Command) {
        diags.push(Diagnostic::error(
            target.span(),
            format!(
                "`{target}` is a {}; a handler or a wiretap is attached to a goal or a command",
                kind.as_str()
            ),
        ));
        return;
    }
    if !task.args.is_empty() && task.args.len() != args.len() {
        let theirs: Vec<String> = args
            .iter()
            .map(|a| format!("{}: {}", a.name, a.ty.to_token_stream()))
            .collect();
        diags.push(
            Diagnostic::error(
                task.span,
                format!(
                    "`{}` takes {} argument(s) but `{target}` has {}",
                    task.name,
                    task.args.len(),
                    args.len()
                ),
            )
            .with_hint(format!(
                "a handler attached with `for` (or a wiretap) receives the arguments of the node it recovers (or checks): declare none, or all of `{target}`'s: ({})",
                theirs.join(", ")
            )),
        );
    }
}

fn task_constraint_name(kind: &TaskConstraintKind) -> &'static str {
    match kind {
        TaskConstraintKind::ExpandFirst => "expand first",
        TaskConstraintKind::DelayExpansion => "delay expansion",
        TaskConstraintKind::ExceptionHandler(_) => "exception handler",
        TaskConstraintKind::OnTerminate(_) => "on terminate",
        TaskConstraintKind::Persistent(_) => "persistent",
        TaskConstraintKind::MaximumActivate(_) => "maximum activate",
        TaskConstraintKind::MaximumTrigger(_) => "maximum trigger",
        TaskConstraintKind::Period(_) => "period",
        TaskConstraintKind::InitialWait => "initial wait",
        TaskConstraintKind::Serial => "serial",
        TaskConstraintKind::Sequential(_) => "sequential",
        TaskConstraintKind::Uses(_) => "uses",
        TaskConstraintKind::Priority(_) => "priority",
    }
}

fn task_header(file: &FileScope<'_>, task: &Task, diags: &mut Vec<Diagnostic>) {
    if let Some(handles) = &task.handles {
        exception(file, handles, diags);
    }
    caught::check(task, diags);
    if let Some(target) = &task.for_task {
        attached_to(file, task, target, diags);
    }
    if let Some(tap) = &task.tap {
        attached_to(file, task, &tap.target, diags);
    }
    let mut expand_first = None;
    let mut delay_expansion = None;
    for constraint in &task.constraints {
        let name = task_constraint_name(&constraint.kind);
        let allowed = match (&constraint.kind, task.kind) {
            (TaskConstraintKind::Persistent(_), _) => true,
            (TaskConstraintKind::MaximumActivate(_), TaskKind::Monitor | TaskKind::Handler) => true,
            (TaskConstraintKind::Uses(_) | TaskConstraintKind::Priority(_), kind) => {
                kind != TaskKind::Handler
            }
            (_, TaskKind::Handler) => false,
            (
                TaskConstraintKind::ExpandFirst
                | TaskConstraintKind::DelayExpansion
                | TaskConstraintKind::ExceptionHandler(_)
                | TaskConstraintKind::OnTerminate(_),
                _,
            ) => true,
            (TaskConstraintKind::Sequential(crate::ast::Facet::Handling), _) => false,
            (_, kind) => kind == TaskKind::Monitor,
        };
        if !allowed {
            let hint = match task.kind {
                TaskKind::Handler => {
                    "a handler takes only `maximum activate N` and `persistent` constraints"
                }
                _ if matches!(constraint.kind, TaskConstraintKind::Sequential(_)) => {
                    "between monitor activations use `sequential expansion`, `sequential execution` or `serial`"
                }
                _ => "make the task a `monitor`, or put the constraint on a spawn of a monitor",
            };
            diags.push(
                Diagnostic::error(
                    constraint.span,
                    format!("`{name}` is not allowed on a {}", task.kind.as_str()),
                )
                .with_hint(hint),
            );
        }
        match &constraint.kind {
            TaskConstraintKind::ExpandFirst => expand_first = Some(constraint.span),
            TaskConstraintKind::DelayExpansion => delay_expansion = Some(constraint.span),
            TaskConstraintKind::ExceptionHandler(it) => handler(file, &it.name, diags),
            TaskConstraintKind::OnTerminate(it) => {
                if let Some(label) = it.labels.first() {
                    diags.push(
                        Diagnostic::error(label.span(), "a task-level `on terminate` takes no label")
                            .with_hint("labels name the on-terminate tasks of a spawn: `spawn t() with on terminate l: spawn c();`"),
                    );
                }
            }
            _ => {}
        }
    }
    if let (Some(first), Some(delay)) = (expand_first, delay_expansion) {
        diags.push(inconsistent_expansion(first, delay));
    }
}

fn inconsistent_expansion(expand_first: Span, delay_expansion: Span) -> Diagnostic {
    Diagnostic::error(
        delay_expansion,
        "inconsistent constraints: `delay expansion` with `expand first` on the same node",
    )
    .with_label(expand_first, "`expand first` is here")
    .with_hint(
        "`expand first` finishes expansion before execution starts, `delay expansion` waits for \
         execution to be enabled; keep one",
    )
}

/// An extern task: its name is not also a task of the program.
fn externs(file: &FileScope<'_>, decl: &crate::ast::ExternDecl, diags: &mut Vec<Diagnostic>) {
    let name = decl.name.to_string();
    if let Some(task) = file.task(&name) {
        diags.push(
            Diagnostic::error(
                decl.span,
                format!("`{name}` is declared `extern` and defined in TDL"),
            )
            .with_label(task.span, "defined here")
            .with_hint("a task is either written in TDL or declared `extern`: remove one"),
        );
    }
}
