//! Lowering of constraints to `tcm` values: the nodes a tag denotes at run time ([`Nodes`]) and
//! each constraint as a `tdl::Constraint` value or a `Spawner` method ([`Low`]).
//!
//! Every timed or event-driven constraint (`disable … until|for`, `terminate …`, `activate …`)
//! is one AST trigger (`ConstraintKind::Trigger { when, then }`) and goes through one function,
//! [`trigger`], to `::tdl::Constraint::Trigger(when, then)`. External events (`When::External`)
//! have no TDL syntax yet, so they are never generated.

use proc_macro2::{Ident, Literal, TokenStream};
use quote::{format_ident, quote};

use super::body::Gen;
use crate::ast::{
    Constraint, ConstraintKind, Event, Facet, Point, RelTime, Tag, TagIndex, TagKind,
};
use crate::ast::{Then, TimeOfDay, When};
use crate::resolve::{Def, Index, Named, Resolution, SpawnId};

/// The nodes a tag denotes at run time.
pub(super) enum Nodes {
    /// One node reference expression (a `NodeId` or a `NodeRef`).
    One(TokenStream),
    /// Several: a `for` loop over `iter`, by reference or by value.
    Many { by_ref: bool, iter: TokenStream },
    /// Nothing to refer to (the diagnosis reported why).
    None,
}

impl Nodes {
    /// `f(node)` for each node: inline for one node, a `for` loop for several.
    pub(super) fn each(
        &self,
        var: &Ident,
        f: impl FnOnce(&TokenStream) -> TokenStream,
    ) -> TokenStream {
        match self {
            Nodes::One(expr) => f(expr),
            Nodes::Many { by_ref, iter } => {
                let body = f(&quote!(#var));
                if *by_ref {
                    quote!(for &#var in &#iter { #body })
                } else {
                    quote!(for #var in #iter { #body })
                }
            }
            Nodes::None => TokenStream::new(),
        }
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

/// A lowered constraint waiting for its node: the nodes the constraint names (`Nodes::One` of
/// nothing when it names none) and the constraint for one of them.
pub(super) type Lowered = (Nodes, Box<dyn FnOnce(&TokenStream) -> Low>);

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
    };
    let then = match then {
        Then::Enable(f) => {
            let f = facet(f.unwrap_or(Facet::Handling));
            quote!(::tdl::Then::Enable(#f))
        }
        Then::Terminate => quote!(::tdl::Then::Terminate),
        Then::Activate => quote!(::tdl::Then::Activate),
    };
    quote!(::tdl::Constraint::Trigger(#when, #then))
}

pub(super) fn facet(f: Facet) -> TokenStream {
    match f {
        Facet::Handling => quote!(::tdl::Facet::Handling),
        Facet::Expansion => quote!(::tdl::Facet::Expansion),
        Facet::Execution => quote!(::tdl::Facet::Execution),
    }
}

fn point(s: Point) -> TokenStream {
    match s {
        Point::Enabled => quote!(::tdl::Point::Enabled),
        Point::Active => quote!(::tdl::Point::Active),
        Point::Completed => quote!(::tdl::Point::Completed),
    }
}

/// `X [facet] state` on the node expression `node`.
fn event(ev: &Event, node: &TokenStream) -> TokenStream {
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
        match self.scope.resolve(tag) {
            Resolution::Previous => Nodes::Many {
                by_ref: true,
                iter: quote!(#prev),
            },
            Resolution::This => Nodes::One(quote!(::tdl::NodeRef::This)),
            Resolution::Parent => Nodes::One(quote!(::tdl::NodeRef::Parent)),
            Resolution::Named(Named {
                def: Def::Spawn(id),
                ..
            }) => match &tag.kind {
                TagKind::Named { indexes, .. } => self.spawn_nodes(id, indexes),
                _ => Nodes::None,
            },
            Resolution::Named(Named {
                def: Def::Group(id),
                ..
            }) => match &self.scope.groups[id].var {
                Some(var) => Nodes::Many {
                    by_ref: true,
                    iter: quote!(#var),
                },
                None => Nodes::None,
            },
            // On-terminate tasks are refused by `codegen::body`; unknown and ambiguous tags by
            // the diagnosis.
            Resolution::Named(Named {
                def: Def::OnTerminate { .. },
                ..
            })
            | Resolution::Unknown
            | Resolution::Ambiguous(_) => Nodes::None,
        }
    }

    /// The nodes of spawn `id` with iteration indexes `indexes`, at the current loops.
    fn spawn_nodes(&self, id: SpawnId, indexes: &[TagIndex]) -> Nodes {
        let info = &self.scope.spawns[id];
        let Some(var) = &info.var else {
            return Nodes::None;
        };
        let depth = info.site.loops.len();
        if depth == 0 {
            return Nodes::One(quote!(#var));
        }
        let Ok(indexes) = self.scope.indexes(id, indexes, &self.loops) else {
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
        Nodes::Many {
            by_ref: false,
            iter,
        }
    }

    /// The nodes of a `sequential`/`serial` tag, `previous` when none is written.
    fn nodes_or_previous(&self, tag: Option<&Tag>, prev: &Ident) -> Nodes {
        match tag {
            Some(tag) => self.nodes(tag, prev),
            None => Nodes::Many {
                by_ref: true,
                iter: quote!(#prev),
            },
        }
    }

    /// The lowered form of `c` with the nodes it names; `None` when it is handled elsewhere.
    pub(super) fn lower(&self, c: &Constraint, prev: &Ident) -> Option<Lowered> {
        let no_node = |low: Low| -> Option<Lowered> {
            Some((Nodes::One(TokenStream::new()), Box::new(move |_| low)))
        };
        match &c.kind {
            ConstraintKind::ExpandFirst => no_node(Low::ExpandFirst),
            ConstraintKind::DelayExpansion => no_node(Low::DelayExpansion),
            ConstraintKind::Sequential { facet: f, tag } => {
                let nodes = self.nodes_or_previous(tag.as_ref(), prev);
                let f = facet(*f);
                Some((nodes, Box::new(move |n| Low::Sequential(f, n.clone()))))
            }
            ConstraintKind::Serial { tag } => {
                let nodes = self.nodes_or_previous(tag.as_ref(), prev);
                Some((nodes, Box::new(|n| Low::Serial(n.clone()))))
            }
            ConstraintKind::Trigger { when, then } => {
                let nodes = match when.event() {
                    Some(ev) => self.nodes(&ev.tag, prev),
                    None => Nodes::One(TokenStream::new()),
                };
                let (when, then) = (when.clone(), *then);
                Some((
                    nodes,
                    Box::new(move |n| Low::Trigger(trigger(&when, then, n))),
                ))
            }
            // Spawner settings, generated by `spawn` (and refused in constraint statements);
            // `on AGENT` is refused by the diagnosis.
            ConstraintKind::MaximumActivate(_)
            | ConstraintKind::MaximumTrigger(_)
            | ConstraintKind::Period(_)
            | ConstraintKind::ExceptionHandler(_)
            | ConstraintKind::OnAgent(_)
            | ConstraintKind::Parallel
            | ConstraintKind::Wait
            | ConstraintKind::Name(_)
            | ConstraintKind::OnTerminate(_) => None,
        }
    }
}
