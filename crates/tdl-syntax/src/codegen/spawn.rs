//! Generation of the TDL statements that make and constrain nodes: `spawn` (a `Spawner` chain
//! with the constraints of the enclosing `with` groups and its own, then the triggers on whole
//! entities once the node exists), `with` groups (their members and `previous` as one entity),
//! `bind` and constraint statements (`ctx.constrain`, `ctx.wait`, `ctx.terminate`, the monitor
//! limits).

use proc_macro2::{Ident, TokenStream};
use quote::{format_ident, quote};

use super::body::Gen;
use super::lower::{Low, Lowered, Nodes, duration};
use super::{count_expr, handler_expr, priority_expr, uses_expr};
use crate::ast::{
    Bind, BindTarget, Binding, Constraint, ConstraintKind, ConstraintStmt, OnTerminate, Spawn,
    TagKind, TaskKind, Then, When, WithGroup,
};
use crate::diagnostic::Diagnostic;
use crate::hir::{LoopId, ResolvedTag, TagTarget, uses_previous};

/// Where the spawn's builder chain stands: plain method calls, a loop over an entity's members,
/// or a method applied only when an entity has no member.
enum Step {
    Method(TokenStream),
    Each(Nodes, Box<dyn FnOnce(&TokenStream) -> TokenStream>),
    IfEmpty(TokenStream, TokenStream),
}

/// A statement arming a trigger on the spawned node once it exists (given its expression).
type Armed = Box<dyn FnOnce(&TokenStream) -> TokenStream>;

