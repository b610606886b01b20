//! A TDL program as the checker runs it: the files parsed and checked as `tdl check` does, every
//! task compiled to instructions ([`crate::ir`]), the exceptions with their ancestries, the
//! external events the program names and the tasks it spawns but does not define.

use std::collections::{BTreeMap, BTreeSet};
use std::time::Duration;

use proc_macro2::{Delimiter, TokenStream, TokenTree};
use tcm_core::{EachActivation, Facet, Outcome, Point, Then};
use tdl_syntax::{ast, hir};

use crate::ir::{
    Body, CIr, Call, Callee, EventIr, Exits, GroupId, GroupIr, HandlerUse, IndexIr, Iter, LoopId,
    MonitorOverride, Op, ResOp, SpawnIr, StmtIr, StmtOp, TagDef, TagId, TagKind, TagOf, TagRef,
    TagUse, TagUseOf, TaskId, TimeIr, UsesIr, Wait, WhenIr,
};
use crate::value::{Sym, VExpr, lower};

/// Why a program cannot be verified.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// The files have errors (rendered as `tdl check` prints them).
    #[error("the program has errors:\n{0}")]
    Invalid(String),
    /// A construct the checker does not model.
    #[error("{file}:{line}: {what} is not supported by `tdl verify` yet")]
    Unsupported {
        /// The file.
        file: String,
        /// The line.
        line: u32,
        /// What it is.
        what: String,
    },
    /// No file, or no task to verify.
    #[error("{0}")]
    NoTask(String),
}

/// A task definition of the program.
#[derive(Clone, Debug)]
pub(crate) struct TaskDef {
    /// Leaked once per program: nodes name their task by a `&'static str`, which the engine
    /// clones for free (docs/verification.md, "Speed").
    pub(crate) name: &'static str,
    pub(crate) kind: ast::TaskKind,
    pub(crate) params: Vec<Sym>,
    pub(crate) body: Body,
    pub(crate) expand_first: bool,
    pub(crate) delay_expansion: bool,
    pub(crate) persistent: bool,
    pub(crate) handlers: Vec<HandlerUse>,
    pub(crate) on_terminate: Vec<Call>,
    pub(crate) max_activations: Option<VExpr>,
    pub(crate) max_triggers: Option<VExpr>,
    pub(crate) period: Option<TimeIr>,
    pub(crate) initial_wait: bool,
    pub(crate) each: EachActivation,
    /// A handler: the exception it handles.
    pub(crate) handles: Option<&'static str>,
    /// A handler declared `for T`.
    pub(crate) for_task: Option<String>,
    /// The exceptions its body raises with `fail` (a bare `fail` is `Fail`).
    pub(crate) raises: BTreeSet<String>,
    /// Its task-level `uses` and `priority`.
    pub(crate) uses: UsesIr,
    pub(crate) file: usize,
}

/// A resource the program declares: `resource name(capacity) [pending N];`.
#[derive(Clone, Debug)]
pub(crate) struct ResourceDef {
    pub(crate) name: &'static str,
    pub(crate) capacity: u32,
    pub(crate) pending: Option<u32>,
}

/// A TDL program, ready to be verified.
#[derive(Clone, Debug, Default)]
pub struct Program {
    pub(crate) tasks: Vec<TaskDef>,
    pub(crate) by_name: BTreeMap<String, TaskId>,
    /// Tasks the program spawns but does not define (Rust functions returning a `Task`).
    pub(crate) externs: Vec<&'static str>,
    /// Declared exceptions with their ancestors, nearest first.
    pub(crate) exceptions: BTreeMap<String, Vec<&'static str>>,
    /// What a command without a TDL body may raise: every exception the program declares or
    /// handles.
    pub(crate) raisable: Vec<&'static str>,
    /// The external events named by literal (and computed names, as a placeholder each).
    pub(crate) external_events: Vec<String>,
    /// The resources it declares, in order.
    pub(crate) resources: Vec<ResourceDef>,
    pub(crate) symbols: Vec<String>,
    pub(crate) files: Vec<String>,
    /// What the checker abstracts that a reader should know of, with its place.
    pub(crate) notes: Vec<String>,
}

impl Program {
    /// Loads a program from its files, `(name, source)`: checked as one program as `tdl check`
    /// does (errors refuse it), then compiled for the checker.
    pub fn load(files: &[(String, String)]) -> Result<Program, LoadError> {
        if files.is_empty() {
            return Err(LoadError::NoTask("no TDL file given".into()));
        }
        let named: Vec<(&str, &str)> = files
            .iter()
            .map(|(n, s)| (n.as_str(), s.as_str()))
            .collect();
        tdl_syntax::compile_program_with(&named, |program, results| {
            let mut rendered = String::new();
            for ((name, src), (_, diags)) in named.iter().zip(results) {
                if diags.iter().any(tdl_syntax::Diagnostic::is_error) {
                    let errors: Vec<_> = diags.into_iter().filter(|d| d.is_error()).collect();
                    rendered.push_str(&tdl_syntax::render_all(&errors, name, Some(src)));
                }
            }
            if !rendered.is_empty() {
                return Err(LoadError::Invalid(rendered));
            }
            Program::build(program, files)
        })
    }

    /// Compiles the resolved program for the checker.
    fn build(program: &hir::Program<'_>, files: &[(String, String)]) -> Result<Program, LoadError> {
        let mut b = Builder::default();
        b.prog.files = files.iter().map(|(n, _)| n.clone()).collect();
        // Pass 1: names.
        let tasks: Vec<hir::TaskRef<'_>> = program.tasks().collect();
        for (i, t) in tasks.iter().enumerate() {
            let id = TaskId::try_from(i)
                .map_err(|_| LoadError::NoTask("more than 65535 tasks".into()))?;
            b.prog.by_name.entry(t.task.name.to_string()).or_insert(id);
        }
        for (_, e) in program.exceptions() {
            let name = e.name.to_string();
            let ancestry = program.ancestry(&name).iter().map(|c| leak(c)).collect();
            b.prog.exceptions.insert(name, ancestry);
        }
        for r in program.resources() {
            b.prog.resources.push(ResourceDef {
                name: leak(&r.name.to_string()),
                capacity: r.capacity.base10_parse().unwrap_or(1),
                pending: r.pending.as_ref().and_then(|p| p.base10_parse().ok()),
            });
        }
        // Pass 2: bodies.
        for t in &tasks {
            let def = b.task(t.file, t.task, program.body(t.task))?;
            b.prog.tasks.push(def);
        }
        let mut raisable: BTreeSet<&'static str> =
            b.prog.exceptions.keys().map(|e| leak(e)).collect();
        raisable.extend(b.prog.tasks.iter().filter_map(|t| t.handles));
        b.prog.raisable = raisable.into_iter().collect();
        Ok(b.prog)
    }

