//! The static diagnosis of resources (docs/semantics.md, "Resources"; docs/language.md,
//! "Resources"): declarations (a capacity of 0 or not an integer; a name declared twice is
//! reported with the other duplicate declarations, `diagnose.rs`), and
//! every `uses` of a task or spawn and every `lock`, `unlock`, `reserve` and `unreserve` (an
//! unknown resource once the program declares any; for `uses`, an amount of 0 or more than a
//! declared capacity), `priority` out of range, the resource options in a
//! constraint statement, and `priority` or `deny if busy` on a spawn that uses no resource.

use proc_macro2::{Ident, Span};

use crate::ast::{
    Ast, Constraint, ConstraintKind, Count, Item, Priority, ResourceAmount, Task,
    TaskConstraintKind,
};
use crate::diagnostic::{Diagnostic, Lint};
use crate::hir::{FileScope, Tdl};

/// Diagnoses the resources of `ast`, one file of the program `file` resolves.
pub(super) fn diagnose(file: &FileScope<'_>, ast: &Ast, diags: &mut Vec<Diagnostic>) {
    for item in &ast.items {
        match item {
            Item::Resource(r) => {
                match r.capacity.base10_parse::<u32>() {
                    Ok(0) => diags.push(
                        Diagnostic::error(
                            r.capacity.span(),
                            format!("resource `{}` has a capacity of 0", r.name),
                        )
                        .with_hint("a resource has at least one unit; lock it to keep it from every task"),
                    ),
                    Ok(_) if r.capacity.suffix().is_empty() => {}
                    _ => diags.push(
                        Diagnostic::error(r.capacity.span(), "a capacity is a whole number of units")
                            .with_hint("write it as a plain integer from 1 to 4294967295, as in `resource arm(2);`"),
                    ),
                }
                if let Some(p) = &r.pending {
                    if p.base10_parse::<u32>().is_err() || !p.suffix().is_empty() {
                        diags.push(
                            Diagnostic::error(
                                p.span(),
                                "a pending limit is a whole number of requests",
                            )
                            .with_hint(
                                "write it as a plain integer, as in `resource arm(2) pending 4;`",
                            ),
                        );
                    }
                }
            }
            Item::Task(task) => task_uses(file, task, diags),
            Item::Exception(_)
            | Item::State(_)
            | Item::Environment(_)
            | Item::Extern(_)
            | Item::Rust(_) => {}
        }
    }
}

/// The resource options of a task and of the spawns, groups and constraint statements of its
/// body.
fn task_uses(file: &FileScope<'_>, task: &Task, diags: &mut Vec<Diagnostic>) {
    for c in &task.constraints {
        match &c.kind {
            TaskConstraintKind::Uses(list) => amounts(file, list, diags),
            TaskConstraintKind::Priority(p) => priority(p, c.span, diags),
            _ => {}
        }
    }
    let scope = file.body(task);
    for group in &scope.groups {
        options(file, &group.group.constraints, diags);
    }
    for def in &scope.spawns {
        options(file, &def.spawn.constraints, diags);
        // `priority` and `deny if busy` mean something only for a node that asks for resources:
        // through the spawn, its groups, or the spawned task of the program.
        let groups = def
            .groups
            .iter()
            .flat_map(|g| scope.groups[*g].group.constraints.iter());
        let all: Vec<&Constraint> = def.spawn.constraints.iter().chain(groups).collect();
        let uses = all
            .iter()
            .any(|c| matches!(c.kind, ConstraintKind::Uses(_)))
            || file.task(&def.spawn.task.to_string()).is_none_or(|t| {
                t.constraints
                    .iter()
                    .any(|c| matches!(c.kind, TaskConstraintKind::Uses(_)))
            });
        if uses {
            continue;
        }
        for c in &def.spawn.constraints {
            let word = match c.kind {
                ConstraintKind::Priority(_) => "priority",
                ConstraintKind::DenyIfBusy => "deny if busy",
                _ => continue,
            };
            diags.push(
                Diagnostic::warning(
                    Lint::UnusedResourceOption,
                    c.span,
                    format!(
                        "`{word}` has no effect: `{}` uses no resource",
                        def.spawn.task
                    ),
                )
                .with_hint("add `uses` to the spawn or to the task, or remove it"),
            );
        }
    }
    for it in &scope.resource_stmts {
        known(file, &it.name, diags);
    }
    for stmt in &scope.stmts {
        let Tdl::Constrain(stmt, _) = stmt else {
            continue;
        };
        let word = match stmt.constraint.kind {
            ConstraintKind::Uses(_) => "uses",
            ConstraintKind::Priority(_) => "priority",
            ConstraintKind::DenyIfBusy => "deny if busy",
            _ => continue,
        };
        diags.push(
            Diagnostic::error(
                stmt.constraint.span,
                format!("`{word}` can only be given on a spawn"),
            )
            .with_hint(
                "a node asks for its resources when it would start: put it in the spawn's `with` list, a `with (...)` group or the task definition",
            ),
        );
    }
}

/// The resource options of a spawn's or a group's constraint list.
fn options(file: &FileScope<'_>, list: &[Constraint], diags: &mut Vec<Diagnostic>) {
    for c in list {
        match &c.kind {
            ConstraintKind::Uses(it) => amounts(file, it, diags),
            ConstraintKind::Priority(p) => priority(p, c.span, diags),
            _ => {}
        }
    }
}

/// Each resource of a `uses` list: declared (once the program declares any), an amount of at
/// least 1 and at most a declared capacity.
fn amounts(file: &FileScope<'_>, list: &[ResourceAmount], diags: &mut Vec<Diagnostic>) {
    for it in list {
        let name = it.name.to_string();
        let decl = file.resource(&name);
        known(file, &it.name, diags);
        let Some(Count::Const(n)) = it.amount else {
            continue;
        };
        if n == 0 {
            diags.push(
                Diagnostic::error(it.span, format!("a use of 0 of `{name}`"))
                    .with_hint(format!("an amount is at least 1; write `{name}` for one")),
            );
            continue;
        }
        let capacity = decl.and_then(|d| d.capacity.base10_parse::<u64>().ok());
        if let Some(capacity) = capacity.filter(|c| n > *c) {
            diags.push(
                Diagnostic::error(
                    it.span,
                    format!("asks for {n} of `{name}`, whose capacity is {capacity}"),
                )
                .with_hint(
                    "such a request can never be granted: its node would fail with `ResourceDenied`",
                ),
            );
        }
    }
}

/// Reports `name` when the program declares resources and `name` is not one of them (a program
/// that declares none may use resources its Rust code declares on the runtime).
fn known(file: &FileScope<'_>, name: &Ident, diags: &mut Vec<Diagnostic>) {
    if file.resource(&name.to_string()).is_some() || !file.declares_resources() {
        return;
    }
    let names: Vec<&str> = file.resource_names().collect();
    diags.push(
        Diagnostic::error(name.span(), format!("unknown resource `{name}`")).with_hint(format!(
            "declare it with `resource {name}(capacity);` or use one of: {}",
            names.join(", ")
        )),
    );
}

/// A literal priority fits an `i32`.
fn priority(p: &Priority, span: Span, diags: &mut Vec<Diagnostic>) {
    if let Priority::Const(n) = p {
        if i32::try_from(*n).is_err() {
            diags.push(
                Diagnostic::error(span, format!("the priority {n} is out of range"))
                    .with_hint("priorities are `i32`: from -2147483648 to 2147483647"),
            );
        }
    }
}
