//! Generation of the TDL statements that make and constrain nodes: `spawn` (a `Spawner` chain
//! with the constraints of the enclosing `with` groups and its own), `with` groups (their members
//! and `previous` as one entity) and constraint statements (`ctx.constrain`, `ctx.wait`,
//! `ctx.terminate`).

use proc_macro2::{Ident, TokenStream};
use quote::{format_ident, quote};

use super::body::Gen;
use super::lower::{Nodes, duration};
use super::{count_expr, handler_expr};
use crate::ast::{
    Binding, Constraint, ConstraintKind, ConstraintStmt, Spawn, TagKind, Then, When, WithGroup,
};
use crate::diagnostic::Diagnostic;
use crate::resolve::uses_previous;

/// Where the spawn's builder chain stands: plain method calls, or a loop over an entity.
enum Step {
    Method(TokenStream),
    Each(Nodes, Box<dyn FnOnce(&TokenStream) -> TokenStream>),
}

/// A `with` group being generated.
pub(super) struct Frame<'a> {
    constraints: &'a [Constraint],
    /// The local holding `previous` for this group's current direct child.
    prev: Ident,
    /// The local collecting the group's nodes, when tracked.
    members: Option<Ident>,
}

impl<'a> Gen<'_, 'a> {
    pub(super) fn spawn(&mut self, spawn: &'a Spawn) -> TokenStream {
        let prev = Self::prev_ident();
        // Constraints: the enclosing groups' (outermost first, each with its own `previous`),
        // then the spawn's own.
        let mut lists: Vec<(&'a [Constraint], Ident)> = self
            .frames
            .iter()
            .map(|f| (f.constraints, f.prev.clone()))
            .collect();
        lists.push((&spawn.constraints, prev.clone()));
        let mut steps = Vec::new();
        let mut wait = false;
        let mut name = None;
        let task_name = &spawn.task;
        let args = &spawn.args;
        for (list, list_prev) in &lists {
            for c in *list {
                match &c.kind {
                    ConstraintKind::Wait => wait = true,
                    ConstraintKind::Name(expr) => name = Some(expr.clone()),
                    ConstraintKind::OnTerminate(it) => {
                        let (t, a) = (&it.task, &it.args);
                        steps.push(Step::Method(quote!(.on_terminate(#t(#(#a),*)))));
                    }
                    ConstraintKind::ExceptionHandler(it) => {
                        let h = handler_expr(it, c.span, self.diags);
                        steps.push(Step::Method(quote!(.handler(#h))));
                    }
                    ConstraintKind::MaximumActivate(n) => {
                        let n = count_expr(n, c.span, self.diags);
                        steps.push(Step::Method(quote!(.max_activations(#n))));
                    }
                    ConstraintKind::MaximumTrigger(n) => {
                        let n = count_expr(n, c.span, self.diags);
                        steps.push(Step::Method(quote!(.max_triggers(#n))));
                    }
                    ConstraintKind::Period(t) => {
                        let d = duration(t);
                        steps.push(Step::Method(quote!(.period(#d))));
                    }
                    _ => {
                        if let Some((nodes, f)) = self.lower(c, list_prev) {
                            match nodes {
                                Nodes::One(n) => steps.push(Step::Method(f(&n).method())),
                                Nodes::None => {}
                                many => {
                                    steps.push(Step::Each(many, Box::new(move |n| f(n).method())))
                                }
                            }
                        }
                    }
                }
            }
        }
        let mut task = quote!(#task_name(#(#args),*));
        if let Some(name) = name {
            task = quote!(#task.named(#name));
        }
        let members: Vec<Ident> = self
            .frames
            .iter()
            .filter_map(|f| f.members.clone())
            .collect();
        let needs_id = self.scope.uses_previous || !members.is_empty();
        let mut pre = TokenStream::new();
        let mut id_expr: Option<TokenStream> = None;
        if let Some(info) = self.scope.spawn_def(spawn) {
            if let Some(var) = &info.var {
                let loops = &info.site.loops;
                if loops.is_empty() {
                    id_expr = Some(quote!(#var));
                } else {
                    let keys = loops.iter().map(|l| format_ident!("tdl_i_{}", l));
                    let name = spawn.task.to_string();
                    let slot = quote!(tdl_slot(&ctx, &mut #var, [#(#keys),*], #name)?);
                    if needs_id && spawn.binding.is_some() {
                        pre.extend(quote!(let tdl_node = #slot;));
                        id_expr = Some(quote!(tdl_node));
                    } else {
                        id_expr = Some(slot);
                    }
                }
            }
        }
        if needs_id && spawn.binding.is_some() && id_expr.is_none() {
            let name = task_name.to_string();
            pre.extend(quote!(let tdl_node = ctx.reserve(#name)?;));
            id_expr = Some(quote!(tdl_node));
        }
        if let Some(id) = &id_expr {
            steps.push(Step::Method(quote!(.fulfils(#id))));
        }
        let (setup, chain) = render_chain(quote!(ctx.spawn(#task)), steps);
        pre.extend(setup);
        let mut out = pre;
        let node = format_ident!("tdl_node");
        match (&spawn.binding, wait) {
            (Some(binding), _) => {
                let ty = self.value_type(spawn, binding);
                let pat = &binding.pat;
                out.extend(quote!(let #pat: #ty = #chain.wait_value::<#ty>().await?;));
            }
            (None, true) if needs_id => out.extend(quote! {
                let #node = #chain.start()?;
                ctx.wait(#node).await?;
            }),
            (None, true) => out.extend(quote!(#chain.wait().await?;)),
            (None, false) if needs_id => out.extend(quote!(let #node = #chain.start()?;)),
            (None, false) => out.extend(quote!(#chain.start()?;)),
        }
        if needs_id {
            let id = match (&spawn.binding, &id_expr) {
                (Some(_), Some(id)) => id.clone(),
                _ => quote!(#node),
            };
            for m in &members {
                out.extend(quote!(#m.push(#id);));
            }
            if self.scope.uses_previous {
                out.extend(quote!(#prev = ::std::vec![#id];));
            }
        }
        out
    }

    /// The type of a waited spawn's value: the callee's declared result, else the annotation.
    fn value_type(&mut self, spawn: &Spawn, binding: &Binding) -> TokenStream {
        if let Some(ty) = &binding.ty {
            return quote!(#ty);
        }
        match self.file.task(&spawn.task.to_string()) {
            Some(task) => match &task.result {
                Some(ty) => quote!(#ty),
                None => quote!(()),
            },
            None => {
                self.diags.push(
                    Diagnostic::error(
                        spawn.task.span(),
                        format!("cannot tell the type of the value `{}` returns", spawn.task),
                    )
                    .with_hint(format!(
                        "`{}` is not defined in this TDL source; annotate the binding: `let v: Type = spawn {}(..) with wait;`",
                        spawn.task, spawn.task
                    )),
                );
                quote!(_)
            }
        }
    }

    pub(super) fn with(&mut self, group: &'a WithGroup) -> TokenStream {
        let index = self.scope.group_id(group).unwrap_or_default();
        let mut out = TokenStream::new();
        let label_var = self.scope.groups.get(index).and_then(|it| it.var.clone());
        let members = match &label_var {
            Some(var) => {
                out.extend(quote!(#var.clear();));
                Some(var.clone())
            }
            None if self.scope.uses_previous => {
                let var = format_ident!("tdl_group_{}", index);
                out.extend(
                    quote!(let mut #var: ::std::vec::Vec<::tdl::NodeId> = ::std::vec::Vec::new();),
                );
                Some(var)
            }
            None => None,
        };
        // The enclosing group sees this group as one entity: its `previous`, for every spawn in
        // here, is the entity before this group.
        let mut saved = None;
        if let Some(parent) = self.frames.last() {
            if uses_previous(parent.constraints) {
                let snapshot = format_ident!("tdl_prev_{}", index);
                let prev = Self::prev_ident();
                out.extend(quote!(let #snapshot = #prev.clone();));
                let last = self.frames.len() - 1;
                saved = Some(std::mem::replace(&mut self.frames[last].prev, snapshot));
            }
        }
        self.frames.push(Frame {
            constraints: &group.constraints,
            prev: Self::prev_ident(),
            members: members.clone(),
        });
        let body = self.block(&group.body);
        self.frames.pop();
        if let Some(saved) = saved {
            let last = self.frames.len() - 1;
            self.frames[last].prev = saved;
        }
        out.extend(quote!({ #body }));
        if self.scope.uses_previous {
            let prev = Self::prev_ident();
            match (&label_var, &members) {
                (Some(var), _) => out.extend(quote!(#prev = #var.clone();)),
                (None, Some(var)) => out.extend(quote!(#prev = #var;)),
                (None, None) => {}
            }
        }
        out
    }

    pub(super) fn constrain(&mut self, stmt: &ConstraintStmt) -> TokenStream {
        let prev = Self::prev_ident();
        let target = match &stmt.tag.kind {
            TagKind::Parent => Nodes::One(quote!(ctx.node())),
            TagKind::Child => {
                self.diags.push(
                    Diagnostic::error(stmt.span, "a constraint statement cannot name `self`")
                        .with_hint(
                            "`self` is the node being spawned; name the task, a label or `parent`",
                        ),
                );
                return TokenStream::new();
            }
            _ => self.nodes(&stmt.tag, &prev),
        };
        let target_var = format_ident!("target");
        let node_var = format_ident!("node");
        match &stmt.constraint.kind {
            ConstraintKind::Wait => {
                return target.each(&target_var, |t| quote!(ctx.wait(#t).await?;));
            }
            ConstraintKind::Trigger {
                when: When::Now,
                then: Then::Terminate,
            } => {
                return target.each(&target_var, |t| quote!(ctx.terminate(#t)?;));
            }
            ConstraintKind::Parallel => return TokenStream::new(),
            ConstraintKind::Name(_)
            | ConstraintKind::OnTerminate(_)
            | ConstraintKind::ExceptionHandler(_)
            | ConstraintKind::MaximumActivate(_)
            | ConstraintKind::MaximumTrigger(_)
            | ConstraintKind::Period(_) => {
                self.diags.push(
                    Diagnostic::error(
                        stmt.constraint.span,
                        "this constraint can only be given on the spawn",
                    )
                    .with_hint("move it into the spawn's `with` list (monitor settings can also go on the monitor's definition)"),
                );
                return TokenStream::new();
            }
            _ => {}
        }
        let Some((nodes, f)) = self.lower(&stmt.constraint, &prev) else {
            return TokenStream::new();
        };
        target.each(&target_var, |t| {
            let t = t.clone();
            nodes.each(&node_var, move |n| {
                let value = f(n).value();
                quote!(ctx.constrain(#t, #value)?;)
            })
        })
    }
}

/// Renders the builder chain: one expression, or a `tdl_spawn` local when an entity is looped over.
fn render_chain(start: TokenStream, steps: Vec<Step>) -> (TokenStream, TokenStream) {
    if steps.iter().all(|s| matches!(s, Step::Method(_))) {
        let methods = steps.into_iter().map(|s| match s {
            Step::Method(m) => m,
            Step::Each(..) => TokenStream::new(),
        });
        return (TokenStream::new(), quote!(#start #(#methods)*));
    }
    let spawner = format_ident!("tdl_spawn");
    let node = format_ident!("node");
    let mut setup = quote!(let mut #spawner = #start;);
    let mut pending = TokenStream::new();
    for step in steps {
        match step {
            Step::Method(m) => pending.extend(m),
            Step::Each(nodes, f) => {
                if !pending.is_empty() {
                    setup.extend(quote!(#spawner = #spawner #pending;));
                    pending = TokenStream::new();
                }
                let body = nodes.each(&node, |n| {
                    let m = f(n);
                    quote!(#spawner = #spawner #m;)
                });
                setup.extend(body);
            }
        }
    }
    (setup, quote!(#spawner #pending))
}
