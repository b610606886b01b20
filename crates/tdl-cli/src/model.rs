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

use tdl_syntax::hir;
use tdl_syntax::print;
use tdl_syntax::{ExceptionDecl, HandlerRef, Item, Task};

mod body;

use body::analyse;

/// A program: the tasks and exceptions of its files, in source order.
pub(crate) struct Program<'a> {
    /// The tasks.
    pub(crate) tasks: Vec<TaskInfo<'a>>,
    /// The exceptions declared.
    pub(crate) exceptions: Vec<ExceptionInfo<'a>>,
    /// The state variables declared (the first of each name).
    pub(crate) states: Vec<StateInfo>,
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
    /// The state variables the body sets, each once, in source order.
    pub(crate) sets: Vec<String>,
    /// The external events the body raises (`"name"`, or `(expr)`), each once, in source order.
    pub(crate) raises_external: Vec<String>,
    /// Every tag written in a constraint, `previous` aside, as the drawings resolve it.
    pub(crate) tags: Vec<hir::ResolvedTag>,
    /// The place of its file among the program's.
    pub(crate) file_index: usize,
}

/// A declared state variable, as the program writes it.
pub(crate) struct StateInfo {
    /// Its name.
    pub(crate) name: String,
    /// `state battery: float = 100.0`.
    pub(crate) text: String,
    /// Its doc comments.
    pub(crate) doc: Option<String>,
    /// The tasks whose bodies `set` it, in source order.
    pub(crate) set_by: Vec<String>,
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
                    Item::Resource(_) | Item::State(_) | Item::Environment(_) | Item::Extern(_) => {
                    }
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
                            sets: Vec::new(),
                            raises_external: Vec::new(),
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
        let states = program
            .states()
            .into_iter()
            .map(|decl| {
                let name = decl.name.to_string();
                let set_by = tasks
                    .iter()
                    .filter(|t| t.sets.contains(&name))
                    .map(|t| t.name.clone())
                    .collect();
                StateInfo {
                    text: print::state_decl(decl),
                    doc: tdl_syntax::ast::doc_text(&decl.attrs),
                    set_by,
                    name,
                }
            })
            .collect();
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
            states,
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

#[cfg(test)]
mod tests;