    /// The task a run starts from: `name`, or else the only goal no task of the program spawns
    /// (nor names as a handler, an on-terminate task or an attached handler's target).
    pub fn root_task(&self, name: Option<&str>) -> Result<String, LoadError> {
        if let Some(name) = name {
            return match self.by_name.get(name) {
                Some(&id) if self.tasks[id as usize].kind != ast::TaskKind::Handler => {
                    Ok(name.to_owned())
                }
                Some(_) => Err(LoadError::NoTask(format!(
                    "`{name}` is a handler: verify a goal, command or monitor"
                ))),
                None => Err(LoadError::NoTask(format!(
                    "no task `{name}` in {}",
                    self.files.join(", ")
                ))),
            };
        }
        let mut spawned: BTreeSet<TaskId> = BTreeSet::new();
        for t in &self.tasks {
            for s in &t.body.spawns {
                if let Callee::Task(id) = s.call.callee {
                    spawned.insert(id);
                }
                for (c, _) in &s.on_terminate {
                    if let Callee::Task(id) = c.callee {
                        spawned.insert(id);
                    }
                }
            }
            for c in &t.on_terminate {
                if let Callee::Task(id) = c.callee {
                    spawned.insert(id);
                }
            }
        }
        let candidates: Vec<&TaskDef> = self
            .tasks
            .iter()
            .enumerate()
            .filter(|(i, t)| t.kind == ast::TaskKind::Goal && !spawned.contains(&(*i as TaskId)))
            .map(|(_, t)| t)
            .collect();
        match candidates.as_slice() {
            [one] => Ok(one.name.to_owned()),
            [] => Err(LoadError::NoTask(
                "every goal of the program is spawned by another: name the task to verify with --task"
                    .into(),
            )),
            many => Err(LoadError::NoTask(format!(
                "several goals are spawned by no other ({}): name the one to verify with --task",
                many.iter()
                    .map(|t| t.name)
                    .collect::<Vec<_>>()
                    .join(", ")
            ))),
        }
    }

    /// Every tag written in a constraint as the loader resolved it (`previous` left out: the
    /// checker follows it at run time), with the file of its task; a group names each spawn the
    /// loader put in it. For a test that holds the back ends to one answer.
    pub fn resolved_tags(&self) -> Vec<hir::ResolvedTag> {
        let mut out = Vec::new();
        for task in &self.tasks {
            let body = &task.body;
            for u in &body.tag_uses {
                let targets: Vec<hir::TagTarget> = match u.tag {
                    TagUseOf::Parent => vec![hir::TagTarget::Parent],
                    TagUseOf::This => vec![hir::TagTarget::This],
                    TagUseOf::Unknown => Vec::new(),
                    TagUseOf::Tag(id) => match &body.tags[usize::from(id)].of {
                        TagOf::Spawn(i) => vec![hir::TagTarget::Spawn(*i)],
                        TagOf::OnTerminate(i, k) => vec![hir::TagTarget::OnTerminate(*i, *k)],
                        TagOf::Bound(name) => vec![hir::TagTarget::Bound(name.clone())],
                        TagOf::Group(g) => body
                            .spawns
                            .iter()
                            .enumerate()
                            .filter(|(_, s)| s.groups.iter().any(|it| usize::from(*it) == *g))
                            .map(|(i, _)| hir::TagTarget::Spawn(i))
                            .collect(),
                    },
                };
                out.push(hir::ResolvedTag {
                    file: task.file,
                    line: u.line,
                    column: u.column,
                    targets: targets.into_iter().collect(),
                });
            }
        }
        out
    }

    /// What the checker abstracts in this program, each with its place (docs/verification.md).
    pub fn notes(&self) -> &[String] {
        &self.notes
    }

    pub(crate) fn task(&self, id: TaskId) -> &TaskDef {
        &self.tasks[id as usize]
    }

    pub(crate) fn callee_name(&self, c: Callee) -> &'static str {
        match c {
            Callee::Task(id) => self.tasks[id as usize].name,
            Callee::Extern(i) => self.externs[i as usize],
        }
    }

    /// Where a body's instruction comes from.
    pub(crate) fn place(&self, task: TaskId, line: u32) -> String {
        let t = self.task(task);
        format!(
            "{}:{line}",
            self.files.get(t.file).map_or("?", String::as_str)
        )
    }
}

#[derive(Default)]
struct Builder {
    prog: Program,
    syms: BTreeMap<String, Sym>,
}

fn facet(f: ast::Facet) -> Facet {
    match f {
        ast::Facet::Handling => Facet::Handling,
        ast::Facet::Expansion => Facet::Expansion,
        ast::Facet::Execution => Facet::Execution,
    }
}

fn line_of(span: proc_macro2::Span) -> u32 {
    u32::try_from(span.start().line).unwrap_or(0)
}

impl Builder {
    fn sym(&mut self, name: &str) -> Sym {
        if let Some(s) = self.syms.get(name) {
            return *s;
        }
        let s = Sym::try_from(self.prog.symbols.len()).unwrap_or(Sym::MAX);
        self.prog.symbols.push(name.to_owned());
        self.syms.insert(name.to_owned(), s);
        s
    }

    fn lower(&mut self, e: &syn::Expr) -> VExpr {
        let mut syms = std::mem::take(&mut self.syms);
        let mut symbols = std::mem::take(&mut self.prog.symbols);
        let v = lower(e, &mut |n| {
            if let Some(s) = syms.get(n) {
                return *s;
            }
            let s = Sym::try_from(symbols.len()).unwrap_or(Sym::MAX);
            symbols.push(n.to_owned());
            syms.insert(n.to_owned(), s);
            s
        });
        self.syms = syms;
        self.prog.symbols = symbols;
        v
    }

    fn callee(&mut self, name: &str) -> Callee {
        if let Some(id) = self.prog.by_name.get(name) {
            return Callee::Task(*id);
        }
        match self.prog.externs.iter().position(|e| *e == name) {
            Some(i) => Callee::Extern(i as u16),
            None => {
                self.prog.externs.push(leak(name));
                Callee::Extern((self.prog.externs.len() - 1) as u16)
            }
        }
    }

    fn call(&mut self, task: &syn::Ident, args: &[syn::Expr]) -> Call {
        let callee = self.callee(&task.to_string());
        let args = args.iter().map(|a| self.lower(a)).collect();
        Call { callee, args }
    }

    fn time(&mut self, t: &ast::RelTime) -> TimeIr {
        match t {
            ast::RelTime::Nanos(n) => TimeIr::Nanos(*n),
            ast::RelTime::Seconds(e) => TimeIr::Secs(self.lower(e)),
        }
    }

    fn count(&mut self, c: &ast::Count) -> VExpr {
        match c {
            ast::Count::Const(n) => VExpr::Lit(crate::value::Value::Int(
                i64::try_from(*n).unwrap_or(i64::MAX),
            )),
            ast::Count::Expr(e) => self.lower(e),
        }
    }

