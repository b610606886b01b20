//! A loaded program ([`Program`]): its files checked as `tdl check` checks them (an error refuses
//! it), every task lowered (`lower.rs`), and the tasks built as the generated code builds them
//! (`tdl-syntax`'s `codegen.rs`, `task_items`): the same `tdl::Task`s, handlers and attached
//! handlers, with the same names, constraints and modifiers in the same order, whose actions run
//! the lowered bodies (`exec.rs`).

use std::collections::{BTreeMap, BTreeSet};
use std::sync::{Arc, Mutex, OnceLock, PoisonError};

use tdl::{Attached, Ctx, Failure, Handler, NodeKind, Runtime, Task};
use tdl_syntax::ast::TaskKind;

use crate::eval::{Flow, Frame, TdlVal};
use crate::exec::Budget;
use crate::ir::{CountEx, FailSt, Init, Modifier, TaskDef, TaskIdx};
use crate::registry::Registry;
use crate::value::{Args, Record, Value};
use crate::{Error, LoadError};

/// What every running body of a program shares.
pub(crate) struct Shared {
    pub(crate) registry: Registry,
    pub(crate) tasks: Vec<TaskDef>,
    pub(crate) by_name: BTreeMap<String, TaskIdx>,
    /// The budget of bodies that compute without waiting: iterations between yields, and in all.
    pub(crate) yield_every: std::sync::atomic::AtomicU32,
    pub(crate) max_steps: std::sync::atomic::AtomicU64,
    /// Every exception's ancestors, nearest first: the program's and the registry's.
    pub(crate) ancestry: BTreeMap<String, Vec<Arc<str>>>,
    /// The content hash of its sources (`Program::hash`).
    pub(crate) hash: String,
    /// The version its tasks name in their `spawned` records, once set (`Program::stamped`).
    pub(crate) version: OnceLock<Arc<str>>,
    /// The newer version whose definitions new spawns use (`Program::supersede`).
    pub(crate) successor: std::sync::RwLock<Option<Program>>,
    /// Whether `successor` is set: read on every spawn, so the common case takes no lock.
    pub(crate) superseded: std::sync::atomic::AtomicBool,
}

impl Shared {
    /// Whether the exception `name` descends from `ancestor`.
    pub(crate) fn is_descendant(&self, name: &str, ancestor: &str) -> bool {
        self.ancestry
            .get(name)
            .is_some_and(|a| a.iter().any(|it| &**it == ancestor))
    }
}

/// A TDL program loaded at run time, ready to run on `tcm`.
#[derive(Clone)]
pub struct Program {
    pub(crate) shared: Arc<Shared>,
}

impl std::fmt::Debug for Program {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Program")
            .field("tasks", &self.shared.by_name.keys().collect::<Vec<_>>())
            .finish()
    }
}

impl Program {
    /// Loads the program of the `.tdl` files at `paths` against `registry`: parsed, checked as
    /// `tdl check` checks them, lowered. Any error refuses the program; the error renders every
    /// diagnostic with its file and line.
    pub fn load<P: AsRef<std::path::Path>>(
        paths: &[P],
        registry: &Registry,
    ) -> Result<Program, LoadError> {
        let mut files = Vec::new();
        for p in paths {
            let p = p.as_ref();
            let text = std::fs::read_to_string(p).map_err(|e| LoadError::Read {
                path: p.display().to_string(),
                reason: e.to_string(),
            })?;
            files.push((p.display().to_string(), text));
        }
        Program::from_sources(&files, registry)
    }

    /// Loads the program of the files `(name, text)`, as [`Program::load`].
    pub fn from_sources(
        files: &[(String, String)],
        registry: &Registry,
    ) -> Result<Program, LoadError> {
        crate::load::load(files, registry, Budget::default())
    }

    /// The same program with another budget for bodies that compute without waiting; its
    /// clones (and the tasks already built from it) share the program, and so the budget.
    pub fn with_budget(self, budget: Budget) -> Program {
        use std::sync::atomic::Ordering;
        self.shared
            .yield_every
            .store(budget.yield_every.max(1), Ordering::Relaxed);
        self.shared
            .max_steps
            .store(budget.max_steps, Ordering::Relaxed);
        self
    }

