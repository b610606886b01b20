//! Generation of one task body: TDL statements become `tcm` builder calls between the Rust
//! statements, which are copied verbatim.
//!
//! Run-time bookkeeping, in generated locals (all named `tdl_*`):
//! 1. Every tag that some constraint names is *reserved* at the top of the body
//!    (`let tdl_x = ctx.reserve("x")?;`) and its spawn *fulfils* the reservation. Forward
//!    references then work, and a reference to a spawn that never runs (an `if` not taken) is a
//!    dead reservation, which the engine treats as TDL does: enablement constraints on it are void
//!    and `terminate at` it fires at once (catalogue §1.6).
//! 2. A tag spawned inside loops is a map from iteration numbers (one 0-based count per enclosing
//!    loop, outermost first) to nodes, `tdl_x: BTreeMap<[i64; N], NodeId>`; `tdl_slot` reserves an
//!    entry on demand, so `move_by[i - 1]` and `move_by[i + 1]` both work. Fewer indexes than loops
//!    name every entry with that prefix so far.
//! 3. `previous` is the *entity* executed just before: one node, or every node of a `with` group,
//!    which counts as one entity for the statements around it (TDL paper, "with/do"). It lives in
//!    `tdl_prev: Vec<NodeId>`. A group's own constraints resolve `previous` relative to the group's
//!    direct child: for a spawn inside a nested group, the outer group's `previous` is the entity
//!    before the nested group (a snapshot `tdl_prev_N` taken when the nested group starts).
//! 4. A constraint naming an entity of several nodes is applied once per node: for enablement all
//!    must be done, for `terminate at` the first wins.

use std::collections::{BTreeMap, BTreeSet};

use proc_macro2::{Ident, Literal, Span, TokenStream, TokenTree};
use quote::{format_ident, quote};

use super::{FileCx, count_expr, handler_expr};
use crate::ast::{
    Binding, Block, Constraint, ConstraintKind, ConstraintStmt, Else, Event, Facet, Fail, RelTime,
    Spawn, State, Stmt, Tag, TagIndex, TagKind, Task, TaskConstraintKind, TaskKind, When,
    WithGroup,
};
use crate::diagnostic::Diagnostic;

/// A generated action body.
pub(super) struct Action {
    /// The statements of the `async move` block, ending with its `Ok(..)`.
    pub(super) code: TokenStream,
    /// Whether `previous` is tracked in `tdl_prev`.
    pub(super) tracks_previous: bool,
}