    /// A declared resource and its amount; `None` for a resource the program does not declare.
    fn resource_amount(&mut self, it: &ast::ResourceAmount) -> Option<(u16, VExpr)> {
        let r = self.resource(&it.name.to_string())?;
        let amount = match &it.amount {
            Some(c) => self.count(c),
            None => VExpr::Lit(crate::value::Value::Int(1)),
        };
        Some((r, amount))
    }

    fn resource(&self, name: &str) -> Option<u16> {
        self.prog
            .resources
            .iter()
            .position(|d| d.name == name)
            .and_then(|i| u16::try_from(i).ok())
    }

    fn priority(&mut self, p: &ast::Priority) -> VExpr {
        match p {
            ast::Priority::Const(n) => VExpr::Lit(crate::value::Value::Int(*n)),
            ast::Priority::Expr(e) => self.lower(e),
        }
    }

    fn handler_use(
        &mut self,
        h: &ast::HandlerRef,
        file: usize,
        line: u32,
    ) -> Result<HandlerUse, LoadError> {
        let name = h.name.to_string();
        let Some(&id) = self.prog.by_name.get(&name) else {
            return Err(LoadError::Unsupported {
                file: self.prog.files[file].clone(),
                line,
                what: format!(
                    "the handler `{name}`, written in Rust (the checker needs the exception it handles)"
                ),
            });
        };
        let args = h.args.iter().map(|a| self.lower(a)).collect();
        let max = h.max_activate.as_ref().map(|c| self.count(c));
        Ok(HandlerUse {
            handler: id,
            args,
            max,
        })
    }

    fn task(
        &mut self,
        file: usize,
        t: &ast::Task,
        scope: &hir::BodyScope<'_>,
    ) -> Result<TaskDef, LoadError> {
        let line = line_of(t.span);
        let mut def = TaskDef {
            name: leak(&t.name.to_string()),
            kind: t.kind,
            params: Vec::new(),
            body: Body::default(),
            expand_first: false,
            delay_expansion: false,
            persistent: t.persistent,
            handlers: Vec::new(),
            on_terminate: Vec::new(),
            max_activations: None,
            max_triggers: None,
            period: None,
            initial_wait: false,
            each: EachActivation::default(),
            handles: t.handles.as_ref().map(|h| leak(&h.to_string())),
            for_task: t.for_task.as_ref().map(|h| h.to_string()),
            raises: BTreeSet::new(),
            uses: UsesIr::default(),
            file,
        };
        def.params = t
            .args
            .iter()
            .map(|a| self.sym(&a.name.to_string()))
            .collect();
        let monitor = t.kind == ast::TaskKind::Monitor;
        for c in &t.constraints {
            let cline = line_of(c.span);
            match &c.kind {
                ast::TaskConstraintKind::ExpandFirst if monitor => def.each.expand_first = true,
                ast::TaskConstraintKind::DelayExpansion if monitor => {
                    def.each.delay_expansion = true;
                }
                ast::TaskConstraintKind::ExpandFirst => def.expand_first = true,
                ast::TaskConstraintKind::DelayExpansion => def.delay_expansion = true,
                ast::TaskConstraintKind::ExceptionHandler(h) => {
                    let u = self.handler_use(h, file, cline)?;
                    def.handlers.push(u);
                }
                ast::TaskConstraintKind::OnTerminate(o) => {
                    let call = self.call(&o.task, &o.args);
                    def.on_terminate.push(call);
                }
                ast::TaskConstraintKind::Persistent(_) => {}
                ast::TaskConstraintKind::Uses(list) => {
                    for it in list {
                        match self.resource_amount(it) {
                            Some(u) => def.uses.amounts.push(u),
                            None => {
                                let n = format!(
                                    "{}:{cline}: `uses {}` of `{}` left out: the program does not \
                                     declare the resource",
                                    b_files_name(&self.prog.files, file),
                                    it.name,
                                    t.name
                                );
                                self.prog.notes.push(n);
                            }
                        }
                    }
                }
                ast::TaskConstraintKind::Priority(p) => def.uses.priority = Some(self.priority(p)),
                ast::TaskConstraintKind::MaximumActivate(n) => {
                    def.max_activations = Some(self.count(n));
                }
                ast::TaskConstraintKind::MaximumTrigger(n) => {
                    def.max_triggers = Some(self.count(n));
                }
                ast::TaskConstraintKind::Period(p) => def.period = Some(self.time(p)),
                ast::TaskConstraintKind::InitialWait => def.initial_wait = true,
                ast::TaskConstraintKind::Serial => def.each.serial = true,
                ast::TaskConstraintKind::Sequential(ast::Facet::Execution) => {
                    def.each.sequential_execution = true;
                }
                ast::TaskConstraintKind::Sequential(_) => def.each.sequential_expansion = true,
            }
        }
        def.raises = scope.raises();
        let mut c = BodyCompiler::new(self, file, def.name, scope);
        c.block(&t.body.stmts)?;
        c.emit(Op::End, line);
        c.finish();
        def.body = std::mem::take(&mut c.body);
        Ok(def)
    }
}

/// Compiles one body.
struct BodyCompiler<'b, 's, 'a> {
    b: &'b mut Builder,
    file: usize,
    task: String,
    /// The body's names, resolved by the front end.
    scope: &'s hir::BodyScope<'a>,
    body: Body,
    /// Tags created, by what they name.
    tags: BTreeMap<TagOf, TagId>,
    /// Tags named by a statement that terminates their node.
    terminated: BTreeSet<TagId>,
    // Compilation state.
    n_spawns: usize,
    n_groups: usize,
    n_loops: u16,
    loops: Vec<LoopFrame>,
    groups: Vec<GroupId>,
}

struct LoopFrame {
    id: LoopId,
    label: Option<String>,
    test: u32,
    /// `break` sites to patch with the exit.
    breaks: Vec<usize>,
}

impl<'b, 's, 'a> BodyCompiler<'b, 's, 'a> {
    fn new(b: &'b mut Builder, file: usize, task: &str, scope: &'s hir::BodyScope<'a>) -> Self {
        BodyCompiler {
            b,
            file,
            task: task.to_owned(),
            scope,
            body: Body::default(),
            tags: BTreeMap::new(),
            terminated: BTreeSet::new(),
            n_spawns: 0,
            n_groups: 0,
            n_loops: 0,
            loops: Vec::new(),
            groups: Vec::new(),
        }
    }

    fn unsupported(&self, line: u32, what: impl Into<String>) -> LoadError {
        LoadError::Unsupported {
            file: self.b.prog.files[self.file].clone(),
            line,
            what: what.into(),
        }
    }

    fn note(&mut self, line: u32, what: impl std::fmt::Display) {
        let n = format!(
            "{}:{line}: {what} (in `{}`)",
            self.b.prog.files[self.file], self.task
        );
        self.b.prog.notes.push(n);
    }

