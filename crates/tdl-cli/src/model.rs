//! The static structure of a TDL program, which `tdl graph` draws and `tdl doc` describes: per
//! task, the spawns of its body (spawn sites, with their labels, flags and constraints), the
//! constraints between those spawns resolved to the spawns their tags name, the exception handlers
//! attached, the exceptions raised; and the exceptions of the program.
//!
//! It is read from the front end's resolved program (`tdl_syntax::hir`): what each tag names, and
//! `previous` as every spawn that may have run just before (`hir::Previous::may`), through `if`
//! branches, `match` arms and loops (a spawn at the start of a loop body may follow the last spawn
//! of the iteration before).

use std::collections::{BTreeMap, BTreeSet};

use tdl_syntax::hir::{self, BodyScope, Def, Resolution, Tdl};
use tdl_syntax::print;
use tdl_syntax::{
    Constraint, ConstraintKind, ExceptionDecl, HandlerRef, Item, Tag, TagIndex, TagKind, Task,
    TaskConstraintKind, Then, When,
};

/// A program: the tasks and exceptions of its files, in source order.
pub(crate) struct Program<'a> {
    /// The tasks.
    pub(crate) tasks: Vec<TaskInfo<'a>>,
    /// The exceptions declared.
    pub(crate) exceptions: Vec<ExceptionInfo<'a>>,
    task_index: BTreeMap<String, usize>,
    exception_index: BTreeMap<String, usize>,
}

/// A task definition and what its body does.
pub(crate) struct TaskInfo<'a> {
    /// The definition.
    pub(crate) task: &'a Task,
    /// Its name.
    pub(crate) name: String,
    /// A name made of `[A-Za-z0-9_]` only, unique among the tasks: for graph ids and file names.
    pub(crate) id: String,
    /// The file it is defined in, and the line of its name.
    pub(crate) file: String,
    /// Line of the task's name.
    pub(crate) line: usize,
    /// Task-level constraints other than handlers and on-terminate tasks (`delay expansion`,
    /// `period 1500ms`), and constraints of the body on the task itself (`parent …`).
    pub(crate) notes: Vec<Text>,
    /// Task-level exception handlers, in the order they are tried.
    pub(crate) handlers: Vec<HandlerUse>,
    /// Every spawn of the body, then the task-level on-terminate tasks.
    pub(crate) sites: Vec<Site>,
    /// Constraints between spawns (or between the task and a spawn).
    pub(crate) relations: Vec<Relation>,
    /// Exceptions the body raises with `fail E`.
    pub(crate) raises: BTreeSet<String>,
    /// The body says `retry;` or `retry with (…)`.
    pub(crate) retries: bool,
    /// The body says `bypass;`.
    pub(crate) bypasses: bool,
    /// The body says `trigger;`.
    pub(crate) triggers: bool,
    /// Every tag written in a constraint, `previous` aside, as the drawings resolve it.
    pub(crate) tags: Vec<hir::ResolvedTag>,
    /// The place of its file among the program's.
    pub(crate) file_index: usize,
}

/// A declared exception.
pub(crate) struct ExceptionInfo<'a> {
    /// The declaration.
    pub(crate) decl: &'a ExceptionDecl,
    /// Its name.
    pub(crate) name: String,
    /// A name made of `[A-Za-z0-9_]` only, unique among the exceptions.
    pub(crate) id: String,
    /// The file it is declared in.
    pub(crate) file: String,
    /// Line of its name.
    pub(crate) line: usize,
    /// Its ancestors, nearest first, as the front end resolves them.
    pub(crate) ancestry: Vec<String>,
}

/// `exception handler h(args) [maximum activate N]`, at a task or a spawn.
#[derive(Clone, Debug)]
pub(crate) struct HandlerUse {
    /// The handler task.
    pub(crate) name: String,
    /// Its arguments as written.
    pub(crate) args: String,
    /// `maximum activate N`, if given.
    pub(crate) max: Option<String>,
}

/// Where a spawn site is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Origin {
    /// A `spawn` statement of the body.
    Body,
    /// `on terminate t(…)` of a spawn (its site) or of the task itself (`None`).
    OnTerminate(Option<usize>),
}

