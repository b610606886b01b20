//! Constraints lowered as `tdl-syntax`'s `codegen/lower.rs` lowers them: the nodes a tag
//! denotes at run time ([`Nodes`]: one node, an entity whose members are known only then, or
//! none), each constraint as a [`Low`] waiting for its node, triggers on whole entities, and the
//! counts, durations, resources and priorities constraints carry.

use std::sync::Arc;
use std::time::Duration;

use proc_macro2::Span;
use tdl_syntax::ast::{
    Constraint, ConstraintKind, Count, ExternalName, Facet, Point, Priority, RelTime,
    ResourceAmount, Tag, TagKind, Then, When,
};
use tdl_syntax::hir::{Def, Index, LoopId, Named, Resolution, SpawnId};

use super::Lower;
use crate::ir::{
    CountEx, DurEx, EntityEx, EventEx, Ex, KeyEx, Low, Lowered, NameEx, NodeEx, Nodes, ResRef,
    WhenEx,
};
use crate::value::Value;

/// A facet of the syntax tree as the runtime's.
pub(crate) fn facet(f: Facet) -> tdl::Facet {
    match f {
        Facet::Handling => tdl::Facet::Handling,
        Facet::Expansion => tdl::Facet::Expansion,
        Facet::Execution => tdl::Facet::Execution,
    }
}

fn then(t: Then) -> tdl::Then {
    match t {
        Then::Enable(f) => tdl::Then::Enable(facet(f.unwrap_or(Facet::Handling))),
        Then::Terminate => tdl::Then::Terminate,
        Then::Activate => tdl::Then::Activate,
        Then::Skip => tdl::Then::Skip,
        Then::Invariant => tdl::Then::Invariant,
        Then::Pause => tdl::Then::Pause,
    }
}

fn point(p: Point) -> tdl::Point {
    match p {
        Point::Enabled => tdl::Point::Enabled,
        Point::Active => tdl::Point::Active,
        Point::Completed | Point::Succeeded | Point::Failed | Point::Terminated => {
            tdl::Point::Completed
        }
    }
}

fn outcome(p: Point) -> Option<tdl::Outcome> {
    match p {
        Point::Succeeded => Some(tdl::Outcome::Succeeded),
        Point::Failed => Some(tdl::Outcome::Failed),
        Point::Terminated => Some(tdl::Outcome::Terminated),
        Point::Enabled | Point::Active | Point::Completed => None,
    }
}

impl Lower<'_, '_> {
    pub(crate) fn count(&mut self, c: &Count, span: Span) -> CountEx {
        match c {
            Count::Const(n) => match u32::try_from(*n) {
                Ok(n) => CountEx::Const(n),
                Err(_) => {
                    self.error(
                        span,
                        format!("the count {n} is too large"),
                        "counts are `u32`: at most 4294967295".into(),
                    );
                    CountEx::Const(u32::MAX)
                }
            },
            Count::Expr(e) => CountEx::Expr(self.expr(e)),
        }
    }

    pub(crate) fn duration(&mut self, t: &RelTime) -> DurEx {
        match t {
            RelTime::Nanos(n) => DurEx::Fixed(Duration::from_nanos(*n)),
            RelTime::Seconds(e) => DurEx::Secs(self.expr(e)),
        }
    }

    /// A resource by its declaration when the program declares it, else by its name.
    pub(crate) fn resource(&mut self, name: &proc_macro2::Ident) -> ResRef {
        let text = name.to_string();
        match self.file.resource(&text) {
            Some(decl) => ResRef::Declared(
                crate::program::intern(&text),
                decl.capacity.base10_parse::<u32>().unwrap_or(0),
                decl.pending
                    .as_ref()
                    .and_then(|p| p.base10_parse::<u32>().ok()),
            ),
            None => ResRef::Named(crate::program::intern(&text)),
        }
    }

    pub(crate) fn uses(&mut self, it: &ResourceAmount) -> (ResRef, CountEx) {
        let r = self.resource(&it.name);
        let n = match &it.amount {
            Some(n) => self.count(n, it.span),
            None => CountEx::Const(1),
        };
        (r, n)
    }

    pub(crate) fn priority(&mut self, p: &Priority) -> Ex {
        match p {
            Priority::Const(n) => Ex::Lit(Value::Int(*n)),
            Priority::Expr(e) => self.expr(e),
        }
    }

    pub(crate) fn name_ex(&mut self, n: &ExternalName) -> NameEx {
        match n {
            ExternalName::Lit(lit) => NameEx::Lit(Arc::from(lit.value().as_str())),
            ExternalName::Expr(e) => NameEx::Expr(self.expr(e)),
        }
    }