    /// The tag of what `def` names, created on first use.
    fn tag_of(&mut self, def: hir::Def<'_>) -> TagId {
        let scope = self.scope;
        let loops_of = |spawn: usize| -> Vec<LoopId> {
            scope.spawns.get(spawn).map_or_else(Vec::new, |it| {
                let loops = it.site.loops.iter();
                loops
                    .map(|l| LoopId::try_from(*l).unwrap_or(LoopId::MAX))
                    .collect()
            })
        };
        let (kind, of, loops, reserve_as) = match def {
            hir::Def::Spawn(i) => (
                TagKind::Spawn,
                TagOf::Spawn(i),
                loops_of(i),
                scope.spawns[i].spawn.task.to_string(),
            ),
            hir::Def::Group(i) => (TagKind::Group, TagOf::Group(i), Vec::new(), String::new()),
            hir::Def::OnTerminate(id) => {
                let cleanup = &scope.cleanups[id];
                (
                    TagKind::OnTerminate,
                    TagOf::OnTerminate(cleanup.spawn, cleanup.index),
                    loops_of(cleanup.spawn),
                    cleanup.on_terminate.task.to_string(),
                )
            }
            hir::Def::Bound(bind) => (
                TagKind::Bound,
                TagOf::Bound(bind.name.to_string()),
                Vec::new(),
                String::new(),
            ),
        };
        if let Some(t) = self.tags.get(&of) {
            return *t;
        }
        let next = TagId::try_from(self.body.tags.len()).unwrap_or(TagId::MAX);
        self.tags.insert(of.clone(), next);
        self.body.tags.push(TagDef {
            kind,
            loops,
            reserve_as,
            of,
        });
        next
    }

    /// Keeps what a tag written in a constraint was taken for.
    fn used(&mut self, tag: &ast::Tag, of: TagUseOf) {
        let at = tag.span.start();
        self.body.tag_uses.push(TagUse {
            line: at.line,
            column: at.column,
            tag: of,
        });
    }

    fn tag(&mut self, tag: &ast::Tag) -> TagRef {
        match &tag.kind {
            ast::TagKind::Previous => TagRef::Previous,
            ast::TagKind::Child => {
                self.used(tag, TagUseOf::This);
                TagRef::This
            }
            ast::TagKind::Parent => {
                self.used(tag, TagUseOf::Parent);
                TagRef::Parent
            }
            ast::TagKind::Named { indexes, .. } => {
                let Some(named) = self.scope.named(tag) else {
                    self.used(tag, TagUseOf::Unknown);
                    return TagRef::Opaque;
                };
                let id = self.tag_of(named.def);
                self.used(tag, TagUseOf::Tag(id));
                let def = &self.body.tags[id as usize];
                if matches!(def.kind, TagKind::Bound) {
                    return TagRef::Opaque;
                }
                let site = def.loops.clone();
                let idx = indexes
                    .iter()
                    .enumerate()
                    .map(|(i, ix)| match ix {
                        ast::TagIndex::Current => {
                            IndexIr::Current(site.get(i).copied().unwrap_or_default())
                        }
                        ast::TagIndex::Expr(e) => IndexIr::Expr(self.b.lower(e)),
                    })
                    .collect();
                TagRef::Named(id, idx)
            }
        }
    }

    fn event(&mut self, e: &ast::Event) -> EventIr {
        let (point, outcome) = match e.point {
            ast::Point::Enabled => (Point::Enabled, None),
            ast::Point::Active => (Point::Active, None),
            ast::Point::Completed => (Point::Completed, None),
            ast::Point::Succeeded => (Point::Completed, Some(Outcome::Succeeded)),
            ast::Point::Failed => (Point::Completed, Some(Outcome::Failed)),
            ast::Point::Terminated => (Point::Completed, Some(Outcome::Terminated)),
        };
        let f = match (e.facet, point, outcome) {
            (_, _, Some(_)) => Facet::Execution,
            (Some(f), _, None) => facet(f),
            (None, Point::Completed, None) => Facet::Execution,
            (None, _, None) => Facet::Handling,
        };
        EventIr {
            tag: self.tag(&e.tag),
            facet: f,
            point,
            outcome,
        }
    }

    fn when(&mut self, w: &ast::When, line: u32) -> WhenIr {
        match w {
            ast::When::Now => WhenIr::Now,
            ast::When::At(t) => WhenIr::At(t.nanos_since_midnight()),
            ast::When::In(t) => WhenIr::In(self.b.time(t)),
            ast::When::Event(e) => WhenIr::Event(self.event(e)),
            ast::When::After(t, e) => {
                let t = self.b.time(t);
                WhenIr::After(t, self.event(e))
            }
            ast::When::External(ast::ExternalName::Lit(l)) => {
                let name = l.value();
                if !self.b.prog.external_events.contains(&name) {
                    self.b.prog.external_events.push(name.clone());
                }
                WhenIr::External(Some(name))
            }
            ast::When::External(ast::ExternalName::Expr(_)) => {
                let name = format!("(computed at {}:{line})", self.b.prog.files[self.file]);
                self.note(line, "an external event's name is computed in Rust: the checker raises it as one event of its own");
                if !self.b.prog.external_events.contains(&name) {
                    self.b.prog.external_events.push(name.clone());
                }
                WhenIr::External(Some(name))
            }
        }
    }

    /// A constraint that waits or triggers, as the checker applies it; `None` for the others.
    /// A spawn's or a group's `uses`, `priority` or `deny if busy`, into `uses`.
    fn uses(&mut self, uses: &mut UsesIr, c: &ast::Constraint) {
        match &c.kind {
            ast::ConstraintKind::Uses(list) => {
                for it in list {
                    match self.b.resource_amount(it) {
                        Some(u) => uses.amounts.push(u),
                        None => self.note(
                            line_of(c.span),
                            format!(
                                "`uses {}` left out: the program does not declare the resource",
                                it.name
                            ),
                        ),
                    }
                }
            }
            ast::ConstraintKind::Priority(p) => uses.priority = Some(self.b.priority(p)),
            ast::ConstraintKind::DenyIfBusy => uses.deny_if_busy = true,
            _ => {}
        }
    }

    fn constraint(&mut self, c: &ast::Constraint) -> Option<CIr> {
        let line = line_of(c.span);
        Some(match &c.kind {
            ast::ConstraintKind::ExpandFirst => CIr::ExpandFirst,
            ast::ConstraintKind::DelayExpansion => CIr::DelayExpansion,
            ast::ConstraintKind::Sequential { facet: f, tag } => {
                let t = tag.as_ref().map_or(TagRef::Previous, |t| self.tag(t));
                CIr::Sequential(facet(*f), t)
            }
            ast::ConstraintKind::Serial { tag } => {
                CIr::Serial(tag.as_ref().map_or(TagRef::Previous, |t| self.tag(t)))
            }
            ast::ConstraintKind::Trigger { when, then } => {
                let then = match then {
                    ast::Then::Enable(f) => Then::Enable(facet(f.unwrap_or(ast::Facet::Handling))),
                    ast::Then::Terminate => Then::Terminate,
                    ast::Then::Activate => Then::Activate,
                };
                CIr::Trigger {
                    when: self.when(when, line),
                    then,
                }
            }
            ast::ConstraintKind::Uses(_)
            | ast::ConstraintKind::Priority(_)
            | ast::ConstraintKind::DenyIfBusy => {
                self.note(
                    line,
                    "a resource constraint given as a statement is left out",
                );
                return None;
            }
            _ => return None,
        })
    }