/// One spawn of a body.
#[derive(Clone, Debug)]
pub(crate) struct Site {
    /// The task spawned.
    pub(crate) task: String,
    /// Its arguments as written.
    pub(crate) args: String,
    /// Labels naming it (`l: spawn …`).
    pub(crate) labels: Vec<String>,
    /// Where it is.
    pub(crate) origin: Origin,
    /// `wait` (on the spawn or a later `X wait;`), `outcome`, `propagate`.
    pub(crate) flags: Vec<&'static str>,
    /// Every constraint on it, in canonical spelling, tags resolved (for `tdl doc`).
    pub(crate) constraints: Vec<Text>,
    /// The constraints that name no other spawn, short (for `tdl graph`'s node label).
    pub(crate) notes: Vec<String>,
    /// Spawn-level exception handlers.
    pub(crate) handlers: Vec<HandlerUse>,
    /// Source line of the spawn.
    pub(crate) line: usize,
    /// Inside a loop: spawned once per iteration.
    pub(crate) repeated: bool,
    /// Inside an `if` or `match`: maybe not spawned.
    pub(crate) conditional: bool,
}

/// Text with references: what `tdl doc` links and `tdl graph` prints plainly.
pub(crate) type Text = Vec<Piece>;

/// A piece of [`Text`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum Piece {
    /// Plain text.
    Text(String),
    /// A tag naming a spawn site of the same body (shown as the string).
    Site(usize, String),
    /// A task name (a link when the program defines it).
    Task(String),
}

/// Plain text of a [`Text`].
pub(crate) fn plain(text: &Text) -> String {
    text.iter()
        .map(|p| match p {
            Piece::Text(s) | Piece::Site(_, s) | Piece::Task(s) => s.as_str(),
        })
        .collect()
}

/// One end of a [`Relation`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) enum Endpoint {
    /// The task whose body it is (`parent`, `this`).
    Task,
    /// A spawn site of the body.
    Site(usize),
}

/// What a relation does to its constrained spawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) enum RelationKind {
    /// Holds it back (`sequential`, `serial`, `disable … until`).
    Order,
    /// Terminates it.
    Terminate,
    /// Activates it (a monitor).
    Activate,
}

/// A constraint on spawn `to` that waits for something of `from`.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) struct Relation {
    /// What it waits for.
    pub(crate) from: Endpoint,
    /// The constrained spawn.
    pub(crate) to: usize,
    /// What it does.
    pub(crate) kind: RelationKind,
    /// The constraint without its tag: `serial`, `terminate at execution completed`.
    pub(crate) label: String,
}

impl<'a> Program<'a> {
    /// The structure of a resolved program.
    pub(crate) fn new(program: &hir::Program<'a>) -> Program<'a> {
        let mut tasks = Vec::new();
        let mut exceptions = Vec::new();
        let mut task_ids = BTreeSet::new();
        let mut exception_ids = BTreeSet::new();
        for (file_index, it) in program.files().iter().enumerate() {
            let file = it.name.to_string();
            for item in &it.ast.items {
                match item {
                    Item::Resource(_) => {}
                    Item::Task(task) => {
                        let name = task.name.to_string();
                        tasks.push(TaskInfo {
                            task,
                            id: unique_id(&name, &mut task_ids),
                            name,
                            file: file.clone(),
                            line: task.name.span().start().line,
                            notes: Vec::new(),
                            handlers: Vec::new(),
                            sites: Vec::new(),
                            relations: Vec::new(),
                            raises: BTreeSet::new(),
                            retries: false,
                            bypasses: false,
                            triggers: false,
                            tags: Vec::new(),
                            file_index,
                        });
                    }
                    Item::Exception(decl) => {
                        let name = decl.name.to_string();
                        exceptions.push(ExceptionInfo {
                            decl,
                            id: unique_id(&name, &mut exception_ids),
                            name,
                            file: file.clone(),
                            line: decl.name.span().start().line,
                            ancestry: program.ancestry(&decl.name.to_string()),
                        });
                    }
                    Item::Rust(_) => {}
                }
            }
        }
        for info in &mut tasks {
            analyse(info, program.body(info.task));
        }
        let mut task_index = BTreeMap::new();
        for (i, t) in tasks.iter().enumerate() {
            task_index.entry(t.name.clone()).or_insert(i);
        }
        let mut exception_index = BTreeMap::new();
        for (i, e) in exceptions.iter().enumerate() {
            exception_index.entry(e.name.clone()).or_insert(i);
        }
        Program {
            tasks,
            exceptions,
            task_index,
            exception_index,
        }
    }

    /// The task of that name, if the program defines it.
    pub(crate) fn task(&self, name: &str) -> Option<&TaskInfo<'a>> {
        self.task_index.get(name).map(|&i| &self.tasks[i])
    }

