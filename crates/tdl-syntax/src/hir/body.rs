//! One task body, resolved ([`BodyScope`]): its TDL statements in source order, flattened out of
//! the Rust control flow around them ([`Tdl`]), each at a [`Site`] (a position and the enclosing
//! loops); its spawns, `with` groups and loops, numbered in source order; the names a tag can
//! use; every named tag written in a constraint ([`Ref`]) and every `node!(tag)` in its Rust code
//! ([`NodeUse`]); `previous` at each TDL statement, as far as it is known statically
//! ([`Previous`]); and what generated code must track at run time: the local of each spawn,
//! group, labelled on-terminate task or bound tag that some tag names, the loops that count their
//! iterations, whether `previous` is used.

use std::collections::{BTreeMap, BTreeSet};

use proc_macro2::{Ident, Span};
use quote::format_ident;

use super::previous::{self, Previous};
pub use super::resolve::{node_macro, node_uses, state_macro, state_uses};
use crate::ast::{
    Bind, Block, Cond, Constraint, ConstraintKind, ConstraintStmt, Event, Fail, OnTerminate, Raise,
    ResourceStmt, SetState, Spawn, Tag, TagIndex, TagKind, Task, WithGroup,
};

/// A spawn of a body, numbered in source order from 0.
pub type SpawnId = usize;
/// A `with` group of a body, numbered in source order from 0.
pub type GroupId = usize;
/// A `for`, `while` or `loop` of a body, numbered in source order from 0.
pub type LoopId = usize;
/// A labelled `on terminate` task of a spawn, numbered in source order from 0.
pub type CleanupId = usize;

/// Where a TDL statement is: its position among the body's statements (Rust ones included, in
/// source order) and its enclosing loops, outermost first.
#[derive(Clone, Debug, Default)]
pub struct Site {
    /// Position in source order, from 1.
    pub position: usize,
    /// Enclosing loops, outermost first.
    pub loops: Vec<LoopId>,
    /// Inside a branch of an `if` or a `match`: it may not run.
    pub branch: bool,
}

/// One TDL statement of a body, in source order.
pub enum Tdl<'a> {
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
pub struct SpawnDef<'a> {
    /// The statement.
    pub spawn: &'a Spawn,
    /// Where it is.
    pub site: Site,
    /// The enclosing `with` groups, outermost first.
    pub groups: Vec<GroupId>,
    /// The local holding its node (a reservation, or a map by iteration in loops), when some tag
    /// names it.
    pub var: Option<Ident>,
    /// It has a `parent` constraint: its node is not a child of this body, so it cannot fulfil a
    /// reservation of the body; its local is bound when it is spawned (`Option<NodeId>`).
    pub late: bool,
}

/// A labelled `on terminate` task of a spawn: its labels name the node inserted if the spawned
/// node is terminated while running.
pub struct CleanupDef<'a> {
    /// The spawn it is attached to.
    pub spawn: SpawnId,
    /// Its place among the spawn's on-terminate tasks, from 0.
    pub index: usize,
    /// The constraint.
    pub on_terminate: &'a OnTerminate,
    /// The local holding the reservation it fulfils (a map by iteration in loops), when some tag
    /// names it.
    pub var: Option<Ident>,
}

/// A tag bound with `bind name = …;`: where its first `bind` is.
pub struct BoundDef {
    /// Where it is.
    pub site: Site,
    /// The local holding the node (`Option<NodeId>`), when some tag names it.
    pub var: Option<Ident>,
}

/// A `with` group.
pub struct GroupDef<'a> {
    /// The statement.
    pub group: &'a WithGroup,
    /// Where it is.
    pub site: Site,
    /// The local collecting its members, when some tag names it.
    pub var: Option<Ident>,
}

/// A node a tag names, in the terms every back end shares: what the code generator, `tdl
/// verify`'s loader and `tdl graph` each report they resolved a tag to, so that a test can hold
/// them to one answer.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum TagTarget {
    /// A spawn of the body (a group names each of its spawns).
    Spawn(SpawnId),
    /// The on-terminate task at this place among a spawn's.
    OnTerminate(SpawnId, usize),
    /// A node bound with `bind` under this name.
    Bound(String),
    /// The task whose body it is (`parent`, `this`).
    Parent,
    /// The node being constrained (`self`, `child`).
    This,
}

