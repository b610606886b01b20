//! The declarations of one file of a program, and the names it can see: its own tasks,
//! exceptions and resources, then those of the program's other files; exception ancestries;
//! the resolved body of every task of the program ([`BodyScope`], computed once per program and
//! shared by every file's scope).

use std::collections::{BTreeMap, BTreeSet};
use std::rc::Rc;

use proc_macro2::{Ident, Span};

use super::body::BodyScope;
use crate::ast::{Ast, ExceptionDecl, Item, ResourceDecl, StateDecl, Task, TaskKind};

/// The exceptions the runtime raises itself, which handlers name without declaring them
/// (docs/semantics.md, "Resources" and "Steering a run").
pub const BUILTIN_EXCEPTIONS: &[&str] = &[
    "ResourceDenied",
    "ResourceDropped",
    "ApprovalRefused",
    "Interrupted",
];

/// The resolved bodies of a program's tasks, by task.
pub(crate) type Bodies<'a> = BTreeMap<*const Task, BodyScope<'a>>;

/// The tasks, exceptions and resources a source declares, and those of the program's other
/// files.
///
/// Compiled as part of a program ([`super::Program`]), names resolve across every file: a name
/// this file declares is its own, else the first file declaring it wins. A later declaration of
/// a name is reported once: in [`FileScope::duplicates`] when the same file declared it first,
/// in [`FileScope::elsewhere`] when an earlier file did.
pub struct FileScope<'a> {
    tasks: BTreeMap<String, &'a Task>,
    exceptions: BTreeMap<String, &'a ExceptionDecl>,
    /// Resources of the program: this file's (the first of a name), then the other files'.
    resources: BTreeMap<String, &'a ResourceDecl>,
    /// State variables of the program: this file's (the first of a name), then the other files'.
    states: BTreeMap<String, &'a StateDecl>,
    /// Declarations of a name this file already declared, in source order.
    pub duplicates: Vec<Duplicate<'a>>,
    /// Tasks and exceptions of the program's other files (the first file declaring a name wins).
    other_tasks: BTreeMap<String, &'a Task>,
    other_exceptions: BTreeMap<String, &'a ExceptionDecl>,
    /// This file's first declarations of names an earlier file of the program declares, in
    /// source order.
    pub elsewhere: Vec<Elsewhere<'a>>,
    /// The resolved body of every task of the program.
    bodies: Rc<Bodies<'a>>,
    /// The `extern` tasks of the program (the first declaration of a name).
    externs: BTreeMap<String, &'a crate::ast::ExternDecl>,
}

/// A declaration of a name declared before in the same file: (this one, the first).
pub enum Duplicate<'a> {
    /// Two tasks of one name.
    Task(&'a Task, &'a Task),
    /// Two exceptions of one name.
    Exception(&'a ExceptionDecl, &'a ExceptionDecl),
    /// Two resources of one name.
    Resource(&'a ResourceDecl, &'a ResourceDecl),
    /// Two state variables of one name.
    State(&'a StateDecl, &'a StateDecl),
}

/// A declaration of a name an earlier file of the program declares.
pub struct Elsewhere<'a> {
    /// The name, as this file writes it.
    pub name: &'a Ident,
    /// The earlier file.
    pub file: &'a str,
    /// The earlier declaration, in that file.
    pub first: Span,
}

