//! The resolved program: what every name of a TDL program means, worked out once by the front end
//! and read by every back end (the static diagnosis, the code generator behind `tdl!` and
//! `tdl-build`, `tdl verify`'s loader, `tdl graph` and `tdl doc`). It is inert: plain data over
//! the syntax trees, which it borrows.
//!
//! - [`Program`]: the files of a program, each with its [`FileScope`] (its tasks, exceptions and
//!   resources, then the other files'; duplicate declarations; exception ancestries), and the
//!   resolved body of every task; the program-wide views (every task in order, the first
//!   declaration of a name, what a task raises, whom it spawns).
//! - [`BodyScope`]: one task body: its TDL statements in source order, its spawns, `with` groups
//!   and loops numbered in source order, every tag resolved to its definition ([`Resolution`]),
//!   and `previous` at each statement as far as it is known statically ([`Previous`]).
//!
//! Name rules (docs/semantics.md, "Tags and forward references"): tags are body-scoped, so forward
//! references resolve. A label (of a spawn, a group or an on-terminate task) or a `bind` names
//! that; the first of duplicated labels wins, and binding a name again rebinds it. Otherwise a
//! task spawned exactly once in the body names its spawn, and one spawned several times is
//! ambiguous. Unknown *task* names in spawns are not errors (tasks may come from other files, or
//! be written in Rust), only unknown *tags* are. A name declared in several files is the first
//! file's.
//!
//! Resolution reports nothing itself: the diagnosis words what it finds (duplicates, unknown or
//! ambiguous tags, wrong index counts, forward references to groups, `[.]` outside its loop).
//! Only this module resolves names: every other crate reads what it found.
//!
//! ```
//! let src = "goal g() { a: spawn step(); spawn step() with serial a; }";
//! let parse = tdl_syntax::parse_str("g.tdl", src);
//! let program = tdl_syntax::hir::Program::new(&[("g.tdl", &parse.file)]);
//! let task = program.task("g").unwrap();
//! let body = program.body(task.task);
//! // The second spawn's `serial a` names the first spawn, through its label.
//! let tdl_syntax::ConstraintKind::Serial { tag: Some(tag) } = &body.spawns[1].spawn.constraints[0].kind
//! else { panic!() };
//! assert!(matches!(
//!     body.resolve(tag),
//!     tdl_syntax::hir::Resolution::Named(tdl_syntax::hir::Named { def: tdl_syntax::hir::Def::Spawn(0), .. })
//! ));
//! // `previous` at the second spawn is the first.
//! assert_eq!(body.previous_at(body.spawns[1].site.position).unwrap().may, [0]);
//! ```

mod body;
mod previous;
mod resolve;
mod scope;
mod visit;

use std::collections::BTreeSet;
use std::rc::Rc;

use proc_macro2::Ident;

pub use body::*;
pub use previous::Previous;
pub use scope::{BUILTIN_EXCEPTIONS, Duplicate, Elsewhere, FileScope};
pub use visit::{Branch, Visit, walk_stmt};

use crate::ast::{
    Ast, ConstraintKind, EnvEntry, ExceptionDecl, Item, ResourceDecl, StateDecl, Task,
    TaskConstraintKind,
};

/// The exception a bare `fail;` raises, as the runtime names it.
pub const BARE_FAIL: &str = "Fail";

/// One file of a program.
pub struct File<'a> {
    /// Its name, as given.
    pub name: &'a str,
    /// Its syntax tree.
    pub ast: &'a Ast,
    /// What its names mean.
    pub scope: FileScope<'a>,
}

/// A task declaration of a program, with the file it is in.
#[derive(Clone, Copy)]
pub struct TaskRef<'a> {
    /// The number of its file, in the order the program's files were given.
    pub file: usize,
    /// The declaration.
    pub task: &'a Task,
}

/// A TDL program of one or more files, resolved.
pub struct Program<'a> {
    files: Vec<File<'a>>,
}

