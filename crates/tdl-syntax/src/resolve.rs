//! The scope and resolution pass: what every name in a source means, worked out once and read by
//! both consumers, the static diagnosis (`diagnose.rs`) and the code generator (`codegen/`).
//!
//! - [`FileScope`]: the tasks and exceptions the source declares (the first of a duplicated name
//!   wins; the later ones are kept in [`FileScope::duplicates`]) and exception ancestries.
//! - [`BodyScope`]: one task body. Its TDL statements in source order, flattened out of the Rust
//!   control flow around them ([`Tdl`]), each at a [`Site`] (a position and the enclosing loops);
//!   its spawns, `with` groups and loops, numbered in source order; the names a tag can use; every
//!   named tag written in a constraint ([`Ref`]) and every `node!(tag)` in its Rust code
//!   ([`NodeUse`]); and what the generated code must track at run time: the local of each spawn,
//!   group, labelled on-terminate task or bound tag that some tag names, the loops that count
//!   their iterations, whether `previous` is used.
//!
//! Name rules (docs/semantics.md, "Tags and forward references"): tags are body-scoped, so forward
//! references resolve. A label (of a spawn, a group or an on-terminate task) or a `bind` names
//! that; the first of duplicated labels wins, and binding a name again rebinds it. Otherwise a
//! task spawned exactly once in the body names its spawn, and one spawned several times is
//! ambiguous. Unknown *task* names in spawns are not errors (tasks may come from other files),
//! only unknown *tags* are.
//!
//! Resolution reports nothing itself: `diagnose` words what it finds (duplicates, unknown or
//! ambiguous tags, wrong index counts, forward references to groups, `[.]` outside its loop), and
//! the generator, which resolves the same tree again from [`crate::generate`], only reads it.

use std::collections::{BTreeMap, BTreeSet};

use proc_macro2::{Delimiter, Ident, Span, TokenStream, TokenTree};
use quote::{ToTokens, format_ident};

use crate::ast::{
    Ast, Bind, Block, Constraint, ConstraintKind, ConstraintStmt, Count, Else, Event,
    ExceptionDecl, ExternalName, Fail, If, Item, OnTerminate, Priority, RelTime, ResourceDecl,
    ResourceStmt, Spawn, Stmt, Tag, TagIndex, TagKind, Task, TaskKind, When, WithGroup,
};

/// A spawn of a body, numbered in source order.
pub(crate) type SpawnId = usize;
/// A `with` group of a body, numbered in source order.
pub(crate) type GroupId = usize;
/// A `for`, `while` or `loop` of a body, numbered in source order.
pub(crate) type LoopId = usize;
/// A labelled `on terminate` task of a spawn, numbered in source order.
pub(crate) type CleanupId = usize;

/// The exceptions the runtime raises itself, which handlers name without declaring them
/// (docs/semantics.md, "Resources").
pub(crate) const BUILTIN_EXCEPTIONS: &[&str] = &["ResourceDenied", "ResourceDropped"];

/// The tasks and exceptions a source declares.
///
/// Compiled as part of a program ([`crate::compile_program`]), it also knows the declarations of
/// the program's other files: names resolve across every file, and a name declared in two files
/// is reported in [`FileScope::elsewhere`].
pub(crate) struct FileScope<'a> {
    tasks: BTreeMap<String, &'a Task>,
    exceptions: BTreeMap<String, &'a ExceptionDecl>,
    /// Resources of the program: this file's (the first of a name), then the other files'.
    resources: BTreeMap<String, &'a ResourceDecl>,
    /// Declarations of a name already declared, in source order.
    pub(crate) duplicates: Vec<Duplicate<'a>>,
    /// Tasks and exceptions of the program's other files (the first file declaring a name wins).
    other_tasks: BTreeMap<String, &'a Task>,
    other_exceptions: BTreeMap<String, &'a ExceptionDecl>,
    /// This file's declarations of a name another file of the program declares too: (the
    /// declaration's name, the other file's name).
    pub(crate) elsewhere: Vec<(&'a Ident, &'a str)>,
}

/// A declaration of a name declared before: (this one, the first).
pub(crate) enum Duplicate<'a> {
    /// Two tasks of one name.
    Task(&'a Task, &'a Task),
    /// Two exceptions of one name.
    Exception(&'a ExceptionDecl, &'a ExceptionDecl),
}