    /// The nodes `tag` denotes; `prev` names the TDL slot holding `previous` at this site.
    pub(crate) fn nodes(&mut self, tag: &Tag, prev: &str) -> Nodes {
        let indexes = match &tag.kind {
            TagKind::Named { indexes, .. } => indexes.as_slice(),
            _ => &[],
        };
        match self.scope.resolve(tag) {
            Resolution::Previous => Nodes::Entity(EntityEx::Prev(self.tdl_slot(prev))),
            Resolution::This => Nodes::One(NodeEx::This),
            Resolution::Parent => Nodes::One(NodeEx::Parent),
            Resolution::Named(Named { def, .. }) => {
                let loops = self.loops.clone();
                self.def_nodes(def, indexes, &loops)
            }
            Resolution::Unknown | Resolution::Ambiguous(_) => Nodes::None,
        }
    }

    fn var_slot(&mut self, var: Option<&proc_macro2::Ident>) -> Option<u32> {
        var.map(|v| self.tdl_slot(&v.to_string()))
    }

    /// The nodes of a definition named with `indexes` inside the loops `site`.
    fn def_nodes(
        &mut self,
        def: Def<'_>,
        indexes: &[tdl_syntax::ast::TagIndex],
        site: &[LoopId],
    ) -> Nodes {
        let scope = self.scope;
        match def {
            Def::Spawn(id) if scope.spawns[id].late => match &scope.spawns[id].var {
                Some(var) if scope.spawns[id].site.loops.is_empty() => {
                    Nodes::Entity(EntityEx::Held(self.tdl_slot(&var.to_string())))
                }
                _ => Nodes::None,
            },
            Def::Bound(bind) => match &scope.bound[&bind.name.to_string()].var {
                Some(var) => Nodes::Entity(EntityEx::Held(self.tdl_slot(&var.to_string()))),
                None => Nodes::None,
            },
            Def::Spawn(id) => {
                let var = self.var_slot(scope.spawns[id].var.as_ref());
                self.spawn_nodes(id, var, indexes, site)
            }
            Def::OnTerminate(id) => {
                let cleanup = &scope.cleanups[id];
                let var = self.var_slot(cleanup.var.as_ref());
                self.spawn_nodes(cleanup.spawn, var, indexes, site)
            }
            Def::Group(id) => match &scope.groups[id].var {
                Some(var) => Nodes::Entity(EntityEx::Held(self.tdl_slot(&var.to_string()))),
                None => Nodes::None,
            },
        }
    }

    /// The nodes held in the TDL slot `var` (reservations of spawn `id`, or of an on-terminate
    /// task of it) with iteration indexes `indexes`, inside the loops `site`.
    fn spawn_nodes(
        &mut self,
        id: SpawnId,
        var: Option<u32>,
        indexes: &[tdl_syntax::ast::TagIndex],
        site: &[LoopId],
    ) -> Nodes {
        let scope = self.scope;
        let info = &scope.spawns[id];
        let Some(var) = var else {
            return Nodes::None;
        };
        let depth = info.site.loops.len();
        if depth == 0 {
            return Nodes::One(NodeEx::Reserved(var));
        }
        let Ok(indexes) = scope.indexes(id, indexes, site) else {
            return Nodes::None;
        };
        let keys: Vec<KeyEx> = indexes
            .iter()
            .map(|index| match index {
                Index::Expr(e) => KeyEx::Expr(self.expr(e)),
                Index::Current(loop_id) => {
                    KeyEx::Current(self.tdl_slot(&format!("tdl_i_{loop_id}")))
                }
            })
            .collect();
        let name = crate::program::intern(&info.spawn.task.to_string());
        if keys.len() == depth {
            return Nodes::One(NodeEx::Slot(var, keys, name));
        }
        Nodes::Entity(EntityEx::Prefix(var, keys))
    }

    /// The nodes of a `sequential`/`serial` tag, `previous` when none is written.
    fn nodes_or_previous(&mut self, tag: Option<&Tag>, prev: &str) -> Nodes {
        match tag {
            Some(tag) => self.nodes(tag, prev),
            None => Nodes::Entity(EntityEx::Prev(self.tdl_slot(prev))),
        }
    }

    /// The lowered form of `c` with the nodes it names; `None` when it is handled elsewhere.
    pub(crate) fn lower_constraint(&mut self, c: &Constraint, prev: &str) -> Option<Lowered> {
        let each = |nodes, low| {
            Some(Lowered::Each {
                nodes,
                low,
                empty: None,
            })
        };
        match &c.kind {
            ConstraintKind::ExpandFirst => each(Nodes::One(NodeEx::Nothing), Low::ExpandFirst),
            ConstraintKind::DelayExpansion => {
                each(Nodes::One(NodeEx::Nothing), Low::DelayExpansion)
            }
            ConstraintKind::Sequential { facet: f, tag } => {
                let nodes = self.nodes_or_previous(tag.as_ref(), prev);
                each(nodes, Low::Sequential(facet(*f)))
            }
            ConstraintKind::Serial { tag } => {
                let nodes = self.nodes_or_previous(tag.as_ref(), prev);
                each(nodes, Low::Serial)
            }
            ConstraintKind::Trigger { when, then: t } => self.lower_trigger(when, *t, prev, c.span),
            _ => None,
        }
    }

