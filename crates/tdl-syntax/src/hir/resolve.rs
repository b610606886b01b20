//! The resolver's walk over one body: each statement numbered in source order at its [`Site`],
//! its spawns, groups, labels, bound names and loops registered, every tag written in a
//! constraint and every `node!(tag)` of its Rust code collected ([`BodyScope`] holds the result).

use proc_macro2::{Delimiter, Ident, Span, TokenStream, TokenTree};
use quote::ToTokens;

use super::body::{
    BodyScope, BoundDef, CleanupDef, Def, GroupDef, GroupId, LoopId, NodeUse, Ref, Refers, Site,
    SpawnDef, StateUse, Tdl, refers,
};
use super::visit::{Branch, Visit, walk_stmt};
use crate::ast::{
    Block, Constraint, ConstraintKind, Count, ExternalName, Priority, RelTime, Stmt, Tag, TagKind,
    Task, When,
};

/// Resolves `task`'s body into `scope`, which is empty: its statements, definitions, names and
/// tags, before [`BodyScope::assign_vars`].
pub(super) fn walk<'a>(task: &'a Task, scope: BodyScope<'a>) -> BodyScope<'a> {
    let mut walk = Walk {
        scope,
        position: 0,
        loops: Vec::new(),
        groups: Vec::new(),
        branches: 0,
        sites: Vec::new(),
    };
    walk.block(&task.body);
    walk.scope
}

/// The walk that builds a [`BodyScope`].
struct Walk<'a> {
    scope: BodyScope<'a>,
    position: usize,
    loops: Vec<LoopId>,
    groups: Vec<GroupId>,
    /// The `if` and `match` branches around the statement.
    branches: usize,
    /// The sites of the compound statements around, innermost last: where the code that chooses
    /// a branch or drives a loop is.
    sites: Vec<Site>,
}