    /// The exception of that name, if the program declares it.
    pub(crate) fn exception(&self, name: &str) -> Option<&ExceptionInfo<'a>> {
        self.exception_index.get(name).map(|&i| &self.exceptions[i])
    }

    /// The handlers declared `for` the task `name` (attached from outside).
    pub(crate) fn attached_to(&self, name: &str) -> Vec<&TaskInfo<'a>> {
        self.tasks
            .iter()
            .filter(|t| t.task.for_task.as_ref().is_some_and(|f| f == name))
            .collect()
    }

    /// The tasks whose bodies spawn `name` (or have it as an on-terminate task), in order.
    pub(crate) fn spawners(&self, name: &str) -> Vec<&TaskInfo<'a>> {
        self.tasks
            .iter()
            .filter(|t| t.sites.iter().any(|s| s.task == name))
            .collect()
    }

    /// The tasks that attach the handler `name` (at task level or at a spawn).
    pub(crate) fn handler_users(&self, name: &str) -> Vec<&TaskInfo<'a>> {
        self.tasks
            .iter()
            .filter(|t| {
                t.handlers.iter().any(|h| h.name == name)
                    || t.sites
                        .iter()
                        .any(|s| s.handlers.iter().any(|h| h.name == name))
            })
            .collect()
    }

    /// The names of tasks spawned somewhere that the program does not define (Rust functions
    /// returning a `Task`), sorted.
    pub(crate) fn external_tasks(&self) -> BTreeSet<String> {
        self.tasks
            .iter()
            .flat_map(|t| t.sites.iter())
            .filter(|s| self.task(&s.task).is_none())
            .map(|s| s.task.clone())
            .collect()
    }

    /// What task `start` reaches: the tasks it spawns, the handlers attached to it (at task level,
    /// at its spawns, or from outside), its on-terminate tasks, and so on from each of those; and
    /// the exceptions they raise or handle, with their ancestors. `None` if there is no such task.
    pub(crate) fn reach(&self, start: &str) -> Option<(BTreeSet<String>, BTreeSet<String>)> {
        self.task(start)?;
        let mut tasks = BTreeSet::new();
        let mut exceptions = BTreeSet::new();
        let mut todo = vec![start.to_string()];
        while let Some(name) = todo.pop() {
            let Some(info) = self.task(&name) else {
                continue;
            };
            if !tasks.insert(name.clone()) {
                continue;
            }
            let mut next: Vec<String> = Vec::new();
            next.extend(info.sites.iter().map(|s| s.task.clone()));
            next.extend(info.handlers.iter().map(|h| h.name.clone()));
            for site in &info.sites {
                next.extend(site.handlers.iter().map(|h| h.name.clone()));
            }
            next.extend(self.attached_to(&name).iter().map(|h| h.name.clone()));
            todo.extend(next.into_iter().filter(|n| !tasks.contains(n)));
            exceptions.extend(info.raises.iter().cloned());
            exceptions.extend(info.task.handles.iter().map(ToString::to_string));
        }
        // The ancestors of every exception reached.
        let ancestors: Vec<String> = exceptions
            .iter()
            .filter_map(|it| self.exception(it))
            .flat_map(|it| it.ancestry.iter().cloned())
            .collect();
        exceptions.extend(ancestors);
        exceptions.retain(|e| self.exception(e).is_some());
        Some((tasks, exceptions))
    }
}

/// `name` reduced to `[A-Za-z0-9_]` (other characters become `_`), made unique among `used`.
pub(crate) fn unique_id(name: &str, used: &mut BTreeSet<String>) -> String {
    let mut base: String = name
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    if base.is_empty() {
        base.push('_');
    }
    let mut id = base.clone();
    let mut n = 2;
    while used.contains(&id) {
        id = format!("{base}_{n}");
        n += 1;
    }
    used.insert(id.clone());
    id
}