    fn monitor_param(&mut self, m: &mut MonitorOverride, c: &ast::Constraint) -> bool {
        match &c.kind {
            ast::ConstraintKind::MaximumActivate(n) => m.max_activations = Some(self.b.count(n)),
            ast::ConstraintKind::MaximumTrigger(n) => m.max_triggers = Some(self.b.count(n)),
            ast::ConstraintKind::Period(p) => m.period = Some(self.b.time(p)),
            _ => return false,
        }
        true
    }

    fn emit(&mut self, op: Op, line: u32) -> usize {
        self.body.ops.push(op);
        self.body.lines.push(line);
        self.body.ops.len() - 1
    }

    fn pc(&self) -> u32 {
        u32::try_from(self.body.ops.len()).unwrap_or(u32::MAX)
    }

    fn finish(&mut self) {
        self.body.n_loops = self.n_loops;
        for s in &mut self.body.spawns {
            if s.tag.is_some_and(|t| self.terminated.contains(&t)) {
                s.terminable = true;
            }
        }
    }

    fn block(&mut self, stmts: &[ast::Stmt]) -> Result<(), LoadError> {
        for s in stmts {
            self.stmt(s)?;
        }
        Ok(())
    }

    fn stmt(&mut self, s: &ast::Stmt) -> Result<(), LoadError> {
        match s {
            ast::Stmt::Rust(r) => self.rust(&r.tokens, line_of(r.span)),
            ast::Stmt::Spawn(sp) => self.spawn(sp)?,
            ast::Stmt::With(g) => self.with(g)?,
            ast::Stmt::Constrain(cs) => self.constrain(cs),
            ast::Stmt::Bind(bd) => {
                let line = line_of(bd.span);
                self.note(
                    line,
                    format!(
                        "`bind {}`: the node is Rust's, so constraints on the tag are left out",
                        bd.name
                    ),
                );
                if let hir::Resolution::Named(named) = self.scope.lookup(&bd.name.to_string()) {
                    let t = self.tag_of(named.def);
                    self.emit(Op::Bind(t), line);
                }
            }
            ast::Stmt::Succeed(span) => {
                self.emit(Op::Succeed, line_of(*span));
            }
            ast::Stmt::Resource(r) => {
                let line = line_of(r.span);
                match self.b.resource(&r.name.to_string()) {
                    Some(i) => {
                        let op = match r.op {
                            ast::ResourceOp::Lock => ResOp::Lock,
                            ast::ResourceOp::Unlock => ResOp::Unlock,
                            ast::ResourceOp::Reserve => ResOp::Reserve,
                            ast::ResourceOp::Unreserve => ResOp::Unreserve,
                        };
                        self.emit(Op::Resource(op, i), line);
                    }
                    None => self.note(
                        line,
                        format!(
                            "`{} {}` left out: the program does not declare the resource",
                            r.op.as_str(),
                            r.name
                        ),
                    ),
                }
            }
            ast::Stmt::Fail(f) => {
                let e = f.exception.as_ref().map(|e| e.to_string());
                self.emit(Op::Fail(e), line_of(f.span));
            }
            ast::Stmt::Bypass(span) => {
                self.emit(Op::Bypass, line_of(*span));
            }
            ast::Stmt::Trigger(span) => {
                self.emit(Op::Trigger, line_of(*span));
            }
            ast::Stmt::Retry(r) => {
                if r.args.is_some() {
                    self.note(
                        line_of(r.span),
                        "`retry with (…)` runs the task again with its first arguments",
                    );
                }
                self.emit(Op::Retry, line_of(r.span));
            }
            ast::Stmt::If(it) => self.if_(it)?,
            ast::Stmt::For(f) => {
                let line = line_of(f.span);
                let iter = self.for_iter(&f.pat, &f.expr);
                let label = f.label.as_ref().map(|l| l.ident.to_string());
                self.looped(iter, label, &f.body, line)?;
            }
            ast::Stmt::While(w) => {
                let line = line_of(w.span);
                let cond = self.b.lower(&w.cond);
                let label = w.label.as_ref().map(|l| l.ident.to_string());
                self.looped(Iter::While(cond), label, &w.body, line)?;
            }
            ast::Stmt::Loop(l) => {
                let line = line_of(l.span);
                let label = l.label.as_ref().map(|l| l.ident.to_string());
                self.looped(Iter::Forever, label, &l.body, line)?;
            }
            ast::Stmt::Match(m) => {
                let line = line_of(m.span);
                let at = self.emit(Op::Match(Vec::new()), line);
                let mut arms = Vec::new();
                let mut ends = Vec::new();
                for arm in &m.arms {
                    arms.push(self.pc());
                    self.block(&arm.body.stmts)?;
                    ends.push(self.emit(Op::Jump(0), line));
                }
                let end = self.pc();
                for e in ends {
                    self.body.ops[e] = Op::Jump(end);
                }
                self.body.ops[at] = Op::Match(arms);
            }
            ast::Stmt::Block(bl) => self.block(&bl.stmts)?,
        }
        Ok(())
    }

    fn if_(&mut self, it: &ast::If) -> Result<(), LoadError> {
        let line = line_of(it.span);
        let cond = match &it.cond {
            syn::Expr::Let(_) => VExpr::Unknown,
            c => self.b.lower(c),
        };
        let at = self.emit(Op::If { cond, else_pc: 0 }, line);
        self.block(&it.then_branch.stmts)?;
        let jump = self.emit(Op::Jump(0), line);
        let else_pc = self.pc();
        match it.else_branch.as_deref() {
            Some(ast::Else::If(next)) => self.if_(next)?,
            Some(ast::Else::Block(bl)) => self.block(&bl.stmts)?,
            None => {}
        }
        let end = self.pc();
        self.body.ops[jump] = Op::Jump(end);
        if let Op::If { else_pc: e, .. } = &mut self.body.ops[at] {
            *e = else_pc;
        }
        Ok(())
    }

