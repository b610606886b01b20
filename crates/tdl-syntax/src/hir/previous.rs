//! `previous` worked out statically: at each spawn, `with` group and constraint statement of a
//! body, which spawns `previous` may name there and, when the body's control flow does not
//! matter, which it surely names.
//!
//! `previous` is the entity executed just before: one spawn, or every spawn of the `with` group
//! run just before (docs/semantics.md, "Tags and forward references"). Generated code tracks it at
//! run time (`codegen/spawn.rs`); the static checks trust only what is known without running the
//! body ([`Previous::known`]), and the drawings show every spawn it may be ([`Previous::may`]):
//! after an `if` or a `match`, the last entity of each branch (or what came before, through a
//! branch that spawns nothing); at the top of a loop's body, what came before the loop or what
//! the body's last iteration ended with.

use std::collections::{BTreeMap, BTreeSet};

use super::body::{BodyScope, GroupId, SpawnId};
use super::visit::{Branch, Visit, walk_stmt};
use crate::ast::{Block, Stmt};

/// `previous` at one TDL statement of a body.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Previous {
    /// Every spawn it may name, in source order: those the branches and iterations that may run
    /// before the statement leave as the entity just before it.
    pub may: Vec<SpawnId>,
    /// What it names whatever runs: `Some(spawns)` (empty when nothing was spawned before, or the
    /// group just before spawned nothing), or `None` when that depends on which branches or
    /// iterations ran (after an `if`, a `match` or a loop that spawns, and inside a loop).
    pub known: Option<Vec<SpawnId>>,
}

/// `previous` at every spawn, `with` group and constraint statement of `body`, by the
/// statement's position (as [`super::Site::position`] counts it).
pub(super) fn compute(body: &Block, scope: &BodyScope<'_>) -> BTreeMap<usize, Previous> {
    let mut members: Vec<Vec<SpawnId>> = vec![Vec::new(); scope.groups.len()];
    for (id, spawn) in scope.spawns.iter().enumerate() {
        for &group in &spawn.groups {
            if let Some(list) = members.get_mut(group) {
                list.push(id);
            }
        }
    }
    let mut walk = Walk {
        scope,
        members,
        now: State {
            may: BTreeSet::new(),
            known: Some(Vec::new()),
            entities: 0,
            position: 0,
        },
        record: true,
        out: BTreeMap::new(),
    };
    walk.block(body);
    walk.out
}

/// Where the walk is.
#[derive(Clone)]
struct State {
    may: BTreeSet<SpawnId>,
    known: Option<Vec<SpawnId>>,
    /// Spawns and groups met so far: what changes `previous`.
    entities: usize,
    position: usize,
}

struct Walk<'s, 'a> {
    scope: &'s BodyScope<'a>,
    /// The spawns of each group, nested groups' included.
    members: Vec<Vec<SpawnId>>,
    now: State,
    /// False while a loop's body is walked to find what its iterations carry.
    record: bool,
    out: BTreeMap<usize, Previous>,
}

impl Walk<'_, '_> {
    fn here(&mut self) {
        if self.record {
            let previous = Previous {
                may: self.now.may.iter().copied().collect(),
                known: self.now.known.clone(),
            };
            self.out.insert(self.now.position, previous);
        }
    }

    fn became(&mut self, spawns: Vec<SpawnId>) {
        self.now.entities += 1;
        self.now.may = spawns.iter().copied().collect();
        self.now.known = Some(spawns);
    }

    fn group_members(&self, id: GroupId) -> Vec<SpawnId> {
        self.members.get(id).cloned().unwrap_or_default()
    }

    /// After branches or a loop: `may` is `ends`; `known` stays what it was before only if
    /// nothing in between spawned or ran a group.
    fn joined(&mut self, before: &State, ends: BTreeSet<SpawnId>) {
        self.now.may = ends;
        self.now.known = if self.now.entities == before.entities {
            before.known.clone()
        } else {
            None
        };
    }
}

impl<'a> Visit<'a> for Walk<'_, '_> {
    fn stmt(&mut self, stmt: &'a Stmt) {
        self.now.position += 1;
        match stmt {
            Stmt::Spawn(spawn) => {
                self.here();
                if let Some(id) = self.scope.spawn_id(spawn) {
                    self.became(vec![id]);
                }
            }
            Stmt::With(group) => {
                self.here();
                self.block(&group.body);
                if let Some(id) = self.scope.group_id(group) {
                    let members = self.group_members(id);
                    self.became(members);
                }
            }
            Stmt::Constrain(_) => self.here(),
            _ => walk_stmt(self, stmt),
        }
    }

    /// Each branch starts from what came before; after them, `previous` may be where any ended,
    /// or what came before when no branch surely runs.
    fn branches(&mut self, branches: Vec<Branch<'a>>, exhaustive: bool) {
        let before = self.now.clone();
        let mut ends = BTreeSet::new();
        for branch in branches {
            self.now.may = before.may.clone();
            self.now.known = before.known.clone();
            self.block(branch.block);
            ends.extend(self.now.may.iter().copied());
        }
        if !exhaustive {
            ends.extend(before.may.iter().copied());
        }
        self.joined(&before, ends);
    }

    fn looped(&mut self, body: &'a Block) {
        let before = self.now.clone();
        // What an iteration may start from: what came before the loop, or what an iteration
        // ended with; walked without recording until it no longer grows.
        let mut start = before.may.clone();
        let record = std::mem::replace(&mut self.record, false);
        loop {
            self.now = State {
                may: start.clone(),
                known: None,
                ..before.clone()
            };
            self.block(body);
            let next: BTreeSet<SpawnId> = before.may.union(&self.now.may).copied().collect();
            if next == start {
                break;
            }
            start = next;
        }
        self.record = record;
        self.now = State {
            may: start,
            known: None,
            ..before.clone()
        };
        self.block(body);
        let ends: BTreeSet<SpawnId> = before.may.union(&self.now.may).copied().collect();
        self.joined(&before, ends);
    }
}
