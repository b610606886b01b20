//! The diagnosis of one task body (docs/semantics.md, "Tags and forward references"): duplicate
//! labels; unknown and ambiguous tags, wrong iteration index counts, forward references to `with`
//! groups and to nodes only known once a statement ran, `[.]` outside the loop it counts; what
//! each constraint allows where it is written (a spawn, a `with` group, a constraint statement),
//! `wait` on a forward reference, circular constraints on `self`, monitor-only constraints on
//! other tasks; misused `node!(tag)`, `bind` and `parent`; and the statements that only handlers or
//! monitors may use. It reads the body's scope of `hir` (`hir/body.rs`).

use std::collections::BTreeSet;

use proc_macro2::{Ident, Span};

use super::{exception, handler, inconsistent_expansion};
use crate::ast::{
    Constraint, ConstraintKind, ConstraintStmt, ExternalName, Fail, Spawn, Tag, TagIndex, TagKind,
    Task, TaskKind, Then, When,
};
use crate::diagnostic::{Diagnostic, Lint};
use crate::hir::{
    BodyScope, Def, FileScope, IndexError, LoopId, Named, NodeUse, Refers, Resolution, Tdl, refers,
};

const TAG_HINT: &str = "a tag is a task spawned in this body, a label (`t1: spawn a();`), \
                        a name bound with `bind name = node;`, `previous`, `self` or `parent`";