/// Fills in the sites, relations, handlers and notes of a task from its resolved body.
fn analyse(info: &mut TaskInfo<'_>, body: &BodyScope<'_>) {
    let task = info.task;
    let (mut sites, spawn_sites, cleanup_sites) = body_sites(body);
    let mut notes = Vec::new();
    for c in &task.constraints {
        match &c.kind {
            TaskConstraintKind::ExceptionHandler(h) => info.handlers.push(handler_use(h)),
            TaskConstraintKind::OnTerminate(ot) => {
                sites.push(Site::new(
                    ot.task.to_string(),
                    print::exprs(&ot.args),
                    Vec::new(),
                    Origin::OnTerminate(None),
                    ot.task.span().start().line,
                ));
            }
            kind => {
                let mut text = String::new();
                print::task_constraint(kind, &mut text);
                notes.push(vec![Piece::Text(text)]);
            }
        }
    }
    let all_sites = sites.clone();
    info.tags = Vec::new();
    let scope = Scope {
        body,
        spawn_sites: &spawn_sites,
        cleanup_sites: &cleanup_sites,
        sites: &all_sites,
    };
    let mut relations = BTreeSet::new();
    let pending = pending(&scope);
    info.tags = resolved_tags(&scope, &pending, info.file_index);
    for p in pending {
        let targets: Vec<usize> = match p.target {
            Target::Site(i) => vec![i],
            Target::Tag(tag) => match scope.resolve(tag, &p.prev) {
                Resolved::Sites(sites) => sites,
                Resolved::Task | Resolved::Own | Resolved::Bound(_) | Resolved::Unknown => {
                    // A constraint on the task itself, or on a node the body holds in Rust.
                    let mut text = scope.tag_text(tag, &p.prev);
                    text.push(Piece::Text(" ".into()));
                    text.extend(constraint_text(&p.constraint.kind, &scope, &p.prev));
                    notes.push(text);
                    continue;
                }
            },
        };
        for t in targets {
            apply(&mut sites, &mut relations, &scope, t, &p);
        }
    }
    info.sites = sites;
    info.relations = relations.into_iter().collect();
    info.notes = notes;
    info.raises = body.raises();
    info.retries = body.stmts.iter().any(|it| matches!(it, Tdl::Retry(_)));
    info.bypasses = body.stmts.iter().any(|it| matches!(it, Tdl::Bypass(_)));
    info.triggers = body.stmts.iter().any(|it| matches!(it, Tdl::Trigger(_)));
}