impl<'a> FileScope<'a> {
    /// The declarations of `ast`.
    pub(crate) fn new(ast: &'a Ast) -> FileScope<'a> {
        let mut scope = FileScope {
            tasks: BTreeMap::new(),
            exceptions: BTreeMap::new(),
            resources: BTreeMap::new(),
            duplicates: Vec::new(),
            other_tasks: BTreeMap::new(),
            other_exceptions: BTreeMap::new(),
            elsewhere: Vec::new(),
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
                // Duplicates are diagnosed with the other resource checks (`diagnose/resources.rs`).
                Item::Resource(r) => {
                    scope.resources.entry(r.name.to_string()).or_insert(r);
                }
                Item::Rust(_) => {}
            }
        }
        scope
    }

    /// The declarations of `ast`, with those of the program's other files, `(file name, tree)`.
    pub(crate) fn in_program(ast: &'a Ast, others: &[(&'a str, &'a Ast)]) -> FileScope<'a> {
        let mut scope = FileScope::new(ast);
        for (file, other) in others {
            for item in &other.items {
                match item {
                    Item::Task(task) => {
                        let name = task.name.to_string();
                        if let Some(mine) = scope.tasks.get(&name) {
                            scope.elsewhere.push((&mine.name, file));
                        }
                        scope.other_tasks.entry(name).or_insert(task);
                    }
                    Item::Exception(exc) => {
                        let name = exc.name.to_string();
                        if let Some(mine) = scope.exceptions.get(&name) {
                            scope.elsewhere.push((&mine.name, file));
                        }
                        scope.other_exceptions.entry(name).or_insert(exc);
                    }
                    Item::Resource(r) => {
                        let name = r.name.to_string();
                        if let Some(mine) = scope.resources.get(&name) {
                            if !std::ptr::eq(*mine, r) {
                                scope.elsewhere.push((&mine.name, file));
                            }
                        }
                        scope.resources.entry(name).or_insert(r);
                    }
                    Item::Rust(_) => {}
                }
            }
        }
        scope.elsewhere.sort_by_key(|(name, _)| {
            let at = name.span().start();
            (at.line, at.column)
        });
        scope
    }

    /// The task of this name defined in the source or another file of the program.
    pub(crate) fn task(&self, name: &str) -> Option<&'a Task> {
        self.tasks
            .get(name)
            .or_else(|| self.other_tasks.get(name))
            .copied()
    }