    fn when_ex(&mut self, when: &When) -> WhenEx {
        let ev = |e: &tdl_syntax::ast::Event| EventEx {
            facet: e.facet.map(facet),
            point: point(e.point),
            outcome: outcome(e.point),
        };
        match when {
            When::Now => WhenEx::Now,
            When::At(t) => {
                #[allow(
                    clippy::cast_precision_loss,
                    reason = "a time of day fits an f64 exactly enough"
                )]
                let secs = t.nanos_since_midnight() as f64 / 1e9;
                WhenEx::At(secs)
            }
            When::In(d) => WhenEx::In(self.duration(d)),
            When::Event(e) => WhenEx::Event(ev(e)),
            When::After(d, e) => WhenEx::After(self.duration(d), ev(e)),
            When::External(n) => WhenEx::External(self.name_ex(n)),
            When::Condition(cond) => {
                let vars = cond
                    .vars()
                    .into_iter()
                    .filter_map(|v| {
                        self.names
                            .states
                            .get(&v.to_string())
                            .map(|(var, _)| var.clone())
                    })
                    .collect();
                WhenEx::Condition(vars, cond.to_expr())
            }
            When::Changed(v) => match self.names.states.get(&v.to_string()) {
                Some((var, _)) => WhenEx::Changed(var.clone()),
                None => WhenEx::Now,
            },
        }
    }

    /// A trigger: per node, or, naming an entity, per member (enablement) or once for the
    /// whole entity (`terminate`, `activate`).
    fn lower_trigger(&mut self, when: &When, t: Then, prev: &str, span: Span) -> Option<Lowered> {
        if let When::Condition(_) | When::Changed(_) = when {
            let w = self.when_ex(when);
            return Some(Lowered::Each {
                nodes: Nodes::One(NodeEx::Nothing),
                low: Low::Trigger(w, then(t)),
                empty: None,
            });
        }
        let nodes = match when.event() {
            Some(ev) => self.nodes(&ev.tag, prev),
            None => Nodes::One(NodeEx::Nothing),
        };
        let (delay, event) = match when {
            When::Event(ev) => (None, Some(ev)),
            When::After(d, ev) => (Some(d), Some(ev)),
            _ => (None, None),
        };
        if let (Nodes::Entity(members), Some(ev), Then::Terminate | Then::Activate) =
            (&nodes, event, t)
        {
            if ev.point.is_outcome() {
                self.error(
                    span,
                    format!(
                        "`{}` on a group, `previous` or a tag bound at run time is not supported with `terminate` or `activate` yet: name one task",
                        ev.point.as_str()
                    ),
                    "the compiled path refuses it too".into(),
                );
                return None;
            }
            let f = facet(ev.facet.unwrap_or(match ev.point {
                Point::Enabled | Point::Active => Facet::Handling,
                _ => Facet::Execution,
            }));
            let delay = delay.map(|d| self.duration(d));
            return Some(Lowered::Entity {
                members: members.clone(),
                delay,
                facet: f,
                point: point(ev.point),
                then: then(t),
            });
        }
        // `disable … for D after E` with no member of `E`: the `after` part is dropped.
        let empty = match (&nodes, delay) {
            (Nodes::Entity(_), Some(d)) => {
                Some(Low::Trigger(WhenEx::In(self.duration(d)), then(t)))
            }
            _ => None,
        };
        let w = self.when_ex(when);
        Some(Lowered::Each {
            nodes,
            low: Low::Trigger(w, then(t)),
            empty,
        })
    }

    /// The node of `node!(tag)` in Rust code: `None` when the tag does not name one node.
    pub(crate) fn node_of(&mut self, tag: &Tag) -> Option<NodeEx> {
        let TagKind::Named { name, indexes } = &tag.kind else {
            return matches!(tag.kind, TagKind::Parent).then_some(NodeEx::Own);
        };
        let Resolution::Named(Named { def, .. }) = self.scope.resolve(tag) else {
            return None;
        };
        let text: Arc<str> = Arc::from(name.to_string());
        let scope = self.scope;
        match def {
            Def::Spawn(id) if scope.spawns[id].late => {
                let info = &scope.spawns[id];
                let var = info.var.as_ref().filter(|_| info.site.loops.is_empty())?;
                Some(NodeEx::Bound(self.tdl_slot(&var.to_string()), text))
            }
            Def::Bound(bind) => {
                let var = scope.bound[&bind.name.to_string()].var.as_ref()?;
                Some(NodeEx::Bound(self.tdl_slot(&var.to_string()), text))
            }
            Def::Group(_) => None,
            Def::Spawn(id) | Def::OnTerminate(id) => {
                let spawn = match def {
                    Def::OnTerminate(_) => scope.cleanups[id].spawn,
                    _ => id,
                };
                let site = scope.spawns[spawn].site.loops.clone();
                match self.def_nodes(def, indexes, &site) {
                    Nodes::One(n) => Some(n),
                    Nodes::Entity(_) | Nodes::None => None,
                }
            }
        }
    }
}