/// A declaration of a task, an exception, a resource or a state variable: its name and its span.
#[derive(Clone, Copy)]
enum Decl<'a> {
    Task(&'a Task),
    Exception(&'a ExceptionDecl),
    Resource(&'a ResourceDecl),
    State(&'a StateDecl),
}

impl<'a> Decl<'a> {
    fn of(item: &'a Item) -> Option<Decl<'a>> {
        match item {
            Item::Task(it) => Some(Decl::Task(it)),
            Item::Exception(it) => Some(Decl::Exception(it)),
            Item::Resource(it) => Some(Decl::Resource(it)),
            Item::State(it) => Some(Decl::State(it)),
            Item::Environment(_) | Item::Extern(_) | Item::Rust(_) => None,
        }
    }

    fn name(self) -> &'a Ident {
        match self {
            Decl::Task(it) => &it.name,
            Decl::Exception(it) => &it.name,
            Decl::Resource(it) => &it.name,
            Decl::State(it) => &it.name,
        }
    }

    fn span(self) -> Span {
        match self {
            Decl::Task(it) => it.span,
            Decl::Exception(it) => it.span,
            Decl::Resource(it) => it.span,
            Decl::State(it) => it.span,
        }
    }

    /// Tasks, exceptions, resources and state variables have name spaces of their own.
    fn space(self) -> u8 {
        match self {
            Decl::Task(_) => 0,
            Decl::Exception(_) => 1,
            Decl::Resource(_) => 2,
            Decl::State(_) => 3,
        }
    }
}

impl<'a> FileScope<'a> {
    /// The declarations of `ast`, a program of one file.
    pub fn new(ast: &'a Ast) -> FileScope<'a> {
        let mut bodies = Bodies::new();
        add_bodies(&mut bodies, ast);
        FileScope::with_bodies(ast, Rc::new(bodies))
    }

    fn with_bodies(ast: &'a Ast, bodies: Rc<Bodies<'a>>) -> FileScope<'a> {
        let mut scope = FileScope {
            tasks: BTreeMap::new(),
            exceptions: BTreeMap::new(),
            resources: BTreeMap::new(),
            states: BTreeMap::new(),
            duplicates: Vec::new(),
            other_tasks: BTreeMap::new(),
            other_exceptions: BTreeMap::new(),
            elsewhere: Vec::new(),
            bodies,
            externs: BTreeMap::new(),
        };
        for item in &ast.items {
            match item {
                Item::Task(task) => match scope.tasks.get(&task.name.to_string()) {
                    Some(first) => scope.duplicates.push(Duplicate::Task(task, first)),
                    None => {
                        scope.tasks.insert(task.name.to_string(), task);
                    }
                },
                Item::Exception(exc) => match scope.exceptions.get(&exc.name.to_string()) {
                    Some(first) => scope.duplicates.push(Duplicate::Exception(exc, first)),
                    None => {
                        scope.exceptions.insert(exc.name.to_string(), exc);
                    }
                },
                Item::Resource(r) => match scope.resources.get(&r.name.to_string()) {
                    Some(first) => scope.duplicates.push(Duplicate::Resource(r, first)),
                    None => {
                        scope.resources.insert(r.name.to_string(), r);
                    }
                },
                Item::State(v) => match scope.states.get(&v.name.to_string()) {
                    Some(first) => scope.duplicates.push(Duplicate::State(v, first)),
                    None => {
                        scope.states.insert(v.name.to_string(), v);
                    }
                },
                Item::Extern(e) => {
                    scope.externs.entry(e.name.to_string()).or_insert(e);
                }
                Item::Environment(_) | Item::Rust(_) => {}
            }
        }
        scope
    }

    /// The scope of file `at` of a program, `(file name, tree)` per file: its declarations, with
    /// those of the other files, and `bodies`, every task's resolved body.
    pub(crate) fn in_program(
        files: &[(&'a str, &'a Ast)],
        at: usize,
        bodies: Rc<Bodies<'a>>,
    ) -> FileScope<'a> {
        let mut scope = FileScope::with_bodies(files[at].1, bodies);
        // The first declaration of each name in the files before this one.
        let mut earlier: BTreeMap<(u8, String), (&'a str, Span)> = BTreeMap::new();
        for (i, (_, other)) in files.iter().enumerate() {
            for item in &other.items {
                if let (Item::Extern(e), false) = (item, i == at) {
                    scope.externs.entry(e.name.to_string()).or_insert(e);
                }
            }
        }
        for (i, (file, other)) in files.iter().enumerate() {
            for decl in other.items.iter().filter_map(Decl::of) {
                let name = decl.name().to_string();
                if i < at {
                    earlier
                        .entry((decl.space(), name.clone()))
                        .or_insert((*file, decl.span()));
                }
                if i == at {
                    continue;
                }
                match decl {
                    Decl::Task(task) => {
                        scope.other_tasks.entry(name).or_insert(task);
                    }
                    Decl::Exception(exc) => {
                        scope.other_exceptions.entry(name).or_insert(exc);
                    }
                    Decl::Resource(r) => {
                        scope.resources.entry(name).or_insert(r);
                    }
                    Decl::State(v) => {
                        scope.states.entry(name).or_insert(v);
                    }
                }
            }
        }
        // Each name this file declares that an earlier file declared: its first declaration here
        // (a later one here is a duplicate within the file).
        let mut seen = BTreeSet::new();
        for decl in files[at].1.items.iter().filter_map(Decl::of) {
            let key = (decl.space(), decl.name().to_string());
            if !seen.insert(key.clone()) {
                continue;
            }
            if let Some((file, first)) = earlier.get(&key) {
                scope.elsewhere.push(Elsewhere {
                    name: decl.name(),
                    file,
                    first: *first,
                });
            }
        }
        scope
    }

    /// The resolved body of `task`, a task of the program.
    ///
    /// # Panics
    ///
    /// If `task` is not a task of the program this scope belongs to: every task of every file
    /// is resolved when the program is.
    pub fn body(&self, task: &Task) -> &BodyScope<'a> {
        self.bodies
            .get(&std::ptr::from_ref(task))
            .expect("every task of the program is resolved with it")
    }

    /// The `extern` task of this name declared in the source or another file of the program.
    pub fn extern_decl(&self, name: &str) -> Option<&'a crate::ast::ExternDecl> {
        self.externs.get(name).copied()
    }

    /// The task of this name defined in the source or another file of the program.
    pub fn task(&self, name: &str) -> Option<&'a Task> {
        self.tasks
            .get(name)
            .or_else(|| self.other_tasks.get(name))
            .copied()
    }

    /// The declaration of the exception of this name in the source or another file of the
    /// program.
    pub fn exception_decl(&self, name: &str) -> Option<&'a ExceptionDecl> {
        self.exceptions
            .get(name)
            .or_else(|| self.other_exceptions.get(name))
            .copied()
    }

    /// Every task of the program, this source's first, then those of the other files (the first
    /// declaration of a name only).
    pub fn all_tasks(&self) -> impl Iterator<Item = &'a Task> + '_ {
        let others = self
            .other_tasks
            .iter()
            .filter(|(name, _)| !self.tasks.contains_key(*name))
            .map(|(_, task)| *task);
        self.tasks.values().copied().chain(others)
    }

    /// Whether `task` is declared in this source (not in another file of the program).
    pub fn is_local(&self, task: &Task) -> bool {
        self.tasks
            .get(&task.name.to_string())
            .is_some_and(|it| std::ptr::eq(*it, task))
    }

    /// Whether the whole ancestry of exception `name` is known: it and each of its ancestors are
    /// declared in the program (an exception declared elsewhere, in Rust, may have ancestors the
    /// front end cannot see).
    pub fn ancestry_known(&self, name: &str) -> bool {
        // `ancestry` ends with the first parent that is not declared, if any.
        self.declares_exception(name)
            && self
                .ancestry(name)
                .iter()
                .all(|it| self.declares_exception(it))
    }

    /// The kind of the task of this name defined in the source.
    pub fn kind_of(&self, name: &str) -> Option<TaskKind> {
        self.task(name).map(|it| it.kind)
    }

    /// The names of the exceptions declared in the program, sorted.
    pub fn exception_names(&self) -> impl Iterator<Item = &str> {
        let mut names: BTreeSet<&str> = self.exceptions.keys().map(String::as_str).collect();
        names.extend(self.other_exceptions.keys().map(String::as_str));
        names.into_iter()
    }

    /// Whether `name` is an exception declared in the source or another file of the program, or
    /// one of the runtime's own (`ResourceDenied`, `ResourceDropped`).
    pub fn declares_exception(&self, name: &str) -> bool {
        self.exception_decl(name).is_some() || BUILTIN_EXCEPTIONS.contains(&name)
    }

    /// The Rust type of the exception `name` as generated code names it: the runtime's own
    /// exceptions through `::tdl` unless the program declares one of that name, others as written.
    pub(crate) fn exception_type(&self, name: &Ident) -> proc_macro2::TokenStream {
        let text = name.to_string();
        if self.exception_decl(&text).is_none() && BUILTIN_EXCEPTIONS.contains(&text.as_str()) {
            quote::quote!(::tdl::#name)
        } else {
            quote::quote!(#name)
        }
    }

    /// The resource of this name declared in the program.
    pub fn resource(&self, name: &str) -> Option<&'a ResourceDecl> {
        self.resources.get(name).copied()
    }

    /// Whether the program declares any resource.
    pub fn declares_resources(&self) -> bool {
        !self.resources.is_empty()
    }

    /// The names of the resources declared in the program, sorted.
    pub fn resource_names(&self) -> impl Iterator<Item = &str> {
        self.resources.keys().map(String::as_str)
    }

    /// The state variable of this name declared in the program.
    pub fn state(&self, name: &str) -> Option<&'a StateDecl> {
        self.states.get(name).copied()
    }

    /// The names of the state variables declared in the program, sorted.
    pub fn state_names(&self) -> impl Iterator<Item = &str> {
        self.states.keys().map(String::as_str)
    }

    /// The ancestors of exception `name`, nearest first: its parent, the parent's parent, ... (a
    /// parent declared elsewhere ends the chain; a cycle is cut).
    pub fn ancestry(&self, name: &str) -> Vec<String> {
        let parent_of = |name: &str| {
            self.exception_decl(name)
                .and_then(|it| it.parent.as_ref())
                .map(ToString::to_string)
        };
        let mut out: Vec<String> = Vec::new();
        let mut at = parent_of(name);
        while let Some(parent) = at {
            if parent == name || out.contains(&parent) {
                break;
            }
            at = parent_of(&parent);
            out.push(parent);
        }
        out
    }
}

/// Resolves the body of every task of `ast` into `bodies`.
pub(crate) fn add_bodies<'a>(bodies: &mut Bodies<'a>, ast: &'a Ast) {
    for item in &ast.items {
        if let Item::Task(task) = item {
            bodies.insert(std::ptr::from_ref(task), BodyScope::new(task));
        }
    }
}