    fn exception_decl(&self, name: &str) -> Option<&'a ExceptionDecl> {
        self.exceptions
            .get(name)
            .or_else(|| self.other_exceptions.get(name))
            .copied()
    }

    /// Every task of the program, this source's first, then those of the other files (the first
    /// declaration of a name only).
    pub(crate) fn all_tasks(&self) -> impl Iterator<Item = &'a Task> + '_ {
        let others = self
            .other_tasks
            .iter()
            .filter(|(name, _)| !self.tasks.contains_key(*name))
            .map(|(_, task)| *task);
        self.tasks.values().copied().chain(others)
    }

    /// Whether `task` is declared in this source (not in another file of the program).
    pub(crate) fn is_local(&self, task: &Task) -> bool {
        self.tasks
            .get(&task.name.to_string())
            .is_some_and(|it| std::ptr::eq(*it, task))
    }

    /// Whether the whole ancestry of exception `name` is known: it and each of its ancestors are
    /// declared in the program (an exception declared elsewhere, in Rust, may have ancestors the
    /// front end cannot see).
    pub(crate) fn ancestry_known(&self, name: &str) -> bool {
        // `ancestry` ends with the first parent that is not declared, if any.
        self.declares_exception(name)
            && self
                .ancestry(name)
                .iter()
                .all(|it| self.declares_exception(it))
    }

    /// The kind of the task of this name defined in the source.
    pub(crate) fn kind_of(&self, name: &str) -> Option<TaskKind> {
        self.task(name).map(|it| it.kind)
    }

    /// The names of the exceptions declared in the program, sorted.
    pub(crate) fn exception_names(&self) -> impl Iterator<Item = &str> {
        let mut names: BTreeSet<&str> = self.exceptions.keys().map(String::as_str).collect();
        names.extend(self.other_exceptions.keys().map(String::as_str));
        names.into_iter()
    }

    /// Whether `name` is an exception declared in the source or another file of the program, or
    /// one of the runtime's own (`ResourceDenied`, `ResourceDropped`).
    pub(crate) fn declares_exception(&self, name: &str) -> bool {
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
    pub(crate) fn resource(&self, name: &str) -> Option<&'a ResourceDecl> {
        self.resources.get(name).copied()
    }

    /// Whether the program declares any resource.
    pub(crate) fn declares_resources(&self) -> bool {
        !self.resources.is_empty()
    }

    /// The names of the resources declared in the program, sorted.
    pub(crate) fn resource_names(&self) -> impl Iterator<Item = &str> {
        self.resources.keys().map(String::as_str)
    }

    /// The ancestors of exception `name`, nearest first: its parent, the parent's parent, ... (a
    /// parent declared elsewhere ends the chain; a cycle is cut).
    pub(crate) fn ancestry(&self, name: &str) -> Vec<String> {
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

/// Where a TDL statement is: its position among the body's statements (Rust ones included, in
/// source order) and its enclosing loops, outermost first.
#[derive(Clone, Debug, Default)]
pub(crate) struct Site {
    /// Position in source order, from 1.
    pub(crate) position: usize,
    /// Enclosing loops, outermost first.
    pub(crate) loops: Vec<LoopId>,
}

/// One TDL statement of a body, in source order.
pub(crate) enum Tdl<'a> {
    /// A spawn.
    Spawn(SpawnId),
    /// A `with` group; its members follow.
    With(GroupId),
    /// A constraint statement `TAG constraint;`.
    Constrain(&'a ConstraintStmt, Site),
    /// `fail ...;`.
    Fail(&'a Fail),
    /// `bypass;`.
    Bypass(Span),
    /// `trigger;`.
    Trigger(Span),
    /// `retry;` or `retry with (args);`.
    Retry(&'a crate::ast::Retry),
}

/// A spawn statement.
pub(crate) struct SpawnDef<'a> {
    /// The statement.
    pub(crate) spawn: &'a Spawn,
    /// Where it is.
    pub(crate) site: Site,
    /// The enclosing `with` groups, outermost first.
    pub(crate) groups: Vec<GroupId>,
    /// The local holding its node (a reservation, or a map by iteration in loops), when some tag
    /// names it.
    pub(crate) var: Option<Ident>,
    /// It has a `parent` constraint: its node is not a child of this body, so it cannot fulfil a
    /// reservation of the body; its local is bound when it is spawned (`Option<NodeId>`).
    pub(crate) late: bool,
}

/// A labelled `on terminate` task of a spawn: its labels name the node inserted if the spawned
/// node is terminated while running.
pub(crate) struct CleanupDef<'a> {
    /// The spawn it is attached to.
    pub(crate) spawn: SpawnId,
    /// The constraint.
    pub(crate) on_terminate: &'a OnTerminate,
    /// The local holding the reservation it fulfils (a map by iteration in loops), when some tag
    /// names it.
    pub(crate) var: Option<Ident>,
}

/// A tag bound with `bind name = …;`: where its first `bind` is.
pub(crate) struct BoundDef {
    /// Where it is.
    pub(crate) site: Site,
    /// The local holding the node (`Option<NodeId>`), when some tag names it.
    pub(crate) var: Option<Ident>,
}

/// A `with` group.
pub(crate) struct GroupDef<'a> {
    /// The statement.
    pub(crate) group: &'a WithGroup,
    /// Where it is.
    pub(crate) site: Site,
    /// The local collecting its members, when some tag names it.
    pub(crate) var: Option<Ident>,
}

/// What a name used as a tag stands for.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Def<'a> {
    /// A spawn, by its label or as the only spawn of its task.
    Spawn(SpawnId),
    /// A labelled `with` group.
    Group(GroupId),
    /// A labelled `on terminate` task of a spawn.
    OnTerminate(CleanupId),
    /// A tag bound with `bind`: the first `bind` of the name.
    Bound(&'a Bind),
}

/// A name's definition and where it is written: the label, or the spawned task's name.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Named<'a> {
    /// What the name stands for.
    pub(crate) def: Def<'a>,
    /// The label, or the spawned task's name.
    pub(crate) span: Span,
}

/// What a tag resolves to.
pub(crate) enum Resolution<'a> {
    /// `previous`: tracked at run time.
    Previous,
    /// `self`/`child`: the node being constrained.
    This,
    /// `parent`/`this`: the enclosing task's node.
    Parent,
    /// A spawn, group or on-terminate task of the body.
    Named(Named<'a>),
    /// No spawn or label of the body has this name.
    Unknown,
    /// The task is spawned several times and no label has its name: those spawns.
    Ambiguous(Vec<SpawnId>),
}

/// A `node!(tag)` in the Rust code of a body.
pub(crate) struct NodeUse {
    /// The tag written, or why the inside is not one.
    pub(crate) tag: Result<Tag, syn::Error>,
    /// Span of `node`.
    pub(crate) span: Span,
    /// Where: the statement it is written in.
    pub(crate) site: Site,
}

