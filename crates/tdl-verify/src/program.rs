//! A TDL program as the checker runs it: the files parsed and checked as `tdl check` does, every
//! task compiled to instructions ([`crate::ir`]), the exceptions with their ancestries, the
//! external events the program names and the tasks it spawns but does not define.

use std::collections::{BTreeMap, BTreeSet};
use std::time::Duration;

use tcm_core::{EachActivation, Facet};
use tdl_syntax::{ast, hir};

use crate::ir::{Body, Call, Callee, HandlerUse, Op, TagOf, TagUseOf, TaskId, TimeIr, UsesIr};
use crate::value::{Sym, VExpr, lower};

mod body;
mod control;
mod rust;

use body::BodyCompiler;

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

/// A state variable the program declares: `state name: type [= value];`.
#[derive(Clone, Debug)]
pub(crate) struct StateDef {
    pub(crate) name: String,
    pub(crate) ty: tcm_core::Type,
    pub(crate) initial: tcm_core::Value,
}

/// One line of the program's environment declaration: what the outside may change, to which
/// values, how many times per run, and only while which condition holds.
#[derive(Clone, Debug)]
pub(crate) struct EnvEntry {
    pub(crate) target: EnvTarget,
    /// For a variable: the values it may take (the current one is skipped).
    pub(crate) values: Vec<tcm_core::Value>,
    pub(crate) at_most: u32,
    pub(crate) when: Option<tcm_core::Expr>,
}

/// What an environment entry changes.
#[derive(Clone, Debug)]
pub(crate) enum EnvTarget {
    /// A state variable, by its number in the program's states.
    State(u16),
    /// An external event, by its number in the program's events.
    External(u16),
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
    /// The state variables it declares, in order.
    pub(crate) states: Vec<StateDef>,
    /// Its environment declaration: what the outside may change (`None`: none declared, and
    /// external events are raised anywhere up to `Options::events` times each).
    pub(crate) environment: Option<Vec<EnvEntry>>,
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
        for s in program.states() {
            b.prog.states.push(StateDef {
                name: s.name.to_string(),
                ty: s.ty().unwrap_or(tcm_core::Type::Bool),
                initial: s.initial(),
            });
        }
        // What the outside may change, before the bodies: a `set` computed in Rust takes the
        // values given here.
        if let Some(entries) = program.environment() {
            let mut env = Vec::new();
            for e in entries {
                let target = match &e.target {
                    ast::EnvTarget::State(v) => match b.state(&v.to_string()) {
                        Some(i) => EnvTarget::State(i),
                        None => continue, // The diagnosis refused the program already.
                    },
                    ast::EnvTarget::External(name) => {
                        EnvTarget::External(b.external_event(name.value()))
                    }
                };
                let ty = match target {
                    EnvTarget::State(i) => Some(b.prog.states[i as usize].ty),
                    EnvTarget::External(_) => None,
                };
                let values = e
                    .values
                    .iter()
                    .map(|l| match ty {
                        Some(ty) => l
                            .value
                            .clone()
                            .coerce(ty)
                            .unwrap_or(tcm_core::Value::Unknown),
                        None => l.value.clone(),
                    })
                    .collect();
                env.push(EnvEntry {
                    target,
                    values,
                    at_most: e.at_most(),
                    when: e.when.as_ref().map(ast::Cond::to_expr),
                });
            }
            b.prog.environment = Some(env);
        }
        // Pass 2: bodies.
        for t in &tasks {
            let def = b.task(t.file, t.task, program.body(t.task))?;
            b.prog.tasks.push(def);
        }
        if b.prog.environment.is_none()
            && (!b.prog.states.is_empty() || !b.prog.external_events.is_empty())
        {
            b.prog.notes.push(
                "no environment declaration: nothing outside the program sets its state \
                 variables, and each external event may be raised at any moment (up to --events \
                 times); say what the outside may do with `environment { … }` \
                 (docs/verification.md, \"The environment\")"
                    .to_owned(),
            );
        }
        let mut raisable: BTreeSet<&'static str> =
            b.prog.exceptions.keys().map(|e| leak(e)).collect();
        raisable.extend(b.prog.tasks.iter().filter_map(|t| t.handles));
        // The engine raises these itself, from what the checker follows (an invariant that is
        // false, a resource refused, an approval refused): a command does not.
        for engine_raised in [
            "InvariantFailed",
            "ResourceDenied",
            "ResourceDropped",
            "ApprovalRefused",
        ] {
            raisable.remove(engine_raised);
        }
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
    /// The number of the external event `name`, added on first use.
    fn external_event(&mut self, name: String) -> u16 {
        let events = &mut self.prog.external_events;
        let i = match events.iter().position(|e| *e == name) {
            Some(i) => i,
            None => {
                events.push(name);
                events.len() - 1
            }
        };
        u16::try_from(i).unwrap_or(u16::MAX)
    }

    /// The number of the state variable `name`, if the program declares it.
    fn state(&self, name: &str) -> Option<u16> {
        let i = self.prog.states.iter().position(|s| s.name == name)?;
        u16::try_from(i).ok()
    }

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

/// A name for the program's lifetime and beyond: the engine's names are `Cow<'static, str>`, and
/// a borrowed one costs nothing to clone with each state. A program leaks its task and exception
/// names once, a few hundred bytes.
fn leak(s: &str) -> &'static str {
    Box::leak(s.to_owned().into_boxed_str())
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