/// What a constraint is attached to.
#[derive(Clone, Copy)]
enum Site<'a> {
    /// A spawn of this task.
    Spawn(&'a Ident),
    /// A `with (...)` group.
    With,
    /// A constraint statement at this position, on this tag.
    Stmt(usize, &'a Tag),
}

/// One task body being diagnosed.
pub(super) struct Body<'s, 'a> {
    pub(super) file: &'s FileScope<'a>,
    pub(super) task: &'a Task,
    pub(super) scope: &'s BodyScope<'a>,
}

impl<'a> Body<'_, 'a> {
    pub(super) fn diagnose(&self, diags: &mut Vec<Diagnostic>) {
        for (label, first) in &self.scope.duplicate_labels {
            diags.push(
                Diagnostic::error(label.span(), format!("duplicate label `{label}`"))
                    .with_label(*first, "first used here")
                    .with_hint("give each spawn or group its own label"),
            );
        }
        let mut current = BTreeSet::new();
        for stmt in &self.scope.stmts {
            match stmt {
                Tdl::Spawn(id) => {
                    let def = &self.scope.spawns[*id];
                    self.spawn(def.spawn, diags);
                    // Group constraints apply at each member spawn, so `[.]` in them is diagnosed
                    // against the loops around the member.
                    for group in &def.groups {
                        let constraints = &self.scope.groups[*group].group.constraints;
                        self.current_indexes(constraints, &def.site.loops, &mut current, diags);
                    }
                    let own = &def.spawn.constraints;
                    self.current_indexes(own, &def.site.loops, &mut current, diags);
                }
                Tdl::With(id) => {
                    let constraints = &self.scope.groups[*id].group.constraints;
                    self.constraint_list(constraints, Site::With, diags);
                }
                Tdl::Constrain(stmt, site) => {
                    self.constraint_stmt(site.position, stmt, diags);
                    self.current_index(&stmt.tag, &site.loops, &mut current, diags);
                    let constraint = std::slice::from_ref(&stmt.constraint);
                    self.current_indexes(constraint, &site.loops, &mut current, diags);
                }
                Tdl::Fail(fail) => self.fail(fail, diags),
                Tdl::Bypass(span) if self.task.kind != TaskKind::Handler => diags.push(
                    Diagnostic::error(*span, "`bypass` outside an exception handler").with_hint(
                        "only a handler can pass its exception on; in other tasks use `fail`",
                    ),
                ),
                Tdl::Retry(it) if self.task.kind != TaskKind::Handler => diags.push(
                    Diagnostic::error(it.span, "`retry` outside an exception handler").with_hint(
                        "only a handler can run the failed task again; attach a `handler` that retries",
                    ),
                ),
                Tdl::Trigger(span) if self.task.kind != TaskKind::Monitor => diags.push(
                    Diagnostic::error(*span, "`trigger` outside a monitor").with_hint(
                        "only a monitor's body can signal a trigger; make the task a `monitor`",
                    ),
                ),
                Tdl::Bypass(_) | Tdl::Retry(_) | Tdl::Trigger(_) => {}
            }
        }
        for it in &self.scope.node_uses {
            self.node_use(it, diags);
        }
        self.forward_group_refs(diags);
        self.unbound_refs(diags);
    }

    fn spawn(&self, spawn: &'a Spawn, diags: &mut Vec<Diagnostic>) {
        self.constraint_list(&spawn.constraints, Site::Spawn(&spawn.task), diags);
        if let Some(tap) = self
            .file
            .task(&spawn.task.to_string())
            .and_then(|t| t.tap.as_ref())
        {
            diags.push(
                Diagnostic::error(
                    spawn.task.span(),
                    format!("`{}` is a wiretap, which is not spawned", spawn.task),
                )
                .with_hint(format!(
                    "it checks every node of `{}` by itself once the program gives it to the runtime (`Runtime::tap`, or loaded into a serving executive)",
                    tap.target
                )),
            );
        }
        let on = spawn
            .constraints
            .iter()
            .find(|it| matches!(it.kind, ConstraintKind::OnAgent(_)));
        let outcome = spawn
            .constraints
            .iter()
            .find(|it| matches!(it.kind, ConstraintKind::Outcome));
        if let (Some(on), Some(outcome)) = (on, outcome) {
            diags.push(
                Diagnostic::error(
                    outcome.span,
                    "`outcome` of a task placed on an agent is not supported yet",
                )
                .with_label(on.span, "placed on an agent here")
                .with_hint(
                    "wait for its value (`let v: T = spawn t(..) with on \"arm\", wait;`) and \
                     handle its failures with an exception handler",
                ),
            );
        }
        let waits = spawn
            .constraints
            .iter()
            .any(|it| matches!(it.kind, ConstraintKind::Wait | ConstraintKind::Outcome));
        let outcome = spawn
            .constraints
            .iter()
            .find(|it| matches!(it.kind, ConstraintKind::Outcome));
        if let (Some(outcome), None) = (outcome, &spawn.binding) {
            diags.push(
                Diagnostic::error(outcome.span, "`outcome` needs a binding to take it")
                    .with_hint("bind it: `let o = spawn task(args) with outcome;`, then `o.succeeded()`, `o.failure()`, …"),
            );
        }
        if spawn.binding.is_some() && !waits {
            diags.push(
                Diagnostic::error(
                    spawn.span,
                    "a spawn bound with `let` must wait for its result",
                )
                .with_hint("add `with wait`: `let v = spawn task(args) with wait;` (or `with outcome` for how it ended)"),
            );
        }
        self.parent(spawn, diags);
        if let [only] = spawn.constraints.as_slice() {
            if matches!(only.kind, ConstraintKind::Parallel) {
                diags.push(
                    Diagnostic::warning(Lint::RedundantParallel, only.span, "`parallel` on a single spawn has no effect")
                        .with_hint("spawns are parallel by default; use `parallel` on a `with (parallel) { ... }` group"),
                );
            }
        }
    }

    /// A spawn with `parent`: its node is not this body's child, so it cannot fulfil a reservation
    /// of the body; what needs one is refused.
    fn parent(&self, spawn: &'a Spawn, diags: &mut Vec<Diagnostic>) {
        let Some(parent) = spawn
            .constraints
            .iter()
            .find(|it| matches!(it.kind, ConstraintKind::Parent(_)))
        else {
            return;
        };
        let refuse = |what: &str, hint: &str| {
            Diagnostic::error(parent.span, format!("`parent` on {what}")).with_hint(hint.to_owned())
        };
        if spawn.binding.is_some() {
            diags.push(refuse(
                "a spawn bound with `let`",
                "spawn it with `parent` and `wait`, then read its result another way, or spawn it under this task",
            ));
        }
        let labelled = spawn
            .constraints
            .iter()
            .any(|it| matches!(&it.kind, ConstraintKind::OnTerminate(ot) if !ot.labels.is_empty()));
        if labelled {
            diags.push(refuse(
                "a spawn whose `on terminate` task has a label",
                "an on-terminate label is a reservation of this task; spawn under this task, or drop the label",
            ));
        }
        let Some(def) = self.scope.spawn_def(spawn) else {
            return;
        };
        if def.var.is_some() && !def.site.loops.is_empty() {
            diags.push(refuse(
                "a spawn inside a loop that a tag names",
                "a tag cannot name the spawns of a loop made under another parent yet; `bind` each node to a tag instead",
            ));
        }
    }

    fn fail(&self, fail: &Fail, diags: &mut Vec<Diagnostic>) {
        match &fail.exception {
            Some(exc) => exception(self.file, exc, diags),
            None if self.task.kind == TaskKind::Handler => diags.push(
                Diagnostic::warning(
                    Lint::FailWithoutException,
                    fail.span,
                    "`fail;` without an exception in a handler",
                )
                .with_hint("to pass the exception on to the next handler write `bypass;`"),
            ),
            None => diags.push(
                Diagnostic::warning(
                    Lint::FailWithoutException,
                    fail.span,
                    "`fail` without an exception",
                )
                .with_hint("name the exception so a handler can match it: `fail Exc;`"),
            ),
        }
    }

    fn constraint_stmt(
        &self,
        position: usize,
        stmt: &'a ConstraintStmt,
        diags: &mut Vec<Diagnostic>,
    ) {
        let site = Site::Stmt(position, &stmt.tag);
        self.tag(&stmt.tag, diags);
        let terminates = matches!(
            stmt.constraint.kind,
            ConstraintKind::Trigger {
                then: Then::Terminate,
                ..
            }
        );
        if terminates && matches!(stmt.tag.kind, TagKind::Child | TagKind::Parent) {
            diags.push(
                Diagnostic::warning(Lint::TerminateSelf, stmt.tag.span, "terminate constraint on the enclosing task")
                    .with_hint("this terminates the task running this body; use `succeed;` or `fail Exc;` to end it"),
            );
        }
        self.constraint_list(std::slice::from_ref(&stmt.constraint), site, diags);
    }

    /// Reports an unknown or ambiguous tag and wrong index counts; the definition it names.
    fn tag(&self, tag: &Tag, diags: &mut Vec<Diagnostic>) -> Option<Named<'a>> {
        let TagKind::Named { name, indexes } = &tag.kind else {
            return None;
        };
        let named = match self.scope.resolve(tag) {
            Resolution::Named(named) => named,
            Resolution::Ambiguous(spawns) => {
                let mut diag = Diagnostic::error(
                    tag.span,
                    format!(
                        "ambiguous tag `{name}`: the task is spawned {} times in this body",
                        spawns.len()
                    ),
                )
                .with_hint("label the spawns (`t1: spawn a(1);`) and refer to a label");
                for id in spawns {
                    diag = diag.with_label(self.scope.spawns[id].spawn.task.span(), "spawned here");
                }
                diags.push(diag);
                return None;
            }
            _ => {
                diags.push(
                    Diagnostic::error(tag.span, format!("unknown tag `{name}`")).with_hint(
                        format!(
                            "`{name}` is not spawned or labelled in `{}`; {TAG_HINT}",
                            self.task.name
                        ),
                    ),
                );
                return None;
            }
        };
        let depth = self.scope.site(named.def).loops.len();
        if !indexes.is_empty() && matches!(named.def, Def::Bound(_)) {
            diags.push(
                Diagnostic::error(
                    tag.span,
                    format!("`{name}` is bound with `bind`, so it takes no iteration index"),
                )
                .with_label(named.span, "bound here")
                .with_hint(
                    "a bound tag names the one node bound last; bind each node to its own name",
                ),
            );
        } else if indexes.len() > depth {
            let msg = if depth == 0 {
                format!("`{name}` is not spawned in a loop, so it takes no iteration index")
            } else {
                format!(
                    "too many iteration indexes for `{name}`: it is spawned inside {depth} loop{}, the tag has {}",
                    if depth == 1 { "" } else { "s" },
                    indexes.len()
                )
            };
            diags.push(
                Diagnostic::error(tag.span, msg)
                    .with_label(named.span, "spawned here")
                    .with_hint("give one `[index]` per enclosing loop, outermost first; `[.]` means the current iteration"),
            );
        }
        Some(named)
    }

    fn constraint_list(
        &self,
        constraints: &[Constraint],
        site: Site<'a>,
        diags: &mut Vec<Diagnostic>,
    ) {
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
            self.constraint(constraint, site, diags);
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

    fn constraint(&self, constraint: &Constraint, site: Site<'a>, diags: &mut Vec<Diagnostic>) {
        let span = constraint.span;
        if let (Some(blocking), ConstraintKind::Wait | ConstraintKind::Outcome) =
            (self.task.blocking, &constraint.kind)
        {
            let what = if matches!(constraint.kind, ConstraintKind::Wait) {
                "`wait`"
            } else {
                "`outcome`"
            };
            diags.push(
                Diagnostic::error(span, format!("{what} in a `blocking` command"))
                    .with_label(
                        blocking,
                        "its body runs on a blocking thread, and cannot wait",
                    )
                    .with_hint(
                        "spawn without waiting from the blocking command, or wait in a goal that \
                         spawns it: `let v = spawn plan(args) with wait;`",
                    ),
            );
        }
        if let ConstraintKind::Trigger {
            when: When::External(ExternalName::Lit(name)),
            ..
        } = &constraint.kind
        {
            external_name(name, diags);
        }
        match (&constraint.kind, refers(&constraint.kind)) {
            // The constrained node waits for the tag: `sequential`, `serial`, `disable until`.
            (_, Some(Refers::WaitsOn(tag)))
            | (
                ConstraintKind::Trigger {
                    when: When::Event(_),
                    then: Then::Enable(_),
                },
                Some(Refers::Event(crate::ast::Event { tag, .. })),
            ) => self.waits_on(tag, site, span, diags),
            (_, Some(Refers::Event(event))) => {
                self.tag(&event.tag, diags);
            }
            (ConstraintKind::ExceptionHandler(it), _) => {
                handler(self.file, &it.name, diags);
                if matches!(site, Site::With) {
                    diags.push(
                        Diagnostic::error(span, "`exception handler` is not allowed in `with (...)`")
                            .with_hint("attach the handler to each spawn with `with exception handler ...`, or to the task definition"),
                    );
                }
            }
            (ConstraintKind::OnTerminate(_), _) if matches!(site, Site::With) => diags.push(
                Diagnostic::error(span, "`on terminate` is not allowed in `with (...)`")
                    .with_hint("put `on terminate` on a spawn or on the task definition"),
            ),
            (ConstraintKind::Outcome, _) if matches!(site, Site::With) => diags.push(
                Diagnostic::error(span, "`outcome` is not allowed in `with (...)`").with_hint(
                    "bind each spawn's outcome: `let o = spawn task(args) with outcome;`",
                ),
            ),
            (ConstraintKind::Parent(_), _) if matches!(site, Site::With) => diags.push(
                Diagnostic::error(span, "`parent` is not allowed in `with (...)`")
                    .with_hint("put `parent` on each spawn that goes under another node"),
            ),
            (ConstraintKind::OnAgent(_), _) => self.on_agent(span, site, diags),
            (ConstraintKind::Wait, _) => {
                if let Some((tag, named)) = self.forward(site) {
                    diags.push(
                        Diagnostic::error(tag.span, "`wait` on a task that is not spawned yet")
                            .with_label(named.span, "spawned later here")
                            .with_hint("move this statement after the spawn, or put `wait` on the spawn itself"),
                    );
                }
            }
            (
                ConstraintKind::MaximumActivate(_)
                | ConstraintKind::MaximumTrigger(_)
                | ConstraintKind::Period(_),
                _,
            ) => {
                if let Some((_, named)) = self.forward(site) {
                    diags.push(
                        Diagnostic::error(span, "a monitor limit set before the monitor is spawned")
                            .with_label(named.span, "spawned later here")
                            .with_hint("put it on the spawn (the spawn's value wins anyway), or move this statement after the spawn"),
                    );
                }
            }
            _ => {}
        }
        let spawn_only = matches!(
            constraint.kind,
            ConstraintKind::Name(_)
                | ConstraintKind::OnTerminate(_)
                | ConstraintKind::ExceptionHandler(_)
                | ConstraintKind::Parent(_)
                | ConstraintKind::Outcome
                | ConstraintKind::Propagate
                | ConstraintKind::Approval(_)
        );
        if spawn_only && matches!(site, Site::Stmt(..)) {
            diags.push(
                Diagnostic::error(span, "this constraint can only be given on the spawn")
                    .with_hint("move it into the spawn's `with` list"),
            );
        }
        if is_monitor_only(&constraint.kind) {
            self.monitor_only(constraint, site, diags);
        }
    }

    /// At a constraint statement naming a task spawned further down (a forward reference): its
    /// tag and that task.
    fn forward(&self, site: Site<'a>) -> Option<(&'a Tag, Named<'a>)> {
        let Site::Stmt(position, tag) = site else {
            return None;
        };
        let named = self.scope.named(tag)?;
        (self.scope.site(named.def).position > position).then_some((tag, named))
    }

    /// Diagnoses a tag that the constrained node waits on: it must exist and not be the node itself.
    fn waits_on(&self, tag: &Tag, site: Site<'_>, span: Span, diags: &mut Vec<Diagnostic>) {
        if matches!(tag.kind, TagKind::Child) && !matches!(site, Site::With) {
            diags.push(
                Diagnostic::error(span, "circular constraint: the task would wait for itself")
                    .with_label(tag.span, "`self` is the task being constrained")
                    .with_hint("refer to another task, `previous` or a label"),
            );
        }
        self.tag(tag, diags);
    }

    /// `on AGENT` places a task when it is spawned: on a spawn (or a `with` group of spawns) of
    /// a goal or command.
    fn on_agent(&self, span: Span, site: Site<'a>, diags: &mut Vec<Diagnostic>) {
        match site {
            Site::Stmt(..) => diags.push(
                Diagnostic::error(span, "`on` places a task when it is spawned").with_hint(
                    "put it on the spawn: `spawn arm_move(1.0) with on \"arm\";` (a node \
                         runs where it was spawned)",
                ),
            ),
            Site::Spawn(task) => {
                let kind = self.file.kind_of(&task.to_string());
                if let Some(kind @ (TaskKind::Monitor | TaskKind::Handler)) = kind {
                    let what = if kind == TaskKind::Monitor {
                        "monitor"
                    } else {
                        "handler"
                    };
                    diags.push(
                        Diagnostic::error(span, format!("a {what} cannot be placed on an agent"))
                            .with_label(task.span(), format!("`{task}` is a {what}"))
                            .with_hint(
                                "place the commands it spawns instead: `spawn read_sensor() \
                                 with on \"robot\", wait;`",
                            ),
                    );
                }
            }
            Site::With => {}
        }
    }

    fn monitor_only(&self, constraint: &Constraint, site: Site<'a>, diags: &mut Vec<Diagnostic>) {
        let task = match site {
            Site::Spawn(task) => Some(task),
            Site::Stmt(_, tag) => self
                .scope
                .named(tag)
                .and_then(|named| self.scope.task_of(named.def)),
            Site::With => None,
        };
        let Some(task) = task else {
            return;
        };
        let Some(kind) = self.file.kind_of(&task.to_string()) else {
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

    /// Diagnoses `[.]` in the tags of `constraints` applied inside the loops `site`.
    fn current_indexes(
        &self,
        constraints: &'a [Constraint],
        site: &[LoopId],
        reported: &mut BTreeSet<*const Tag>,
        diags: &mut Vec<Diagnostic>,
    ) {
        for constraint in constraints {
            match refers(&constraint.kind) {
                Some(Refers::WaitsOn(tag)) => self.current_index(tag, site, reported, diags),
                Some(Refers::Event(event)) => {
                    self.current_index(&event.tag, site, reported, diags);
                }
                Some(Refers::Previous) | None => {}
            }
        }
    }

    /// Reports `[.]` in `tag` used outside the loop it counts (once per tag).
    fn current_index(
        &self,
        tag: &'a Tag,
        site: &[LoopId],
        reported: &mut BTreeSet<*const Tag>,
        diags: &mut Vec<Diagnostic>,
    ) {
        let TagKind::Named { indexes, .. } = &tag.kind else {
            return;
        };
        if !indexes.iter().any(|it| matches!(it, TagIndex::Current)) {
            return;
        }
        let Some(Named {
            def: Def::Spawn(id),
            ..
        }) = self.scope.named(tag)
        else {
            return;
        };
        let outside = matches!(
            self.scope.indexes(id, indexes, site),
            Err(IndexError::CurrentOutside)
        );
        if outside && reported.insert(std::ptr::from_ref(tag)) {
            diags.push(
                Diagnostic::error(tag.span, "`[.]` outside the loop it counts")
                    .with_hint("`[.]` means the current iteration of the loop around the spawn; use it inside that loop, or write the iteration number"),
            );
        }
    }

    /// Diagnoses one `node!(tag)`: the tag must name one node.
    fn node_use(&self, it: &NodeUse, diags: &mut Vec<Diagnostic>) {
        const HINT: &str = "`node!(tag)` takes a task spawned once in this body, a label, a bound \
                            name or `parent`, with one index per loop around its spawn";
        let tag = match &it.tag {
            Ok(tag) => tag,
            Err(err) => {
                diags.push(
                    Diagnostic::error(it.span, format!("`node!(…)` needs a tag: {err}"))
                        .with_hint(HINT),
                );
                return;
            }
        };
        let several = |what: &str| {
            Diagnostic::error(tag.span, format!("`node!` names one node, and {what}"))
                .with_hint(HINT)
        };
        let TagKind::Named { name, indexes } = &tag.kind else {
            match tag.kind {
                TagKind::Previous => diags.push(several("`previous` may be a whole group")),
                TagKind::Child => diags.push(
                    Diagnostic::error(tag.span, "`node!(self)` outside a spawn")
                        .with_hint("`self` is the node being spawned; `node!(parent)` is the node running this body"),
                ),
                _ => {}
            }
            return;
        };
        let Some(named) = self.tag(tag, diags) else {
            return;
        };
        let depth = self.scope.site(named.def).loops.len();
        match named.def {
            Def::Group(_) => diags.push(several(&format!("`{name}` is a `with` group"))),
            Def::Spawn(_) | Def::OnTerminate(_) if indexes.len() < depth => {
                diags.push(several(&format!(
                    "`{name}` is spawned inside {depth} loop{}: give one index per loop",
                    if depth == 1 { "" } else { "s" }
                )));
            }
            Def::Spawn(id) | Def::OnTerminate(id)
                if matches!(
                    self.scope
                        .indexes(self.spawn_of(named.def, id), indexes, &it.site.loops),
                    Err(IndexError::CurrentOutside)
                ) =>
            {
                diags.push(
                    Diagnostic::error(tag.span, "`[.]` outside the loop it counts")
                        .with_hint("`[.]` means the current iteration of the loop around the spawn; use it inside that loop, or write the iteration number"),
                );
            }
            _ => {}
        }
    }

    /// The spawn a spawn or on-terminate definition belongs to (`id` is its own number).
    fn spawn_of(&self, def: Def<'a>, id: usize) -> usize {
        match def {
            Def::OnTerminate(_) => self.scope.cleanups[id].spawn,
            _ => id,
        }
    }

    /// Reports tags whose node is only known once a statement ran (a `bind`, a spawn with
    /// `parent`) used before that statement (once per name).
    fn unbound_refs(&self, diags: &mut Vec<Diagnostic>) {
        let uses = self.scope.node_uses.iter().filter_map(|it| {
            let tag = it.tag.as_ref().ok()?;
            let TagKind::Named { name, .. } = &tag.kind else {
                return None;
            };
            Some((tag, name, it.site.position))
        });
        let refs = self.scope.refs.iter().map(|r| (r.tag, r.name, r.position));
        let mut reported = BTreeSet::new();
        for (tag, name, position) in refs.chain(uses) {
            let Some(named) = self.scope.named(tag) else {
                continue;
            };
            if self.scope.is_late(named.def)
                && position < self.scope.site(named.def).position
                && reported.insert(name.to_string())
            {
                let what = match named.def {
                    Def::Bound(_) => "bound",
                    _ => "spawned (under another `parent`)",
                };
                diags.push(
                    Diagnostic::error(tag.span, format!("`{name}` is used before it is {what}"))
                        .with_label(named.span, format!("{what} here"))
                        .with_hint(
                            "its node is only known once that statement ran; move this after it",
                        ),
                );
            }
        }
    }

    /// Reports references to a `with` group written before it (once per group name).
    fn forward_group_refs(&self, diags: &mut Vec<Diagnostic>) {
        let mut reported = BTreeSet::new();
        for r in &self.scope.refs {
            let Some(Named {
                def: Def::Group(id),
                ..
            }) = self.scope.named(r.tag)
            else {
                continue;
            };
            if r.position < self.scope.groups[id].site.position
                && reported.insert(r.name.to_string())
            {
                diags.push(
                    Diagnostic::error(
                        r.tag.span,
                        format!("forward reference to the `with` group `{}`", r.name),
                    )
                    .with_hint("a group's members are only known once it has run; move this after the group, or name one of its spawns"),
                );
            }
        }
    }
}

/// Reports an empty external event name: no program raises `""` on purpose, and it would be one
/// event shared by every such constraint.
fn external_name(name: &syn::LitStr, diags: &mut Vec<Diagnostic>) {
    if name.value().is_empty() {
        diags.push(
            Diagnostic::error(name.span(), "the name of an external event is empty")
                .with_hint("write the name the program raises, as in `terminate at external \"goal_updated\"` with `session.raise(\"goal_updated\")`"),
        );
    }
}

fn is_monitor_only(kind: &ConstraintKind) -> bool {
    matches!(
        kind,
        ConstraintKind::Trigger {
            then: Then::Activate,
            ..
        } | ConstraintKind::MaximumActivate(_)
            | ConstraintKind::MaximumTrigger(_)
            | ConstraintKind::Period(_)
    )
}