/// A named tag written in a constraint, at the position of its statement.
pub(crate) struct Ref<'a> {
    /// The tag.
    pub(crate) tag: &'a Tag,
    /// Its name.
    pub(crate) name: &'a Ident,
    /// The position of the spawn, group or constraint statement it is written in.
    pub(crate) position: usize,
}

/// One iteration index of a tag on a spawn inside loops.
pub(crate) enum Index<'a> {
    /// `[expr]`.
    Expr(&'a syn::Expr),
    /// `[.]`: the current iteration of this loop.
    Current(LoopId),
}

/// Why a tag's iteration indexes do not fit its spawn.
#[derive(Debug, PartialEq, Eq)]
pub(crate) enum IndexError {
    /// More indexes than loops around the spawn.
    TooMany,
    /// `[.]` where the loop it counts does not enclose the use.
    CurrentOutside,
}

/// What a constraint refers to besides the node it constrains.
pub(crate) enum Refers<'a> {
    /// `sequential`/`serial` without a tag: `previous`.
    Previous,
    /// The tag of `sequential`/`serial`: the constrained node waits for it.
    WaitsOn(&'a Tag),
    /// The event of a trigger (`until`, `at`, `after`).
    Event(&'a Event),
}

impl Refers<'_> {
    /// Whether it is `previous`, written or implied.
    fn is_previous(&self) -> bool {
        match self {
            Refers::Previous => true,
            Refers::WaitsOn(tag) => matches!(tag.kind, TagKind::Previous),
            Refers::Event(event) => matches!(event.tag.kind, TagKind::Previous),
        }
    }
}

/// The node `kind` refers to, if any.
pub(crate) fn refers(kind: &ConstraintKind) -> Option<Refers<'_>> {
    match kind {
        ConstraintKind::Sequential { tag, .. } | ConstraintKind::Serial { tag } => {
            Some(tag.as_ref().map_or(Refers::Previous, Refers::WaitsOn))
        }
        ConstraintKind::Trigger { when, .. } => when.event().map(Refers::Event),
        _ => None,
    }
}

/// Whether any of `constraints` refers to `previous`.
pub(crate) fn uses_previous(constraints: &[Constraint]) -> bool {
    constraints
        .iter()
        .filter_map(|it| refers(&it.kind))
        .any(|it| it.is_previous())
}

/// One task body, resolved.
pub(crate) struct BodyScope<'a> {
    /// Its TDL statements in source order.
    pub(crate) stmts: Vec<Tdl<'a>>,
    /// Its spawns in source order.
    pub(crate) spawns: Vec<SpawnDef<'a>>,
    /// Its `with` groups in source order.
    pub(crate) groups: Vec<GroupDef<'a>>,
    /// Every named tag written in a constraint, in source order.
    pub(crate) refs: Vec<Ref<'a>>,
    /// Every `node!(tag)` in the body's Rust code, in source order.
    pub(crate) node_uses: Vec<NodeUse>,
    /// Its labelled on-terminate tasks, in source order.
    pub(crate) cleanups: Vec<CleanupDef<'a>>,
    /// Its bound tags, by name.
    pub(crate) bound: BTreeMap<String, BoundDef>,
    /// Labels already used: (the later label, the first one's span).
    pub(crate) duplicate_labels: Vec<(&'a Ident, Span)>,
    /// Whether some constraint refers to `previous`.
    pub(crate) uses_previous: bool,
    /// Its `lock`, `unlock`, `reserve` and `unreserve` statements, in source order.
    pub(crate) resource_stmts: Vec<&'a ResourceStmt>,
    /// Labels, the first of each.
    labels: BTreeMap<String, Named<'a>>,
    /// The spawns of each task.
    by_task: BTreeMap<String, Vec<SpawnId>>,
    spawn_ids: BTreeMap<*const Spawn, SpawnId>,
    group_ids: BTreeMap<*const WithGroup, GroupId>,
    cleanup_ids: BTreeMap<*const OnTerminate, CleanupId>,
    /// Loops by their body.
    loop_ids: BTreeMap<*const Block, LoopId>,
    /// Loops that count their iterations, for iteration-indexed tags.
    counted: BTreeSet<LoopId>,
}

