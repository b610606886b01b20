//! The waits of one task body, as the checks for circular constraints (`cycles.rs`) and for
//! waits that cannot end (`waits.rs`) see them: every enablement constraint with the node it
//! gates and the event it waits for, every `wait` of the body, and, for each spawn, whether it
//! surely runs.
//!
//! The model follows docs/semantics.md. An event is a facet reaching a stage ("Events"); an
//! enablement constraint holds a facet of its node disabled until an event ("Constraints"); and a
//! disabled facet keeps some of its node's own events from ever happening ("Facets and states"):
//! [`blocked`] says which, for the node's task kind. A spawn inside an `if`, a `match` or a loop
//! may not run, and its tag is then a dead reference whose waits are void ("Tags and forward
//! references"), so the checks only trust what runs unconditionally, and `previous` only where it
//! is known statically (the code generator tracks it at run time, `codegen/spawn.rs`).

use proc_macro2::Span;

use crate::ast::{
    Block, Constraint, ConstraintKind, Event, Facet, Point, Stmt, Tag, TagKind, Task,
    TaskConstraintKind, TaskKind, Then, When,
};
use crate::hir::{BodyScope, Branch, Def, FileScope, GroupId, SpawnId, Visit, walk_stmt};

/// How far a facet got: the stages of `enabled`, `active` and `completed` (an outcome is the
/// execution's completion).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(super) enum Stage {
    Enabled,
    Active,
    Completed,
}

/// One event of a node: its facet reaching a stage.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(super) struct Ev {
    pub(super) facet: Facet,
    pub(super) stage: Stage,
}

impl Ev {
    /// The number of distinct events of a node.
    pub(super) const COUNT: usize = 9;

    const fn new(facet: Facet, stage: Stage) -> Ev {
        Ev { facet, stage }
    }

    /// The event a TDL event names: `enabled`/`active` default to the handling, `completed` to
    /// the execution; an outcome is the execution's completion (docs/semantics.md, "Events",
    /// "Outcomes").
    pub(super) fn of(event: &Event) -> Ev {
        let stage = match event.point {
            Point::Enabled => Stage::Enabled,
            Point::Active => Stage::Active,
            _ => Stage::Completed,
        };
        let facet = match (event.facet, event.point) {
            (_, point) if point.is_outcome() => Facet::Execution,
            (Some(facet), _) => facet,
            (None, Point::Completed) => Facet::Execution,
            (None, _) => Facet::Handling,
        };
        Ev::new(facet, stage)
    }

    /// A number in `0..COUNT`.
    pub(super) fn index(self) -> usize {
        let facet = match self.facet {
            Facet::Handling => 0,
            Facet::Expansion => 1,
            Facet::Execution => 2,
        };
        let stage = match self.stage {
            Stage::Enabled => 0,
            Stage::Active => 1,
            Stage::Completed => 2,
        };
        facet * 3 + stage
    }

    /// `execution completed`, as TDL writes it.
    pub(super) fn text(self) -> String {
        let stage = match self.stage {
            Stage::Enabled => "enabled",
            Stage::Active => "active",
            Stage::Completed => "completed",
        };
        format!("{} {stage}", self.facet.as_str())
    }
}

const H_EN: Ev = Ev::new(Facet::Handling, Stage::Enabled);
const H_ACT: Ev = Ev::new(Facet::Handling, Stage::Active);
const H_DONE: Ev = Ev::new(Facet::Handling, Stage::Completed);
const X_EN: Ev = Ev::new(Facet::Expansion, Stage::Enabled);
const X_DONE: Ev = Ev::new(Facet::Expansion, Stage::Completed);
const E_EN: Ev = Ev::new(Facet::Execution, Stage::Enabled);
pub(super) const E_DONE: Ev = Ev::new(Facet::Execution, Stage::Completed);

/// What kind of node a spawn makes, as far as the facets go.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Shape {
    /// A goal (or a handler): its handling is part of its expansion.
    GoalLike,
    /// A command or a monitor: its expansion is completed from the start, its handling is part
    /// of its execution.
    CommandLike,
    /// A task the program does not define (written in Rust): either.
    Unknown,
}

impl Shape {
    pub(super) fn of(kind: Option<TaskKind>) -> Shape {
        match kind {
            Some(TaskKind::Goal | TaskKind::Handler) => Shape::GoalLike,
            Some(TaskKind::Command | TaskKind::Monitor) => Shape::CommandLike,
            None => Shape::Unknown,
        }
    }
}