impl<'a> Program<'a> {
    /// Resolves the program whose files are `(name, tree)`, in order.
    pub fn new(files: &[(&'a str, &'a Ast)]) -> Program<'a> {
        let mut bodies = scope::Bodies::new();
        for (_, ast) in files {
            scope::add_bodies(&mut bodies, ast);
        }
        let bodies = Rc::new(bodies);
        let files = (0..files.len())
            .map(|at| File {
                name: files[at].0,
                ast: files[at].1,
                scope: FileScope::in_program(files, at, Rc::clone(&bodies)),
            })
            .collect();
        Program { files }
    }

    /// Its files, in the order given.
    pub fn files(&self) -> &[File<'a>] {
        &self.files
    }

    /// Every task declaration, file by file in source order (a duplicated name included).
    pub fn tasks(&self) -> impl Iterator<Item = TaskRef<'a>> + '_ {
        self.files.iter().enumerate().flat_map(|(file, it)| {
            it.ast.items.iter().filter_map(move |item| match item {
                Item::Task(task) => Some(TaskRef { file, task }),
                _ => None,
            })
        })
    }

    /// The task a name denotes: its first declaration, in file order.
    pub fn task(&self, name: &str) -> Option<TaskRef<'a>> {
        self.tasks().find(|it| it.task.name == name)
    }

    /// The resolved body of `task`, a task of the program.
    ///
    /// # Panics
    ///
    /// If `task` is not a task of this program.
    pub fn body(&self, task: &Task) -> &BodyScope<'a> {
        self.scope().body(task)
    }

    /// The scope names are looked up in program-wide: the first file's, which sees every file's
    /// declarations, the first of a name winning.
    ///
    /// # Panics
    ///
    /// If the program has no file.
    pub fn scope(&self) -> &FileScope<'a> {
        &self.files[0].scope
    }

    /// Every exception declaration, the first of each name, file by file in source order, with
    /// its file.
    pub fn exceptions(&self) -> Vec<(usize, &'a ExceptionDecl)> {
        let mut seen = BTreeSet::new();
        let mut out = Vec::new();
        for (file, it) in self.files.iter().enumerate() {
            for item in &it.ast.items {
                if let Item::Exception(exc) = item {
                    if seen.insert(exc.name.to_string()) {
                        out.push((file, exc));
                    }
                }
            }
        }
        out
    }

    /// Every resource declaration, the first of each name, file by file in source order.
    pub fn resources(&self) -> Vec<&'a ResourceDecl> {
        let mut seen = BTreeSet::new();
        let mut out = Vec::new();
        for it in &self.files {
            for item in &it.ast.items {
                if let Item::Resource(r) = item {
                    if seen.insert(r.name.to_string()) {
                        out.push(r);
                    }
                }
            }
        }
        out
    }

    /// Every state variable declaration, the first of each name, file by file in source order.
    pub fn states(&self) -> Vec<&'a StateDecl> {
        let mut seen = BTreeSet::new();
        let mut out = Vec::new();
        for it in &self.files {
            for item in &it.ast.items {
                if let Item::State(v) = item {
                    if seen.insert(v.name.to_string()) {
                        out.push(v);
                    }
                }
            }
        }
        out
    }

    /// The entries of the program's environment declarations, in file order (docs/
    /// Every `extern` task declaration, file by file in source order.
    pub fn externs(&self) -> Vec<&'a crate::ast::ExternDecl> {
        self.files
            .iter()
            .flat_map(|it| {
                it.ast.items.iter().filter_map(|item| match item {
                    Item::Extern(e) => Some(e),
                    _ => None,
                })
            })
            .collect()
    }

    /// verification.md, "The environment"), and whether it has one at all.
    pub fn environment(&self) -> Option<Vec<&'a EnvEntry>> {
        let mut found = false;
        let mut out = Vec::new();
        for it in &self.files {
            for item in &it.ast.items {
                if let Item::Environment(env) = item {
                    found = true;
                    out.extend(env.entries.iter());
                }
            }
        }
        found.then_some(out)
    }

    /// The ancestors of exception `name`, nearest first (see [`FileScope::ancestry`]).
    pub fn ancestry(&self, name: &str) -> Vec<String> {
        self.files
            .first()
            .map(|it| it.scope.ancestry(name))
            .unwrap_or_default()
    }

    /// The exceptions `task`'s body raises with `fail` ([`BARE_FAIL`] for a bare `fail;`).
    pub fn raises(&self, task: &Task) -> BTreeSet<String> {
        self.body(task).raises()
    }

    /// The tasks `task` may start, in source order: those its body spawns, their on-terminate
    /// tasks, and its own (task-level) on-terminate tasks. Handlers are named in
    /// [`Program::handlers`].
    pub fn spawned(&self, task: &'a Task) -> Vec<&'a Ident> {
        let mut out = Vec::new();
        for spawn in &self.body(task).spawns {
            out.push(&spawn.spawn.task);
            for c in &spawn.spawn.constraints {
                if let ConstraintKind::OnTerminate(it) = &c.kind {
                    out.push(&it.task);
                }
            }
        }
        for c in &task.constraints {
            if let TaskConstraintKind::OnTerminate(it) = &c.kind {
                out.push(&it.task);
            }
        }
        out
    }

    /// The handlers `task` attaches: its own (task-level), then those of its body's spawns, then
    /// those of its `with` groups, each in source order.
    pub fn handlers(&self, task: &'a Task) -> Vec<&'a Ident> {
        let mut out = Vec::new();
        for c in &task.constraints {
            if let TaskConstraintKind::ExceptionHandler(h) = &c.kind {
                out.push(&h.name);
            }
        }
        let body = self.body(task);
        let spawns = body.spawns.iter().map(|it| &it.spawn.constraints);
        let groups = body.groups.iter().map(|it| &it.group.constraints);
        for list in spawns.chain(groups) {
            for c in list {
                if let ConstraintKind::ExceptionHandler(h) = &c.kind {
                    out.push(&h.name);
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests;