/// A tag written in a constraint, as one back end resolved it (`previous` is left out: the
/// generated code and the checker follow it at run time, the drawings statically).
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct ResolvedTag {
    /// The file, by its place among the program's files.
    pub file: usize,
    /// The line where the tag is written, from 1.
    pub line: usize,
    /// The column where it starts, from 0.
    pub column: usize,
    /// What it names (nothing, for a tag the back end cannot follow).
    pub targets: BTreeSet<TagTarget>,
}

impl ResolvedTag {
    /// `tag` of file `file`, resolved to `targets`.
    pub fn new(
        file: usize,
        tag: &Tag,
        targets: impl IntoIterator<Item = TagTarget>,
    ) -> ResolvedTag {
        let at = tag.span.start();
        ResolvedTag {
            file,
            line: at.line,
            column: at.column,
            targets: targets.into_iter().collect(),
        }
    }
}

/// What a name used as a tag stands for.
#[derive(Clone, Copy, Debug)]
pub enum Def<'a> {
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
pub struct Named<'a> {
    /// What the name stands for.
    pub def: Def<'a>,
    /// The label, or the spawned task's name.
    pub span: Span,
}

/// What a tag resolves to.
pub enum Resolution<'a> {
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
pub struct NodeUse {
    /// The tag written, or why the inside is not one.
    pub tag: Result<Tag, syn::Error>,
    /// Span of `node`.
    pub span: Span,
    /// Where: the statement it is written in.
    pub site: Site,
}

/// A named tag written in a constraint, at the position of its statement.
pub struct Ref<'a> {
    /// The tag.
    pub tag: &'a Tag,
    /// Its name.
    pub name: &'a Ident,
    /// The position of the spawn, group or constraint statement it is written in.
    pub position: usize,
}

/// One iteration index of a tag on a spawn inside loops.
pub enum Index<'a> {
    /// `[expr]`.
    Expr(&'a syn::Expr),
    /// `[.]`: the current iteration of this loop.
    Current(LoopId),
}

/// Why a tag's iteration indexes do not fit its spawn.
#[derive(Debug, PartialEq, Eq)]
pub enum IndexError {
    /// More indexes than loops around the spawn.
    TooMany,
    /// `[.]` where the loop it counts does not enclose the use.
    CurrentOutside,
}

/// What a constraint refers to besides the node it constrains.
pub enum Refers<'a> {
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
pub fn refers(kind: &ConstraintKind) -> Option<Refers<'_>> {
    match kind {
        ConstraintKind::Sequential { tag, .. } | ConstraintKind::Serial { tag } => {
            Some(tag.as_ref().map_or(Refers::Previous, Refers::WaitsOn))
        }
        ConstraintKind::Trigger { when, .. } => when.event().map(Refers::Event),
        _ => None,
    }
}

/// Whether any of `constraints` refers to `previous`.
pub fn uses_previous(constraints: &[Constraint]) -> bool {
    constraints
        .iter()
        .filter_map(|it| refers(&it.kind))
        .any(|it| it.is_previous())
}

/// A `state!(var)` in a body's Rust code.
pub struct StateUse {
    /// The variable named inside the parentheses, or why they do not hold one name.
    pub name: Result<Ident, syn::Error>,
    /// Span of `state`.
    pub span: Span,
}

