//! Exceptions no handler of the program handles (docs/language.md, "Static checks"): a warning at
//! each `fail E;` whose failure, searched for as docs/semantics.md, "Exceptions and handlers"
//! says, finds no handler of `E` or of an ancestor of `E` on any way up.
//!
//! The search goes from the node of the task that raises up through the tasks that spawn it, at
//! every spawn of it in the program: at each node, the task's own handlers, the handlers attached
//! to it with `for`, and the handlers given at the spawn. It stops, handled, at a spawn whose
//! body takes the outcome (`with outcome`, or a constraint on the spawn's `failed` event: the
//! body reacts to the failure by design), and at a spawn under another `parent`, whose place the
//! front end cannot see. It ends unhandled at a task that no task of the program spawns: its
//! caller is Rust. A handler's own failure is searched for above the node it is attached to; a
//! failure under a handler also passes the nodes between the failing node and that node, any of
//! the attached task's subtree, whose handlers all count. What the front end cannot see counts
//! as a handler that may match: a handler or a task written in Rust, an exception whose ancestry
//! is not all declared in the program.

use std::collections::{BTreeMap, BTreeSet};

use proc_macro2::Ident;

use super::flow::{Flow, Node};
use crate::ast::{Ast, ConstraintKind, Item, Point, Task, TaskConstraintKind, TaskKind};
use crate::diagnostic::{Diagnostic, Lint};
use crate::hir::{BodyScope, FileScope, Tdl};

/// A spawn of a task: where its failures go next.
struct Site<'a> {
    /// The task whose body spawns it (for an on-terminate task: the task it cleans up after).
    up: String,
    /// The handlers given at the spawn.
    handlers: Vec<&'a Ident>,
    /// The body takes the failure itself (`with outcome`, `X failed`), or the node goes under
    /// another `parent`: the search ends here, handled as far as the front end can tell.
    stops: bool,
}

/// Where a handler is attached.
struct Attach<'a> {
    /// The task of the node it is attached to.
    task: String,
    /// At a spawn in this task's body, with these spawn-level handlers; `None`: task level or
    /// `for` (on every node of the task).
    at_spawn: Option<(String, Vec<&'a Ident>)>,
}

/// The handler structure of the whole program.
struct Program<'s, 'a> {
    file: &'s FileScope<'a>,
    /// The spawns of each task, by its name.
    sites: BTreeMap<String, Vec<Site<'a>>>,
    /// Where each handler is attached, by its name.
    attachments: BTreeMap<String, Vec<Attach<'a>>>,
    /// The task-level handlers of each task, and those attached to it with `for`.
    own: BTreeMap<String, Vec<&'a Ident>>,
    /// The tasks each task's body spawns.
    children: BTreeMap<String, BTreeSet<String>>,
}

/// Warns at each `fail E;` of `ast` that no handler of the program can handle.
pub(super) fn check(file: &FileScope<'_>, ast: &Ast, diags: &mut Vec<Diagnostic>) {
    let mut program: Option<Program<'_, '_>> = None;
    for item in &ast.items {
        let Item::Task(task) = item else { continue };
        let scope = file.body(task);
        for stmt in &scope.stmts {
            let Tdl::Fail(fail) = stmt else { continue };
            let Some(exc) = &fail.exception else { continue };
            // An exception the program does not declare, once it declares some, is an error
            // already.
            let declared = file.declares_exception(&exc.to_string());
            if !declared && file.exception_names().next().is_some() {
                continue;
            }
            let program = program.get_or_insert_with(|| Program::new(file));
            let mut search = Search {
                program,
                exc: exc.to_string(),
                seen: BTreeSet::new(),
                ends: Vec::new(),
            };
            let handled = if task.kind == TaskKind::Handler {
                search.handler_raise(task)
            } else {
                search.at_task(&task.name.to_string())
            };
            if !handled {
                diags.push(diagnostic(file, exc, &search.ends));
            }
        }
    }
}