impl<'a> BodyScope<'a> {
    /// Resolves the body of `task`.
    pub(crate) fn new(task: &'a Task) -> BodyScope<'a> {
        let mut walk = Walk {
            scope: BodyScope {
                stmts: Vec::new(),
                spawns: Vec::new(),
                groups: Vec::new(),
                refs: Vec::new(),
                node_uses: Vec::new(),
                cleanups: Vec::new(),
                bound: BTreeMap::new(),
                duplicate_labels: Vec::new(),
                uses_previous: false,
                resource_stmts: Vec::new(),
                labels: BTreeMap::new(),
                by_task: BTreeMap::new(),
                spawn_ids: BTreeMap::new(),
                group_ids: BTreeMap::new(),
                cleanup_ids: BTreeMap::new(),
                loop_ids: BTreeMap::new(),
                counted: BTreeSet::new(),
            },
            position: 0,
            loops: Vec::new(),
            groups: Vec::new(),
        };
        walk.block(&task.body);
        let mut scope = walk.scope;
        scope.assign_vars();
        scope
    }

    /// What `tag` denotes.
    pub(crate) fn resolve(&self, tag: &Tag) -> Resolution<'a> {
        match &tag.kind {
            TagKind::Previous => Resolution::Previous,
            TagKind::Child => Resolution::This,
            TagKind::Parent => Resolution::Parent,
            TagKind::Named { name, .. } => self.lookup(&name.to_string()),
        }
    }