/// One task body, resolved.
pub struct BodyScope<'a> {
    /// Its TDL statements in source order.
    pub stmts: Vec<Tdl<'a>>,
    /// Its spawns in source order.
    pub spawns: Vec<SpawnDef<'a>>,
    /// Its `with` groups in source order.
    pub groups: Vec<GroupDef<'a>>,
    /// Every named tag written in a constraint, in source order.
    pub refs: Vec<Ref<'a>>,
    /// Every `node!(tag)` in the body's Rust code, in source order.
    pub node_uses: Vec<NodeUse>,
    /// Its labelled on-terminate tasks, in source order.
    pub cleanups: Vec<CleanupDef<'a>>,
    /// Its bound tags, by name.
    pub bound: BTreeMap<String, BoundDef>,
    /// Labels already used: (the later label, the first one's span).
    pub duplicate_labels: Vec<(&'a Ident, Span)>,
    /// Whether some constraint refers to `previous`.
    pub uses_previous: bool,
    /// Its `lock`, `unlock`, `reserve` and `unreserve` statements, in source order.
    pub resource_stmts: Vec<&'a ResourceStmt>,
    /// The conditions of its constraints (`disable until`, `terminate when`, `activate when`,
    /// `skip if`, `invariant`, `pause while`), in source order.
    pub conditions: Vec<&'a Cond>,
    /// The state variables of `activate on change of VAR`, in source order.
    pub changes: Vec<&'a Ident>,
    /// Its `set` statements, in source order.
    pub sets: Vec<&'a SetState>,
    /// Its `raise` statements, in source order.
    pub raises_external: Vec<&'a Raise>,
    /// Every `state!(var)` in the body's Rust code, in source order.
    pub state_uses: Vec<StateUse>,
    /// `previous` at each spawn, group and constraint statement, by position.
    pub(super) previous: BTreeMap<usize, Previous>,
    /// Labels, the first of each.
    pub(super) labels: BTreeMap<String, Named<'a>>,
    /// The spawns of each task.
    pub(super) by_task: BTreeMap<String, Vec<SpawnId>>,
    pub(super) spawn_ids: BTreeMap<*const Spawn, SpawnId>,
    pub(super) group_ids: BTreeMap<*const WithGroup, GroupId>,
    pub(super) cleanup_ids: BTreeMap<*const OnTerminate, CleanupId>,
    /// Loops by their body.
    pub(super) loop_ids: BTreeMap<*const Block, LoopId>,
    /// Loops that count their iterations, for iteration-indexed tags.
    pub(super) counted: BTreeSet<LoopId>,
}

impl<'a> BodyScope<'a> {
    /// Resolves the body of `task`.
    pub fn new(task: &'a Task) -> BodyScope<'a> {
        let empty = BodyScope {
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
            conditions: Vec::new(),
            changes: Vec::new(),
            sets: Vec::new(),
            raises_external: Vec::new(),
            state_uses: Vec::new(),
            previous: BTreeMap::new(),
            labels: BTreeMap::new(),
            by_task: BTreeMap::new(),
            spawn_ids: BTreeMap::new(),
            group_ids: BTreeMap::new(),
            cleanup_ids: BTreeMap::new(),
            loop_ids: BTreeMap::new(),
            counted: BTreeSet::new(),
        };
        let mut scope = super::resolve::walk(task, empty);
        scope.assign_vars();
        scope.previous = previous::compute(&task.body, &scope);
        scope
    }

    /// `previous` at the spawn, group or constraint statement at `position` (see [`Site`]).
    pub fn previous_at(&self, position: usize) -> Option<&Previous> {
        self.previous.get(&position)
    }

    /// What `def` names, as [`TagTarget`]s.
    pub fn targets(&self, def: Def<'_>) -> Vec<TagTarget> {
        match def {
            Def::Spawn(id) => vec![TagTarget::Spawn(id)],
            Def::Group(id) => self.members(id).into_iter().map(TagTarget::Spawn).collect(),
            Def::OnTerminate(id) => self
                .cleanups
                .get(id)
                .map(|it| TagTarget::OnTerminate(it.spawn, it.index))
                .into_iter()
                .collect(),
            Def::Bound(bind) => vec![TagTarget::Bound(bind.name.to_string())],
        }
    }

    /// The spawns of group `id`, those of its nested groups included, in source order.
    pub fn members(&self, id: GroupId) -> Vec<SpawnId> {
        (0..self.spawns.len())
            .filter(|it| self.spawns[*it].groups.contains(&id))
            .collect()
    }

    /// What `tag` denotes.
    pub fn resolve(&self, tag: &Tag) -> Resolution<'a> {
        match &tag.kind {
            TagKind::Previous => Resolution::Previous,
            TagKind::Child => Resolution::This,
            TagKind::Parent => Resolution::Parent,
            TagKind::Named { name, .. } => self.lookup(&name.to_string()),
        }
    }