/// Every tag of the pending constraints, `previous` aside, as [`Scope::resolve`] resolves it.
fn resolved_tags(
    scope: &Scope<'_, '_>,
    pending: &[Pending<'_>],
    file: usize,
) -> Vec<hir::ResolvedTag> {
    let mut out = Vec::new();
    for p in pending {
        let mut tags: Vec<&Tag> = Vec::new();
        if let Target::Tag(tag) = p.target {
            tags.push(tag);
        }
        match &p.constraint.kind {
            ConstraintKind::Sequential { tag: Some(tag), .. }
            | ConstraintKind::Serial { tag: Some(tag) } => {
                tags.push(tag);
            }
            ConstraintKind::Trigger { when, .. } => tags.extend(when.event().map(|it| &it.tag)),
            _ => {}
        }
        for tag in tags {
            let targets = match (&tag.kind, scope.resolve(tag, &p.prev)) {
                (TagKind::Previous, _) => continue,
                (_, Resolved::Sites(sites)) => {
                    sites.iter().filter_map(|&s| scope.target(s)).collect()
                }
                (_, Resolved::Task) => vec![hir::TagTarget::Parent],
                (_, Resolved::Own) => vec![hir::TagTarget::This],
                (_, Resolved::Bound(name)) => vec![hir::TagTarget::Bound(name)],
                (_, Resolved::Unknown) => Vec::new(),
            };
            out.push(hir::ResolvedTag::new(file, tag, targets));
        }
    }
    out
}

/// The spawn sites of a body: each spawn followed by its on-terminate tasks, in source order;
/// with the site of each spawn and of each labelled on-terminate task.
fn body_sites(body: &BodyScope<'_>) -> (Vec<Site>, Vec<usize>, Vec<usize>) {
    // Sites are numbered as the body's spawns and their on-terminate tasks come.
    let mut sites = Vec::new();
    let mut spawn_sites = Vec::with_capacity(body.spawns.len());
    let mut cleanup_sites = vec![0; body.cleanups.len()];
    for def in &body.spawns {
        let spawn = def.spawn;
        let i = sites.len();
        spawn_sites.push(i);
        let labels: Vec<String> = spawn.labels.iter().map(ToString::to_string).collect();
        let mut own = vec![Site::new(
            spawn.task.to_string(),
            print::exprs(&spawn.args),
            labels,
            Origin::Body,
            spawn.task.span().start().line,
        )];
        for c in &spawn.constraints {
            if let ConstraintKind::OnTerminate(ot) = &c.kind {
                if let Some(id) = body.cleanup_id(ot) {
                    cleanup_sites[id] = i + own.len();
                }
                let labels: Vec<String> = ot.labels.iter().map(ToString::to_string).collect();
                own.push(Site::new(
                    ot.task.to_string(),
                    print::exprs(&ot.args),
                    labels,
                    Origin::OnTerminate(Some(i)),
                    ot.task.span().start().line,
                ));
            }
        }
        for site in &mut own {
            site.repeated = !def.site.loops.is_empty();
            site.conditional = def.site.branch;
        }
        sites.extend(own);
    }
    (sites, spawn_sites, cleanup_sites)
}

/// Every constraint of a body, in source order, with what it applies to and `previous` there:
/// a spawn's own, then those of its `with` groups, outermost first (for the innermost group,
/// `previous` is the entity before the spawn; for an outer one, the entity before the group nested
/// in it); and the constraint statements.
fn pending<'a>(scope: &Scope<'_, 'a>) -> Vec<Pending<'a>> {
    let body = scope.body;
    let mut out = Vec::new();
    for stmt in &body.stmts {
        match stmt {
            Tdl::Spawn(id) => {
                let def = &body.spawns[*id];
                let site = scope.spawn_sites[*id];
                let prev = scope.previous(def.site.position);
                for c in &def.spawn.constraints {
                    if !matches!(c.kind, ConstraintKind::OnTerminate(_)) {
                        out.push(Pending {
                            target: Target::Site(site),
                            constraint: c,
                            prev: prev.clone(),
                        });
                    }
                }
                for (k, &group) in def.groups.iter().enumerate() {
                    let prev = match def.groups.get(k + 1) {
                        Some(&inner) => scope.previous(body.groups[inner].site.position),
                        None => prev.clone(),
                    };
                    for c in &body.groups[group].group.constraints {
                        out.push(Pending {
                            target: Target::Site(site),
                            constraint: c,
                            prev: prev.clone(),
                        });
                    }
                }
            }
            Tdl::Constrain(it, site) => out.push(Pending {
                target: Target::Tag(&it.tag),
                constraint: &it.constraint,
                prev: scope.previous(site.position),
            }),
            Tdl::With(_) | Tdl::Fail(_) | Tdl::Bypass(_) | Tdl::Trigger(_) | Tdl::Retry(_) => {}
        }
    }
    out
}

/// Applies one pending constraint to the spawn site `t`.
fn apply(
    sites: &mut [Site],
    relations: &mut BTreeSet<Relation>,
    scope: &Scope<'_, '_>,
    t: usize,
    p: &Pending<'_>,
) {
    let kind = &p.constraint.kind;
    let text = constraint_text(kind, scope, &p.prev);
    let mut relate = |tag: Option<&Tag>, kind: RelationKind, label: String| -> bool {
        let from: Vec<Endpoint> = match tag.map(|tag| scope.resolve(tag, &p.prev)) {
            None => p.prev.iter().map(|&s| Endpoint::Site(s)).collect(),
            Some(Resolved::Sites(s)) => s.into_iter().map(Endpoint::Site).collect(),
            Some(Resolved::Task) => vec![Endpoint::Task],
            Some(Resolved::Own | Resolved::Bound(_) | Resolved::Unknown) => Vec::new(),
        };
        for from in &from {
            relations.insert(Relation {
                from: *from,
                to: t,
                kind,
                label: label.clone(),
            });
        }
        !from.is_empty()
    };
    let site = &mut sites[t];
    let mut flag = |f: &'static str| {
        if !site.flags.contains(&f) {
            site.flags.push(f);
        }
    };
    match kind {
        ConstraintKind::Wait => flag("wait"),
        ConstraintKind::Outcome => flag("outcome"),
        ConstraintKind::Propagate => flag("propagate"),
        ConstraintKind::Uses(_) => flag("uses resources"),
        ConstraintKind::Priority(_) => flag("priority"),
        ConstraintKind::DenyIfBusy => flag("deny if busy"),
        ConstraintKind::Parallel => {}
        ConstraintKind::ExceptionHandler(h) => site.handlers.push(handler_use(h)),
        ConstraintKind::Sequential { facet, tag } => {
            relate(
                tag.as_ref(),
                RelationKind::Order,
                format!("sequential {}", facet.as_str()),
            );
        }
        ConstraintKind::Serial { tag } => {
            relate(tag.as_ref(), RelationKind::Order, "serial".into());
        }
        ConstraintKind::Trigger { when, then } => {
            let related = when.event().is_some_and(|ev| {
                let kind = match then {
                    Then::Enable(_) => RelationKind::Order,
                    Then::Terminate => RelationKind::Terminate,
                    Then::Activate => RelationKind::Activate,
                };
                relate(Some(&ev.tag), kind, when_label(when, *then))
            });
            if !related {
                site.notes.push(plain(&text));
            }
        }
        _ => site.notes.push(plain(&text)),
    }
    site.constraints.push(text);
}