fn diagnostic(file: &FileScope<'_>, exc: &Ident, ends: &[String]) -> Diagnostic {
    let mut diag = Diagnostic::warning(
        Lint::UnhandledException,
        exc.span(),
        format!("no handler in this program handles `{exc}` raised here"),
    );
    for end in ends.iter().take(3) {
        if let Some(task) = file.task(end).filter(|it| file.is_local(it)) {
            diag = diag.with_label(
                task.span,
                format!(
                    "no task of this program spawns `{end}`: its failures go to its Rust caller"
                ),
            );
        }
    }
    diag.with_hint(format!(
        "unless the Rust caller handles it, the run reports it unhandled (fatal under \
         `FailurePolicy::Fatal`); add a handler of `{exc}` or of an ancestor on the way up \
         (`with exception handler h()`, or `handler h() handles {exc} for TASK`), or take the \
         outcome where it is spawned (`let o = spawn … with outcome;`)"
    ))
}

impl<'s, 'a> Program<'s, 'a> {
    fn new(file: &'s FileScope<'a>) -> Program<'s, 'a> {
        let mut program = Program {
            file,
            sites: BTreeMap::new(),
            attachments: BTreeMap::new(),
            own: BTreeMap::new(),
            children: BTreeMap::new(),
        };
        for task in file.all_tasks() {
            program.task(task);
        }
        program
    }

    fn task(&mut self, task: &'a Task) {
        let name = task.name.to_string();
        for constraint in &task.constraints {
            match &constraint.kind {
                TaskConstraintKind::ExceptionHandler(h) => {
                    self.own.entry(name.clone()).or_default().push(&h.name);
                    self.attach(&h.name, name.clone(), None);
                }
                TaskConstraintKind::OnTerminate(it) => {
                    self.site(&it.task, name.clone(), Vec::new(), false)
                }
                _ => {}
            }
        }
        if let (Some(target), TaskKind::Handler) = (&task.for_task, task.kind) {
            self.own
                .entry(target.to_string())
                .or_default()
                .push(&task.name);
            self.attach(&task.name, target.to_string(), None);
        }
        let scope = self.file.body(task);
        let observed = failures_observed(self.file, task, scope);
        for (id, def) in scope.spawns.iter().enumerate() {
            let spawn = def.spawn;
            let spawned = spawn.task.to_string();
            self.children
                .entry(name.clone())
                .or_default()
                .insert(spawned.clone());
            let mut handlers = Vec::new();
            let mut stops = observed.contains(&id);
            for constraint in &spawn.constraints {
                match &constraint.kind {
                    ConstraintKind::ExceptionHandler(h) => handlers.push(&h.name),
                    ConstraintKind::Outcome | ConstraintKind::Parent(_) => stops = true,
                    _ => {}
                }
            }
            for constraint in &spawn.constraints {
                match &constraint.kind {
                    ConstraintKind::ExceptionHandler(h) => {
                        let at = Some((name.clone(), handlers.clone()));
                        self.attach(&h.name, spawned.clone(), at);
                    }
                    // An on-terminate task is a child of the spawned node.
                    ConstraintKind::OnTerminate(it) => {
                        self.site(&it.task, spawned.clone(), handlers.clone(), false);
                    }
                    _ => {}
                }
            }
            self.site(&spawn.task, name.clone(), handlers, stops);
        }
    }

    fn site(&mut self, task: &Ident, up: String, handlers: Vec<&'a Ident>, stops: bool) {
        self.sites.entry(task.to_string()).or_default().push(Site {
            up,
            handlers,
            stops,
        });
    }

    fn attach(
        &mut self,
        handler: &Ident,
        task: String,
        at_spawn: Option<(String, Vec<&'a Ident>)>,
    ) {
        self.attachments
            .entry(handler.to_string())
            .or_default()
            .push(Attach { task, at_spawn });
    }

    /// Whether the handler named `handler` may handle `exc`.
    fn matches(&self, handler: &Ident, exc: &str) -> bool {
        let Some(task) = self.file.task(&handler.to_string()) else {
            // A handler written in Rust: what it handles is not known here.
            return true;
        };
        let Some(handled) = &task.handles else {
            return true;
        };
        let handled = handled.to_string();
        handled == exc
            || !self.file.ancestry_known(exc)
            || self.file.ancestry(exc).contains(&handled)
    }
}

/// The spawns of `task`'s body whose `failed` event a constraint of the body names: the body
/// reacts to their failure by design (a fallback).
fn failures_observed(file: &FileScope<'_>, task: &Task, scope: &BodyScope<'_>) -> BTreeSet<usize> {
    let flow = Flow::new(file, task, scope);
    let mut out = BTreeSet::new();
    for applied in &flow.applied {
        let ConstraintKind::Trigger { when, .. } = &applied.constraint.kind else {
            continue;
        };
        let Some(event) = when.event() else { continue };
        if event.point != Point::Failed {
            continue;
        }
        for node in flow
            .nodes(scope, &event.tag, &applied.prev)
            .unwrap_or_default()
        {
            if let Node::Spawn(id) = node {
                out.insert(id);
            }
        }
    }
    out
}

/// One search for a handler of `exc`.
struct Search<'p, 's, 'a> {
    program: &'p Program<'s, 'a>,
    exc: String,
    seen: BTreeSet<String>,
    /// The tasks where a way up ended unhandled: no task of the program spawns them.
    ends: Vec<String>,
}