    /// The names of the program's goals and commands, which can be run.
    pub fn tasks(&self) -> Vec<&str> {
        self.shared
            .tasks
            .iter()
            .filter(|t| matches!(t.kind, TaskKind::Goal | TaskKind::Command) && t.tap.is_none())
            .map(|t| t.name)
            .collect()
    }

    /// The parameters of the task `name`: names and types as written.
    pub fn params(&self, name: &str) -> Option<Vec<(String, String)>> {
        let idx = *self.shared.by_name.get(name)?;
        Some(
            self.shared.tasks[idx]
                .params
                .iter()
                .map(|(n, t)| (n.to_string(), t.describe()))
                .collect(),
        )
    }

    /// The task `name` with its arguments, checked against its parameters' types.
    pub fn task(&self, name: &str, args: Vec<Value>) -> Result<Task, Error> {
        let idx = *self.shared.by_name.get(name).ok_or_else(|| Error::NoTask {
            name: name.to_string(),
            offered: self.tasks().join(", "),
        })?;
        let def = &self.shared.tasks[idx];
        if !matches!(def.kind, TaskKind::Goal | TaskKind::Command) || def.tap.is_some() {
            return Err(Error::NotRunnable(name.to_string()));
        }
        if def.params.len() != args.len() {
            return Err(Error::Args {
                task: name.to_string(),
                reason: format!(
                    "it takes {} argument(s), given {}",
                    def.params.len(),
                    args.len()
                ),
            });
        }
        let mut checked = Vec::with_capacity(args.len());
        for ((pname, ty), v) in def.params.iter().zip(args) {
            checked.push(ty.coerce(v).map_err(|e| Error::Args {
                task: name.to_string(),
                reason: format!("`{pname}`: {e}"),
            })?);
        }
        task(&self.shared, idx, checked).map_err(Error::Build)
    }

    /// The task `name` with arguments given as JSON: an array of one value per parameter (or,
    /// for a task of one parameter, that value).
    pub fn task_json(&self, name: &str, args: &serde_json::Value) -> Result<Task, Error> {
        let n = self.params(name).map_or(0, |p| p.len());
        let values = match args {
            serde_json::Value::Array(items) if n != 1 => {
                items.iter().map(Value::from_json).collect()
            }
            serde_json::Value::Null if n == 0 => Vec::new(),
            one => vec![Value::from_json(one)],
        };
        self.task(name, values)
    }

    /// The tasks the handlers declared `for` a task are attached to, in declaration order.
    pub fn attached_tasks(&self) -> Vec<String> {
        self.shared
            .tasks
            .iter()
            .filter(|d| d.kind == TaskKind::Handler)
            .filter_map(|d| d.for_task.as_ref().map(ToString::to_string))
            .collect()
    }

    /// The handlers declared `for` a task, to attach to a run (`Runtime::attach`).
    pub fn attached(&self) -> Vec<Attached> {
        let mut out = Vec::new();
        for (idx, def) in self.shared.tasks.iter().enumerate() {
            if let (TaskKind::Handler, Some(target)) = (def.kind, &def.for_task) {
                if let Ok(h) = handler(&self.shared, idx, Vec::new()) {
                    out.push(Attached::new(intern(target), h));
                }
            }
        }
        out
    }

    /// Runs the task `name` with `args` on `runtime`, with the program's `for` handlers
    /// attached: the run's report.
    pub async fn run(
        &self,
        runtime: Runtime,
        name: &str,
        args: Vec<Value>,
    ) -> Result<tdl::Report, Error> {
        let task = self.task(name, args)?;
        let mut runtime = runtime;
        for a in self.attached() {
            runtime = runtime.attach(a);
        }
        for t in self.taps() {
            runtime = runtime.tap(t);
        }
        runtime.run(task).await.map_err(Error::Run)
    }
}