    /// What the name `name` denotes: a label, else a task spawned once.
    fn lookup(&self, name: &str) -> Resolution<'a> {
        if let Some(named) = self.labels.get(name) {
            return Resolution::Named(*named);
        }
        match self.by_task.get(name).map(Vec::as_slice) {
            None | Some([]) => Resolution::Unknown,
            Some([only]) => Resolution::Named(Named {
                def: Def::Spawn(*only),
                span: self.spawns[*only].spawn.task.span(),
            }),
            Some(many) => Resolution::Ambiguous(many.to_vec()),
        }
    }

    /// The named definition `tag` denotes, if it denotes one.
    pub(crate) fn named(&self, tag: &Tag) -> Option<Named<'a>> {
        match self.resolve(tag) {
            Resolution::Named(named) => Some(named),
            _ => None,
        }
    }

    /// Where a definition is (an on-terminate task: where its spawn is; a bound tag: its first
    /// `bind`).
    pub(crate) fn site(&self, def: Def<'a>) -> &Site {
        match def {
            Def::Spawn(id) => &self.spawns[id].site,
            Def::OnTerminate(id) => &self.spawns[self.cleanups[id].spawn].site,
            Def::Group(id) => &self.groups[id].site,
            Def::Bound(bind) => &self.bound[&bind.name.to_string()].site,
        }
    }

    /// The task a definition runs: a spawn's or an on-terminate task; none for a group or a
    /// bound tag.
    pub(crate) fn task_of(&self, def: Def<'a>) -> Option<&'a Ident> {
        match def {
            Def::Spawn(id) => Some(&self.spawns[id].spawn.task),
            Def::OnTerminate(id) => Some(&self.cleanups[id].on_terminate.task),
            Def::Group(_) | Def::Bound(_) => None,
        }
    }

    /// Whether the node of a definition is only known once a statement ran: a bound tag, or a
    /// spawn under another parent (its local is an `Option<NodeId>`, not a reservation).
    pub(crate) fn is_late(&self, def: Def<'a>) -> bool {
        match def {
            Def::Spawn(id) => self.spawns[id].late,
            Def::Bound(_) => true,
            Def::Group(_) | Def::OnTerminate(_) => false,
        }
    }

    /// The labelled on-terminate task `it`, if it has a label.
    pub(crate) fn cleanup(&self, it: &OnTerminate) -> Option<&CleanupDef<'a>> {
        let id = self.cleanup_ids.get(&std::ptr::from_ref(it))?;
        self.cleanups.get(*id)
    }

    /// The spawn statement `spawn`.
    pub(crate) fn spawn_def(&self, spawn: &Spawn) -> Option<&SpawnDef<'a>> {
        let id = self.spawn_ids.get(&std::ptr::from_ref(spawn))?;
        self.spawns.get(*id)
    }

    /// The number of the spawn statement `spawn`.
    pub(crate) fn spawn_id(&self, spawn: &Spawn) -> Option<SpawnId> {
        self.spawn_ids.get(&std::ptr::from_ref(spawn)).copied()
    }

    /// The number of the group `group`.
    pub(crate) fn group_id(&self, group: &WithGroup) -> Option<GroupId> {
        self.group_ids.get(&std::ptr::from_ref(group)).copied()
    }

    /// The number of the loop whose body is `body`.
    pub(crate) fn loop_id(&self, body: &Block) -> Option<LoopId> {
        self.loop_ids.get(&std::ptr::from_ref(body)).copied()
    }

    /// Whether the loop counts its iterations (a tag names a spawn inside it).
    pub(crate) fn is_counted(&self, id: LoopId) -> bool {
        self.counted.contains(&id)
    }

    /// The iteration indexes of a tag naming spawn `id`, used inside the loops `site`: one per
    /// index written. A spawn outside loops takes none (more are reported by the index count).
    pub(crate) fn indexes<'t>(
        &self,
        id: SpawnId,
        indexes: &'t [TagIndex],
        site: &[LoopId],
    ) -> Result<Vec<Index<'t>>, IndexError> {
        let loops = &self.spawns[id].site.loops;
        if loops.is_empty() {
            return Ok(Vec::new());
        }
        let mut out = Vec::new();
        for (level, index) in indexes.iter().enumerate() {
            match index {
                TagIndex::Expr(expr) => out.push(Index::Expr(expr)),
                TagIndex::Current => {
                    let Some(&loop_id) = loops.get(level) else {
                        return Err(IndexError::TooMany);
                    };
                    if site.get(level) != Some(&loop_id) {
                        return Err(IndexError::CurrentOutside);
                    }
                    out.push(Index::Current(loop_id));
                }
            }
        }
        if out.len() > loops.len() {
            return Err(IndexError::TooMany);
        }
        Ok(out)
    }

    fn add_label(&mut self, label: &'a Ident, def: Def<'a>) {
        let name = label.to_string();
        if let Some(first) = self.labels.get(&name) {
            // Binding a bound name again rebinds it.
            if !matches!((first.def, def), (Def::Bound(_), Def::Bound(_))) {
                self.duplicate_labels.push((label, first.span));
            }
            return;
        }
        let span = label.span();
        self.labels.insert(name, Named { def, span });
    }

    /// Marks what the tags name and gives each named spawn, group, labelled on-terminate task
    /// and bound tag its local.
    fn assign_vars(&mut self) {
        let mut spawns = BTreeSet::new();
        let mut groups = BTreeSet::new();
        let mut cleanups = BTreeSet::new();
        let mut bound = BTreeSet::new();
        let uses = self.node_uses.iter().filter_map(|it| match &it.tag {
            Ok(Tag {
                kind: TagKind::Named { name, .. },
                ..
            }) => Some(name.to_string()),
            _ => None,
        });
        let names: Vec<String> = self
            .refs
            .iter()
            .map(|r| r.name.to_string())
            .chain(uses)
            .collect();
        for name in names {
            let Resolution::Named(Named { def, .. }) = self.lookup(&name) else {
                continue;
            };
            match def {
                Def::Spawn(id) => {
                    spawns.insert(id);
                }
                Def::Group(id) => {
                    groups.insert(id);
                }
                Def::OnTerminate(id) => {
                    cleanups.insert(id);
                }
                Def::Bound(bind) => {
                    bound.insert(bind.name.to_string());
                }
            }
        }
        let mut used = BTreeSet::new();
        let mut local = |base: &str| {
            let mut var = format!("tdl_{}", base.trim_start_matches("r#"));
            while !used.insert(var.clone()) {
                var.push('_');
            }
            format_ident!("{}", var)
        };
        for id in spawns {
            let def = &mut self.spawns[id];
            let spawn = def.spawn;
            let base = spawn.labels.first().unwrap_or(&spawn.task).to_string();
            def.var = Some(local(&base));
            self.counted.extend(def.site.loops.iter().copied());
        }
        for id in groups {
            let def = &mut self.groups[id];
            let base = def
                .group
                .labels
                .first()
                .map(ToString::to_string)
                .unwrap_or_default();
            def.var = Some(local(&base));
        }
        for id in cleanups {
            let def = &mut self.cleanups[id];
            let base = def
                .on_terminate
                .labels
                .first()
                .unwrap_or(&def.on_terminate.task)
                .to_string();
            def.var = Some(local(&base));
            let loops = &self.spawns[def.spawn].site.loops;
            self.counted.extend(loops.iter().copied());
        }
        for name in bound {
            if let Some(def) = self.bound.get_mut(&name) {
                def.var = Some(local(&name));
            }
        }
    }
}

/// The walk that builds a [`BodyScope`].
struct Walk<'a> {
    scope: BodyScope<'a>,
    position: usize,
    loops: Vec<LoopId>,
    groups: Vec<GroupId>,
}

impl<'a> Walk<'a> {
    fn block(&mut self, block: &'a Block) {
        for stmt in &block.stmts {
            self.stmt(stmt);
        }
    }