    fn for_iter(&mut self, pat: &syn::Pat, expr: &syn::Expr) -> Iter {
        let var = match pat {
            syn::Pat::Ident(p) => Some(self.b.sym(&p.ident.to_string())),
            _ => None,
        };
        let mut e = expr;
        while let syn::Expr::Paren(p) = e {
            e = &p.expr;
        }
        match e {
            syn::Expr::Range(r) => match (&r.start, &r.end) {
                (Some(s), Some(t)) => Iter::Range {
                    start: self.b.lower(s),
                    end: self.b.lower(t),
                    inclusive: matches!(r.limits, syn::RangeLimits::Closed(_)),
                    var,
                },
                _ => Iter::Unknown,
            },
            syn::Expr::Array(a) if var.is_none() || !a.elems.is_empty() => {
                Iter::Count(u32::try_from(a.elems.len()).unwrap_or(u32::MAX))
            }
            _ => Iter::Unknown,
        }
    }

    fn looped(
        &mut self,
        iter: Iter,
        label: Option<String>,
        body: &ast::Block,
        line: u32,
    ) -> Result<(), LoadError> {
        let id = self.n_loops;
        self.n_loops += 1;
        // The loop variable is not followed unless the range is counted.
        self.emit(Op::LoopStart { id, iter }, line);
        let test = self.emit(Op::LoopTest { id, exit: 0 }, line);
        self.loops.push(LoopFrame {
            id,
            label,
            test: u32::try_from(test).unwrap_or(u32::MAX),
            breaks: Vec::new(),
        });
        self.block(&body.stmts)?;
        self.emit(Op::Jump(u32::try_from(test).unwrap_or(u32::MAX)), line);
        let exit = self.pc();
        let frame = self.loops.pop();
        if let Op::LoopTest { exit: e, .. } = &mut self.body.ops[test] {
            *e = exit;
        }
        for b in frame.map(|f| f.breaks).unwrap_or_default() {
            if let Op::Exit(x) = &mut self.body.ops[b] {
                if let Some((_, pc)) = &mut x.brk {
                    *pc = exit;
                }
            }
        }
        Ok(())
    }

    /// A Rust statement: what it assigns the checker can follow, what it may change, and the ways
    /// out of the body or loop it may take.
    fn rust(&mut self, tokens: &TokenStream, line: u32) {
        if mentions(tokens, "ctx") {
            self.note(line, "Rust code that uses `ctx` is not run: what it does to the tree, and its failures, are not explored");
        } else if has_question_mark(tokens) {
            self.note(
                line,
                "a `?` in Rust code is not run: the failure it may raise is not explored",
            );
        }
        let block: Option<syn::Block> = syn::parse2(quote_block(tokens)).ok();
        if let Some(block) = &block {
            for st in &block.stmts {
                match st {
                    syn::Stmt::Local(l) => {
                        let init = l.init.as_ref().map(|i| &*i.expr);
                        match (&l.pat, init) {
                            (syn::Pat::Ident(p), Some(e)) => {
                                let s = self.b.sym(&p.ident.to_string());
                                let v = self.b.lower(e);
                                self.emit(Op::Let(s, v), line);
                            }
                            (syn::Pat::Type(pt), Some(e)) => {
                                if let syn::Pat::Ident(p) = &*pt.pat {
                                    let s = self.b.sym(&p.ident.to_string());
                                    let v = self.b.lower(e);
                                    self.emit(Op::Let(s, v), line);
                                } else {
                                    self.forget_pattern(&l.pat, line);
                                }
                            }
                            _ => self.forget_pattern(&l.pat, line),
                        }
                    }
                    syn::Stmt::Expr(syn::Expr::Assign(a), _) => match &*a.left {
                        syn::Expr::Path(p) if p.path.get_ident().is_some() => {
                            let name = p
                                .path
                                .get_ident()
                                .map(ToString::to_string)
                                .unwrap_or_default();
                            let s = self.b.sym(&name);
                            let v = self.b.lower(&a.right);
                            self.emit(Op::Let(s, v), line);
                        }
                        _ => self.forget_assigned(tokens, line),
                    },
                    _ => self.forget_assigned(&quote::ToTokens::to_token_stream(st), line),
                }
            }
        } else {
            self.forget_assigned(tokens, line);
        }
        let mut exits = Exits::default();
        let (ret, brk, cont) = scan_exits(tokens);
        exits.ret = ret;
        if brk.is_some() || cont.is_some() {
            let want = |l: &Option<Option<String>>| l.clone();
            for (which, label) in [(0, want(&brk)), (1, want(&cont))] {
                let Some(label) = label else { continue };
                let frame = match &label {
                    Some(l) => self
                        .loops
                        .iter()
                        .rev()
                        .find(|f| f.label.as_deref() == Some(l)),
                    None => self.loops.last(),
                };
                if let Some(f) = frame {
                    if which == 0 {
                        exits.brk = Some((f.id, 0));
                    } else {
                        exits.cont = Some((f.id, f.test));
                    }
                }
            }
        }
        if exits.ret || exits.brk.is_some() || exits.cont.is_some() {
            let brk_loop = exits.brk.map(|(l, _)| l);
            let at = self.emit(Op::Exit(exits), line);
            if let Some(l) = brk_loop {
                if let Some(f) = self.loops.iter_mut().rev().find(|f| f.id == l) {
                    f.breaks.push(at);
                }
            }
        }
    }

    fn forget_pattern(&mut self, pat: &syn::Pat, line: u32) {
        let mut names = Vec::new();
        idents(&quote::ToTokens::to_token_stream(pat), &mut names);
        let syms: Vec<Sym> = names.iter().map(|n| self.b.sym(n)).collect();
        if !syms.is_empty() {
            self.emit(Op::Forget(syms), line);
        }
    }

    /// Every variable a statement may assign (`x = …`, `x += …`, `&mut x`) becomes unknown.
    fn forget_assigned(&mut self, tokens: &TokenStream, line: u32) {
        let mut names = Vec::new();
        assigned(tokens, &mut names);
        let known: Vec<Sym> = names
            .iter()
            .filter_map(|n| self.b.syms.get(n.as_str()).copied())
            .collect();
        if !known.is_empty() {
            self.emit(Op::Forget(known), line);
        }
    }