/// `name` as a `&'static str`, leaked once per distinct name for the whole process: nodes and
/// reservations name their task by one.
pub(crate) fn intern(name: &str) -> &'static str {
    static NAMES: OnceLock<Mutex<BTreeSet<&'static str>>> = OnceLock::new();
    let mut names = NAMES
        .get_or_init(Default::default)
        .lock()
        .unwrap_or_else(PoisonError::into_inner);
    if let Some(it) = names.get(name) {
        return it;
    }
    let leaked: &'static str = Box::leak(name.to_string().into_boxed_str());
    names.insert(leaked);
    leaked
}

/// The value an interpreted task's action returned (`()` for a task without a result type).
/// A fault's JSON value stands for it as for a task from an agent (docs/semantics.md, "Steering a
/// run", rule 4).
pub(crate) fn value_of_value(v: Box<dyn std::any::Any + Send>) -> Option<Value> {
    let v = match v.downcast::<Value>() {
        Ok(v) => return Some(*v),
        Err(v) => v,
    };
    match v.downcast::<serde_json::Value>() {
        Ok(j) => Some(Value::from_json(&j)),
        Err(v) => v.downcast::<()>().ok().map(|_| Value::Unit),
    }
}

/// The failure `fail E { fields }` raises: as `tdl::Exception::raise` makes it for the generated
/// exception type (its name, its `Debug` as the message, its ancestors), carrying the fields as a
/// record for handlers to read.
pub(crate) fn raise(f: &FailSt, fields: Vec<(Arc<str>, Value)>) -> Failure {
    let Some(name) = &f.exception else {
        return Failure::new("Fail", "fail without an exception");
    };
    let record = Value::Record(Arc::new(Record {
        name: Arc::from(*name),
        fields,
    }));
    let mut failure = Failure::new(*name, record.debug())
        .with_ancestry(f.ancestry.iter().map(|a| (*a).into()).collect());
    failure.data = Some(Arc::new(record));
    failure
}

fn count(frame: &mut Frame, c: &CountEx) -> Result<u32, Failure> {
    match c {
        CountEx::Const(n) => Ok(*n),
        CountEx::Expr(e) => match frame.eval(e) {
            Ok(Value::Int(i)) => Ok(u32::try_from(i).unwrap_or(u32::MAX)),
            Ok(other) => Err(crate::builtin::bad("a count", &other)),
            Err(flow) => Err(failure_of(flow)),
        },
    }
}

pub(crate) fn failure_of(flow: Flow) -> Failure {
    match flow {
        Flow::Fail(f) => f,
        Flow::Return(_) | Flow::Break(_) | Flow::Continue(_) => Failure::new(
            "Interpreter",
            "`return`, `break` or `continue` outside their place",
        ),
    }
}

/// A frame for the task `def` with its parameters bound: to evaluate what its constructor
/// evaluates (no context), or to run its body.
fn frame(shared: &Arc<Shared>, def: &TaskDef, ctx: Option<Ctx>, args: &[Value]) -> Frame {
    let mut locals = vec![Value::Unit; def.locals.max(args.len())];
    for (slot, v) in locals.iter_mut().zip(args) {
        *slot = v.clone();
    }
    Frame {
        ctx,
        locals,
        tdl: vec![TdlVal::Empty; def.tdl_slots],
        shared: shared.clone(),
        since_yield: 0,
        steps: 0,
    }
}

