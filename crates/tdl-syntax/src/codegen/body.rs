//! Generation of one task body: TDL statements become `tcm` builder calls between the Rust
//! statements, which are copied verbatim. This file assembles the body (its prelude, tail value,
//! handler locals and persistent variables) and walks its statements; spawns, groups and
//! constraint statements are in `spawn.rs`, constraints in `lower.rs`. What the names mean comes
//! from the resolved program (`hir.rs`).
//!
//! Run-time bookkeeping, in generated locals (all named `tdl_*`):
//! 1. Every tag that some constraint names is *reserved* at the top of the body
//!    (`let tdl_x = ctx.reserve("x")?;`) and its spawn *fulfils* the reservation. Forward
//!    references then work, and a reference to a spawn that never runs (an `if` not taken) is a
//!    dead reservation, which the engine treats as TDL does: enablement constraints on it are void
//!    and `terminate at` it fires at once (docs/semantics.md, "Tags and forward references").
//! 2. A tag spawned inside loops is a map from iteration numbers (one 0-based count per enclosing
//!    loop, outermost first) to nodes, `tdl_x: BTreeMap<[i64; N], NodeId>`; `tdl_slot` reserves an
//!    entry on demand, so `move_by[i - 1]` and `move_by[i + 1]` both work. Fewer indexes than loops
//!    name every entry with that prefix so far.
//! 3. `previous` is the *entity* executed just before: one node, or every node of a `with` group,
//!    which counts as one entity for the statements around it (TDL paper, "with/do"). It lives in
//!    `tdl_prev: Option<Vec<NodeId>>`, `None` before anything ran. A group's own constraints
//!    resolve `previous` relative to the group's direct child: for a spawn inside a nested group,
//!    the outer group's `previous` is the entity before the nested group (a snapshot `tdl_prev_N`
//!    taken when the nested group starts).
//! 4. A constraint naming an entity of several nodes (`codegen/lower.rs`) is applied once per
//!    node for enablement, so all must be done; `terminate` and `activate` on its event happen
//!    once every member reached it, at once for an entity with no member.
//! 5. A tag whose node is only known when a statement runs (`bind name = …;`, a spawn with
//!    `parent`) is a local `Option<NodeId>`, an entity of at most one node.
//! 6. `node!(tag)` in Rust code becomes the tag's node expression (its reservation, its entry in
//!    a loop's map, or `tdl::codegen::bound(..)?` for a tag bound at run time).

use std::cell::RefCell;

use proc_macro2::{Ident, Literal, Span, TokenStream, TokenTree};
use quote::{format_ident, quote};

use super::spawn::Frame;
use crate::ast::{Block, Else, Fail, ResourceOp, Stmt, Task, TaskConstraintKind, TaskKind};
use crate::diagnostic::Diagnostic;
use crate::hir::{BodyScope, FileScope, LoopId, ResolvedTag, node_macro, state_macro};

/// A generated action body.
pub(super) struct Action {
    /// The statements of the `async move` block, ending with its `Ok(..)`.
    pub(super) code: TokenStream,
    /// Whether locals are assigned that the code may not read again: `previous` tracked in
    /// `tdl_prev`, or tags bound at run time.
    pub(super) reassigns: bool,
}