impl<'a> Visit<'a> for Walk<'a> {
    fn stmt(&mut self, stmt: &'a Stmt) {
        self.position += 1;
        let site = Site {
            position: self.position,
            loops: self.loops.clone(),
            branch: self.branches > 0,
        };
        match stmt {
            Stmt::Spawn(spawn) => {
                let id = self.scope.spawns.len();
                self.scope.spawn_ids.insert(std::ptr::from_ref(spawn), id);
                self.scope
                    .by_task
                    .entry(spawn.task.to_string())
                    .or_default()
                    .push(id);
                let late = spawn
                    .constraints
                    .iter()
                    .any(|it| matches!(it.kind, ConstraintKind::Parent(_)));
                for arg in &spawn.args {
                    self.rust(arg.to_token_stream(), &site);
                }
                self.scope.spawns.push(SpawnDef {
                    spawn,
                    site: site.clone(),
                    groups: self.groups.clone(),
                    var: None,
                    late,
                });
                self.scope.stmts.push(Tdl::Spawn(id));
                for label in &spawn.labels {
                    self.scope.add_label(label, Def::Spawn(id));
                }
                let on_terminate = spawn.constraints.iter().filter_map(|it| match &it.kind {
                    ConstraintKind::OnTerminate(it) => Some(it),
                    _ => None,
                });
                for (index, it) in on_terminate.enumerate() {
                    {
                        if !it.labels.is_empty() {
                            let cleanup = self.scope.cleanups.len();
                            self.scope.cleanups.push(CleanupDef {
                                spawn: id,
                                index,
                                on_terminate: it,
                                var: None,
                            });
                            self.scope
                                .cleanup_ids
                                .insert(std::ptr::from_ref(it), cleanup);
                            for label in &it.labels {
                                self.scope.add_label(label, Def::OnTerminate(cleanup));
                            }
                        }
                    }
                }
                self.constraints(&spawn.constraints, &site);
            }
            Stmt::With(group) => {
                let id = self.scope.groups.len();
                self.scope.group_ids.insert(std::ptr::from_ref(group), id);
                self.scope.groups.push(GroupDef {
                    group,
                    site: site.clone(),
                    var: None,
                });
                self.scope.stmts.push(Tdl::With(id));
                for label in &group.labels {
                    self.scope.add_label(label, Def::Group(id));
                }
                self.constraints(&group.constraints, &site);
                self.groups.push(id);
                self.group(group);
                self.groups.pop();
            }
            Stmt::Constrain(it) => {
                self.tag(&it.tag);
                self.constraints(std::slice::from_ref(&it.constraint), &site);
                self.scope.stmts.push(Tdl::Constrain(it, site));
            }
            Stmt::Bind(it) => {
                self.rust(it.expr.to_token_stream(), &site);
                let name = it.name.to_string();
                self.scope
                    .bound
                    .entry(name)
                    .or_insert(BoundDef { site, var: None });
                self.scope.add_label(&it.name, Def::Bound(it));
            }
            Stmt::Fail(it) => {
                for field in &it.fields {
                    self.rust(field.to_token_stream(), &site);
                }
                self.scope.stmts.push(Tdl::Fail(it));
            }
            Stmt::Resource(it) => self.scope.resource_stmts.push(it),
            Stmt::Log(it) => self.rust(it.format_args(), &site),
            Stmt::Set(it) => {
                self.rust(it.value.to_token_stream(), &site);
                self.scope.sets.push(it);
            }
            Stmt::Raise(it) => {
                if let ExternalName::Expr(expr) = &it.name {
                    self.rust(expr.to_token_stream(), &site);
                }
                self.scope.raises_external.push(it);
            }
            Stmt::Bypass(span) => self.scope.stmts.push(Tdl::Bypass(*span)),
            Stmt::Trigger(span) => self.scope.stmts.push(Tdl::Trigger(*span)),
            Stmt::Retry(it) => {
                for arg in it.args.iter().flatten() {
                    self.rust(arg.to_token_stream(), &site);
                }
                self.scope.stmts.push(Tdl::Retry(it));
            }
            Stmt::Rust(it) => self.rust(it.tokens.clone(), &site),
            Stmt::Succeed(_) => {}
            Stmt::If(_)
            | Stmt::Match(_)
            | Stmt::For(_)
            | Stmt::While(_)
            | Stmt::Loop(_)
            | Stmt::Block(_) => {
                self.sites.push(site);
                walk_stmt(self, stmt);
                self.sites.pop();
            }
        }
    }

    fn branch(&mut self, branch: Branch<'a>) {
        if let Some(code) = branch.code {
            self.code(code);
        }
        self.branches += 1;
        self.block(branch.block);
        self.branches -= 1;
    }

    fn looped(&mut self, body: &'a Block) {
        let id = self.scope.loop_ids.len();
        self.scope.loop_ids.insert(std::ptr::from_ref(body), id);
        self.loops.push(id);
        self.block(body);
        self.loops.pop();
    }

    fn code(&mut self, code: TokenStream) {
        let site = self.sites.last().cloned().unwrap_or_default();
        self.rust(code, &site);
    }
}

impl<'a> Walk<'a> {
    /// Records the `node!(tag)` and `state!(var)` uses in Rust code at `site`.
    fn rust(&mut self, tokens: TokenStream, site: &Site) {
        for (name, span) in state_uses(tokens.clone()) {
            self.scope.state_uses.push(StateUse { name, span });
        }
        for (tag, span) in node_uses(tokens) {
            self.scope.node_uses.push(NodeUse {
                tag,
                span,
                site: site.clone(),
            });
        }
    }

    fn constraints(&mut self, constraints: &'a [Constraint], site: &Site) {
        for constraint in constraints {
            self.rust(constraint_code(&constraint.kind), site);
            match &constraint.kind {
                ConstraintKind::Trigger {
                    when: When::Condition(cond),
                    ..
                } => self.scope.conditions.push(cond),
                ConstraintKind::Trigger {
                    when: When::Changed(var),
                    ..
                } => self.scope.changes.push(var),
                _ => {}
            }
            match refers(&constraint.kind) {
                Some(Refers::Previous) => self.scope.uses_previous = true,
                Some(Refers::WaitsOn(tag)) => self.tag(tag),
                Some(Refers::Event(event)) => self.tag(&event.tag),
                None => {}
            }
        }
    }

    fn tag(&mut self, tag: &'a Tag) {
        match &tag.kind {
            TagKind::Previous => self.scope.uses_previous = true,
            TagKind::Named { name, .. } => self.scope.refs.push(Ref {
                tag,
                name,
                position: self.position,
            }),
            TagKind::Child | TagKind::Parent => {}
        }
    }
}

