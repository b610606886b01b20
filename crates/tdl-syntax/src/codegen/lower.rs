//! Lowering of constraints to `tcm` values: the nodes a tag denotes at run time ([`Nodes`]) and
//! each constraint as a `tdl::Constraint` value or a `Spawner` method ([`Low`]).
//!
//! Every timed or event-driven constraint (`disable … until|for`, `terminate …`, `activate …`)
//! is one AST trigger (`ConstraintKind::Trigger { when, then }`) and goes through one function,
//! [`trigger`], to `::tdl::Constraint::Trigger(when, then)`. An external event (`at external
//! "name"`) is bound to the run's event id where the constraint is applied, by `ctx.external`.
//!
//! A tag may denote an *entity* whose members are only known at run time (`previous`, a `with`
//! group, an iteration set, a tag bound by a statement): [`Nodes::Entity`]. A constraint on it is
//! applied per member, except a `terminate` or `activate` trigger, which happens once every member
//! reached the event ([`Lowered::Entity`], through `tdl::codegen::trigger_entity`); with no member
//! or no entity at all, the `after` part of a delay is dropped (docs/semantics.md, "Tags and
//! forward references").

use proc_macro2::{Ident, Literal, TokenStream};
use quote::{format_ident, quote, quote_spanned};

use super::body::Gen;
use crate::ast::{
    Constraint, ConstraintKind, Event, ExternalName, Facet, Point, RelTime, Tag, TagIndex, TagKind,
};
use crate::ast::{Then, TimeOfDay, When};
use crate::hir::{Def, Index, LoopId, Named, Resolution, ResolvedTag, SpawnId, TagTarget};

/// The nodes a tag denotes at run time.
pub(super) enum Nodes {
    /// One node reference expression (a `NodeId` or a `NodeRef`).
    One(TokenStream),
    /// An entity: an `Option<&[NodeId]>` expression of its members, `None` when there is no
    /// entity at all (`previous` before anything was spawned).
    Entity(TokenStream),
    /// Nothing to refer to (the diagnosis reported why).
    None,
}