impl Site {
    fn new(task: String, args: String, labels: Vec<String>, origin: Origin, line: usize) -> Site {
        Site {
            task,
            args,
            labels,
            origin,
            flags: Vec::new(),
            constraints: Vec::new(),
            notes: Vec::new(),
            handlers: Vec::new(),
            line,
            repeated: false,
            conditional: false,
        }
    }
}

fn handler_use(h: &HandlerRef) -> HandlerUse {
    HandlerUse {
        name: h.name.to_string(),
        args: print::exprs(&h.args),
        max: h.max_activate.as_ref().map(print::count),
    }
}

/// What a constraint applies to.
#[derive(Clone)]
enum Target<'a> {
    /// The spawn site (a constraint written on the spawn or its group).
    Site(usize),
    /// A constraint statement's tag.
    Tag(&'a Tag),
}

/// A constraint to apply.
#[derive(Clone)]
struct Pending<'a> {
    target: Target<'a>,
    constraint: &'a Constraint,
    /// The sites `previous` may be where the constraint applies.
    prev: Vec<usize>,
}

/// What a tag names.
enum Resolved {
    /// Spawn sites of the body.
    Sites(Vec<usize>),
    /// The task itself (`parent`, `this`).
    Task,
    /// The node being spawned (`self`, `child`).
    Own,
    /// A node bound in Rust (`bind name = …;`).
    Bound(String),
    /// Nothing known.
    Unknown,
}

/// The names of one body, resolved by the front end, and its spawn sites.
struct Scope<'s, 'a> {
    body: &'s BodyScope<'a>,
    /// The site of each spawn.
    spawn_sites: &'s [usize],
    /// The site of each labelled on-terminate task.
    cleanup_sites: &'s [usize],
    sites: &'s [Site],
}

impl Scope<'_, '_> {
    /// What site `s` is: a spawn, or an on-terminate task of one.
    fn target(&self, s: usize) -> Option<hir::TagTarget> {
        match self.sites.get(s)?.origin {
            Origin::Body => self
                .spawn_sites
                .iter()
                .position(|it| *it == s)
                .map(hir::TagTarget::Spawn),
            Origin::OnTerminate(Some(of)) => {
                let spawn = self.spawn_sites.iter().position(|it| *it == of)?;
                Some(hir::TagTarget::OnTerminate(spawn, s - of - 1))
            }
            Origin::OnTerminate(None) => None,
        }
    }

    /// The sites `previous` may be at the statement at `position`.
    fn previous(&self, position: usize) -> Vec<usize> {
        self.body
            .previous_at(position)
            .map(|it| it.may.iter().map(|&id| self.spawn_sites[id]).collect())
            .unwrap_or_default()
    }

    fn resolve(&self, tag: &Tag, prev: &[usize]) -> Resolved {
        match &tag.kind {
            TagKind::Named { .. } => match self.body.resolve(tag) {
                Resolution::Named(named) => match named.def {
                    Def::Spawn(id) => Resolved::Sites(vec![self.spawn_sites[id]]),
                    Def::Group(id) => Resolved::Sites(
                        self.body
                            .members(id)
                            .into_iter()
                            .map(|it| self.spawn_sites[it])
                            .collect(),
                    ),
                    Def::OnTerminate(id) => Resolved::Sites(vec![self.cleanup_sites[id]]),
                    Def::Bound(bind) => Resolved::Bound(bind.name.to_string()),
                },
                Resolution::Ambiguous(ids) => {
                    Resolved::Sites(ids.into_iter().map(|it| self.spawn_sites[it]).collect())
                }
                Resolution::Unknown
                | Resolution::Previous
                | Resolution::This
                | Resolution::Parent => Resolved::Unknown,
            },
            TagKind::Previous if prev.is_empty() => Resolved::Unknown,
            TagKind::Previous => Resolved::Sites(prev.to_vec()),
            TagKind::Child => Resolved::Own,
            TagKind::Parent => Resolved::Task,
        }
    }
    /// The tag as written, a reference to the spawn it names; `previous` followed by the spawns
    /// it may be.
    fn tag_text(&self, tag: &Tag, prev: &[usize]) -> Text {
        match &tag.kind {
            TagKind::Named { name, indexes } => {
                let mut written = name.to_string();
                for index in indexes {
                    match index {
                        TagIndex::Expr(e) => written.push_str(&format!("[{}]", print::expr(e))),
                        TagIndex::Current => written.push_str("[.]"),
                    }
                }
                match self.resolve(tag, prev) {
                    Resolved::Sites(sites) if !sites.is_empty() => {
                        vec![Piece::Site(sites[0], written)]
                    }
                    _ => vec![Piece::Text(written)],
                }
            }
            TagKind::Previous => self.previous_text(prev),
            TagKind::Child => vec![Piece::Text("self".into())],
            TagKind::Parent => vec![Piece::Text("parent".into())],
        }
    }