    fn stmt(&mut self, stmt: &'a Stmt) {
        self.position += 1;
        let site = Site {
            position: self.position,
            loops: self.loops.clone(),
        };
        match stmt {
            Stmt::Spawn(spawn) => {
                let id = self.scope.spawns.len();
                self.scope.spawn_ids.insert(std::ptr::from_ref(spawn), id);
                self.scope
                    .by_task
                    .entry(spawn.task.to_string())
                    .or_default()
                    .push(id);
                let late = spawn
                    .constraints
                    .iter()
                    .any(|it| matches!(it.kind, ConstraintKind::Parent(_)));
                for arg in &spawn.args {
                    self.rust(arg.to_token_stream(), &site);
                }
                self.scope.spawns.push(SpawnDef {
                    spawn,
                    site: site.clone(),
                    groups: self.groups.clone(),
                    var: None,
                    late,
                });
                self.scope.stmts.push(Tdl::Spawn(id));
                for label in &spawn.labels {
                    self.scope.add_label(label, Def::Spawn(id));
                }
                for constraint in &spawn.constraints {
                    if let ConstraintKind::OnTerminate(it) = &constraint.kind {
                        if !it.labels.is_empty() {
                            let cleanup = self.scope.cleanups.len();
                            self.scope.cleanups.push(CleanupDef {
                                spawn: id,
                                on_terminate: it,
                                var: None,
                            });
                            self.scope
                                .cleanup_ids
                                .insert(std::ptr::from_ref(it), cleanup);
                            for label in &it.labels {
                                self.scope.add_label(label, Def::OnTerminate(cleanup));
                            }
                        }
                    }
                }
                self.constraints(&spawn.constraints, &site);
            }
            Stmt::With(group) => {
                let id = self.scope.groups.len();
                self.scope.group_ids.insert(std::ptr::from_ref(group), id);
                self.scope.groups.push(GroupDef {
                    group,
                    site: site.clone(),
                    var: None,
                });
                self.scope.stmts.push(Tdl::With(id));
                for label in &group.labels {
                    self.scope.add_label(label, Def::Group(id));
                }
                self.constraints(&group.constraints, &site);
                self.groups.push(id);
                self.block(&group.body);
                self.groups.pop();
            }
            Stmt::Constrain(it) => {
                self.tag(&it.tag);
                self.constraints(std::slice::from_ref(&it.constraint), &site);
                self.scope.stmts.push(Tdl::Constrain(it, site));
            }
            Stmt::Bind(it) => {
                self.rust(it.expr.to_token_stream(), &site);
                let name = it.name.to_string();
                self.scope
                    .bound
                    .entry(name)
                    .or_insert(BoundDef { site, var: None });
                self.scope.add_label(&it.name, Def::Bound(it));
            }
            Stmt::Fail(it) => {
                for field in &it.fields {
                    self.rust(field.to_token_stream(), &site);
                }
                self.scope.stmts.push(Tdl::Fail(it));
            }
            Stmt::Resource(it) => self.scope.resource_stmts.push(it),
            Stmt::Bypass(span) => self.scope.stmts.push(Tdl::Bypass(*span)),
            Stmt::Trigger(span) => self.scope.stmts.push(Tdl::Trigger(*span)),
            Stmt::Retry(it) => {
                for arg in it.args.iter().flatten() {
                    self.rust(arg.to_token_stream(), &site);
                }
                self.scope.stmts.push(Tdl::Retry(it));
            }
            Stmt::If(it) => self.if_stmt(it, &site),
            Stmt::For(it) => {
                self.rust(it.expr.to_token_stream(), &site);
                self.loop_body(&it.body);
            }
            Stmt::While(it) => {
                self.rust(it.cond.to_token_stream(), &site);
                self.loop_body(&it.body);
            }
            Stmt::Loop(it) => self.loop_body(&it.body),
            Stmt::Match(it) => {
                self.rust(it.expr.to_token_stream(), &site);
                for arm in &it.arms {
                    self.rust(arm.guard.to_token_stream(), &site);
                    self.block(&arm.body);
                }
            }
            Stmt::Block(it) => self.block(it),
            Stmt::Rust(it) => self.rust(it.tokens.clone(), &site),
            Stmt::Succeed(_) => {}
        }
    }

    fn if_stmt(&mut self, it: &'a If, site: &Site) {
        self.rust(it.cond.to_token_stream(), site);
        self.block(&it.then_branch);
        match it.else_branch.as_deref() {
            Some(Else::If(next)) => self.if_stmt(next, site),
            Some(Else::Block(block)) => self.block(block),
            None => {}
        }
    }