/// What a spawn's constraints (its groups' and its own) make of it.
#[derive(Default)]
struct Parts {
    /// The builder chain.
    steps: Vec<Step>,
    /// Triggers armed once the node exists.
    armed: Vec<Armed>,
    /// `wait`.
    wait: bool,
    /// `outcome`: the binding takes how the child ended.
    outcome: bool,
    /// `name "…"`.
    name: Option<syn::Expr>,
    /// `on AGENT`: the task runs on that agent.
    on: Option<syn::Expr>,
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
        let task_name = &spawn.task;
        let values = self.clones.values(&spawn.args);
        let (var, loops, late) = match self.scope.spawn_def(spawn) {
            Some(info) => (info.var.clone(), info.site.loops.clone(), info.late),
            None => (None, Vec::new(), false),
        };
        let Parts {
            mut steps,
            armed,
            wait,
            outcome,
            name,
            on,
        } = self.spawn_parts(spawn, &loops);
        let mut task = match &on {
            None => quote!(#task_name(#(#values),*)),
            // `on AGENT`: the run's placer makes the task (docs/distributed.md, "TDL").
            Some(agent) => {
                let name = task_name.to_string();
                let kind = match self.file.task(&name).map(|t| t.kind) {
                    Some(TaskKind::Goal) => quote!(::tdl::NodeKind::Goal),
                    _ => quote!(::tdl::NodeKind::Command),
                };
                quote!(ctx.remote_task(
                    ::core::convert::AsRef::<str>::as_ref(&(#agent)),
                    #name,
                    #kind,
                    ::tdl::remote_args(#name, &(#(#values),*))?,
                )?)
            }
        };
        if let Some(name) = name {
            // `name (expr)`: the parentheses are TDL's; as a call argument they would warn.
            let mut name = &name;
            while let syn::Expr::Paren(inner) = name {
                name = &*inner.expr;
            }
            task = quote!(#task.named(#name));
        }
        let members: Vec<Ident> = self
            .frames
            .iter()
            .filter_map(|f| f.members.clone())
            .collect();
        let binds_late = late && var.is_some();
        let needs_id =
            self.scope.uses_previous || !members.is_empty() || !armed.is_empty() || binds_late;
        let mut pre = TokenStream::new();
        let mut id_expr: Option<TokenStream> = None;
        if let (Some(var), false) = (&var, late) {
            let slot = own_slot(var, &loops, &spawn.task.to_string());
            if needs_id && spawn.binding.is_some() && !loops.is_empty() {
                pre.extend(quote!(let tdl_node = #slot;));
                id_expr = Some(quote!(tdl_node));
            } else {
                id_expr = Some(slot);
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
        let node = quote!(tdl_node);
        let id = match (&spawn.binding, &id_expr) {
            (Some(_), Some(id)) => id.clone(),
            _ => node.clone(),
        };
        match (&spawn.binding, needs_id) {
            (Some(binding), _) => {
                // The node is a reservation until the spawn: the triggers are kept on it.
                for arm in armed {
                    out.extend(arm(&id));
                }
                match &binding.target {
                    BindTarget::Let(pat) if outcome => {
                        // The annotation, if any, is of the whole outcome (`tdl::Ended<T>`).
                        let ty = match &binding.ty {
                            Some(ty) => quote!(#ty),
                            None => {
                                let value = self.value_type(spawn, binding);
                                quote!(::tdl::Ended<#value>)
                            }
                        };
                        out.extend(quote!(let #pat: #ty = #chain.wait_outcome().await?;));
                    }
                    BindTarget::Let(pat) if on.is_some() => {
                        let ty = self.value_type(spawn, binding);
                        let name = task_name.to_string();
                        out.extend(quote!(let #pat: #ty = ::tdl::remote_value::<#ty>(
                            #name,
                            #chain.wait_value::<::tdl::Json>().await?,
                        )?;));
                    }
                    BindTarget::Let(pat) => {
                        let ty = self.value_type(spawn, binding);
                        out.extend(quote!(let #pat: #ty = #chain.wait_value::<#ty>().await?;));
                    }
                    BindTarget::Assign(place) if outcome => {
                        out.extend(quote!(#place = #chain.wait_outcome().await?;));
                    }
                    BindTarget::Assign(place) if on.is_some() => {
                        let name = task_name.to_string();
                        out.extend(quote!(#place = ::tdl::remote_value(
                            #name,
                            #chain.wait_value::<::tdl::Json>().await?,
                        )?;));
                    }
                    // The place's type tells the value's when the callee is not in the program.
                    BindTarget::Assign(place) => {
                        let ty = match self.file.task(&spawn.task.to_string()) {
                            Some(task) => match &task.result {
                                Some(ty) => quote!(#ty),
                                None => quote!(()),
                            },
                            None => quote!(_),
                        };
                        out.extend(quote!(#place = #chain.wait_value::<#ty>().await?;));
                    }
                }
            }
            (None, true) => {
                out.extend(quote!(let #node = #chain.start()?;));
                for arm in armed {
                    out.extend(arm(&node));
                }
                if let (Some(var), true) = (&var, binds_late) {
                    out.extend(quote!(#var = ::core::option::Option::Some(#node);));
                }
                if wait {
                    out.extend(quote!(ctx.wait(#node).await?;));
                }
            }
            (None, false) if wait => out.extend(quote!(#chain.wait().await?;)),
            (None, false) => out.extend(quote!(#chain.start()?;)),
        }
        if needs_id {
            for m in &members {
                out.extend(quote!(#m.push(#id);));
            }
            if self.scope.uses_previous {
                out.extend(quote!(#prev = ::core::option::Option::Some(::std::vec![#id]);));
            }
        }
        out
    }

    /// The builder steps and the rest of a spawn inside the loops `loops`, from the constraints of
    /// the enclosing groups (outermost first, each with its own `previous`), then its own.
    fn spawn_parts(&mut self, spawn: &'a Spawn, loops: &[LoopId]) -> Parts {
        let mut lists: Vec<(&'a [Constraint], Ident)> = self
            .frames
            .iter()
            .map(|f| (f.constraints, f.prev.clone()))
            .collect();
        lists.push((&spawn.constraints, Self::prev_ident()));
        let mut parts = Parts::default();
        for (list, list_prev) in &lists {
            for c in *list {
                let method = match &c.kind {
                    ConstraintKind::Wait => {
                        parts.wait = true;
                        continue;
                    }
                    ConstraintKind::Outcome => {
                        parts.wait = true;
                        parts.outcome = true;
                        continue;
                    }
                    ConstraintKind::Propagate => quote!(.propagate()),
                    ConstraintKind::Approval(None) => {
                        quote!(.approval(::core::option::Option::None))
                    }
                    ConstraintKind::Approval(Some(t)) => {
                        let d = duration(t);
                        quote!(.approval(::core::option::Option::Some(#d)))
                    }
                    ConstraintKind::Name(expr) => {
                        parts.name = Some(expr.clone());
                        continue;
                    }
                    ConstraintKind::Parent(expr) => quote!(.under(#expr)),
                    ConstraintKind::OnAgent(expr) => {
                        parts.on = Some(expr.clone());
                        continue;
                    }
                    ConstraintKind::OnTerminate(it) => self.on_terminate(it, loops),
                    ConstraintKind::ExceptionHandler(it) => {
                        let h = handler_expr(it, self.clones, c.span, self.diags);
                        quote!(.handler(#h))
                    }
                    ConstraintKind::MaximumActivate(n) => {
                        let n = count_expr(n, c.span, self.diags);
                        quote!(.max_activations(#n))
                    }
                    ConstraintKind::MaximumTrigger(n) => {
                        let n = count_expr(n, c.span, self.diags);
                        quote!(.max_triggers(#n))
                    }
                    ConstraintKind::Period(t) => {
                        let d = duration(t);
                        quote!(.period(#d))
                    }
                    ConstraintKind::Uses(list) => {
                        for it in list {
                            let m = uses_expr(self.file, it, self.diags);
                            parts.steps.push(Step::Method(m));
                        }
                        continue;
                    }
                    ConstraintKind::Priority(p) => priority_expr(p),
                    ConstraintKind::DenyIfBusy => quote!(.deny_if_busy()),
                    _ => {
                        match self.lower(c, list_prev) {
                            Some(Lowered::Each { nodes, low, empty }) => {
                                each_step(&mut parts.steps, nodes, low, empty);
                            }
                            Some(Lowered::Entity(arm)) => parts.armed.push(arm),
                            None => {}
                        }
                        continue;
                    }
                };
                parts.steps.push(Step::Method(method));
            }
        }
        parts
    }

    /// `on terminate [label:] spawn t(args)` on a spawn inside the loops `loops`: a labelled one
    /// that some tag names fulfils the label's reservation, which the spawned node takes over.
    fn on_terminate(&self, it: &OnTerminate, loops: &[LoopId]) -> TokenStream {
        let (t, a) = (&it.task, self.clones.values(&it.args));
        let task = quote!(#t(#(#a),*));
        match self.scope.cleanup(it).and_then(|c| c.var.as_ref()) {
            Some(var) => {
                let slot = own_slot(var, loops, &it.task.to_string());
                quote!(.on_terminate_fulfils(#task, #slot))
            }
            None => quote!(.on_terminate(#task)),
        }
    }

    /// `bind name = expr;`: the tag's local holds the node from now on.
    pub(super) fn bind(&mut self, bind: &Bind) -> TokenStream {
        let expr = &bind.expr;
        match self
            .scope
            .bound
            .get(&bind.name.to_string())
            .and_then(|it| it.var.as_ref())
        {
            Some(var) => quote!(#var = ::core::option::Option::Some::<::tdl::NodeId>(#expr);),
            None => quote!(let _: ::tdl::NodeId = #expr;),
        }
    }

    /// The type of a waited spawn's value: the callee's declared result, else the annotation.
    fn value_type(&mut self, spawn: &Spawn, binding: &Binding) -> TokenStream {
        if let Some(ty) = &binding.ty {
            return quote!(#ty);
        }
        let name = spawn.task.to_string();
        if let (None, Some(decl)) = (self.file.task(&name), self.file.extern_decl(&name)) {
            return match &decl.result {
                Some(ty) => quote!(#ty),
                None => quote!(()),
            };
        }
        match self.file.task(&name) {
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
                (Some(var), _) => {
                    out.extend(quote!(#prev = ::core::option::Option::Some(#var.clone());));
                }
                (None, Some(var)) => {
                    out.extend(quote!(#prev = ::core::option::Option::Some(#var);))
                }
                (None, None) => {}
            }
        }
        out
    }

    pub(super) fn constrain(&mut self, stmt: &ConstraintStmt) -> TokenStream {
        let prev = Self::prev_ident();
        let target = match &stmt.tag.kind {
            TagKind::Parent => {
                if let Some(resolved) = self.resolved {
                    let parent = [TagTarget::Parent];
                    resolved
                        .borrow_mut()
                        .push(ResolvedTag::new(0, &stmt.tag, parent));
                }
                Nodes::One(quote!(ctx.node()))
            }
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
        let c = &stmt.constraint;
        match &c.kind {
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
            // Monitor limits set again after the spawn (docs/semantics.md, "Monitors").
            ConstraintKind::MaximumActivate(n) => {
                let n = count_expr(n, c.span, self.diags);
                return target.each(&target_var, |t| quote!(ctx.set_max_activations(#t, #n)?;));
            }
            ConstraintKind::MaximumTrigger(n) => {
                let n = count_expr(n, c.span, self.diags);
                return target.each(&target_var, |t| quote!(ctx.set_max_triggers(#t, #n)?;));
            }
            ConstraintKind::Period(t) => {
                let d = duration(t);
                return target.each(&target_var, |t| quote!(ctx.set_period(#t, #d)?;));
            }
            // Refused by the diagnosis: they only go on a spawn.
            ConstraintKind::Name(_)
            | ConstraintKind::OnTerminate(_)
            | ConstraintKind::ExceptionHandler(_)
            | ConstraintKind::Parent(_)
            | ConstraintKind::Outcome
            | ConstraintKind::Propagate
            | ConstraintKind::Approval(_)
            | ConstraintKind::Uses(_)
            | ConstraintKind::Priority(_)
            | ConstraintKind::DenyIfBusy => return TokenStream::new(),
            _ => {}
        }
        match self.lower(c, &prev) {
            Some(Lowered::Each { nodes, low, empty }) => target.each(&target_var, |t| {
                let t = t.clone();
                let mut out = nodes.each(&node_var, |n| {
                    let value = low(n).value();
                    quote!(ctx.constrain(#t, #value)?;)
                });
                if let (Nodes::Entity(members), Some(empty)) = (&nodes, empty) {
                    let value = empty.value();
                    out.extend(quote! {
                        if ::tdl::codegen::no_members(#members) {
                            ctx.constrain(#t, #value)?;
                        }
                    });
                }
                out
            }),
            Some(Lowered::Entity(arm)) => target.each(&target_var, arm),
            None => TokenStream::new(),
        }
    }
}

/// The steps of a constraint applied per node: one method, a loop over an entity's members (and,
/// for an entity with no member, `empty`), or nothing.
fn each_step(
    steps: &mut Vec<Step>,
    nodes: Nodes,
    low: Box<dyn FnOnce(&TokenStream) -> Low>,
    empty: Option<Low>,
) {
    match nodes {
        Nodes::One(n) => steps.push(Step::Method(low(&n).method())),
        Nodes::None => {}
        Nodes::Entity(members) => {
            steps.push(Step::Each(
                Nodes::Entity(members.clone()),
                Box::new(move |n| low(n).method()),
            ));
            if let Some(empty) = empty {
                steps.push(Step::IfEmpty(members, empty.method()));
            }
        }
    }
}

/// The node of a spawn (or of its labelled on-terminate task) held in `var`: the reservation, or,
/// inside the loops `loops`, this iteration's entry of the map, reserved on first use.
fn own_slot(var: &Ident, loops: &[LoopId], name: &str) -> TokenStream {
    if loops.is_empty() {
        return quote!(#var);
    }
    let keys = loops.iter().map(|l| format_ident!("tdl_i_{}", l));
    quote!(tdl_slot(&ctx, &mut #var, [#(#keys),*], #name)?)
}

/// Renders the builder chain: one expression, or a `tdl_spawn` local when an entity is looped over.
fn render_chain(start: TokenStream, steps: Vec<Step>) -> (TokenStream, TokenStream) {
    if steps.iter().all(|s| matches!(s, Step::Method(_))) {
        let methods = steps.into_iter().map(|s| match s {
            Step::Method(m) => m,
            Step::Each(..) | Step::IfEmpty(..) => TokenStream::new(),
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
            Step::IfEmpty(members, m) => {
                if !pending.is_empty() {
                    setup.extend(quote!(#spawner = #spawner #pending;));
                    pending = TokenStream::new();
                }
                setup.extend(quote! {
                    if ::tdl::codegen::no_members(#members) {
                        #spawner = #spawner #m;
                    }
                });
            }
        }
    }
    (setup, quote!(#spawner #pending))
}