    /// What the name `name` denotes: a label, else a task spawned once.
    pub fn lookup(&self, name: &str) -> Resolution<'a> {
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
    pub fn named(&self, tag: &Tag) -> Option<Named<'a>> {
        match self.resolve(tag) {
            Resolution::Named(named) => Some(named),
            _ => None,
        }
    }

    /// Where a definition is (an on-terminate task: where its spawn is; a bound tag: its first
    /// `bind`).
    pub fn site(&self, def: Def<'a>) -> &Site {
        match def {
            Def::Spawn(id) => &self.spawns[id].site,
            Def::OnTerminate(id) => &self.spawns[self.cleanups[id].spawn].site,
            Def::Group(id) => &self.groups[id].site,
            Def::Bound(bind) => &self.bound[&bind.name.to_string()].site,
        }
    }

    /// The task a definition runs: a spawn's or an on-terminate task; none for a group or a
    /// bound tag.
    pub fn task_of(&self, def: Def<'a>) -> Option<&'a Ident> {
        match def {
            Def::Spawn(id) => Some(&self.spawns[id].spawn.task),
            Def::OnTerminate(id) => Some(&self.cleanups[id].on_terminate.task),
            Def::Group(_) | Def::Bound(_) => None,
        }
    }

    /// Whether the node of a definition is only known once a statement ran: a bound tag, or a
    /// spawn under another parent (its local is an `Option<NodeId>`, not a reservation).
    pub fn is_late(&self, def: Def<'a>) -> bool {
        match def {
            Def::Spawn(id) => self.spawns[id].late,
            Def::Bound(_) => true,
            Def::Group(_) | Def::OnTerminate(_) => false,
        }
    }

    /// The labelled on-terminate task `it`, if it has a label.
    pub fn cleanup(&self, it: &OnTerminate) -> Option<&CleanupDef<'a>> {
        let id = self.cleanup_ids.get(&std::ptr::from_ref(it))?;
        self.cleanups.get(*id)
    }

    /// The number of the labelled on-terminate task `it`.
    pub fn cleanup_id(&self, it: &OnTerminate) -> Option<CleanupId> {
        self.cleanup_ids.get(&std::ptr::from_ref(it)).copied()
    }

    /// The exceptions the body raises with `fail` ([`super::BARE_FAIL`] for a bare `fail;`).
    pub fn raises(&self) -> BTreeSet<String> {
        self.stmts
            .iter()
            .filter_map(|it| match it {
                Tdl::Fail(fail) => Some(
                    fail.exception
                        .as_ref()
                        .map_or_else(|| super::BARE_FAIL.to_owned(), ToString::to_string),
                ),
                _ => None,
            })
            .collect()
    }

    /// The spawn statement `spawn`.
    pub fn spawn_def(&self, spawn: &Spawn) -> Option<&SpawnDef<'a>> {
        let id = self.spawn_ids.get(&std::ptr::from_ref(spawn))?;
        self.spawns.get(*id)
    }

    /// The number of the spawn statement `spawn`.
    pub fn spawn_id(&self, spawn: &Spawn) -> Option<SpawnId> {
        self.spawn_ids.get(&std::ptr::from_ref(spawn)).copied()
    }

    /// The number of the group `group`.
    pub fn group_id(&self, group: &WithGroup) -> Option<GroupId> {
        self.group_ids.get(&std::ptr::from_ref(group)).copied()
    }

    /// The number of the loop whose body is `body`.
    pub fn loop_id(&self, body: &Block) -> Option<LoopId> {
        self.loop_ids.get(&std::ptr::from_ref(body)).copied()
    }

    /// Whether the loop counts its iterations (a tag names a spawn inside it).
    pub fn is_counted(&self, id: LoopId) -> bool {
        self.counted.contains(&id)
    }

    /// The iteration indexes of a tag naming spawn `id`, used inside the loops `site`: one per
    /// index written. A spawn outside loops takes none (more are reported by the index count).
    pub fn indexes<'t>(
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

    pub(super) fn add_label(&mut self, label: &'a Ident, def: Def<'a>) {
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
    pub(super) fn assign_vars(&mut self) {
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