    fn spawn(&mut self, sp: &ast::Spawn) -> Result<(), LoadError> {
        let line = line_of(sp.span);
        let index = self.n_spawns;
        self.n_spawns += 1;
        let call = self.b.call(&sp.task, &sp.args);
        let mut ir = SpawnIr {
            call,
            tag: None,
            groups: self.groups.clone(),
            cons: Vec::new(),
            wait: Wait::No,
            propagate: false,
            name: None,
            handlers: Vec::new(),
            on_terminate: Vec::new(),
            monitor: MonitorOverride::default(),
            uses: UsesIr::default(),
            terminable: false,
            remote: false,
            line,
        };
        let mut outcome = false;
        let mut wait = false;
        for c in &sp.constraints {
            let cline = line_of(c.span);
            if self.monitor_param(&mut ir.monitor, c) {
                continue;
            }
            match &c.kind {
                ast::ConstraintKind::Wait => wait = true,
                ast::ConstraintKind::Outcome => outcome = true,
                ast::ConstraintKind::Propagate => ir.propagate = true,
                ast::ConstraintKind::Parallel => {}
                ast::ConstraintKind::Name(e) => ir.name = Some(self.b.lower(e)),
                ast::ConstraintKind::Parent(_) => {
                    return Err(self.unsupported(cline, "`parent` (a spawn under another node)"));
                }
                // Runs on an agent: a command of the checker's choice, which may also lose its
                // agent (docs/verification.md, "Commands").
                ast::ConstraintKind::OnAgent(_) => ir.remote = true,
                ast::ConstraintKind::ExceptionHandler(h) => {
                    let u = self.b.handler_use(h, self.file, cline)?;
                    ir.handlers.push(u);
                }
                ast::ConstraintKind::OnTerminate(o) => {
                    let call = self.b.call(&o.task, &o.args);
                    let tag = self.cleanup_tag(o);
                    ir.on_terminate.push((call, tag));
                }
                ast::ConstraintKind::Uses(_)
                | ast::ConstraintKind::Priority(_)
                | ast::ConstraintKind::DenyIfBusy => self.uses(&mut ir.uses, c),
                _ => {
                    if let Some(ci) = self.constraint(c) {
                        ir.terminable |= ci.terminates();
                        ir.cons.push(ci);
                    }
                }
            }
        }
        ir.wait = match (&sp.binding, outcome, wait) {
            (Some(_), true, _) => Wait::Outcome,
            (Some(_), false, _) => Wait::Value,
            (None, _, true) => Wait::Plain,
            (None, _, false) => Wait::No,
        };
        for g in &self.groups {
            let gi = &self.body.groups[*g as usize];
            ir.terminable |= gi.terminable;
            if gi.wait && ir.wait == Wait::No {
                ir.wait = Wait::Plain;
            }
            ir.propagate |= gi.propagate;
            ir.remote |= gi.remote;
        }
        // Its own tag, if some tag or `node!` of the body names it (references may come later
        // in the body: the front end resolved them all).
        if self.scope.spawn_def(sp).is_some_and(|it| it.var.is_some()) {
            ir.tag = Some(self.tag_of(hir::Def::Spawn(index)));
        }
        let binds = match &sp.binding {
            Some(b) => match &b.target {
                ast::BindTarget::Let(p) => {
                    let mut names = Vec::new();
                    idents(&quote::ToTokens::to_token_stream(p), &mut names);
                    names
                }
                ast::BindTarget::Assign(e) => {
                    let mut names = Vec::new();
                    idents(&quote::ToTokens::to_token_stream(e), &mut names);
                    names
                }
            },
            None => Vec::new(),
        };
        let sid = u32::try_from(self.body.spawns.len()).unwrap_or(u32::MAX);
        self.body.spawns.push(ir);
        self.emit(Op::Spawn(sid), line);
        let syms: Vec<Sym> = binds.iter().map(|n| self.b.sym(n)).collect();
        if !syms.is_empty() {
            self.emit(Op::Forget(syms), line);
        }
        Ok(())
    }

    /// The tag of a labelled on-terminate task, when its first label names it.
    fn cleanup_tag(&mut self, o: &ast::OnTerminate) -> Option<TagId> {
        let label = o.labels.first()?;
        let id = self.scope.cleanup_id(o)?;
        match self.scope.lookup(&label.to_string()) {
            hir::Resolution::Named(named) if matches!(named.def, hir::Def::OnTerminate(it) if it == id) => {
                Some(self.tag_of(named.def))
            }
            _ => None,
        }
    }

    fn with(&mut self, g: &ast::WithGroup) -> Result<(), LoadError> {
        let line = line_of(g.span);
        let index = self.n_groups;
        self.n_groups += 1;
        let mut ir = GroupIr {
            cons: Vec::new(),
            monitor: MonitorOverride::default(),
            uses: UsesIr::default(),
            wait: false,
            propagate: false,
            terminable: false,
            remote: false,
            uses_previous: false,
            tag: None,
        };
        for c in &g.constraints {
            if self.monitor_param(&mut ir.monitor, c) {
                continue;
            }
            match &c.kind {
                ast::ConstraintKind::Wait => ir.wait = true,
                ast::ConstraintKind::Propagate => ir.propagate = true,
                ast::ConstraintKind::OnAgent(_) => ir.remote = true,
                ast::ConstraintKind::Parallel | ast::ConstraintKind::Name(_) => {}
                ast::ConstraintKind::Uses(_)
                | ast::ConstraintKind::Priority(_)
                | ast::ConstraintKind::DenyIfBusy => self.uses(&mut ir.uses, c),
                _ => {
                    if let Some(ci) = self.constraint(c) {
                        ir.terminable |= ci.terminates();
                        ir.uses_previous |= ci.uses_previous();
                        ir.cons.push(ci);
                    }
                }
            }
        }
        if self
            .scope
            .groups
            .get(index)
            .is_some_and(|it| it.var.is_some())
        {
            ir.tag = Some(self.tag_of(hir::Def::Group(index)));
        }
        let gid = GroupId::try_from(self.body.groups.len()).unwrap_or(GroupId::MAX);
        self.body.groups.push(ir);
        self.emit(Op::GroupStart(gid), line);
        self.groups.push(gid);
        self.block(&g.body.stmts)?;
        self.groups.pop();
        self.emit(Op::GroupEnd(gid), line);
        Ok(())
    }

    fn constrain(&mut self, cs: &ast::ConstraintStmt) {
        let line = line_of(cs.span);
        let target = self.tag(&cs.tag);
        let c = &cs.constraint;
        let op = match &c.kind {
            ast::ConstraintKind::Wait => StmtOp::Wait,
            ast::ConstraintKind::Trigger {
                when: ast::When::Now,
                then: ast::Then::Terminate,
            } => StmtOp::Terminate,
            ast::ConstraintKind::MaximumActivate(n) => StmtOp::MaxActivations(self.b.count(n)),
            ast::ConstraintKind::MaximumTrigger(n) => StmtOp::MaxTriggers(self.b.count(n)),
            ast::ConstraintKind::Period(p) => StmtOp::Period(self.b.time(p)),
            _ => match self.constraint(c) {
                Some(ci) => StmtOp::Constrain(ci),
                None => return,
            },
        };
        let terminates = matches!(op, StmtOp::Terminate)
            || matches!(&op, StmtOp::Constrain(ci) if ci.terminates());
        if let (true, TagRef::Named(t, _)) = (terminates, &target) {
            self.terminated.insert(*t);
        }
        let sid = u32::try_from(self.body.stmts.len()).unwrap_or(u32::MAX);
        self.body.stmts.push(StmtIr { target, op });
        self.emit(Op::Stmt(sid), line);
    }
}