/// The `node!(tag)` uses in `tokens`, outermost first: the tag parsed from inside the
/// parentheses (or why it is not one) and the span of `node`.
pub fn node_uses(tokens: TokenStream) -> Vec<(Result<Tag, syn::Error>, Span)> {
    let mut out = Vec::new();
    let tts: Vec<TokenTree> = tokens.into_iter().collect();
    let mut i = 0;
    while i < tts.len() {
        if let Some((inner, span)) = node_macro(&tts[i..]) {
            out.push((crate::parser::parse_tag_tokens(inner), span));
            i += 3;
            continue;
        }
        if let TokenTree::Group(group) = &tts[i] {
            out.extend(node_uses(group.stream()));
        }
        i += 1;
    }
    out
}

/// `node ! ( … )` at the start of `tts`: the tokens inside and the span of `node`.
pub fn node_macro(tts: &[TokenTree]) -> Option<(TokenStream, Span)> {
    macro_call(tts, "node")
}

/// `state ! ( … )` at the start of `tts`: the tokens inside and the span of `state`.
pub fn state_macro(tts: &[TokenTree]) -> Option<(TokenStream, Span)> {
    macro_call(tts, "state")
}

/// `name ! ( … )` at the start of `tts`: the tokens inside and the span of `name`.
fn macro_call(tts: &[TokenTree], macro_name: &str) -> Option<(TokenStream, Span)> {
    match tts {
        [
            TokenTree::Ident(name),
            TokenTree::Punct(bang),
            TokenTree::Group(group),
            ..,
        ] if name == macro_name
            && bang.as_char() == '!'
            && group.delimiter() == Delimiter::Parenthesis =>
        {
            Some((group.stream(), name.span()))
        }
        _ => None,
    }
}

/// The `state!(var)` uses in `tokens`, outermost first: the variable named inside the
/// parentheses (or why they hold no one name) and the span of `state`.
pub fn state_uses(tokens: TokenStream) -> Vec<(Result<Ident, syn::Error>, Span)> {
    let mut out = Vec::new();
    let tts: Vec<TokenTree> = tokens.into_iter().collect();
    let mut i = 0;
    while i < tts.len() {
        if let Some((inner, span)) = state_macro(&tts[i..]) {
            let name = syn::parse2::<Ident>(inner).map_err(|_| {
                syn::Error::new(
                    span,
                    "`state!` takes the name of one state variable, as in `state!(battery)`",
                )
            });
            out.push((name, span));
            i += 3;
            continue;
        }
        if let TokenTree::Group(group) = &tts[i] {
            out.extend(state_uses(group.stream()));
        }
        i += 1;
    }
    out
}

/// The Rust expressions of a constraint (a name, a parent, counts, times in seconds, an external
/// event's name, handler and on-terminate arguments), as one token stream to search for `node!(tag)`.
fn constraint_code(kind: &ConstraintKind) -> TokenStream {
    let mut out = TokenStream::new();
    let count = |it: &Count, out: &mut TokenStream| {
        if let Count::Expr(expr) = it {
            expr.to_tokens(out);
        }
    };
    let seconds = |it: &RelTime, out: &mut TokenStream| {
        if let RelTime::Seconds(expr) = it {
            expr.to_tokens(out);
        }
    };
    match kind {
        ConstraintKind::Name(expr)
        | ConstraintKind::Parent(expr)
        | ConstraintKind::OnAgent(expr) => {
            expr.to_tokens(&mut out);
        }
        ConstraintKind::MaximumActivate(n) | ConstraintKind::MaximumTrigger(n) => {
            count(n, &mut out);
        }
        ConstraintKind::Period(t) => seconds(t, &mut out),
        ConstraintKind::ExceptionHandler(it) => {
            for arg in &it.args {
                arg.to_tokens(&mut out);
            }
            if let Some(n) = &it.max_activate {
                count(n, &mut out);
            }
        }
        ConstraintKind::OnTerminate(it) => {
            for arg in &it.args {
                arg.to_tokens(&mut out);
            }
        }
        ConstraintKind::Trigger {
            when: When::In(t) | When::After(t, _),
            ..
        } => seconds(t, &mut out),
        ConstraintKind::Trigger {
            when: When::External(ExternalName::Expr(expr)),
            ..
        } => expr.to_tokens(&mut out),
        ConstraintKind::Uses(list) => {
            for it in list {
                if let Some(n) = &it.amount {
                    count(n, &mut out);
                }
            }
        }
        ConstraintKind::Priority(Priority::Expr(expr)) => expr.to_tokens(&mut out),
        _ => {}
    }
    out
}