/// Generates the body of `task`.
pub(super) fn task_body(file: &FileCx, task: &Task, diags: &mut Vec<Diagnostic>) -> Action {
    let mut an = Analysis::default();
    an.walk_block(&task.body);
    an.resolve(diags);
    let mut g = Gen {
        file,
        task,
        an,
        diags,
        n_spawn: 0,
        n_group: 0,
        n_loop: 0,
        frames: Vec::new(),
        loops: Vec::new(),
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
        None => code.extend(quote! {
            #inner
            ::core::result::Result::Ok(())
        }),
    }
    let tracks_previous = g.an.uses_prev;
    // Handler bodies: the exception's data and the nodes involved, when the body names them.
    let mut head = quote!(ctx.hold_children(true)?;);
    if task.kind == TaskKind::Handler {
        let name = task.name.to_string();
        if let Some(exc) = &task.handles {
            if mentions(&code, "exception") {
                head.extend(quote! {
                    let exception: ::std::sync::Arc<#exc> = ::tdl::codegen::caught::<#exc>(&ctx, #name)?;
                });
            }
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
    Action {
        code,
        tracks_previous,
    }
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

/// Whether `tokens` name `word`, as an identifier or as an inline format argument (`"{word}"`,
/// `"{word:?}"`).
fn mentions(tokens: &TokenStream, word: &str) -> bool {
    tokens.clone().into_iter().any(|it| match it {
        TokenTree::Ident(id) => id == word,
        TokenTree::Group(group) => mentions(&group.stream(), word),
        TokenTree::Literal(lit) => {
            let text = lit.to_string();
            text.contains(&format!("{{{word}}}")) || text.contains(&format!("{{{word}:"))
        }
        TokenTree::Punct(_) => false,
    })
}

/// `fail Exc { .. }` as a `tdl::Failure` expression: raised through `tdl::Exception` when the
/// exception is declared in the source (so handlers of its ancestors match), else converted as
/// any error.
fn fail_error(file: &FileCx, fail: &Fail) -> TokenStream {
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

/// Where a tag is defined.
#[derive(Clone, Copy)]
enum Def {
    Spawn(usize),
    Group(usize),
    OnTerminate,
}

#[derive(Default)]
struct SpawnInfo {
    task: String,
    labels: Vec<String>,
    /// Enclosing loops, outermost first.
    loops: Vec<usize>,
    referenced: bool,
    var: Option<Ident>,
}

#[derive(Default)]
struct GroupInfo {
    labels: Vec<String>,
    position: usize,
    referenced: bool,
    var: Option<Ident>,
}

struct Reference {
    name: String,
    position: usize,
    span: Span,
}

/// What the generator must know before it writes a body: which tags are named, by whom.
#[derive(Default)]
struct Analysis {
    spawns: Vec<SpawnInfo>,
    groups: Vec<GroupInfo>,
    on_terminate_labels: Vec<(String, Span)>,
    refs: Vec<Reference>,
    uses_prev: bool,
    /// Loops whose iterations are counted, for iteration-indexed tags.
    counted: BTreeSet<usize>,
    n_loops: usize,
    loops: Vec<usize>,
    position: usize,
    names: BTreeMap<String, Def>,
}

impl Analysis {
    fn walk_block(&mut self, block: &Block) {
        for stmt in &block.stmts {
            self.walk_stmt(stmt);
        }
    }

    fn walk_stmt(&mut self, stmt: &Stmt) {
        self.position += 1;
        match stmt {
            Stmt::Spawn(spawn) => {
                self.spawns.push(SpawnInfo {
                    task: spawn.task.to_string(),
                    labels: spawn.labels.iter().map(ToString::to_string).collect(),
                    loops: self.loops.clone(),
                    ..SpawnInfo::default()
                });
                self.constraints(&spawn.constraints);
            }
            Stmt::With(group) => {
                self.groups.push(GroupInfo {
                    labels: group.labels.iter().map(ToString::to_string).collect(),
                    position: self.position,
                    ..GroupInfo::default()
                });
                self.constraints(&group.constraints);
                self.walk_block(&group.body);
            }
            Stmt::Constrain(it) => {
                self.tag(&it.tag);
                self.constraints(std::slice::from_ref(&it.constraint));
            }
            Stmt::If(it) => self.walk_if(it),
            Stmt::For(it) => self.walk_loop(&it.body),
            Stmt::While(it) => self.walk_loop(&it.body),
            Stmt::Loop(it) => self.walk_loop(&it.body),
            Stmt::Match(it) => {
                for arm in &it.arms {
                    self.walk_block(&arm.body);
                }
            }
            Stmt::Block(it) => self.walk_block(it),
            Stmt::Rust(_)
            | Stmt::Succeed(_)
            | Stmt::Fail(_)
            | Stmt::Bypass(_)
            | Stmt::Trigger(_)
            | Stmt::Retry(_) => {}
        }
    }

    fn walk_if(&mut self, it: &crate::ast::If) {
        self.walk_block(&it.then_branch);
        match it.else_branch.as_deref() {
            Some(Else::If(next)) => self.walk_if(next),
            Some(Else::Block(block)) => self.walk_block(block),
            None => {}
        }
    }

    fn walk_loop(&mut self, body: &Block) {
        let id = self.n_loops;
        self.n_loops += 1;
        self.loops.push(id);
        self.walk_block(body);
        self.loops.pop();
    }

    fn constraints(&mut self, constraints: &[Constraint]) {
        for c in constraints {
            match &c.kind {
                ConstraintKind::Sequential { tag, .. } | ConstraintKind::Serial { tag } => {
                    match tag {
                        Some(tag) => self.tag(tag),
                        None => self.uses_prev = true,
                    }
                }
                ConstraintKind::DisableUntil {
                    until: When::Event(ev),
                    ..
                }
                | ConstraintKind::TerminateAt(When::Event(ev))
                | ConstraintKind::ActivateAt(When::Event(ev)) => self.tag(&ev.tag),
                ConstraintKind::DisableFor { after, .. }
                | ConstraintKind::TerminateIn { after, .. }
                | ConstraintKind::ActivateIn { after, .. } => {
                    if let Some(ev) = after {
                        self.tag(&ev.tag);
                    }
                }
                ConstraintKind::OnTerminate(it) => {
                    for label in &it.labels {
                        self.on_terminate_labels
                            .push((label.to_string(), label.span()));
                    }
                }
                _ => {}
            }
        }
    }

    fn tag(&mut self, tag: &Tag) {
        match &tag.kind {
            TagKind::Previous => self.uses_prev = true,
            TagKind::Named { name, .. } => self.refs.push(Reference {
                name: name.to_string(),
                position: self.position,
                span: tag.span,
            }),
            TagKind::Child | TagKind::Parent => {}
        }
    }

    /// Resolves names to definitions and marks what must be reserved or counted.
    fn resolve(&mut self, diags: &mut Vec<Diagnostic>) {
        let mut by_task: BTreeMap<&str, Vec<usize>> = BTreeMap::new();
        for (i, spawn) in self.spawns.iter().enumerate() {
            by_task.entry(&spawn.task).or_default().push(i);
        }
        let mut names = BTreeMap::new();
        for (task, ids) in by_task {
            if let [only] = ids.as_slice() {
                names.insert(task.to_owned(), Def::Spawn(*only));
            }
        }
        for (i, spawn) in self.spawns.iter().enumerate() {
            for label in &spawn.labels {
                names.insert(label.clone(), Def::Spawn(i));
            }
        }
        for (i, group) in self.groups.iter().enumerate() {
            for label in &group.labels {
                names.insert(label.clone(), Def::Group(i));
            }
        }
        for (label, _) in &self.on_terminate_labels {
            names.insert(label.clone(), Def::OnTerminate);
        }
        let mut reported = BTreeSet::new();
        for r in &self.refs {
            match names.get(&r.name) {
                Some(Def::Spawn(i)) => self.spawns[*i].referenced = true,
                Some(Def::Group(i)) => {
                    let group = &mut self.groups[*i];
                    group.referenced = true;
                    if r.position < group.position && reported.insert(r.name.clone()) {
                        diags.push(
                            Diagnostic::error(
                                r.span,
                                format!("forward reference to the `with` group `{}`", r.name),
                            )
                            .with_hint("a group's members are only known once it has run; move this after the group, or name one of its spawns"),
                        );
                    }
                }
                Some(Def::OnTerminate) if reported.insert(r.name.clone()) => {
                    diags.push(
                        Diagnostic::error(
                            r.span,
                            format!("`{}` names an `on terminate` task, which the code generator cannot refer to yet", r.name),
                        )
                        .with_hint("constrain the on-terminate task inside its own definition instead"),
                    );
                }
                Some(Def::OnTerminate) => {}
                // Unknown and ambiguous tags are reported by the checks.
                None => {}
            }
        }
        let mut used = BTreeSet::new();
        for spawn in &mut self.spawns {
            if !spawn.referenced {
                continue;
            }
            let base = spawn.labels.first().unwrap_or(&spawn.task).clone();
            let mut var = format!("tdl_{}", base.trim_start_matches("r#"));
            while !used.insert(var.clone()) {
                var.push('_');
            }
            spawn.var = Some(format_ident!("{}", var));
            self.counted.extend(spawn.loops.iter().copied());
        }
        for group in &mut self.groups {
            if !group.referenced {
                continue;
            }
            let base = group.labels.first().cloned().unwrap_or_default();
            let mut var = format!("tdl_{}", base.trim_start_matches("r#"));
            while !used.insert(var.clone()) {
                var.push('_');
            }
            group.var = Some(format_ident!("{}", var));
        }
        self.names = names;
    }
}

/// The nodes a tag denotes at run time.
enum Nodes {
    /// One node reference expression (a `NodeId` or a `NodeRef`).
    One(TokenStream),
    /// Several: `for #pat in #iter`, binding `node`.
    Many { by_ref: bool, iter: TokenStream },
    /// Nothing to refer to (an error was reported).
    None,
}

impl Nodes {
    /// `f(node)` for each node: inline for one node, a `for` loop for several.
    fn each(&self, var: &Ident, f: impl FnOnce(&TokenStream) -> TokenStream) -> TokenStream {
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
enum Low {
    /// `activate ...`, with its `tdl::ActivateWhen`.
    Activate(TokenStream),
    ExpandFirst,
    DelayExpansion,
    Sequential(TokenStream, TokenStream),
    Serial(TokenStream),
    DisableUntil(TokenStream, TokenStream),
    DisableUntilTime(TokenStream, TokenStream),
    DisableFor(TokenStream, TokenStream),
    DisableForAfter(TokenStream, TokenStream, TokenStream),
    TerminateNow,
    TerminateAt(TokenStream),
    TerminateAtTime(TokenStream),
    TerminateIn(TokenStream),
    TerminateInAfter(TokenStream, TokenStream),
}

impl Low {
    /// As a `tdl::Constraint` value.
    fn value(&self) -> TokenStream {
        match self {
            Low::Activate(when) => quote!(::tdl::Constraint::Activate(#when)),
            Low::ExpandFirst => quote!(::tdl::Constraint::ExpandFirst),
            Low::DelayExpansion => quote!(::tdl::Constraint::DelayExpansion),
            Low::Sequential(f, n) => {
                quote!(::tdl::Constraint::Sequential(#f, ::tdl::NodeRef::from(#n)))
            }
            Low::Serial(n) => quote!(::tdl::Constraint::Serial(::tdl::NodeRef::from(#n))),
            Low::DisableUntil(f, ev) => {
                quote!(::tdl::Constraint::Disable(#f, ::tdl::Until::Event(#ev)))
            }
            Low::DisableUntilTime(f, t) => {
                quote!(::tdl::Constraint::Disable(#f, ::tdl::Until::Time(#t)))
            }
            Low::DisableFor(f, d) => quote!(::tdl::Constraint::Disable(#f, ::tdl::Until::For(#d))),
            Low::DisableForAfter(f, d, ev) => {
                quote!(::tdl::Constraint::Disable(#f, ::tdl::Until::ForAfter(#d, #ev)))
            }
            Low::TerminateNow => quote!(::tdl::Constraint::Terminate(::tdl::TerminateWhen::Now)),
            Low::TerminateAt(ev) => {
                quote!(::tdl::Constraint::Terminate(::tdl::TerminateWhen::Event(#ev)))
            }
            Low::TerminateAtTime(t) => {
                quote!(::tdl::Constraint::Terminate(::tdl::TerminateWhen::Time(#t)))
            }
            Low::TerminateIn(d) => {
                quote!(::tdl::Constraint::Terminate(::tdl::TerminateWhen::In(#d)))
            }
            Low::TerminateInAfter(d, ev) => {
                quote!(::tdl::Constraint::Terminate(::tdl::TerminateWhen::InAfter(#d, #ev)))
            }
        }
    }

    /// As a `Spawner` method call, with the builder's shorthands where there is one.
    fn method(&self) -> TokenStream {
        match self {
            Low::ExpandFirst => quote!(.expand_first()),
            Low::DelayExpansion => quote!(.delay_expansion()),
            Low::Sequential(f, n) => quote!(.sequential(#f, #n)),
            Low::Serial(n) => quote!(.serial(#n)),
            Low::DisableUntil(f, ev) => quote!(.disable_until(#f, #ev)),
            Low::DisableFor(f, d) => quote!(.disable_for(#f, #d)),
            Low::TerminateAt(ev) => quote!(.terminate_at(#ev)),
            Low::TerminateIn(d) => quote!(.terminate_in(#d)),
            Low::Activate(when) => quote!(.activate(#when)),
            _ => {
                let value = self.value();
                quote!(.with(#value))
            }
        }
    }
}

fn facet(f: Facet) -> TokenStream {
    match f {
        Facet::Handling => quote!(::tdl::Facet::Handling),
        Facet::Expansion => quote!(::tdl::Facet::Expansion),
        Facet::Execution => quote!(::tdl::Facet::Execution),
    }
}

fn point(s: State) -> TokenStream {
    match s {
        State::Enabled => quote!(::tdl::Point::Enabled),
        State::Active => quote!(::tdl::Point::Active),
        State::Completed => quote!(::tdl::Point::Completed),
    }
}

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

/// Where the spawn's builder chain stands: plain method calls, or a loop over an entity.
enum Step {
    Method(TokenStream),
    Each(Nodes, Box<dyn FnOnce(&TokenStream) -> TokenStream>),
}

/// A `with` group being generated.
struct Frame<'a> {
    constraints: &'a [Constraint],
    /// The local holding `previous` for this group's current direct child.
    prev: Ident,
    /// The local collecting the group's nodes, when tracked.
    members: Option<Ident>,
}

struct Gen<'a, 'd> {
    file: &'a FileCx,
    task: &'a Task,
    an: Analysis,
    diags: &'d mut Vec<Diagnostic>,
    n_spawn: usize,
    n_group: usize,
    n_loop: usize,
    frames: Vec<Frame<'a>>,
    loops: Vec<usize>,
}

impl<'a> Gen<'a, '_> {
    fn prev_ident() -> Ident {
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
        for spawn in &self.an.spawns {
            let Some(var) = &spawn.var else { continue };
            let name = &spawn.task;
            if spawn.loops.is_empty() {
                out.extend(quote!(let #var = ctx.reserve(#name)?;));
            } else {
                maps = true;
                let n = Literal::usize_unsuffixed(spawn.loops.len());
                out.extend(quote! {
                    let mut #var: ::std::collections::BTreeMap<[i64; #n], ::tdl::NodeId> =
                        ::std::collections::BTreeMap::new();
                });
            }
        }
        for group in &self.an.groups {
            if let Some(var) = &group.var {
                out.extend(
                    quote!(let mut #var: ::std::vec::Vec<::tdl::NodeId> = ::std::vec::Vec::new();),
                );
            }
        }
        if self.an.uses_prev {
            let prev = Self::prev_ident();
            out.extend(
                quote!(let mut #prev: ::std::vec::Vec<::tdl::NodeId> = ::std::vec::Vec::new();),
            );
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

    fn block(&mut self, block: &'a Block) -> TokenStream {
        let mut out = TokenStream::new();
        for stmt in &block.stmts {
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
            // Handlers only, monitors only (the checks report them elsewhere).
            Stmt::Bypass(_) => quote!(return ctx.bypass();),
            Stmt::Trigger(_) => quote!(ctx.trigger()?;),
            Stmt::Retry(_) => quote! {
                let tdl_retry = ctx.retry()?;
                ctx.wait(tdl_retry).await?;
            },
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
        let id = self.n_loop;
        self.n_loop += 1;
        self.loops.push(id);
        let inner = self.block(body);
        self.loops.pop();
        if !self.an.counted.contains(&id) {
            return wrap(inner);
        }
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

    /// The nodes `tag` denotes; `prev` is the local holding `previous` at this site.
    fn nodes(&mut self, tag: &Tag, prev: &Ident) -> Nodes {
        match &tag.kind {
            TagKind::Previous => Nodes::Many {
                by_ref: true,
                iter: quote!(#prev),
            },
            TagKind::Child => Nodes::One(quote!(::tdl::NodeRef::This)),
            TagKind::Parent => Nodes::One(quote!(::tdl::NodeRef::Parent)),
            TagKind::Named { name, indexes } => match self.an.names.get(&name.to_string()) {
                Some(Def::Spawn(i)) => self.spawn_nodes(*i, indexes, tag.span),
                Some(Def::Group(i)) => match &self.an.groups[*i].var {
                    Some(var) => Nodes::Many {
                        by_ref: true,
                        iter: quote!(#var),
                    },
                    None => Nodes::None,
                },
                Some(Def::OnTerminate) | None => Nodes::None,
            },
        }
    }

    fn spawn_nodes(&mut self, i: usize, indexes: &[TagIndex], span: Span) -> Nodes {
        let info = &self.an.spawns[i];
        let Some(var) = info.var.clone() else {
            return Nodes::None;
        };
        if info.loops.is_empty() {
            return Nodes::One(quote!(#var));
        }
        let depth = info.loops.len();
        let mut keys = Vec::new();
        for (level, index) in indexes.iter().enumerate() {
            match index {
                TagIndex::Expr(expr) => keys.push(quote!((#expr) as i64)),
                TagIndex::Current => {
                    let Some(&loop_id) = info.loops.get(level) else {
                        return Nodes::None;
                    };
                    if self.loops.get(level) != Some(&loop_id) {
                        self.diags.push(
                            Diagnostic::error(span, "`[.]` outside the loop it counts")
                                .with_hint("`[.]` means the current iteration of the loop around the spawn; use it inside that loop, or write the iteration number"),
                        );
                        return Nodes::None;
                    }
                    let it = format_ident!("tdl_i_{}", loop_id);
                    keys.push(quote!(#it));
                }
            }
        }
        if keys.len() > depth {
            return Nodes::None;
        }
        let name = &info.task;
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

    fn event(ev: &Event, node: &TokenStream) -> TokenStream {
        let p = point(ev.state);
        match ev.facet {
            None => quote!(::tdl::Event::new(#node, #p)),
            Some(f) => {
                let f = facet(f);
                quote!(::tdl::Event::on(#node, #f, #p))
            }
        }
    }

    /// The lowered form of `c` with the nodes it names; `None` when it is handled elsewhere.
    #[allow(clippy::type_complexity)]
    fn lower(
        &mut self,
        c: &Constraint,
        prev: &Ident,
    ) -> Option<(Nodes, Box<dyn FnOnce(&TokenStream) -> Low>)> {
        let no_node = |low: Low| -> Option<(Nodes, Box<dyn FnOnce(&TokenStream) -> Low>)> {
            Some((Nodes::One(TokenStream::new()), Box::new(move |_| low)))
        };
        let prev_tag = Tag {
            kind: TagKind::Previous,
            span: c.span,
        };
        match &c.kind {
            ConstraintKind::ExpandFirst => no_node(Low::ExpandFirst),
            ConstraintKind::DelayExpansion => no_node(Low::DelayExpansion),
            ConstraintKind::Sequential { facet: f, tag } => {
                let nodes = self.nodes(tag.as_ref().unwrap_or(&prev_tag), prev);
                let f = facet(*f);
                Some((nodes, Box::new(move |n| Low::Sequential(f, n.clone()))))
            }
            ConstraintKind::Serial { tag } => {
                let nodes = self.nodes(tag.as_ref().unwrap_or(&prev_tag), prev);
                Some((nodes, Box::new(|n| Low::Serial(n.clone()))))
            }
            ConstraintKind::DisableUntil { facet: f, until } => {
                let f = facet(f.unwrap_or(Facet::Handling));
                match until {
                    When::Event(ev) => {
                        let nodes = self.nodes(&ev.tag, prev);
                        let ev = ev.clone();
                        Some((
                            nodes,
                            Box::new(move |n| Low::DisableUntil(f, Self::event(&ev, n))),
                        ))
                    }
                    When::Time(t) => no_node(Low::DisableUntilTime(f, time_of_day(t))),
                }
            }
            ConstraintKind::DisableFor {
                facet: f,
                delay,
                after,
            } => {
                let f = facet(f.unwrap_or(Facet::Handling));
                let d = duration(delay);
                match after {
                    None => no_node(Low::DisableFor(f, d)),
                    Some(ev) => {
                        let nodes = self.nodes(&ev.tag, prev);
                        let ev = ev.clone();
                        Some((
                            nodes,
                            Box::new(move |n| Low::DisableForAfter(f, d, Self::event(&ev, n))),
                        ))
                    }
                }
            }
            ConstraintKind::Terminate => no_node(Low::TerminateNow),
            ConstraintKind::TerminateAt(When::Event(ev)) => {
                let nodes = self.nodes(&ev.tag, prev);
                let ev = ev.clone();
                Some((
                    nodes,
                    Box::new(move |n| Low::TerminateAt(Self::event(&ev, n))),
                ))
            }
            ConstraintKind::TerminateAt(When::Time(t)) => {
                no_node(Low::TerminateAtTime(time_of_day(t)))
            }
            ConstraintKind::TerminateIn { delay, after } => {
                let d = duration(delay);
                match after {
                    None => no_node(Low::TerminateIn(d)),
                    Some(ev) => {
                        let nodes = self.nodes(&ev.tag, prev);
                        let ev = ev.clone();
                        Some((
                            nodes,
                            Box::new(move |n| Low::TerminateInAfter(d, Self::event(&ev, n))),
                        ))
                    }
                }
            }
            ConstraintKind::Activate => no_node(Low::Activate(quote!(::tdl::ActivateWhen::Now))),
            ConstraintKind::ActivateAt(When::Event(ev)) => {
                let nodes = self.nodes(&ev.tag, prev);
                let ev = ev.clone();
                Some((
                    nodes,
                    Box::new(move |n| {
                        let ev = Self::event(&ev, n);
                        Low::Activate(quote!(::tdl::ActivateWhen::Event(#ev)))
                    }),
                ))
            }
            ConstraintKind::ActivateAt(When::Time(t)) => {
                let t = time_of_day(t);
                no_node(Low::Activate(quote!(::tdl::ActivateWhen::Time(#t))))
            }
            ConstraintKind::ActivateIn { delay, after } => {
                let d = duration(delay);
                match after {
                    None => no_node(Low::Activate(quote!(::tdl::ActivateWhen::In(#d)))),
                    Some(ev) => {
                        let nodes = self.nodes(&ev.tag, prev);
                        let ev = ev.clone();
                        Some((
                            nodes,
                            Box::new(move |n| {
                                let ev = Self::event(&ev, n);
                                Low::Activate(quote!(::tdl::ActivateWhen::InAfter(#d, #ev)))
                            }),
                        ))
                    }
                }
            }
            // Spawner settings, generated by `spawn` (and refused in constraint statements).
            ConstraintKind::MaximumActivate(_)
            | ConstraintKind::MaximumTrigger(_)
            | ConstraintKind::Period(_)
            | ConstraintKind::ExceptionHandler(_) => None,
            ConstraintKind::OnAgent(_) => {
                self.diags.push(
                    Diagnostic::error(c.span, "distributed agents are not supported yet")
                        .with_hint("remove `on ...`"),
                );
                None
            }
            ConstraintKind::Parallel
            | ConstraintKind::Wait
            | ConstraintKind::Name(_)
            | ConstraintKind::OnTerminate(_) => None,
        }
    }

    fn spawn(&mut self, spawn: &'a Spawn) -> TokenStream {
        let index = self.n_spawn;
        self.n_spawn += 1;
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
        let needs_id = self.an.uses_prev || !members.is_empty();
        let mut pre = TokenStream::new();
        let info = &self.an.spawns[index];
        let mut id_expr: Option<TokenStream> = None;
        if let Some(var) = info.var.clone() {
            if info.loops.is_empty() {
                id_expr = Some(quote!(#var));
            } else {
                let keys = info.loops.iter().map(|l| format_ident!("tdl_i_{}", l));
                let name = &info.task;
                let slot = quote!(tdl_slot(&ctx, &mut #var, [#(#keys),*], #name)?);
                if needs_id && spawn.binding.is_some() {
                    pre.extend(quote!(let tdl_node = #slot;));
                    id_expr = Some(quote!(tdl_node));
                } else {
                    id_expr = Some(slot);
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
            if self.an.uses_prev {
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
        match self.file.results.get(&spawn.task.to_string()) {
            Some(Some(ty)) => quote!(#ty),
            Some(None) => quote!(()),
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

    fn with(&mut self, group: &'a WithGroup) -> TokenStream {
        let index = self.n_group;
        self.n_group += 1;
        let mut out = TokenStream::new();
        let label_var = self.an.groups[index].var.clone();
        let members = match &label_var {
            Some(var) => {
                out.extend(quote!(#var.clear();));
                Some(var.clone())
            }
            None if self.an.uses_prev => {
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
            if parent_uses_previous(parent.constraints) {
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
        if self.an.uses_prev {
            let prev = Self::prev_ident();
            match (&label_var, &members) {
                (Some(var), _) => out.extend(quote!(#prev = #var.clone();)),
                (None, Some(var)) => out.extend(quote!(#prev = #var;)),
                (None, None) => {}
            }
        }
        out
    }

    fn constrain(&mut self, stmt: &ConstraintStmt) -> TokenStream {
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
            ConstraintKind::Terminate => {
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

fn time_of_day(t: &crate::ast::TimeOfDay) -> TokenStream {
    #[allow(
        clippy::cast_precision_loss,
        reason = "a time of day fits an f64 exactly enough"
    )]
    let secs = Literal::f64_unsuffixed(t.nanos_since_midnight() as f64 / 1e9);
    quote!(ctx.time_of_day(#secs))
}

fn parent_uses_previous(constraints: &[Constraint]) -> bool {
    let mut an = Analysis::default();
    an.constraints(constraints);
    an.uses_prev
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