impl Nodes {
    /// `f(node)` for each node: inline for one node, a `for` loop over an entity's members.
    pub(super) fn each(
        &self,
        var: &Ident,
        f: impl FnOnce(&TokenStream) -> TokenStream,
    ) -> TokenStream {
        match self {
            Nodes::One(expr) => f(expr),
            Nodes::Entity(members) => {
                let body = f(&quote!(#var));
                quote!(for &#var in ::core::option::Option::unwrap_or_default(#members) { #body })
            }
            Nodes::None => TokenStream::new(),
        }
    }

    /// `Some(nodes)` of an expression holding a `Vec<NodeId>` or an `Option<NodeId>`.
    fn slice(holder: impl quote::ToTokens) -> Nodes {
        Nodes::Entity(quote!(::core::option::Option::Some(#holder.as_slice())))
    }
}

/// A constraint after its tag was replaced by a node expression.
pub(super) enum Low {
    ExpandFirst,
    DelayExpansion,
    Sequential(TokenStream, TokenStream),
    Serial(TokenStream),
    /// A `tdl::Constraint::Trigger` value, from [`trigger`].
    Trigger(TokenStream),
}

impl Low {
    /// As a `tdl::Constraint` value.
    pub(super) fn value(&self) -> TokenStream {
        match self {
            Low::ExpandFirst => quote!(::tdl::Constraint::ExpandFirst),
            Low::DelayExpansion => quote!(::tdl::Constraint::DelayExpansion),
            Low::Sequential(f, n) => {
                quote!(::tdl::Constraint::Sequential(#f, ::tdl::NodeRef::from(#n)))
            }
            Low::Serial(n) => quote!(::tdl::Constraint::Serial(::tdl::NodeRef::from(#n))),
            Low::Trigger(value) => value.clone(),
        }
    }

    /// As a `Spawner` method call, with the builder's shorthands where there is one.
    pub(super) fn method(&self) -> TokenStream {
        match self {
            Low::ExpandFirst => quote!(.expand_first()),
            Low::DelayExpansion => quote!(.delay_expansion()),
            Low::Sequential(f, n) => quote!(.sequential(#f, #n)),
            Low::Serial(n) => quote!(.serial(#n)),
            Low::Trigger(value) => quote!(.with(#value)),
        }
    }
}

/// A lowered constraint waiting for its nodes.
pub(super) enum Lowered {
    /// The constraint for each node of `nodes` (`Nodes::One` of nothing when it names none),
    /// built by `low` from one node; when `nodes` is an entity with no member (or none at all),
    /// `empty` instead, if anything.
    Each {
        nodes: Nodes,
        low: Box<dyn FnOnce(&TokenStream) -> Low>,
        empty: Option<Low>,
    },
    /// A `terminate` or `activate` trigger on an entity's event: the statement arming it on a
    /// target node expression, once that node exists.
    Entity(Box<dyn FnOnce(&TokenStream) -> TokenStream>),
}

/// `disable [facet] until|for …`, `terminate …`, `activate …`: the one lowering of a trigger,
/// `::tdl::Constraint::Trigger(when, then)`. `node` is the node of the when's event, if it has one.
pub(super) fn trigger(when: &When, then: Then, node: &TokenStream) -> TokenStream {
    let when = match when {
        When::Now => quote!(::tdl::When::Now),
        When::At(time) => {
            let time = time_of_day(time);
            quote!(::tdl::When::At(#time))
        }
        When::In(delay) => {
            let delay = duration(delay);
            quote!(::tdl::When::In(#delay))
        }
        When::Event(ev) => {
            let ev = event(ev, node);
            quote!(::tdl::When::Event(#ev))
        }
        When::After(delay, ev) => {
            let delay = duration(delay);
            let ev = event(ev, node);
            quote!(::tdl::When::After(#delay, #ev))
        }
        When::External(name) => {
            let id = external_id(name);
            quote!(::tdl::When::External(#id))
        }
        // Lowered with the program's declarations by `Gen::lower_trigger` (`state.rs`).
        When::Condition(_) | When::Changed(_) => {
            return quote!(::core::compile_error!(
                "a condition needs the program's state variables"
            ));
        }
    };
    let then = then_expr(then);
    quote!(::tdl::Constraint::Trigger(#when, #then))
}

/// The run's `tdl::ExternalId` of an external event's name. The name is bound when the
/// constraint is applied, so `external (expr)` may compute it from the task's arguments.
fn external_id(name: &ExternalName) -> TokenStream {
    match name {
        ExternalName::Lit(lit) => quote!(ctx.external(#lit)?),
        // Borrowed, so an argument naming the event is not moved; the parentheses keep `&` off
        // a binary expression's first operand.
        ExternalName::Expr(expr) => {
            quote!(ctx.external(::core::convert::AsRef::<str>::as_ref(&(#expr)))?)
        }
    }
}

/// A `tdl::Then` expression.
fn then_expr(then: Then) -> TokenStream {
    match then {
        Then::Enable(f) => {
            let f = facet(f.unwrap_or(Facet::Handling));
            quote!(::tdl::Then::Enable(#f))
        }
        Then::Terminate => quote!(::tdl::Then::Terminate),
        Then::Activate => quote!(::tdl::Then::Activate),
        Then::Skip => quote!(::tdl::Then::Skip),
        Then::Invariant => quote!(::tdl::Then::Invariant),
        Then::Pause => quote!(::tdl::Then::Pause),
    }
}

pub(super) fn facet(f: Facet) -> TokenStream {
    match f {
        Facet::Handling => quote!(::tdl::Facet::Handling),
        Facet::Expansion => quote!(::tdl::Facet::Expansion),
        Facet::Execution => quote!(::tdl::Facet::Execution),
    }
}

/// `terminate|activate at|in … after E` where `E` names an entity: armed on `target` by
/// `tdl::codegen::trigger_entity` (every member must reach the event; none: at once).
fn entity_trigger(
    target: &TokenStream,
    members: &TokenStream,
    delay: Option<&RelTime>,
    ev: &Event,
    then: Then,
) -> TokenStream {
    if ev.point.is_outcome() {
        let msg = format!(
            "`{}` on a group, `previous` or a tag bound at run time is not supported with `terminate` or `activate` yet: name one task",
            ev.point.as_str()
        );
        return quote_spanned!(ev.tag.span=> ::core::compile_error!(#msg););
    }
    let f = facet(ev.facet.unwrap_or(match ev.point {
        Point::Enabled | Point::Active => Facet::Handling,
        _ => Facet::Execution,
    }));
    let p = point(ev.point);
    let delay = match delay {
        Some(d) => {
            let d = duration(d);
            quote!(::core::option::Option::Some(#d))
        }
        None => quote!(::core::option::Option::None),
    };
    let then = then_expr(then);
    quote!(::tdl::codegen::trigger_entity(&ctx, #target, #members, #f, #p, #delay, #then)?;)
}

fn point(s: Point) -> TokenStream {
    match s {
        Point::Enabled => quote!(::tdl::Point::Enabled),
        Point::Active => quote!(::tdl::Point::Active),
        Point::Completed | Point::Succeeded | Point::Failed | Point::Terminated => {
            quote!(::tdl::Point::Completed)
        }
    }
}

/// The run-time outcome of an outcome event's point.
fn outcome(p: Point) -> Option<TokenStream> {
    match p {
        Point::Succeeded => Some(quote!(::tdl::Outcome::Succeeded)),
        Point::Failed => Some(quote!(::tdl::Outcome::Failed)),
        Point::Terminated => Some(quote!(::tdl::Outcome::Terminated)),
        Point::Enabled | Point::Active | Point::Completed => None,
    }
}

/// `X [facet] state` on the node expression `node`.
fn event(ev: &Event, node: &TokenStream) -> TokenStream {
    if let Some(o) = outcome(ev.point) {
        return quote!(::tdl::Event::ended(#node, #o));
    }
    let p = point(ev.point);
    match ev.facet {
        None => quote!(::tdl::Event::new(#node, #p)),
        Some(f) => {
            let f = facet(f);
            quote!(::tdl::Event::on(#node, #f, #p))
        }
    }
}

/// A relative time as a `std::time::Duration` expression.
pub(super) fn duration(t: &RelTime) -> TokenStream {
    match t {
        RelTime::Nanos(n) => {
            let n = *n;
            if n % 1_000_000_000 == 0 {
                let s = Literal::u64_unsuffixed(n / 1_000_000_000);
                quote!(::std::time::Duration::from_secs(#s))
            } else if n % 1_000_000 == 0 {
                let ms = Literal::u64_unsuffixed(n / 1_000_000);
                quote!(::std::time::Duration::from_millis(#ms))
            } else {
                let ns = Literal::u64_unsuffixed(n);
                quote!(::std::time::Duration::from_nanos(#ns))
            }
        }
        RelTime::Seconds(expr) => quote!(::std::time::Duration::from_secs_f64(#expr)),
    }
}

/// A time of day as the run's `tdl::Time` (`ctx.time_of_day(seconds)`).
fn time_of_day(t: &TimeOfDay) -> TokenStream {
    #[allow(
        clippy::cast_precision_loss,
        reason = "a time of day fits an f64 exactly enough"
    )]
    let secs = Literal::f64_unsuffixed(t.nanos_since_midnight() as f64 / 1e9);
    quote!(ctx.time_of_day(#secs))
}

impl Gen<'_, '_> {
    /// The nodes `tag` denotes; `prev` is the local holding `previous` at this site.
    pub(super) fn nodes(&self, tag: &Tag, prev: &Ident) -> Nodes {
        let indexes = match &tag.kind {
            TagKind::Named { indexes, .. } => indexes.as_slice(),
            _ => &[],
        };
        let resolution = self.scope.resolve(tag);
        if let Some(resolved) = self.resolved {
            let targets = match &resolution {
                Resolution::This => Some(vec![TagTarget::This]),
                Resolution::Parent => Some(vec![TagTarget::Parent]),
                Resolution::Named(Named { def, .. }) => Some(self.scope.targets(*def)),
                Resolution::Unknown | Resolution::Ambiguous(_) => Some(Vec::new()),
                Resolution::Previous => None,
            };
            if let Some(targets) = targets {
                resolved
                    .borrow_mut()
                    .push(ResolvedTag::new(0, tag, targets));
            }
        }
        match resolution {
            Resolution::Previous => Nodes::Entity(quote!(#prev.as_deref())),
            Resolution::This => Nodes::One(quote!(::tdl::NodeRef::This)),
            Resolution::Parent => Nodes::One(quote!(::tdl::NodeRef::Parent)),
            Resolution::Named(Named { def, .. }) => self.def_nodes(def, indexes, &self.loops),
            // Unknown and ambiguous tags are reported by the diagnosis.
            Resolution::Unknown | Resolution::Ambiguous(_) => Nodes::None,
        }
    }

    /// The nodes of a definition named with `indexes` inside the loops `site`.
    fn def_nodes(&self, def: Def<'_>, indexes: &[TagIndex], site: &[LoopId]) -> Nodes {
        match def {
            // A spawn under another parent, or a bound tag: known once its statement ran.
            Def::Spawn(id) if self.scope.spawns[id].late => match &self.scope.spawns[id].var {
                Some(var) if self.scope.spawns[id].site.loops.is_empty() => Nodes::slice(var),
                _ => Nodes::None,
            },
            Def::Bound(bind) => match &self.scope.bound[&bind.name.to_string()].var {
                Some(var) => Nodes::slice(var),
                None => Nodes::None,
            },
            Def::Spawn(id) => {
                let var = self.scope.spawns[id].var.as_ref();
                self.spawn_nodes(id, var, indexes, site)
            }
            Def::OnTerminate(id) => {
                let cleanup = &self.scope.cleanups[id];
                self.spawn_nodes(cleanup.spawn, cleanup.var.as_ref(), indexes, site)
            }
            Def::Group(id) => match &self.scope.groups[id].var {
                Some(var) => Nodes::slice(var),
                None => Nodes::None,
            },
        }
    }

    /// The nodes held in `var` (reservations of spawn `id`, or of an on-terminate task of it)
    /// with iteration indexes `indexes`, inside the loops `site`.
    fn spawn_nodes(
        &self,
        id: SpawnId,
        var: Option<&Ident>,
        indexes: &[TagIndex],
        site: &[LoopId],
    ) -> Nodes {
        let info = &self.scope.spawns[id];
        let Some(var) = var else {
            return Nodes::None;
        };
        let depth = info.site.loops.len();
        if depth == 0 {
            return Nodes::One(quote!(#var));
        }
        let Ok(indexes) = self.scope.indexes(id, indexes, site) else {
            return Nodes::None;
        };
        let keys: Vec<TokenStream> = indexes
            .iter()
            .map(|index| match index {
                Index::Expr(expr) => quote!((#expr) as i64),
                Index::Current(loop_id) => {
                    let it = format_ident!("tdl_i_{}", loop_id);
                    quote!(#it)
                }
            })
            .collect();
        let name = info.spawn.task.to_string();
        if keys.len() == depth {
            return Nodes::One(quote!(tdl_slot(&ctx, &mut #var, [#(#keys),*], #name)?));
        }
        let n = Literal::usize_unsuffixed(keys.len());
        let iter = if keys.is_empty() {
            quote!(#var.values().copied().collect::<::std::vec::Vec<_>>())
        } else {
            quote! {
                #var.iter()
                    .filter(|(key, _)| key[..#n] == [#(#keys),*])
                    .map(|(_, node)| *node)
                    .collect::<::std::vec::Vec<_>>()
            }
        };
        Nodes::slice(quote!((#iter)))
    }

    /// The nodes of a `sequential`/`serial` tag, `previous` when none is written.
    fn nodes_or_previous(&self, tag: Option<&Tag>, prev: &Ident) -> Nodes {
        match tag {
            Some(tag) => self.nodes(tag, prev),
            None => Nodes::Entity(quote!(#prev.as_deref())),
        }
    }

    /// The lowered form of `c` with the nodes it names; `None` when it is handled elsewhere.
    pub(super) fn lower(&self, c: &Constraint, prev: &Ident) -> Option<Lowered> {
        let each = |nodes: Nodes, low: Box<dyn FnOnce(&TokenStream) -> Low>| {
            Some(Lowered::Each {
                nodes,
                low,
                empty: None,
            })
        };
        let no_node = |low: Low| each(Nodes::One(TokenStream::new()), Box::new(move |_| low));
        match &c.kind {
            ConstraintKind::ExpandFirst => no_node(Low::ExpandFirst),
            ConstraintKind::DelayExpansion => no_node(Low::DelayExpansion),
            ConstraintKind::Sequential { facet: f, tag } => {
                let nodes = self.nodes_or_previous(tag.as_ref(), prev);
                let f = facet(*f);
                each(nodes, Box::new(move |n| Low::Sequential(f, n.clone())))
            }
            ConstraintKind::Serial { tag } => {
                let nodes = self.nodes_or_previous(tag.as_ref(), prev);
                each(nodes, Box::new(|n| Low::Serial(n.clone())))
            }
            ConstraintKind::Trigger { when, then } => Some(self.lower_trigger(when, *then, prev)),
            // Spawner settings and monitor limits, generated by `spawn` and `constrain`; `on
            // AGENT` by `spawn` (the diagnosis refuses it elsewhere).
            ConstraintKind::MaximumActivate(_)
            | ConstraintKind::MaximumTrigger(_)
            | ConstraintKind::Period(_)
            | ConstraintKind::ExceptionHandler(_)
            | ConstraintKind::OnAgent(_)
            | ConstraintKind::Parallel
            | ConstraintKind::Wait
            | ConstraintKind::Outcome
            | ConstraintKind::Propagate
            | ConstraintKind::Approval(_)
            | ConstraintKind::Name(_)
            | ConstraintKind::Parent(_)
            | ConstraintKind::OnTerminate(_)
            | ConstraintKind::Uses(_)
            | ConstraintKind::Priority(_)
            | ConstraintKind::DenyIfBusy => None,
        }
    }

    /// A trigger: per node, or, naming an entity, per member (enablement) or once for the
    /// whole entity (`terminate`, `activate`).
    fn lower_trigger(&self, when: &When, then: Then, prev: &Ident) -> Lowered {
        if let When::Condition(_) | When::Changed(_) = when {
            let value = super::state::constraint(self.file, when, then);
            return Lowered::Each {
                nodes: Nodes::One(TokenStream::new()),
                low: Box::new(move |_| Low::Trigger(value)),
                empty: None,
            };
        }
        let nodes = match when.event() {
            Some(ev) => self.nodes(&ev.tag, prev),
            None => Nodes::One(TokenStream::new()),
        };
        let (delay, event) = match when {
            When::Event(ev) => (None, Some(ev)),
            When::After(d, ev) => (Some(d), Some(ev)),
            When::Now
            | When::At(_)
            | When::In(_)
            | When::External(_)
            | When::Condition(_)
            | When::Changed(_) => (None, None),
        };
        if let (Nodes::Entity(members), Some(ev), Then::Terminate | Then::Activate) =
            (&nodes, event, then)
        {
            let (members, delay, ev) = (members.clone(), delay.cloned(), ev.clone());
            return Lowered::Entity(Box::new(move |target| {
                entity_trigger(target, &members, delay.as_ref(), &ev, then)
            }));
        }
        // `disable … for D after E` with no member of `E`: the `after` part is dropped.
        let empty = match (&nodes, delay) {
            (Nodes::Entity(_), Some(d)) => {
                let none = TokenStream::new();
                Some(Low::Trigger(trigger(&When::In(d.clone()), then, &none)))
            }
            _ => None,
        };
        let when = when.clone();
        Lowered::Each {
            nodes,
            low: Box::new(move |n| Low::Trigger(trigger(&when, then, n))),
            empty,
        }
    }

    /// The node expression of `node!(tag)` in Rust code: `None` when the tag does not name one
    /// node (the diagnosis reported why).
    pub(super) fn node_expr(&self, tag: &Tag) -> Option<TokenStream> {
        let TagKind::Named { name, indexes } = &tag.kind else {
            return matches!(tag.kind, TagKind::Parent).then(|| quote!(ctx.node()));
        };
        let Resolution::Named(Named { def, .. }) = self.scope.resolve(tag) else {
            return None;
        };
        let text = name.to_string();
        let late = |var: &Ident| quote!(::tdl::codegen::bound(#var, #text)?);
        match def {
            Def::Spawn(id) if self.scope.spawns[id].late => {
                let info = &self.scope.spawns[id];
                info.var
                    .as_ref()
                    .filter(|_| info.site.loops.is_empty())
                    .map(late)
            }
            Def::Bound(bind) => self.scope.bound[&bind.name.to_string()]
                .var
                .as_ref()
                .map(late),
            Def::Group(_) => None,
            // `[.]` is the spawn's own loop wherever the use is (the diagnosis checked it is
            // inside that loop).
            Def::Spawn(id) | Def::OnTerminate(id) => {
                let spawn = match def {
                    Def::OnTerminate(_) => self.scope.cleanups[id].spawn,
                    _ => id,
                };
                let site = &self.scope.spawns[spawn].site.loops;
                match self.def_nodes(def, indexes, site) {
                    Nodes::One(expr) => Some(expr),
                    Nodes::Entity(_) | Nodes::None => None,
                }
            }
        }
    }
}