/// Generates the body of `task`.
pub(super) fn task_body(
    file: &FileScope<'_>,
    task: &Task,
    clones: &super::by_value::Clones,
    source: Option<&str>,
    diags: &mut Vec<Diagnostic>,
    resolved: Option<&RefCell<Vec<ResolvedTag>>>,
) -> Action {
    let mut g = Gen {
        file,
        task,
        source,
        scope: file.body(task),
        diags,
        frames: Vec::new(),
        loops: Vec::new(),
        resolved,
        clones,
    };
    let mut code = g.prelude();
    let stmts = &task.body.stmts;
    let tail_is_exit = matches!(
        stmts.last(),
        Some(Stmt::Succeed(_) | Stmt::Fail(_) | Stmt::Bypass(_))
    );
    let n_stmts = stmts.len();
    let mut inner = TokenStream::new();
    for (i, stmt) in stmts.iter().enumerate() {
        let last = i + 1 == n_stmts;
        inner.extend(g.source_marker(Some(stmt)));
        match stmt {
            // The last statement of a unit task: a tail expression becomes a statement, and the
            // exits become the block's value (no unreachable `Ok(())` after them).
            Stmt::Rust(it) if last && task.result.is_none() => {
                let tokens = &it.tokens;
                if ends_with_semicolon(tokens) {
                    inner.extend(tokens.clone());
                } else {
                    inner.extend(quote!(#tokens;));
                }
            }
            Stmt::Succeed(span) if last => {
                if task.result.is_some() {
                    g.diags.push(succeed_with_result(*span));
                }
                inner.extend(quote!(::core::result::Result::Ok(())));
            }
            Stmt::Fail(it) if last => {
                let err = fail_error(file, it);
                inner.extend(quote!(::core::result::Result::Err::<(), ::tdl::Failure>(#err)));
            }
            Stmt::Bypass(_) if last && task.result.is_none() => inner.extend(quote!(ctx.bypass())),
            _ => inner.extend(g.stmt(stmt)),
        }
    }
    match &task.result {
        Some(ty) => code.extend(quote! {
            let tdl_result: #ty = { #inner };
            ::core::result::Result::Ok(tdl_result)
        }),
        None if tail_is_exit => code.extend(inner),
        None => {
            // The closing `Ok(())` is the generator's, not the last statement's.
            let marker = g.source_marker(None);
            code.extend(quote! {
                #inner
                #marker
                ::core::result::Result::Ok(())
            });
        }
    }
    let code = g.rewrite_node_uses(code);
    let reassigns = g.scope.uses_previous
        || g.scope.bound.values().any(|it| it.var.is_some())
        || g.scope.spawns.iter().any(|it| it.late && it.var.is_some());
    // Handler bodies: the exception's data and the nodes involved, when the body names them.
    let mut head = quote!(ctx.hold_children(true)?;);
    if task.kind == TaskKind::Handler {
        let name = task.name.to_string();
        // The caught exception only through the explicit binding `handles E as name`: a word
        // `exception` in the body is plain Rust (docs/semantics.md, "Exceptions and handlers").
        if let (Some(exc), Some(var)) = (&task.handles, &task.caught) {
            let exc = g.file.exception_type(exc);
            head.extend(quote! {
                let #var: ::tdl::Caught<#exc> = ::tdl::codegen::caught::<#exc>(&ctx, #name)?;
            });
        }
        if mentions(&code, "failing") {
            head.extend(quote!(let failing: ::tdl::NodeId = ::tdl::codegen::failing_node(&ctx)?;));
        }
        if mentions(&code, "attached") {
            head.extend(
                quote!(let attached: ::tdl::NodeId = ::tdl::codegen::attached_node(&ctx)?;),
            );
        }
    }
    let cells = persistent_cells(task);
    let code = if cells.is_empty() {
        quote!(#head #code)
    } else {
        // Each run starts from the stored values and stores its own back however its body ends
        // (the inner block catches `return` and `?`).
        let ok = match &task.result {
            Some(ty) => quote!(#ty),
            None => quote!(()),
        };
        let loads = cells.iter().map(
            |(var, cell, ty, _)| quote!(#[allow(unused_mut)] let mut #var: #ty = #cell.load();),
        );
        let stores = cells
            .iter()
            .map(|(var, cell, _, _)| quote!(#cell.store(#var);));
        quote! {
            #head
            #(#loads)*
            let tdl_outcome: ::core::result::Result<#ok, ::tdl::Failure> = async { #code }.await;
            #(#stores)*
            tdl_outcome
        }
    };
    Action { code, reassigns }
}

/// The `persistent` variables of a monitor or handler, shared by its runs: (variable, cell,
/// type, initial value). Goals and commands run once, so theirs are plain locals.
pub(super) fn persistent_cells(task: &Task) -> Vec<(Ident, Ident, syn::Type, TokenStream)> {
    if !matches!(task.kind, TaskKind::Monitor | TaskKind::Handler) {
        return Vec::new();
    }
    task.constraints
        .iter()
        .filter_map(|c| match &c.kind {
            TaskConstraintKind::Persistent(p) => {
                let init = match &p.init {
                    Some(init) => quote!(#init),
                    None => quote!(::core::default::Default::default()),
                };
                let cell = format_ident!("tdl_persistent_{}", p.name);
                Some((p.name.clone(), cell, p.ty.clone(), init))
            }
            _ => None,
        })
        .collect()
}

fn succeed_with_result(span: Span) -> Diagnostic {
    Diagnostic::error(span, "`succeed` in a task with a result type")
        .with_hint("end the body with the result value instead, as a Rust tail expression")
}

fn ends_with_semicolon(tokens: &TokenStream) -> bool {
    matches!(tokens.clone().into_iter().last(), Some(TokenTree::Punct(p)) if p.as_char() == ';')
}

/// Whether `tokens` name `word`, as an identifier that is not a field or method (`x.word`), or as
/// an inline format argument (`"{word}"`, `"{word:?}"`).
fn mentions(tokens: &TokenStream, word: &str) -> bool {
    let mut after_dot = false;
    tokens.clone().into_iter().any(|it| {
        let found = match &it {
            TokenTree::Ident(id) => id == word && !after_dot,
            TokenTree::Group(group) => mentions(&group.stream(), word),
            TokenTree::Literal(lit) => {
                let text = lit.to_string();
                text.contains(&format!("{{{word}}}")) || text.contains(&format!("{{{word}:"))
            }
            TokenTree::Punct(_) => false,
        };
        after_dot = matches!(&it, TokenTree::Punct(p) if p.as_char() == '.');
        found
    })
}

/// `fail Exc { .. }` as a `tdl::Failure` expression: raised through `tdl::Exception` when the
/// exception is declared in the source (so handlers of its ancestors match), else converted as
/// any error.
fn fail_error(file: &FileScope<'_>, fail: &Fail) -> TokenStream {
    match &fail.exception {
        Some(exc) if file.declares_exception(&exc.to_string()) => {
            let fields = &fail.fields;
            quote!(::tdl::Exception::raise(#exc { #(#fields),* }))
        }
        Some(exc) => {
            let fields = &fail.fields;
            quote!(::tdl::Failure::from(#exc { #(#fields),* }))
        }
        None => quote!(::tdl::Failure::new("Fail", "fail without an exception")),
    }
}

/// The macro name of the source markers that the generator puts before each statement when it
/// generates for a `.tdl` file; [`super::pretty`] turns them into comments.
pub(crate) const SOURCE_MARKER: &str = "__tdl_source";

/// The span of a statement's first token.
fn stmt_span(stmt: &Stmt) -> Span {
    match stmt {
        Stmt::Rust(it) => it.span,
        Stmt::Spawn(it) => it.span,
        Stmt::With(it) => it.span,
        Stmt::Constrain(it) => it.span,
        Stmt::Bind(it) => it.span,
        Stmt::Fail(it) => it.span,
        Stmt::If(it) => it.span,
        Stmt::For(it) => it.span,
        Stmt::While(it) => it.span,
        Stmt::Loop(it) => it.span,
        Stmt::Match(it) => it.span,
        Stmt::Block(it) => it.span,
        Stmt::Succeed(span) | Stmt::Bypass(span) | Stmt::Trigger(span) => *span,
        Stmt::Retry(it) => it.span,
        Stmt::Resource(it) => it.span,
        Stmt::Set(it) => it.span,
        Stmt::Raise(it) => it.span,
        Stmt::Log(it) => it.span,
    }
}

/// The generator of one body.
pub(super) struct Gen<'s, 'a> {
    pub(super) file: &'s FileScope<'a>,
    pub(super) task: &'a Task,
    /// The `.tdl` file's name when generating for a file: each statement is then preceded by a
    /// source marker (see [`SOURCE_MARKER`]).
    pub(super) source: Option<&'s str>,
    /// The body's names, resolved.
    pub(super) scope: &'s BodyScope<'a>,
    pub(super) diags: &'s mut Vec<Diagnostic>,
    /// The `with` groups around the statement being generated, outermost first.
    pub(super) frames: Vec<Frame<'a>>,
    /// The loops around the statement being generated, outermost first.
    pub(super) loops: Vec<LoopId>,
    /// Where to record what each tag of a constraint resolved to ([`super::generated_tags`]).
    pub(super) resolved: Option<&'s RefCell<Vec<ResolvedTag>>>,
    /// The arguments passed as clones (`by_value.rs`).
    pub(super) clones: &'s super::by_value::Clones,
}

impl<'a> Gen<'_, 'a> {
    pub(super) fn prev_ident() -> Ident {
        format_ident!("tdl_prev")
    }

    /// Locals declared at the top of the body: persistent variables, reservations, maps and the
    /// `previous` tracker.
    fn prelude(&mut self) -> TokenStream {
        let mut out = TokenStream::new();
        let local_persistent = matches!(self.task.kind, TaskKind::Goal | TaskKind::Command);
        for c in &self.task.constraints {
            if let (TaskConstraintKind::Persistent(p), true) = (&c.kind, local_persistent) {
                let (name, ty) = (&p.name, &p.ty);
                let init = match &p.init {
                    Some(init) => quote!(#init),
                    None => quote!(::core::default::Default::default()),
                };
                out.extend(quote!(let mut #name: #ty = #init;));
            }
        }
        let mut maps = false;
        let late = self
            .scope
            .spawns
            .iter()
            .filter(|it| it.late)
            .filter_map(|it| it.var.as_ref())
            .chain(self.scope.bound.values().filter_map(|it| it.var.as_ref()));
        for var in late {
            out.extend(quote! {
                let mut #var: ::core::option::Option<::tdl::NodeId> = ::core::option::Option::None;
            });
        }
        let reserved = self
            .scope
            .spawns
            .iter()
            .filter(|it| !it.late)
            .filter_map(|it| Some((it.var.as_ref()?, &it.spawn.task, &it.site.loops)));
        let cleanups = self.scope.cleanups.iter().filter_map(|it| {
            let loops = &self.scope.spawns[it.spawn].site.loops;
            Some((it.var.as_ref()?, &it.on_terminate.task, loops))
        });
        for (var, task, loops) in reserved.chain(cleanups) {
            let name = task.to_string();
            if loops.is_empty() {
                out.extend(quote!(let #var = ctx.reserve(#name)?;));
            } else {
                maps = true;
                let n = Literal::usize_unsuffixed(loops.len());
                out.extend(quote! {
                    let mut #var: ::std::collections::BTreeMap<[i64; #n], ::tdl::NodeId> =
                        ::std::collections::BTreeMap::new();
                });
            }
        }
        for group in &self.scope.groups {
            if let Some(var) = &group.var {
                out.extend(
                    quote!(let mut #var: ::std::vec::Vec<::tdl::NodeId> = ::std::vec::Vec::new();),
                );
            }
        }
        if self.scope.uses_previous {
            let prev = Self::prev_ident();
            out.extend(quote! {
                let mut #prev: ::core::option::Option<::std::vec::Vec<::tdl::NodeId>> =
                    ::core::option::Option::None;
            });
        }
        if maps {
            out.extend(quote! {
                /// The node of an iteration-indexed tag, reserved on first use.
                fn tdl_slot<const N: usize>(
                    ctx: &::tdl::Ctx,
                    slots: &mut ::std::collections::BTreeMap<[i64; N], ::tdl::NodeId>,
                    key: [i64; N],
                    name: &'static str,
                ) -> ::core::result::Result<::tdl::NodeId, ::tdl::Error> {
                    if let ::core::option::Option::Some(node) = slots.get(&key) {
                        return ::core::result::Result::Ok(*node);
                    }
                    let node = ctx.reserve(name)?;
                    slots.insert(key, node);
                    ::core::result::Result::Ok(node)
                }
            });
        }
        out
    }

    /// The source marker before `stmt` (`__tdl_source!("walk.tdl:42");`), or before code of
    /// the generator's own (`__tdl_source!();`) when `stmt` is `None`; nothing when generating
    /// for the macro, whose spans already point at the source.
    fn source_marker(&self, stmt: Option<&Stmt>) -> TokenStream {
        let Some(file) = self.source else {
            return TokenStream::new();
        };
        let marker = Ident::new(SOURCE_MARKER, Span::call_site());
        match stmt {
            Some(stmt) => {
                let text = format!("{file}:{}", stmt_span(stmt).start().line);
                quote!(#marker!(#text);)
            }
            None => quote!(#marker!();),
        }
    }

    pub(super) fn block(&mut self, block: &'a Block) -> TokenStream {
        let mut out = TokenStream::new();
        for stmt in &block.stmts {
            out.extend(self.source_marker(Some(stmt)));
            out.extend(self.stmt(stmt));
        }
        out
    }

    fn stmt(&mut self, stmt: &'a Stmt) -> TokenStream {
        match stmt {
            Stmt::Rust(it) => it.tokens.clone(),
            Stmt::Spawn(spawn) => self.spawn(spawn),
            Stmt::With(group) => self.with(group),
            Stmt::Constrain(it) => self.constrain(it),
            Stmt::Bind(it) => self.bind(it),
            Stmt::Succeed(span) => {
                if self.task.result.is_some() {
                    self.diags.push(succeed_with_result(*span));
                }
                quote!(return ::core::result::Result::Ok(());)
            }
            Stmt::Fail(it) => {
                let err = fail_error(self.file, it);
                quote!(return ::core::result::Result::Err(#err);)
            }
            // Handlers only, monitors only (the diagnosis reports them elsewhere).
            Stmt::Bypass(_) => quote!(return ctx.bypass();),
            Stmt::Trigger(_) => quote!(ctx.trigger()?;),
            Stmt::Resource(it) => {
                let r = super::resource_ref(self.file, &it.name);
                match it.op {
                    ResourceOp::Lock => quote!(ctx.lock_resource(#r)?;),
                    ResourceOp::Unlock => quote!(ctx.unlock_resource(#r)?;),
                    ResourceOp::Reserve => quote!(ctx.reserve_resource(#r, ctx.node())?;),
                    ResourceOp::Unreserve => quote!(ctx.unreserve_resource(#r)?;),
                }
            }
            Stmt::Set(it) => super::state::set(self.file, it),
            Stmt::Raise(it) => super::state::raise(it),
            Stmt::Log(it) => {
                let args = it.format_args();
                quote!(ctx.log(::std::format!(#args))?;)
            }
            Stmt::Retry(it) => {
                let retry = match &it.args {
                    None => quote!(ctx.retry()?),
                    Some(args) => {
                        let args = self.clones.values(args);
                        quote!(ctx.retry_with((#(#args,)*))?)
                    }
                };
                quote! {
                    let tdl_retry = #retry;
                    ctx.wait(tdl_retry).await?;
                }
            }
            Stmt::If(it) => self.if_stmt(it),
            Stmt::For(it) => {
                let (label, pat, expr) = (&it.label, &it.pat, &it.expr);
                let label = label.as_ref().map(|l| quote!(#l:));
                self.loop_stmt(&it.body, |body| quote!(#label for #pat in #expr { #body }))
            }
            Stmt::While(it) => {
                let (label, cond) = (&it.label, &it.cond);
                let label = label.as_ref().map(|l| quote!(#l:));
                self.loop_stmt(&it.body, |body| quote!(#label while #cond { #body }))
            }
            Stmt::Loop(it) => {
                let label = it.label.as_ref().map(|l| quote!(#l:));
                self.loop_stmt(&it.body, |body| quote!(#label loop { #body }))
            }
            Stmt::Match(it) => {
                let expr = &it.expr;
                let arms: Vec<TokenStream> = it
                    .arms
                    .iter()
                    .map(|arm| {
                        let pat = &arm.pat;
                        let guard = arm.guard.as_ref().map(|g| quote!(if #g));
                        let body = self.block(&arm.body);
                        quote!(#pat #guard => { #body })
                    })
                    .collect();
                quote!(match #expr { #(#arms)* })
            }
            Stmt::Block(it) => {
                let body = self.block(it);
                quote!({ #body })
            }
        }
    }

    fn if_stmt(&mut self, it: &'a crate::ast::If) -> TokenStream {
        let cond = &it.cond;
        let then = self.block(&it.then_branch);
        let els = match it.else_branch.as_deref() {
            Some(Else::If(next)) => {
                let next = self.if_stmt(next);
                quote!(else #next)
            }
            Some(Else::Block(block)) => {
                let body = self.block(block);
                quote!(else { #body })
            }
            None => TokenStream::new(),
        };
        quote!(if #cond { #then } #els)
    }

    /// A loop; counted loops number their iterations for iteration-indexed tags.
    fn loop_stmt(
        &mut self,
        body: &'a Block,
        wrap: impl FnOnce(TokenStream) -> TokenStream,
    ) -> TokenStream {
        let id = self.scope.loop_id(body);
        self.loops.extend(id);
        let inner = self.block(body);
        if id.is_some() {
            self.loops.pop();
        }
        let Some(id) = id.filter(|id| self.scope.is_counted(*id)) else {
            return wrap(inner);
        };
        let (count, iter) = (format_ident!("tdl_n_{}", id), format_ident!("tdl_i_{}", id));
        let body = quote! {
            let #iter = #count;
            #count += 1;
            #inner
        };
        let looped = wrap(body);
        quote! {
            let mut #count: i64 = 0;
            #looped
        }
    }

    /// Replaces each `node!(tag)` in the generated body by the tag's node (docs/language.md,
    /// "Tags, `previous` and groups"), and each `state!(x)` by the variable's value read as an
    /// `Option` of its type ("State and conditions"); one the diagnosis refused stays as written.
    fn rewrite_node_uses(&self, tokens: TokenStream) -> TokenStream {
        let tts: Vec<TokenTree> = tokens.into_iter().collect();
        let mut out = TokenStream::new();
        let mut i = 0;
        while i < tts.len() {
            let node = node_macro(&tts[i..])
                .and_then(|(inner, _)| crate::parser::parse_tag_tokens(inner).ok())
                .and_then(|tag| self.node_expr(&tag));
            let state = || {
                state_macro(&tts[i..])
                    .and_then(|(inner, _)| syn::parse2::<Ident>(inner).ok())
                    .and_then(|name| super::state::read(self.file, &name))
            };
            if let Some(expr) = node.or_else(state) {
                out.extend(quote!((#expr)));
                i += 3;
                continue;
            }
            match &tts[i] {
                TokenTree::Group(group) => {
                    let mut inner = proc_macro2::Group::new(
                        group.delimiter(),
                        self.rewrite_node_uses(group.stream()),
                    );
                    inner.set_span(group.span());
                    out.extend([TokenTree::Group(inner)]);
                }
                other => out.extend([other.clone()]),
            }
            i += 1;
        }
        out
    }
}