/// The task `idx` with `args`, as its generated `into_task` builds it.
pub(crate) fn task(shared: &Arc<Shared>, idx: TaskIdx, args: Vec<Value>) -> Result<Task, Failure> {
    if let Some((newer, j)) = shared.newest(shared.tasks[idx].name) {
        return task(&newer, j, args);
    }
    let def = &shared.tasks[idx];
    let name = def.name;
    let prelude = modifiers(shared, def, &args)?;
    let mut task = match def.kind {
        TaskKind::Goal | TaskKind::Command => {
            let kind = if def.kind == TaskKind::Command {
                NodeKind::Command
            } else {
                NodeKind::Goal
            };
            let s = shared.clone();
            let stored = (!args.is_empty()).then(|| Arc::new(args.clone()));
            // A re-run reads the arguments kept for its node (`retry with`).
            let args_of = move |ctx: &Ctx| match (ctx.args_ref::<Args>(), &stored) {
                (Some(a), _) => a.0.clone(),
                (None, Some(stored)) => (**stored).clone(),
                (None, None) => Vec::new(),
            };
            // A body that never awaits is a synchronous action, as the compiler makes it.
            let t = if def.awaits || def.blocking {
                Task::retryable(kind, name, move |ctx: Ctx| {
                    let args = args_of(&ctx);
                    run(s.clone(), idx, ctx, args, None)
                })
            } else {
                Task::retryable_now(kind, name, move |ctx: Ctx| {
                    let args = args_of(&ctx);
                    SyncRun {
                        shared: s.clone(),
                        idx,
                        ctx,
                        args,
                        cells: None,
                    }
                    .run()
                })
            };
            if args.is_empty() {
                t
            } else {
                t.with_args_erased(Some(Arc::new(Args(args.clone(), Some(def.shown.clone())))))
                    .describe_args(Args::describe)
            }
        }
        TaskKind::Monitor => {
            let mut params = def.monitor.clone();
            let mut f = frame(shared, def, None, &args);
            if let Some(c) = &def.monitor_counts.0 {
                params.max_activations = Some(count(&mut f, c)?);
            }
            if let Some(c) = &def.monitor_counts.1 {
                params.max_triggers = Some(count(&mut f, c)?);
            }
            let cells = cells(shared, def, &args)?;
            let s = shared.clone();
            Task::monitor(name, params, move |ctx: Ctx| {
                run(s.clone(), idx, ctx, args.clone(), cells.clone())
            })
        }
        TaskKind::Handler => {
            return Err(Failure::new(
                "NotATask",
                format!("`{name}` is a handler: name it in `exception handler`, not in `spawn`"),
            ));
        }
    };
    if def.persistent {
        task = task.persistent();
    }
    if def.idempotent {
        task = task.idempotent();
    }
    if let Some(v) = shared.version.get() {
        task = task.version(v.clone());
    }
    for m in prelude {
        task = match m {
            Built::With(c) => task.with(c),
            Built::OnTerminate(t) => task.on_terminate(t),
            Built::Handler(h) => task.handler(h),
            Built::Uses(r, n) => task.uses(r, n),
            Built::Priority(p) => task.priority(p),
            Built::MaxActivations(_) => task,
        };
    }
    Ok(task)
}

/// The handler `idx` with `args`, as its generated `into_handler` builds it.
pub(crate) fn handler(
    shared: &Arc<Shared>,
    idx: TaskIdx,
    args: Vec<Value>,
) -> Result<Handler, Failure> {
    if let Some((newer, j)) = shared.newest(shared.tasks[idx].name) {
        return handler(&newer, j, args);
    }
    let def = &shared.tasks[idx];
    let name = def.name;
    let prelude = modifiers(shared, def, &args)?;
    let exception = def.handles.as_deref().map_or("", intern);
    let cells = cells(shared, def, &args)?;
    let s = shared.clone();
    // A handler attached with `for` reads the arguments of the node it recovers, when it has
    // parameters to read them into (as the generated code does).
    let attached = def.for_task.is_some() && !def.params.is_empty();
    let mut h = Handler::new(name, exception, move |ctx: Ctx| {
        let (s, cells, args) = (s.clone(), cells.clone(), args.clone());
        async move {
            // A handler attached with `for` reads the arguments of the node it recovers (inside
            // its action, as the generated code does: not while the runtime hands it out).
            let args = if attached {
                match ctx.attached_args::<Args>() {
                    Some(a) => a.0.clone(),
                    None => {
                        return Err(Failure::new(
                            "NotAttached",
                            format!(
                                "`{name}` ran outside a failure of the task it is attached to, so it has no arguments to read"
                            ),
                        ));
                    }
                }
            } else {
                args
            };
            run(s, idx, ctx, args, cells).await
        }
    });
    for m in prelude {
        if let Built::MaxActivations(n) = m {
            h = h.max_activations(n);
        }
    }
    Ok(h)
}

