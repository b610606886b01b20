//! Static checks over a parsed [`Ast`] (catalogue §1.6), reported as diagnostics.
//!
//! File-level checks look at names: duplicate tasks and exceptions, unknown exceptions (only when
//! the file declares exceptions, since others may come from Rust), and task-level constraints
//! allowed per task kind. Body-level checks first flatten each task body into its TDL statements
//! in source order ([`Node`]), then resolve every tag against the body's spawns and labels: tags
//! are body-scoped, so forward references are fine except for `wait`. Unknown *task* names in
//! spawns are not errors (tasks may come from other files), only unknown *tags* are.

use std::collections::BTreeMap;

use proc_macro2::{Ident, Span};

use crate::ast::{
    Ast, Block, Constraint, ConstraintKind, ConstraintStmt, Else, Event, Fail, Item, Spawn, Stmt,
    Tag, TagKind, Task, TaskConstraintKind, TaskKind, When, WithGroup,
};
use crate::diagnostic::Diagnostic;

const TAG_HINT: &str = "a tag is a task spawned in this body, a label (`t1: spawn a();`), \
                        `previous`, `self` or `parent`";

/// Runs every check and appends the findings to `diags`.
pub(crate) fn check(ast: &Ast, diags: &mut Vec<Diagnostic>) {
    let file = FileInfo::new(ast, diags);
    for item in &ast.items {
        match item {
            Item::Task(task) => {
                check_task_header(&file, task, diags);
                Body::new(&file, task, diags).check(diags);
            }
            Item::Exception(exc) => {
                if let Some(parent) = &exc.parent {
                    file.check_exception(parent, diags);
                }
            }
            Item::Rust(_) => {}
        }
    }
}

/// Names declared in the file.
struct FileInfo {
    tasks: BTreeMap<String, TaskKind>,
    exceptions: BTreeMap<String, Span>,
}

impl FileInfo {
    fn new(ast: &Ast, diags: &mut Vec<Diagnostic>) -> FileInfo {
        let mut tasks: BTreeMap<String, (TaskKind, Span)> = BTreeMap::new();
        let mut exceptions = BTreeMap::new();
        for item in &ast.items {
            match item {
                Item::Task(task) => {
                    let name = task.name.to_string();
                    if let Some((_, first)) = tasks.get(&name) {
                        diags.push(
                            Diagnostic::error(task.span, format!("duplicate task `{name}`"))
                                .with_label(*first, "first defined here")
                                .with_hint("rename one of the tasks"),
                        );
                    } else {
                        tasks.insert(name, (task.kind, task.span));
                    }
                }
                Item::Exception(exc) => {
                    let name = exc.name.to_string();
                    if let Some(first) = exceptions.get(&name) {
                        diags.push(
                            Diagnostic::error(exc.span, format!("duplicate exception `{name}`"))
                                .with_label(*first, "first declared here")
                                .with_hint("rename one of the exceptions"),
                        );
                    } else {
                        exceptions.insert(name, exc.span);
                    }
                }
                Item::Rust(_) => {}
            }
        }
        let tasks = tasks.into_iter().map(|(k, (kind, _))| (k, kind)).collect();
        FileInfo { tasks, exceptions }
    }

    fn kind_of(&self, task: &Ident) -> Option<TaskKind> {
        self.tasks.get(&task.to_string()).copied()
    }

    /// Reports `name` when the file declares exceptions and `name` is not one of them.
    fn check_exception(&self, name: &Ident, diags: &mut Vec<Diagnostic>) {
        if self.exceptions.is_empty() || self.exceptions.contains_key(&name.to_string()) {
            return;
        }
        let known: Vec<&str> = self.exceptions.keys().map(String::as_str).collect();
        diags.push(
            Diagnostic::error(name.span(), format!("unknown exception `{name}`")).with_hint(
                format!(
                    "declare it with `exception {name};` or use one of: {}",
                    known.join(", ")
                ),
            ),
        );
    }