    /// `previous`, followed by the spawns it may be.
    fn previous_text(&self, prev: &[usize]) -> Text {
        let mut text = vec![Piece::Text("previous".into())];
        if !prev.is_empty() {
            text.push(Piece::Text(" (".into()));
            for (n, &s) in prev.iter().enumerate() {
                if n > 0 {
                    text.push(Piece::Text(", ".into()));
                }
                let name = self.sites.get(s).map_or("?", |site| site.task.as_str());
                text.push(Piece::Site(s, name.to_string()));
            }
            text.push(Piece::Text(")".into()));
        }
        text
    }
}

/// A constraint in canonical TDL spelling (`tdl_syntax::print`), tags resolved.
fn constraint_text(kind: &ConstraintKind, scope: &Scope<'_, '_>, prev: &[usize]) -> Text {
    let mut out = Linked {
        scope,
        prev,
        text: Vec::new(),
    };
    print::constraint(kind, &mut out);
    out.text
}

/// A trigger without its tag, for an edge's label: `terminate at execution completed`.
fn when_label(when: &When, then: Then) -> String {
    let mut out = Label(String::new());
    print::trigger(when, then, &mut out);
    out.0
}

/// Text with references: a tag names the sites it resolves to, `previous` (written or implied)
/// the sites it may be, a task its page.
struct Linked<'x, 's, 'a> {
    scope: &'x Scope<'s, 'a>,
    prev: &'x [usize],
    text: Text,
}

impl print::Sink for Linked<'_, '_, '_> {
    fn text(&mut self, text: &str) {
        match self.text.last_mut() {
            Some(Piece::Text(last)) => last.push_str(text),
            _ => self.text.push(Piece::Text(text.to_owned())),
        }
    }

    fn tag(&mut self, it: &Tag) {
        let text = self.scope.tag_text(it, self.prev);
        self.text.extend(text);
    }

    fn implied_previous(&mut self) {
        self.text(" ");
        let text = self.scope.previous_text(self.prev);
        self.text.extend(text);
    }

    fn task(&mut self, name: &str) {
        self.text.push(Piece::Task(name.to_owned()));
    }
}

/// Plain text with the tags left out.
struct Label(String);

impl print::Sink for Label {
    fn text(&mut self, text: &str) {
        let text = match text.strip_prefix(' ') {
            Some(rest) if self.0.ends_with(' ') => rest,
            _ => text,
        };
        self.0.push_str(text);
    }

    fn tag(&mut self, _: &Tag) {}
}

#[cfg(test)]
mod tests {
    use super::*;

    fn program(src: &str) -> tdl_syntax::Ast {
        let parse = tdl_syntax::parse_str("t.tdl", src);
        assert!(!parse.has_errors(), "{:?}", parse.diagnostics);
        parse.file
    }