/// A task-level modifier, built.
#[allow(
    clippy::large_enum_variant,
    reason = "a handful per task built, consumed at once"
)]
enum Built {
    With(tdl::Constraint),
    OnTerminate(Task),
    Handler(Handler),
    Uses(tdl::ResourceRef, u32),
    Priority(i32),
    MaxActivations(u32),
}

/// The modifiers of a task, built with its arguments, in the generator's order.
fn modifiers(shared: &Arc<Shared>, def: &TaskDef, args: &[Value]) -> Result<Vec<Built>, Failure> {
    let mut out = Vec::new();
    if def.modifiers.is_empty() {
        return Ok(out);
    }
    let mut f = frame(shared, def, None, args);
    let eval_all = |f: &mut Frame, exs: &[crate::ir::Ex]| f.eval_all(exs).map_err(failure_of);
    for m in &def.modifiers {
        out.push(match m {
            Modifier::ExpandFirst => Built::With(tdl::Constraint::ExpandFirst),
            Modifier::DelayExpansion => Built::With(tdl::Constraint::DelayExpansion),
            Modifier::OnTerminate(call) => match call {
                crate::ir::TaskCall::Tdl(i, exs) => {
                    let vals = eval_all(&mut f, exs)?;
                    Built::OnTerminate(task(shared, *i, vals)?)
                }
                crate::ir::TaskCall::Rust(entry, exs, _) => {
                    let vals = eval_all(&mut f, exs)?;
                    Built::OnTerminate((entry.make)(&vals)?)
                }
                crate::ir::TaskCall::Remote { .. } => {
                    return Err(Failure::new(
                        "Interpreter",
                        "a task-level `on terminate` on an agent",
                    ));
                }
            },
            Modifier::Handler(h) => {
                let vals = eval_all(&mut f, &h.args)?;
                let mut built = handler(shared, h.task, vals)?;
                if let Some(c) = &h.max {
                    built = built.max_activations(count(&mut f, c)?);
                }
                Built::Handler(built)
            }
            Modifier::MaxActivations(c) => Built::MaxActivations(count(&mut f, c)?),
            Modifier::Uses(r, c) => Built::Uses(crate::exec::resource_ref(r), count(&mut f, c)?),
            Modifier::Priority(e) => {
                let p = f.eval(e).map_err(failure_of)?.as_int().unwrap_or(0);
                Built::Priority(i32::try_from(p).unwrap_or(if p < 0 { i32::MIN } else { i32::MAX }))
            }
        });
    }
    Ok(out)
}

/// The persistent variables of a monitor or handler, shared by its runs, at their initial
/// values.
fn cells(
    shared: &Arc<Shared>,
    def: &TaskDef,
    args: &[Value],
) -> Result<Option<Arc<Mutex<Vec<Value>>>>, Failure> {
    if def.persistents.is_empty() || !matches!(def.kind, TaskKind::Monitor | TaskKind::Handler) {
        return Ok(None);
    }
    let mut f = frame(shared, def, None, args);
    let mut values = Vec::with_capacity(def.persistents.len());
    for (_, ty, init) in &def.persistents {
        values.push(match init {
            Some(e) => f.eval(e).map_err(failure_of)?,
            None => default_of(ty),
        });
    }
    Ok(Some(Arc::new(Mutex::new(values))))
}