/// A name for the program's lifetime and beyond: the engine's names are `Cow<'static, str>`, and
/// a borrowed one costs nothing to clone with each state. A program leaks its task and exception
/// names once, a few hundred bytes.
fn leak(s: &str) -> &'static str {
    Box::leak(s.to_owned().into_boxed_str())
}

/// `{ tokens }` as a token stream.
fn quote_block(tokens: &TokenStream) -> TokenStream {
    let group = proc_macro2::Group::new(Delimiter::Brace, tokens.clone());
    TokenStream::from(TokenTree::Group(group))
}

/// Whether the tokens name `word` as an identifier.
fn mentions(tokens: &TokenStream, word: &str) -> bool {
    tokens.clone().into_iter().any(|tt| match tt {
        TokenTree::Ident(i) => i == word,
        TokenTree::Group(g) => mentions(&g.stream(), word),
        _ => false,
    })
}

fn has_question_mark(tokens: &TokenStream) -> bool {
    tokens.clone().into_iter().any(|tt| match tt {
        TokenTree::Punct(p) => p.as_char() == '?',
        TokenTree::Group(g) => has_question_mark(&g.stream()),
        _ => false,
    })
}

/// Identifiers in a pattern or place (the variables it binds or assigns).
fn idents(tokens: &TokenStream, out: &mut Vec<String>) {
    for tt in tokens.clone() {
        match tt {
            TokenTree::Ident(i) => {
                let s = i.to_string();
                if !matches!(s.as_str(), "mut" | "ref" | "_") && !out.contains(&s) {
                    out.push(s);
                }
            }
            TokenTree::Group(g) => idents(&g.stream(), out),
            _ => {}
        }
    }
}

/// Variables a statement may assign: `x = …` (not `==`), `x op= …`, `&mut x`.
fn assigned(tokens: &TokenStream, out: &mut Vec<String>) {
    let tts: Vec<TokenTree> = tokens.clone().into_iter().collect();
    for (i, tt) in tts.iter().enumerate() {
        match tt {
            TokenTree::Group(g) => assigned(&g.stream(), out),
            TokenTree::Ident(id) => {
                let next = tts.get(i + 1);
                let after = tts.get(i + 2);
                let is_assign = match next {
                    Some(TokenTree::Punct(p)) if p.as_char() == '=' => {
                        !matches!(after, Some(TokenTree::Punct(q)) if q.as_char() == '=')
                            && p.spacing() == proc_macro2::Spacing::Alone
                    }
                    Some(TokenTree::Punct(p)) if "+-*/%^&|".contains(p.as_char()) => {
                        p.spacing() == proc_macro2::Spacing::Joint
                            && matches!(after, Some(TokenTree::Punct(q)) if q.as_char() == '=')
                    }
                    _ => false,
                };
                let mut_ref = i >= 2
                    && matches!(&tts[i - 1], TokenTree::Ident(m) if m == "mut")
                    && matches!(&tts[i - 2], TokenTree::Punct(p) if p.as_char() == '&');
                if (is_assign || mut_ref) && !out.contains(&id.to_string()) {
                    out.push(id.to_string());
                }
            }
            TokenTree::Punct(_) | TokenTree::Literal(_) => {}
        }
    }
}

/// Whether a Rust statement may `return`, and the labels of the `break` and `continue` it may
/// take out of the loops around it (`Some(None)`: unlabelled). A `break` or `continue` inside a
/// loop of the statement itself, or inside a closure, is that loop's.
#[allow(clippy::type_complexity)]
fn scan_exits(tokens: &TokenStream) -> (bool, Option<Option<String>>, Option<Option<String>>) {
    let mut ret = false;
    let mut brk = None;
    let mut cont = None;
    scan(tokens, false, &mut ret, &mut brk, &mut cont);
    (ret, brk, cont)
}

fn scan(
    tokens: &TokenStream,
    in_loop: bool,
    ret: &mut bool,
    brk: &mut Option<Option<String>>,
    cont: &mut Option<Option<String>>,
) {
    let tts: Vec<TokenTree> = tokens.clone().into_iter().collect();
    let mut loop_next = false;
    let mut closure = false;
    for (i, tt) in tts.iter().enumerate() {
        match tt {
            TokenTree::Ident(id) => {
                let s = id.to_string();
                match s.as_str() {
                    "loop" | "while" | "for" => loop_next = true,
                    "return" if !closure => *ret = true,
                    "break" | "continue" => {
                        let label = match tts.get(i + 1) {
                            Some(TokenTree::Punct(p)) if p.as_char() == '\'' => {
                                match tts.get(i + 2) {
                                    Some(TokenTree::Ident(l)) => Some(l.to_string()),
                                    _ => None,
                                }
                            }
                            _ => None,
                        };
                        // An unlabelled one inside a loop of the statement is that loop's.
                        if label.is_some() || !in_loop {
                            if s == "break" {
                                *brk = Some(label);
                            } else {
                                *cont = Some(label);
                            }
                        }
                    }
                    _ => {}
                }
            }
            TokenTree::Punct(p) if p.as_char() == '|' => closure = true,
            TokenTree::Group(g) => {
                let inner_loop = in_loop || (loop_next && g.delimiter() == Delimiter::Brace);
                if g.delimiter() == Delimiter::Brace {
                    loop_next = false;
                }
                if !closure {
                    scan(&g.stream(), inner_loop, ret, brk, cont);
                }
            }
            _ => {}
        }
    }
}

/// A duration, for a relative time known when the constraint is applied.
pub(crate) fn duration(t: &TimeIr, env: &crate::value::Env) -> Option<Duration> {
    match t {
        TimeIr::Nanos(n) => Some(Duration::from_nanos(*n)),
        TimeIr::Secs(e) => e.eval(env).seconds().map(Duration::from_secs_f64),
    }
}

/// The name of file `i` of the program, for notes.
fn b_files_name(files: &[String], i: usize) -> &str {
    files.get(i).map_or("?", String::as_str)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ts(src: &str) -> TokenStream {
        src.parse().expect("tokens")
    }

    #[test]
    fn exits_of_a_rust_statement() {
        assert_eq!(scan_exits(&ts("if done() { return; }")), (true, None, None));
        assert_eq!(
            scan_exits(&ts("if x { break; }")),
            (false, Some(None), None)
        );
        // A loop of the statement's own keeps its break.
        assert_eq!(
            scan_exits(&ts("for i in v { if i { break; } }")),
            (false, None, None)
        );
        assert_eq!(
            scan_exits(&ts("while a { continue 'outer; }")),
            (false, None, Some(Some("outer".into())))
        );
        assert_eq!(
            scan_exits(&ts("let f = |x| { return x; };")),
            (false, None, None)
        );
    }

    #[test]
    fn assigned_variables() {
        let mut out = Vec::new();
        assigned(&ts("x += 1; y = f(z == 2); g(&mut w);"), &mut out);
        assert_eq!(out, vec!["x", "y", "w"]);
    }
}