/// The node's own events that cannot happen while `gate` stays disabled (docs/semantics.md,
/// "Facets and states"): the facet's own enabling and everything after, and whatever the
/// structural conditions make wait for it. `active` points reached through the subtree are left
/// out, and for a task of unknown kind only what holds for both kinds counts, so a wait is never
/// claimed where it might not be one. An expansion constraint on a command-like node is void.
pub(super) fn blocked(shape: Shape, gate: Facet, delay_expansion: bool) -> &'static [Ev] {
    const ALL_GOAL: &[Ev] = &[H_EN, H_ACT, H_DONE, X_EN, X_DONE, E_EN, E_DONE];
    match (shape, gate) {
        (Shape::GoalLike, Facet::Handling) => &[H_EN, H_ACT, H_DONE, X_DONE, E_DONE],
        (Shape::GoalLike, Facet::Expansion) => &[H_EN, H_ACT, H_DONE, X_EN, X_DONE, E_DONE],
        // `delay expansion`: the expansion, and with it the handling, waits for the execution.
        (Shape::GoalLike, Facet::Execution) if delay_expansion => ALL_GOAL,
        (Shape::GoalLike, Facet::Execution) => &[E_EN, E_DONE],
        (Shape::CommandLike | Shape::Unknown, Facet::Handling) => &[H_EN, H_ACT, H_DONE, E_DONE],
        (Shape::CommandLike | Shape::Unknown, Facet::Expansion) => &[],
        (Shape::CommandLike, Facet::Execution) => &[H_EN, H_ACT, H_DONE, E_EN, E_DONE],
        (Shape::Unknown, Facet::Execution) if delay_expansion => {
            &[H_EN, H_ACT, H_DONE, E_EN, E_DONE]
        }
        (Shape::Unknown, Facet::Execution) => &[E_EN, E_DONE],
    }
}

/// Where a statement is with respect to control flow.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Cond {
    /// Inside a branch of an `if` or a `match`.
    pub(super) branch: bool,
    /// Inside a loop.
    pub(super) looped: bool,
}

impl Cond {
    /// It surely runs (when the body gets that far).
    pub(super) fn sure(self) -> bool {
        !self.branch && !self.looped
    }
}

/// `previous` at a point of the body, as far as it is known statically.
#[derive(Clone, Debug)]
pub(super) enum Prev {
    /// Nothing was spawned before: a constraint on it is void.
    Nothing,
    /// These spawns (one, or every spawn of the group just finished).
    Known(Vec<SpawnId>),
    /// It depends on which branches or iterations ran.
    Unknown,
}

/// What a constraint is applied to.
#[derive(Clone, Copy, Debug)]
pub(super) enum Target<'a> {
    /// A spawn's own constraint, or one of its `with` groups'.
    Spawn(SpawnId),
    /// A constraint statement's tag.
    Tag(&'a Tag),
}

/// A constraint as it is applied.
pub(super) struct Applied<'a> {
    pub(super) target: Target<'a>,
    pub(super) constraint: &'a Constraint,
    /// `previous` for this constraint.
    pub(super) prev: Prev,
    /// The position of the statement (the spawn, or the constraint statement).
    pub(super) position: usize,
    pub(super) cond: Cond,
}

/// A wait of the body: `spawn … with wait` (or `outcome`, or a waited value), or `X wait;`.
pub(super) struct WaitPoint<'a> {
    pub(super) target: Target<'a>,
    pub(super) prev: Prev,
    pub(super) position: usize,
    pub(super) cond: Cond,
    /// The `wait` (or `outcome`) constraint.
    pub(super) span: Span,
}

/// A spawn of the body.
pub(super) struct SpawnFlow {
    pub(super) position: usize,
    pub(super) cond: Cond,
    /// What kind of node it makes.
    pub(super) shape: Shape,
    /// `delay expansion` on it, on one of its groups or on its task.
    pub(super) delay_expansion: bool,
    /// It goes under another node (`parent EXPR`): not a child of this body.
    pub(super) late: bool,
}

/// A wait of a node, read from one enablement constraint: the facets it holds disabled, the tag
/// it waits for (`None`: `previous`) and the event.
pub(super) struct Gate<'a> {
    pub(super) facets: &'static [Facet],
    pub(super) tag: Option<&'a Tag>,
    pub(super) event: Ev,
}