    /// Records the `node!(tag)` uses in Rust code at `site`.
    fn rust(&mut self, tokens: TokenStream, site: &Site) {
        for (tag, span) in node_uses(tokens) {
            self.scope.node_uses.push(NodeUse {
                tag,
                span,
                site: site.clone(),
            });
        }
    }

    fn loop_body(&mut self, body: &'a Block) {
        let id = self.scope.loop_ids.len();
        self.scope.loop_ids.insert(std::ptr::from_ref(body), id);
        self.loops.push(id);
        self.block(body);
        self.loops.pop();
    }

    fn constraints(&mut self, constraints: &'a [Constraint], site: &Site) {
        for constraint in constraints {
            self.rust(constraint_code(&constraint.kind), site);
            match refers(&constraint.kind) {
                Some(Refers::Previous) => self.scope.uses_previous = true,
                Some(Refers::WaitsOn(tag)) => self.tag(tag),
                Some(Refers::Event(event)) => self.tag(&event.tag),
                None => {}
            }
        }
    }

    fn tag(&mut self, tag: &'a Tag) {
        match &tag.kind {
            TagKind::Previous => self.scope.uses_previous = true,
            TagKind::Named { name, .. } => self.scope.refs.push(Ref {
                tag,
                name,
                position: self.position,
            }),
            TagKind::Child | TagKind::Parent => {}
        }
    }
}

/// The `node!(tag)` uses in `tokens`, outermost first: the tag parsed from inside the
/// parentheses (or why it is not one) and the span of `node`.
pub(crate) fn node_uses(tokens: TokenStream) -> Vec<(Result<Tag, syn::Error>, Span)> {
    let mut out = Vec::new();
    let tts: Vec<TokenTree> = tokens.into_iter().collect();
    let mut i = 0;
    while i < tts.len() {
        if let Some((inner, span)) = node_macro(&tts[i..]) {
            out.push((crate::parser::parse_tag_tokens(inner), span));
            i += 3;
            continue;
        }
        if let TokenTree::Group(group) = &tts[i] {
            out.extend(node_uses(group.stream()));
        }
        i += 1;
    }
    out
}

/// `node ! ( … )` at the start of `tts`: the tokens inside and the span of `node`.
pub(crate) fn node_macro(tts: &[TokenTree]) -> Option<(TokenStream, Span)> {
    match tts {
        [
            TokenTree::Ident(name),
            TokenTree::Punct(bang),
            TokenTree::Group(group),
            ..,
        ] if name == "node"
            && bang.as_char() == '!'
            && group.delimiter() == Delimiter::Parenthesis =>
        {
            Some((group.stream(), name.span()))
        }
        _ => None,
    }
}

/// The Rust expressions of a constraint (a name, a parent, counts, times in seconds, an external
/// event's name, handler and on-terminate arguments), as one token stream to search for `node!(tag)`.
fn constraint_code(kind: &ConstraintKind) -> TokenStream {
    let mut out = TokenStream::new();
    let count = |it: &Count, out: &mut TokenStream| {
        if let Count::Expr(expr) = it {
            expr.to_tokens(out);
        }
    };
    let seconds = |it: &RelTime, out: &mut TokenStream| {
        if let RelTime::Seconds(expr) = it {
            expr.to_tokens(out);
        }
    };
    match kind {
        ConstraintKind::Name(expr)
        | ConstraintKind::Parent(expr)
        | ConstraintKind::OnAgent(expr) => {
            expr.to_tokens(&mut out);
        }
        ConstraintKind::MaximumActivate(n) | ConstraintKind::MaximumTrigger(n) => {
            count(n, &mut out);
        }
        ConstraintKind::Period(t) => seconds(t, &mut out),
        ConstraintKind::ExceptionHandler(it) => {
            for arg in &it.args {
                arg.to_tokens(&mut out);
            }
            if let Some(n) = &it.max_activate {
                count(n, &mut out);
            }
        }
        ConstraintKind::OnTerminate(it) => {
            for arg in &it.args {
                arg.to_tokens(&mut out);
            }
        }
        ConstraintKind::Trigger {
            when: When::In(t) | When::After(t, _),
            ..
        } => seconds(t, &mut out),
        ConstraintKind::Trigger {
            when: When::External(ExternalName::Expr(expr)),
            ..
        } => expr.to_tokens(&mut out),
        ConstraintKind::Uses(list) => {
            for it in list {
                if let Some(n) = &it.amount {
                    count(n, &mut out);
                }
            }
        }
        ConstraintKind::Priority(Priority::Expr(expr)) => expr.to_tokens(&mut out),
        _ => {}
    }
    out
}

#[cfg(test)]
mod tests;