    fn structure(ast: &tdl_syntax::Ast) -> Program<'_> {
        Program::new(&hir::Program::new(&[("t.tdl", ast)]))
    }

    fn relations(p: &Program<'_>, task: &str) -> Vec<String> {
        let t = p.task(task).expect("the task");
        t.relations
            .iter()
            .map(|r| {
                let from = match r.from {
                    Endpoint::Task => "this".to_string(),
                    Endpoint::Site(s) => t.sites[s].task.clone(),
                };
                format!("{from} -> {}: {}", t.sites[r.to].task, r.label)
            })
            .collect()
    }

    #[test]
    fn constraints_name_the_spawns_their_tags_resolve_to() {
        let files = program(
            "goal g() {
                spawn a();
                spawn w() with terminate at a execution completed;
                spawn b() with sequential execution previous, terminate in 30s after self handling active;
                l: spawn c() with wait, exception handler h(1) maximum activate 2;
                spawn d() with serial l, disable until parent handling active, on terminate e();
            }
            handler h(n: u32) handles Oops { bypass; }
            exception Oops;",
        );
        let p = structure(&files);
        assert_eq!(
            relations(&p, "g"),
            [
                "this -> d: disable until handling active",
                "a -> w: terminate at execution completed",
                "w -> b: sequential execution",
                "c -> d: serial",
            ]
        );
        let g = p.task("g").expect("g");
        let names: Vec<&str> = g.sites.iter().map(|s| s.task.as_str()).collect();
        assert_eq!(names, ["a", "w", "b", "c", "d", "e"]);
        assert_eq!(g.sites[5].origin, Origin::OnTerminate(Some(4)));
        assert_eq!(
            g.sites[2].notes,
            ["terminate in 30s after self handling active"]
        );
        assert_eq!(g.sites[3].flags, ["wait"]);
        assert_eq!(g.sites[3].labels, ["l"]);
        assert_eq!(g.sites[3].handlers[0].name, "h");
        assert_eq!(g.sites[3].handlers[0].max.as_deref(), Some("2"));
        assert_eq!(
            plain(&g.sites[2].constraints[0]),
            "sequential execution previous (w)"
        );
        let h = p.task("h").expect("h");
        assert!(h.bypasses);
        assert_eq!(p.handler_users("h").len(), 1);
    }

    #[test]
    fn previous_is_every_spawn_that_may_come_just_before() {
        let files = program(
            "goal g(n: u32) {
                spawn p();
                for i in 0..n {
                    if i > 0 { spawn t() with sequential execution previous; }
                    spawn m() with sequential execution previous;
                }
                with (serial previous) { spawn x(); spawn y(); }
                spawn z() with serial previous;
            }",
        );
        let p = structure(&files);
        assert_eq!(
            relations(&p, "g"),
            [
                "p -> t: sequential execution",
                "p -> m: sequential execution",
                "p -> x: serial",
                "t -> m: sequential execution",
                "m -> t: sequential execution",
                "m -> m: sequential execution",
                "m -> x: serial",
                "x -> y: serial",
                "x -> z: serial",
                "y -> z: serial",
            ]
        );
        let g = p.task("g").expect("g");
        assert!(g.sites[1].repeated && g.sites[1].conditional);
        assert!(g.sites[2].repeated && !g.sites[2].conditional);
    }

    #[test]
    fn reach_follows_spawns_handlers_and_exceptions() {
        let files = program(
            "exception Base;
            exception Oops: Base;
            goal top() with exception handler fix() { spawn mid(); }
            goal mid() { spawn leaf(); fail Oops; }
            command leaf() {}
            handler fix() handles Base { retry; }
            handler outside() handles Base for leaf { bypass; }
            goal unrelated() {}",
        );
        let p = structure(&files);
        let (tasks, exceptions) = p.reach("mid").expect("mid");
        assert_eq!(
            tasks.into_iter().collect::<Vec<_>>(),
            ["leaf", "mid", "outside"]
        );
        assert_eq!(exceptions.into_iter().collect::<Vec<_>>(), ["Base", "Oops"]);
        let (tasks, _) = p.reach("top").expect("top");
        assert_eq!(tasks.len(), 5, "{tasks:?}");
        assert!(p.reach("nowhere").is_none());
    }

    #[test]
    fn ids_are_plain_and_unique() {
        let mut used = BTreeSet::new();
        assert_eq!(unique_id("r#type", &mut used), "r_type");
        assert_eq!(unique_id("r_type", &mut used), "r_type_2");
        assert_eq!(unique_id("façade", &mut used), "fa_ade");
    }

    #[test]
    fn rust_fragments_are_written_as_rustfmt_would() {
        let files = program(
            "goal g(v: Vec < Option < u32 > >, m: & 'static str) { spawn t(m . len (), v [0] . clone ()); }",
        );
        let g = structure(&files);
        let g = g.task("g").expect("g");
        assert_eq!(print::type_text(&g.task.args[0].ty), "Vec<Option<u32>>");
        assert_eq!(print::type_text(&g.task.args[1].ty), "&'static str");
        assert_eq!(g.sites[0].args, "m.len(), v[0].clone()");
    }
}