/// The wait a constraint puts on its node, if it is an enablement constraint on another node's
/// event: `sequential`, `serial`, `disable … until EVENT`, `disable … for D after EVENT`.
/// Termination and activation constraints hold nothing (docs/semantics.md, "Termination").
pub(super) fn gate(kind: &ConstraintKind) -> Option<Gate<'_>> {
    const HANDLING: &[Facet] = &[Facet::Handling];
    const EXPANSION: &[Facet] = &[Facet::Expansion];
    const EXECUTION: &[Facet] = &[Facet::Execution];
    let one = |facet: Facet| match facet {
        Facet::Handling => HANDLING,
        Facet::Expansion => EXPANSION,
        Facet::Execution => EXECUTION,
    };
    match kind {
        ConstraintKind::Sequential { facet, tag } => Some(Gate {
            facets: one(*facet),
            tag: tag.as_ref(),
            event: Ev::new(*facet, Stage::Completed),
        }),
        ConstraintKind::Serial { tag } => Some(Gate {
            facets: &[Facet::Expansion, Facet::Execution],
            tag: tag.as_ref(),
            event: E_DONE,
        }),
        ConstraintKind::Trigger {
            when: When::Event(event) | When::After(_, event),
            then: Then::Enable(facet),
        } => Some(Gate {
            facets: one(facet.unwrap_or(Facet::Handling)),
            tag: Some(&event.tag),
            event: Ev::of(event),
        }),
        _ => None,
    }
}

/// A node a wait can be on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Node {
    /// A spawn of the body.
    Spawn(SpawnId),
    /// The node running the body (`parent`, `this`).
    Parent,
}

/// The waits of one body.
pub(super) struct Flow<'a> {
    pub(super) task: &'a Task,
    pub(super) spawns: Vec<SpawnFlow>,
    pub(super) applied: Vec<Applied<'a>>,
    pub(super) waits: Vec<WaitPoint<'a>>,
    /// Every spawn of each `with` group, nested groups included.
    pub(super) members: Vec<Vec<SpawnId>>,
}

impl<'a> Flow<'a> {
    pub(super) fn new(file: &FileScope<'a>, task: &'a Task, scope: &BodyScope<'a>) -> Flow<'a> {
        let mut walk = Walk {
            file,
            scope,
            flow: Flow {
                task,
                spawns: Vec::new(),
                applied: Vec::new(),
                waits: Vec::new(),
                members: vec![Vec::new(); scope.groups.len()],
            },
            position: 0,
            cond: Cond::default(),
            frames: Vec::new(),
        };
        walk.block(&task.body);
        walk.flow
    }

    /// The spawns a tag names, for a wait on it: `None` when that is not known statically (a
    /// bound tag, an on-terminate label, `previous` after branches, `self`).
    pub(super) fn nodes(&self, scope: &BodyScope<'a>, tag: &Tag, prev: &Prev) -> Option<Vec<Node>> {
        match &tag.kind {
            TagKind::Previous => match prev {
                Prev::Nothing => Some(Vec::new()),
                Prev::Known(ids) => Some(ids.iter().map(|id| Node::Spawn(*id)).collect()),
                Prev::Unknown => None,
            },
            TagKind::Parent => Some(vec![Node::Parent]),
            TagKind::Child => None,
            TagKind::Named { indexes, .. } => match scope.named(tag)?.def {
                // A tag with fewer indexes than loops names the entries so far: none is a
                // reservation of a later spawn, and which ones it names is not known here.
                Def::Spawn(id) if indexes.len() < scope.spawns.get(id)?.site.loops.len() => None,
                Def::Spawn(id) => Some(vec![Node::Spawn(id)]),
                Def::Group(id) => Some(
                    self.members
                        .get(id)?
                        .iter()
                        .map(|it| Node::Spawn(*it))
                        .collect(),
                ),
                Def::OnTerminate(_) | Def::Bound(_) => None,
            },
        }
    }

    /// The spawns a constraint applies to (`None` as for [`Flow::nodes`]).
    pub(super) fn targets(
        &self,
        scope: &BodyScope<'a>,
        target: Target<'a>,
        prev: &Prev,
    ) -> Option<Vec<SpawnId>> {
        match target {
            Target::Spawn(id) => Some(vec![id]),
            Target::Tag(tag) => {
                let nodes = self.nodes(scope, tag, prev)?;
                Some(
                    nodes
                        .into_iter()
                        .filter_map(|it| match it {
                            Node::Spawn(id) => Some(id),
                            Node::Parent => None,
                        })
                        .collect(),
                )
            }
        }
    }

    /// How to name a spawn in a message: its first label, or its task.
    pub(super) fn name(scope: &BodyScope<'a>, id: SpawnId) -> String {
        scope.spawns.get(id).map_or_else(String::new, |def| {
            def.spawn
                .labels
                .first()
                .unwrap_or(&def.spawn.task)
                .to_string()
        })
    }

    /// The span naming a spawn: its first label, or its task.
    pub(super) fn span(scope: &BodyScope<'a>, id: SpawnId) -> Option<Span> {
        let def = scope.spawns.get(id)?;
        Some(def.spawn.labels.first().unwrap_or(&def.spawn.task).span())
    }
}

/// A `with` group being walked.
struct Frame<'a> {
    group: GroupId,
    constraints: &'a [Constraint],
    /// The position of the group's statement.
    position: usize,
}