/// `Default::default()` of a type.
fn default_of(ty: &crate::ty::Ty) -> Value {
    use crate::ty::Ty;
    match ty {
        Ty::Bool => Value::Bool(false),
        Ty::Int { .. } => Value::Int(0),
        Ty::Float => Value::Float(0.0),
        Ty::Str => Value::str(""),
        Ty::List(_) => Value::list([]),
        Ty::Option(_) => Value::none(),
        Ty::Map(_) => Value::Map(Arc::default()),
        Ty::Duration => Value::Duration(std::time::Duration::ZERO),
        Ty::Tuple(ts) => Value::tuple(ts.iter().map(default_of).collect()),
        _ => Value::Unit,
    }
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// What runs before a body's statements: children held, the caught exception and the nodes a
/// handler names, the persistent variables loaded, the TDL slots made (reservations in the
/// generator's order).
fn prologue(
    f: &mut Frame,
    def: &TaskDef,
    ctx: &Ctx,
    cells: Option<&Arc<Mutex<Vec<Value>>>>,
) -> Result<(), Failure> {
    // A body that makes no children has none to hold (the generated code holds them anyway;
    // nothing tells the two apart).
    if def.holds {
        ctx.hold_children(true)?;
    }
    if let Some(slot) = def.caught {
        match ctx.failure() {
            Some(failure) => f.set_local(slot, Value::Failure(Arc::new(failure.clone()))),
            None => {
                return Err(Failure::new(
                    "NotAHandler",
                    format!(
                        "`{}` reads its caught exception outside an exception handler",
                        def.name
                    ),
                ));
            }
        }
    }
    if let Some(slot) = def.failing {
        let node = tdl::codegen::failing_node(ctx)?;
        f.set_local(slot, Value::Node(node));
    }
    if let Some(slot) = def.attached {
        let node = tdl::codegen::attached_node(ctx)?;
        f.set_local(slot, Value::Node(node));
    }
    if let Some(cells) = cells {
        let values = lock(cells).clone();
        for ((slot, ..), v) in def.persistents.iter().zip(values) {
            f.set_local(*slot, v);
        }
    }
    Ok(())
}

/// The goal's or command's own persistent variables and the TDL slots, in the generator's order.
fn locals(f: &mut Frame, def: &TaskDef, ctx: &Ctx) -> Result<(), Failure> {
    if matches!(def.kind, TaskKind::Goal | TaskKind::Command) {
        for (slot, ty, init) in &def.persistents {
            let v = match init {
                Some(e) => f.eval(e).map_err(failure_of)?,
                None => default_of(ty),
            };
            f.set_local(*slot, v);
        }
    }
    for (slot, init) in &def.prelude {
        let v = match init {
            Init::Reserve(name) => TdlVal::Node(ctx.reserve(name)?),
            Init::Map => TdlVal::Map(BTreeMap::new()),
            Init::Nodes => TdlVal::Nodes(Vec::new()),
            Init::Maybe => TdlVal::Maybe(None),
        };
        f.set_tdl(*slot, v);
    }
    Ok(())
}

/// The body's value as the task returns it: its tail for a task with a result type (checked
/// against it), unit for the others.
fn ending(def: &TaskDef, r: Result<Value, Flow>) -> Result<Value, Failure> {
    let v = match r {
        Ok(v) => v,
        // `return Err(e)` fails the node, `return Ok(v)` gives `v`, as from a Rust body.
        Err(Flow::Return(Value::Variant(var))) if &*var.ty == "Result" => {
            match (&*var.name, var.fields.first()) {
                ("Err", Some(e)) => {
                    return Err(e
                        .as_failure()
                        .cloned()
                        .unwrap_or_else(|| Failure::new("Error", format!("{e:?}"))));
                }
                (_, v) => v.cloned().unwrap_or_default(),
            }
        }
        Err(Flow::Return(v)) => v,
        Err(flow) => return Err(failure_of(flow)),
    };
    match &def.result {
        None => Ok(Value::Unit),
        Some(ty) => ty.coerce(v).map_err(|e| {
            Failure::new(
                "TypeMismatch",
                format!("the value of `{}` (at {}): {e}", def.name, def.loc),
            )
        }),
    }
}

/// What an action returns: its value, boxed as the runtime keeps values.
type Run = std::pin::Pin<
    Box<dyn std::future::Future<Output = Result<Box<dyn std::any::Any + Send>, Failure>> + Send>,
>;

/// One run of the body of task `idx`, as a boxed future (moved around as a pointer, not as the
/// body's state). A task with a result gives its value; one without gives Rust's `()`, so that
/// Rust code waiting for it (a pattern, a registered function) reads it as a compiled task's.
pub(crate) fn run(
    shared: Arc<Shared>,
    idx: TaskIdx,
    ctx: Ctx,
    args: Vec<Value>,
    cells: Option<Arc<Mutex<Vec<Value>>>>,
) -> RunFut {
    let def = &shared.tasks[idx];
    if def.blocking {
        return RunFut::Boxed(Box::pin(run_blocking(shared, idx, ctx, args)));
    }
    // A body that never awaits runs within its first poll, without a boxed future of its own.
    if !def.awaits {
        return RunFut::Sync(Some(SyncRun {
            shared,
            idx,
            ctx,
            args,
            cells,
        }));
    }
    RunFut::Boxed(Box::pin(async move {
        let def = &shared.tasks[idx];
        let mut f = frame(&shared, def, Some(ctx.clone()), &args);
        prologue(&mut f, def, &ctx, cells.as_ref())?;
        let r = match locals(&mut f, def, &ctx) {
            Ok(()) => f.block(&def.body).await,
            Err(failure) => Err(Flow::Fail(failure)),
        };
        store(def, &f, cells.as_ref());
        boxed(def, ending(def, r)?)
    }))
}

/// An action's run: a body that never awaits, run when first polled; any other, boxed.
pub(crate) enum RunFut {
    Sync(Option<SyncRun>),
    Boxed(Run),
}

/// What a body that never awaits needs to run.
pub(crate) struct SyncRun {
    shared: Arc<Shared>,
    idx: TaskIdx,
    ctx: Ctx,
    args: Vec<Value>,
    cells: Option<Arc<Mutex<Vec<Value>>>>,
}

impl std::future::Future for RunFut {
    type Output = Result<Box<dyn std::any::Any + Send>, Failure>;

    fn poll(
        self: std::pin::Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
    ) -> std::task::Poll<Self::Output> {
        match self.get_mut() {
            RunFut::Boxed(f) => f.as_mut().poll(cx),
            RunFut::Sync(run) => std::task::Poll::Ready(match run.take() {
                Some(run) => run.run(),
                None => Err(Failure::new(
                    "Interpreter",
                    "an action polled after it ended",
                )),
            }),
        }
    }
}

impl SyncRun {
    /// Runs the body, which never awaits, to its end.
    fn run(self) -> Result<Box<dyn std::any::Any + Send>, Failure> {
        let SyncRun {
            shared,
            idx,
            ctx,
            args,
            cells,
        } = self;
        let def = &shared.tasks[idx];
        let mut f = frame(&shared, def, Some(ctx.clone()), &args);
        prologue(&mut f, def, &ctx, cells.as_ref())?;
        let r = locals(&mut f, def, &ctx)
            .map_err(Flow::Fail)
            .and_then(|()| f.block_sync(&def.body));
        store(def, &f, cells.as_ref());
        ending(def, r).and_then(|v| boxed(def, v))
    }
}

/// Each run starts from the stored values of the persistent variables and stores its own back
/// however its body ends.
fn store(def: &TaskDef, f: &Frame, cells: Option<&Arc<Mutex<Vec<Value>>>>) {
    if let Some(cells) = cells {
        let mut stored = lock(cells);
        for (i, (slot, ..)) in def.persistents.iter().enumerate() {
            if let Some(cell) = stored.get_mut(i) {
                *cell = f.local(*slot);
            }
        }
    }
}

/// The value as the runtime keeps it: `()` for a task without a result type.
fn boxed(def: &TaskDef, v: Value) -> Result<Box<dyn std::any::Any + Send>, Failure> {
    Ok(if def.result.is_none() {
        Box::new(())
    } else {
        Box::new(v)
    })
}

/// A `blocking command`: the body runs on a blocking thread, and the action waits for it.
async fn run_blocking(
    shared: Arc<Shared>,
    idx: TaskIdx,
    ctx: Ctx,
    args: Vec<Value>,
) -> Result<Box<dyn std::any::Any + Send>, Failure> {
    let s = shared.clone();
    let v = ctx
        .blocking(move |ctx: Ctx| {
            let def = &s.tasks[idx];
            let mut f = frame(&s, def, Some(ctx.clone()), &args);
            prologue(&mut f, def, &ctx, None)?;
            locals(&mut f, def, &ctx)?;
            let r = f.block_sync(&def.body);
            ending(def, r)
        })
        .await?;
    boxed(&shared.tasks[idx], v)
}