    /// Reports a handler reference that names a known task which is not a handler.
    fn check_handler(&self, name: &Ident, diags: &mut Vec<Diagnostic>) {
        if let Some(kind) = self.kind_of(name) {
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
    }
}

fn check_task_header(file: &FileInfo, task: &Task, diags: &mut Vec<Diagnostic>) {
    if let Some(handles) = &task.handles {
        file.check_exception(handles, diags);
    }
    let mut expand_first = None;
    let mut delay_expansion = None;
    for constraint in &task.constraints {
        let name = task_constraint_name(&constraint.kind);
        let allowed = match (&constraint.kind, task.kind) {
            (TaskConstraintKind::Persistent(_), _) => true,
            (TaskConstraintKind::MaximumActivate(_), TaskKind::Monitor | TaskKind::Handler) => true,
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
            TaskConstraintKind::ExceptionHandler(it) => file.check_handler(&it.name, diags),
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

/// One TDL statement of a body, in source order.
enum Node<'a> {
    Spawn { spawn: &'a Spawn, depth: usize },
    With { group: &'a WithGroup, depth: usize },
    Constrain(&'a ConstraintStmt),
    Fail(&'a Fail),
    Bypass(Span),
    Trigger(Span),
    Retry(Span),
}

/// Where a spawn or label is defined: its index in the flattened body and its loop depth.
#[derive(Clone, Copy)]
struct Def {
    index: usize,
    depth: usize,
    span: Span,
}

/// One task body being checked.
struct Body<'a> {
    file: &'a FileInfo,
    task: &'a Task,
    nodes: Vec<Node<'a>>,
    /// Spawns by task name.
    spawns: BTreeMap<String, Vec<Def>>,
    /// Labels (of spawns, groups and on-terminate tasks) by name; the first of each is kept.
    labels: BTreeMap<String, Def>,
    /// Task spawned under each label, when the label is on a spawn.
    label_tasks: BTreeMap<String, String>,
}

fn flatten<'a>(block: &'a Block, depth: usize, out: &mut Vec<Node<'a>>) {
    for stmt in &block.stmts {
        match stmt {
            Stmt::Rust(_) => {}
            Stmt::Spawn(spawn) => out.push(Node::Spawn { spawn, depth }),
            Stmt::With(group) => {
                out.push(Node::With { group, depth });
                flatten(&group.body, depth, out);
            }
            Stmt::Constrain(it) => out.push(Node::Constrain(it)),
            Stmt::Succeed(_) => {}
            Stmt::Fail(it) => out.push(Node::Fail(it)),
            Stmt::Bypass(span) => out.push(Node::Bypass(*span)),
            Stmt::Trigger(span) => out.push(Node::Trigger(*span)),
            Stmt::Retry(span) => out.push(Node::Retry(*span)),
            Stmt::If(it) => {
                let mut it = it;
                loop {
                    flatten(&it.then_branch, depth, out);
                    match it.else_branch.as_deref() {
                        Some(Else::If(next)) => it = next,
                        Some(Else::Block(block)) => {
                            flatten(block, depth, out);
                            break;
                        }
                        None => break,
                    }
                }
            }
            Stmt::For(it) => flatten(&it.body, depth + 1, out),
            Stmt::While(it) => flatten(&it.body, depth + 1, out),
            Stmt::Loop(it) => flatten(&it.body, depth + 1, out),
            Stmt::Match(it) => {
                for arm in &it.arms {
                    flatten(&arm.body, depth, out);
                }
            }
            Stmt::Block(it) => flatten(it, depth, out),
        }
    }
}

/// What a constraint is attached to.
#[derive(Clone, Copy)]
enum Site<'a> {
    /// A spawn of this task.
    Spawn(&'a Ident),
    /// A `with (...)` group.
    With,
    /// A constraint statement at this flattened index, on this tag.
    Stmt(usize, &'a Tag),
}

impl<'a> Body<'a> {
    fn new(file: &'a FileInfo, task: &'a Task, diags: &mut Vec<Diagnostic>) -> Body<'a> {
        let mut nodes = Vec::new();
        flatten(&task.body, 0, &mut nodes);
        let mut body = Body {
            file,
            task,
            nodes: Vec::new(),
            spawns: BTreeMap::new(),
            labels: BTreeMap::new(),
            label_tasks: BTreeMap::new(),
        };
        for (index, node) in nodes.iter().enumerate() {
            match node {
                Node::Spawn { spawn, depth } => {
                    let def = Def {
                        index,
                        depth: *depth,
                        span: spawn.task.span(),
                    };
                    body.spawns
                        .entry(spawn.task.to_string())
                        .or_default()
                        .push(def);
                    for label in &spawn.labels {
                        body.add_label(label, index, *depth, Some(&spawn.task), diags);
                    }
                    for constraint in &spawn.constraints {
                        if let ConstraintKind::OnTerminate(it) = &constraint.kind {
                            for label in &it.labels {
                                body.add_label(label, index, *depth, Some(&it.task), diags);
                            }
                        }
                    }
                }
                Node::With { group, depth } => {
                    for label in &group.labels {
                        body.add_label(label, index, *depth, None, diags);
                    }
                }
                _ => {}
            }
        }
        body.nodes = nodes;
        body
    }

    fn add_label(
        &mut self,
        label: &Ident,
        index: usize,
        depth: usize,
        task: Option<&Ident>,
        diags: &mut Vec<Diagnostic>,
    ) {
        let name = label.to_string();
        if let Some(first) = self.labels.get(&name) {
            diags.push(
                Diagnostic::error(label.span(), format!("duplicate label `{name}`"))
                    .with_label(first.span, "first used here")
                    .with_hint("give each spawn or group its own label"),
            );
            return;
        }
        self.labels.insert(
            name.clone(),
            Def {
                index,
                depth,
                span: label.span(),
            },
        );
        if let Some(task) = task {
            self.label_tasks.insert(name, task.to_string());
        }
    }

    fn check(&self, diags: &mut Vec<Diagnostic>) {
        for (index, node) in self.nodes.iter().enumerate() {
            match node {
                Node::Spawn { spawn, .. } => self.check_spawn(spawn, diags),
                Node::With { group, .. } => self.check_list(&group.constraints, Site::With, diags),
                Node::Constrain(stmt) => self.check_constraint_stmt(index, stmt, diags),
                Node::Fail(fail) => self.check_fail(fail, diags),
                Node::Bypass(span) if self.task.kind != TaskKind::Handler => diags.push(
                    Diagnostic::error(*span, "`bypass` outside an exception handler").with_hint(
                        "only a handler can pass its exception on; in other tasks use `fail`",
                    ),
                ),
                Node::Retry(span) if self.task.kind != TaskKind::Handler => diags.push(
                    Diagnostic::error(*span, "`retry` outside an exception handler").with_hint(
                        "only a handler can run the failed task again; attach a `handler` that retries",
                    ),
                ),
                Node::Trigger(span) if self.task.kind != TaskKind::Monitor => diags.push(
                    Diagnostic::error(*span, "`trigger` outside a monitor").with_hint(
                        "only a monitor's body can signal a trigger; make the task a `monitor`",
                    ),
                ),
                _ => {}
            }
        }
    }

    fn check_spawn(&self, spawn: &Spawn, diags: &mut Vec<Diagnostic>) {
        self.check_list(&spawn.constraints, Site::Spawn(&spawn.task), diags);
        let waits = spawn
            .constraints
            .iter()
            .any(|it| matches!(it.kind, ConstraintKind::Wait));
        if spawn.binding.is_some() && !waits {
            diags.push(
                Diagnostic::error(
                    spawn.span,
                    "a spawn bound with `let` must wait for its result",
                )
                .with_hint("add `with wait`: `let v = spawn task(args) with wait;`"),
            );
        }
        if let [only] = spawn.constraints.as_slice() {
            if matches!(only.kind, ConstraintKind::Parallel) {
                diags.push(
                    Diagnostic::warning(only.span, "`parallel` on a single spawn has no effect")
                        .with_hint("spawns are parallel by default; use `parallel` on a `with (parallel) { ... }` group"),
                );
            }
        }
    }

    fn check_fail(&self, fail: &Fail, diags: &mut Vec<Diagnostic>) {
        match &fail.exception {
            Some(exc) => self.file.check_exception(exc, diags),
            None if self.task.kind == TaskKind::Handler => diags.push(
                Diagnostic::warning(fail.span, "`fail;` without an exception in a handler")
                    .with_hint("to pass the exception on to the next handler write `bypass;`"),
            ),
            None => diags.push(
                Diagnostic::warning(fail.span, "`fail` without an exception")
                    .with_hint("name the exception so a handler can match it: `fail Exc;`"),
            ),
        }
    }

    fn check_constraint_stmt(
        &self,
        index: usize,
        stmt: &ConstraintStmt,
        diags: &mut Vec<Diagnostic>,
    ) {
        let site = Site::Stmt(index, &stmt.tag);
        self.resolve(&stmt.tag, diags);
        let terminates = matches!(
            stmt.constraint.kind,
            ConstraintKind::Terminate
                | ConstraintKind::TerminateAt(_)
                | ConstraintKind::TerminateIn { .. }
        );
        if terminates && matches!(stmt.tag.kind, TagKind::Child | TagKind::Parent) {
            diags.push(
                Diagnostic::warning(stmt.tag.span, "terminate constraint on the enclosing task")
                    .with_hint("this terminates the task running this body; use `succeed;` or `fail Exc;` to end it"),
            );
        }
        self.check_list(std::slice::from_ref(&stmt.constraint), site, diags);
    }

    /// The spawns `tag` may denote, when it is a name: `(task name, definitions)`.
    fn named_defs<'s>(&'s self, name: &'s str) -> Option<(Option<&'s str>, Vec<Def>)> {
        if let Some(def) = self.labels.get(name) {
            return Some((self.label_tasks.get(name).map(String::as_str), vec![*def]));
        }
        self.spawns.get(name).map(|defs| (Some(name), defs.clone()))
    }

    /// Resolves a tag, reporting unknown and ambiguous names and wrong index counts.
    fn resolve(&self, tag: &Tag, diags: &mut Vec<Diagnostic>) -> Option<Def> {
        let TagKind::Named { name, indexes } = &tag.kind else {
            return None;
        };
        let text = name.to_string();
        let Some((_, defs)) = self.named_defs(&text) else {
            diags.push(
                Diagnostic::error(tag.span, format!("unknown tag `{text}`")).with_hint(format!(
                    "`{text}` is not spawned or labelled in `{}`; {TAG_HINT}",
                    self.task.name
                )),
            );
            return None;
        };
        let [def] = defs.as_slice() else {
            let mut diag = Diagnostic::error(
                tag.span,
                format!(
                    "ambiguous tag `{text}`: the task is spawned {} times in this body",
                    defs.len()
                ),
            )
            .with_hint("label the spawns (`t1: spawn a(1);`) and refer to a label");
            for def in &defs {
                diag = diag.with_label(def.span, "spawned here");
            }
            diags.push(diag);
            return None;
        };
        if indexes.len() > def.depth {
            let msg = if def.depth == 0 {
                format!("`{text}` is not spawned in a loop, so it takes no iteration index")
            } else {
                format!(
                    "too many iteration indexes for `{text}`: it is spawned inside {} loop{}, the tag has {}",
                    def.depth,
                    if def.depth == 1 { "" } else { "s" },
                    indexes.len()
                )
            };
            diags.push(
                Diagnostic::error(tag.span, msg)
                    .with_label(def.span, "spawned here")
                    .with_hint("give one `[index]` per enclosing loop, outermost first; `[.]` means the current iteration"),
            );
        }
        Some(*def)
    }

    fn check_list(&self, constraints: &[Constraint], site: Site<'_>, diags: &mut Vec<Diagnostic>) {
        let mut expand_first = None;
        for constraint in constraints {
            match &constraint.kind {
                ConstraintKind::ExpandFirst => expand_first = Some(constraint.span),
                ConstraintKind::DelayExpansion => {
                    if let Some(first) = expand_first {
                        diags.push(inconsistent_expansion(first, constraint.span));
                    }
                }
                _ => {}
            }
            self.check_constraint(constraint, site, diags);
        }
        if let Some(first) = expand_first {
            let delay = constraints
                .iter()
                .take_while(|it| !matches!(it.kind, ConstraintKind::ExpandFirst))
                .find(|it| matches!(it.kind, ConstraintKind::DelayExpansion));
            if let Some(delay) = delay {
                diags.push(inconsistent_expansion(first, delay.span));
            }
        }
    }

    fn check_constraint(
        &self,
        constraint: &Constraint,
        site: Site<'_>,
        diags: &mut Vec<Diagnostic>,
    ) {
        let span = constraint.span;
        match &constraint.kind {
            ConstraintKind::Sequential { tag: Some(tag), .. } | ConstraintKind::Serial { tag: Some(tag) } => {
                self.check_waits_on(tag, site, span, diags);
            }
            ConstraintKind::DisableUntil { until: When::Event(event), .. } => {
                self.check_waits_on(&event.tag, site, span, diags);
            }
            ConstraintKind::DisableFor { after, .. }
            | ConstraintKind::TerminateIn { after, .. }
            | ConstraintKind::ActivateIn { after, .. } => {
                if let Some(event) = after {
                    self.check_event(event, diags);
                }
            }
            ConstraintKind::TerminateAt(When::Event(event))
            | ConstraintKind::ActivateAt(When::Event(event)) => self.check_event(event, diags),
            ConstraintKind::ExceptionHandler(it) => {
                self.file.check_handler(&it.name, diags);
                if matches!(site, Site::With) {
                    diags.push(
                        Diagnostic::error(span, "`exception handler` is not allowed in `with (...)`")
                            .with_hint("attach the handler to each spawn with `with exception handler ...`, or to the task definition"),
                    );
                }
            }
            ConstraintKind::OnTerminate(_) if matches!(site, Site::With) => diags.push(
                Diagnostic::error(span, "`on terminate` is not allowed in `with (...)`")
                    .with_hint("put `on terminate` on a spawn or on the task definition"),
            ),
            ConstraintKind::OnAgent(_) => diags.push(
                Diagnostic::error(span, "distributed agents are not supported yet")
                    .with_hint("remove `on ...`: every task runs in this process until distributed agents exist"),
            ),
            ConstraintKind::Wait => {
                if let Site::Stmt(index, tag) = site {
                    if let Some(def) = self.resolve_quiet(tag) {
                        if def.index > index {
                            diags.push(
                                Diagnostic::error(tag.span, "`wait` on a task that is not spawned yet")
                                    .with_label(def.span, "spawned later here")
                                    .with_hint("move this statement after the spawn, or put `wait` on the spawn itself"),
                            );
                        }
                    }
                }
            }
            _ => {}
        }
        if is_monitor_only(&constraint.kind) {
            self.check_monitor_only(constraint, site, diags);
        }
    }

    /// `tag` without reporting anything (the tag is reported where it is resolved).
    fn resolve_quiet(&self, tag: &Tag) -> Option<Def> {
        let TagKind::Named { name, .. } = &tag.kind else {
            return None;
        };
        match self.named_defs(&name.to_string()) {
            Some((_, defs)) if defs.len() == 1 => defs.first().copied(),
            _ => None,
        }
    }

    fn check_event(&self, event: &Event, diags: &mut Vec<Diagnostic>) {
        self.resolve(&event.tag, diags);
    }

    /// Checks a tag that the constrained node waits on: it must exist and not be the node itself.
    fn check_waits_on(&self, tag: &Tag, site: Site<'_>, span: Span, diags: &mut Vec<Diagnostic>) {
        if matches!(tag.kind, TagKind::Child) && !matches!(site, Site::With) {
            diags.push(
                Diagnostic::error(span, "circular constraint: the task would wait for itself")
                    .with_label(tag.span, "`self` is the task being constrained")
                    .with_hint("refer to another task, `previous` or a label"),
            );
        }
        self.resolve(tag, diags);
    }

    fn check_monitor_only(
        &self,
        constraint: &Constraint,
        site: Site<'_>,
        diags: &mut Vec<Diagnostic>,
    ) {
        let task = match site {
            Site::Spawn(task) => Some(task.to_string()),
            Site::Stmt(
                _,
                Tag {
                    kind: TagKind::Named { name, .. },
                    ..
                },
            ) => match self.named_defs(&name.to_string()) {
                Some((Some(task), defs)) if defs.len() == 1 => Some(task.to_owned()),
                _ => None,
            },
            _ => None,
        };
        let Some(task) = task else {
            return;
        };
        let Some(kind) = self.file.tasks.get(&task).copied() else {
            return;
        };
        if kind != TaskKind::Monitor {
            diags.push(
                Diagnostic::error(
                    constraint.span,
                    format!("this constraint only applies to monitors, and `{task}` is a {}", kind.as_str()),
                )
                .with_hint("`activate`, `maximum activate`, `maximum trigger` and `period` configure monitors; remove it or make the task a `monitor`"),
            );
        }
    }
}

fn is_monitor_only(kind: &ConstraintKind) -> bool {
    matches!(
        kind,
        ConstraintKind::Activate
            | ConstraintKind::ActivateAt(_)
            | ConstraintKind::ActivateIn { .. }
            | ConstraintKind::MaximumActivate(_)
            | ConstraintKind::MaximumTrigger(_)
            | ConstraintKind::Period(_)
    )
}