impl Prev {
    /// `previous` at the statement at `position`, as the resolver found it.
    fn at(scope: &BodyScope<'_>, position: usize) -> Prev {
        match scope.previous_at(position).map(|it| &it.known) {
            Some(Some(ids)) if ids.is_empty() => Prev::Nothing,
            Some(Some(ids)) => Prev::Known(ids.clone()),
            Some(None) | None => Prev::Unknown,
        }
    }
}

/// The walk that builds a [`Flow`]; positions are counted as in `hir/resolve.rs`.
struct Walk<'s, 'a> {
    file: &'s FileScope<'a>,
    scope: &'s BodyScope<'a>,
    flow: Flow<'a>,
    position: usize,
    cond: Cond,
    frames: Vec<Frame<'a>>,
}

impl<'a> Visit<'a> for Walk<'_, 'a> {
    fn stmt(&mut self, stmt: &'a Stmt) {
        self.position += 1;
        match stmt {
            Stmt::Spawn(spawn) => {
                // Spawns are numbered in source order by `hir/resolve.rs`, as they are met here.
                let Some(id) = self.scope.spawn_id(spawn) else {
                    return;
                };
                if self.flow.spawns.len() != id {
                    return;
                }
                let mut delay_expansion = false;
                let mut wait = None;
                // `previous` for a spawn's own constraints and its innermost group's is the
                // entity before it; for an outer group's, the entity before the group nested in
                // it (TDL paper, "with/do"; `codegen/spawn.rs`).
                let prev = Prev::at(self.scope, self.position);
                let mut lists: Vec<(&'a [Constraint], Prev)> = self
                    .frames
                    .iter()
                    .enumerate()
                    .map(|(k, f)| match self.frames.get(k + 1) {
                        Some(inner) => (f.constraints, Prev::at(self.scope, inner.position)),
                        None => (f.constraints, prev.clone()),
                    })
                    .collect();
                lists.push((&spawn.constraints, prev.clone()));
                for (list, prev) in lists {
                    for constraint in list {
                        match constraint.kind {
                            ConstraintKind::DelayExpansion => delay_expansion = true,
                            ConstraintKind::Wait | ConstraintKind::Outcome => {
                                wait = Some(constraint.span);
                            }
                            _ => {}
                        }
                        self.flow.applied.push(Applied {
                            target: Target::Spawn(id),
                            constraint,
                            prev: prev.clone(),
                            position: self.position,
                            cond: self.cond,
                        });
                    }
                }
                let task = self.file.task(&spawn.task.to_string());
                delay_expansion |= task.is_some_and(|t| {
                    t.constraints
                        .iter()
                        .any(|c| matches!(c.kind, TaskConstraintKind::DelayExpansion))
                });
                let late = spawn
                    .constraints
                    .iter()
                    .any(|c| matches!(c.kind, ConstraintKind::Parent(_)));
                self.flow.spawns.push(SpawnFlow {
                    position: self.position,
                    cond: self.cond,
                    shape: Shape::of(task.map(|t| t.kind)),
                    delay_expansion,
                    late,
                });
                if let Some(span) = wait {
                    self.flow.waits.push(WaitPoint {
                        target: Target::Spawn(id),
                        prev,
                        position: self.position,
                        cond: self.cond,
                        span,
                    });
                }
                for frame in &self.frames {
                    if let Some(members) = self.flow.members.get_mut(frame.group) {
                        members.push(id);
                    }
                }
            }
            Stmt::With(group) => {
                let Some(id) = self.scope.group_id(group) else {
                    return;
                };
                self.frames.push(Frame {
                    group: id,
                    constraints: &group.constraints,
                    position: self.position,
                });
                self.block(&group.body);
                self.frames.pop();
            }
            Stmt::Constrain(it) => {
                let target = Target::Tag(&it.tag);
                let prev = Prev::at(self.scope, self.position);
                if matches!(it.constraint.kind, ConstraintKind::Wait) {
                    self.flow.waits.push(WaitPoint {
                        target,
                        prev: prev.clone(),
                        position: self.position,
                        cond: self.cond,
                        span: it.constraint.span,
                    });
                }
                self.flow.applied.push(Applied {
                    target,
                    constraint: &it.constraint,
                    prev,
                    position: self.position,
                    cond: self.cond,
                });
            }
            _ => walk_stmt(self, stmt),
        }
    }

    /// The branches of an `if` or a `match`: what runs there may not run.
    fn branches(&mut self, branches: Vec<Branch<'a>>, _: bool) {
        let outer = self.cond;
        self.cond.branch = true;
        for branch in branches {
            self.block(branch.block);
        }
        self.cond = outer;
    }

    fn looped(&mut self, body: &'a Block) {
        let outer = self.cond;
        self.cond.looped = true;
        self.block(body);
        self.cond = outer;
    }
}