impl Search<'_, '_, '_> {
    fn any(&self, handlers: &[&Ident]) -> bool {
        handlers.iter().any(|h| self.program.matches(h, &self.exc))
    }

    /// A failure searched for at a node of the task `name`, then above it.
    fn at_task(&mut self, name: &str) -> bool {
        if !self.seen.insert(format!("task {name}")) {
            return false;
        }
        let Some(task) = self.program.file.task(name) else {
            // A task written in Rust: its handlers are not known here.
            return true;
        };
        if self.any(self.program.own.get(name).map_or(&[], Vec::as_slice)) {
            return true;
        }
        if task.kind == TaskKind::Handler {
            return self.under_handler(task);
        }
        self.above(name, true)
    }

    /// The search from the spawns of `name` on, with the handlers given at them or not.
    fn above(&mut self, name: &str, with_spawn_handlers: bool) -> bool {
        let program = self.program;
        let sites = program.sites.get(name).map_or(&[][..], Vec::as_slice);
        if sites.is_empty() {
            self.ends.push(name.to_owned());
            return false;
        }
        for site in sites {
            if site.stops || (with_spawn_handlers && self.any(&site.handlers)) {
                return true;
            }
            if self.at_task(&site.up) {
                return true;
            }
        }
        false
    }

    /// A failure under the node of handler `handler` (of a task its body spawns): it passes the
    /// handler's node, then the failing node, which is the attached node or one of its
    /// descendants, up to the attached node, then above.
    fn under_handler(&mut self, handler: &Task) -> bool {
        let program = self.program;
        let Some(attachments) = program.attachments.get(&handler.name.to_string()) else {
            // Given only in Rust: where it runs is not known here.
            return true;
        };
        for attach in attachments {
            if self.subtree_handles(&attach.task) {
                return true;
            }
            let handled = match &attach.at_spawn {
                Some((body, handlers)) => self.any(handlers) || self.at_task(body),
                None => self.at_task(&attach.task),
            };
            if handled {
                return true;
            }
        }
        false
    }

    /// A handler's own `fail`: searched for above the node it is attached to.
    fn handler_raise(&mut self, handler: &Task) -> bool {
        let program = self.program;
        let Some(attachments) = program.attachments.get(&handler.name.to_string()) else {
            return true;
        };
        for attach in attachments {
            let handled = match &attach.at_spawn {
                Some((body, _)) => self.at_task(body),
                None => self.above(&attach.task, false),
            };
            if handled {
                return true;
            }
        }
        false
    }

    /// Whether a task of the static subtree of `root` (itself, what its body spawns, and so on)
    /// has a handler of the exception: its own, attached with `for`, or at a spawn in its body.
    fn subtree_handles(&self, root: &str) -> bool {
        let program = self.program;
        let mut seen: BTreeSet<&str> = BTreeSet::new();
        let mut todo: Vec<&str> = vec![root];
        while let Some(name) = todo.pop() {
            if !seen.insert(name) {
                continue;
            }
            if self.any(program.own.get(name).map_or(&[], Vec::as_slice)) {
                return true;
            }
            for child in program.children.get(name).into_iter().flatten() {
                let at_spawn = program
                    .sites
                    .get(child)
                    .into_iter()
                    .flatten()
                    .filter(|site| site.up == name)
                    .any(|site| self.any(&site.handlers));
                if at_spawn {
                    return true;
                }
                todo.push(child);
            }
        }
        false
    }
}
