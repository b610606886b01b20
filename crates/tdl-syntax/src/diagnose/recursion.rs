//! Recursion without a base case (docs/language.md, "Static checks"): a task that spawns itself,
//! directly or through other tasks, on every path through its body. Each node then spawns the
//! next and none ever completes, since a node's execution completes only after its children's
//! (docs/semantics.md, "Facets and states"): a warning.
//!
//! A spawn counts when the body surely reaches it: not inside a loop, and not after anything that
//! may end the body first (`return`, `?`, a panicking macro, `succeed;`, `fail`, `bypass;`,
//! `retry`, a waited value, whose child's failure fails the body). An `if` or a `match` counts
//! only where every branch spawns the task. A spawn that may be stopped does not count: one with
//! a termination constraint, one enabled by an outcome or an external event (it is terminated, or
//! waits, if that never comes), one a constraint statement or `node!` names, and every spawn of a
//! body whose Rust code terminates nodes by hand. Handlers are never spawned, so a handler that
//! spawns the task it recovers is no recursion.

use std::collections::BTreeMap;

use proc_macro2::{TokenStream, TokenTree};
use quote::ToTokens;

use super::graph;
use crate::ast::{
    Ast, Block, Constraint, ConstraintKind, Else, Item, Spawn, Stmt, Task, TaskKind, Then, When,
};
use crate::diagnostic::{Diagnostic, Lint};
use crate::hir::{Def, FileScope, Tdl};

/// Warns at each cycle of tasks that spawn one another on every path through their bodies.
pub(super) fn check(file: &FileScope<'_>, ast: &Ast, diags: &mut Vec<Diagnostic>) {
    let has_tasks = ast.items.iter().any(|it| matches!(it, Item::Task(_)));
    if !has_tasks {
        return;
    }
    let tasks: Vec<&Task> = file
        .all_tasks()
        .filter(|it| it.kind != TaskKind::Handler)
        .collect();
    let index: BTreeMap<String, usize> = tasks
        .iter()
        .enumerate()
        .map(|(i, task)| (task.name.to_string(), i))
        .collect();
    let mut edges: Vec<(usize, usize)> = Vec::new();
    let mut spawns: Vec<&Spawn> = Vec::new();
    for (i, task) in tasks.iter().enumerate() {
        for spawn in must_spawn(file, task) {
            if let Some(&j) = index.get(&spawn.task.to_string()) {
                edges.push((i, j));
                spawns.push(spawn);
            }
        }
    }
    for cycle in graph::cycles(tasks.len(), &edges) {
        // Each file of a program finds the same cycles: the file of the task named first reports.
        let Some(first) = cycle
            .iter()
            .enumerate()
            .filter_map(|(at, e)| Some((at, tasks.get(edges.get(*e)?.0)?)))
            .min_by_key(|(_, task)| task.name.to_string())
            .map(|(at, _)| at)
        else {
            continue;
        };
        let mut ordered = cycle[first..].to_vec();
        ordered.extend_from_slice(&cycle[..first]);
        let steps: Vec<(&Task, &Spawn)> = ordered
            .iter()
            .filter_map(|e| Some((*tasks.get(edges.get(*e)?.0)?, *spawns.get(*e)?)))
            .collect();
        let Some((reporter, spawn)) = steps.first() else {
            continue;
        };
        if !file.is_local(reporter) {
            continue;
        }
        diags.push(diagnostic(file, &steps, reporter, spawn));
    }
}

fn diagnostic(
    file: &FileScope<'_>,
    steps: &[(&Task, &Spawn)],
    first: &Task,
    spawn: &Spawn,
) -> Diagnostic {
    let message = if steps.len() == 1 {
        format!(
            "`{}` spawns itself on every path through its body: the recursion never ends",
            first.name
        )
    } else {
        let mut chain = format!("`{}` spawns `{}`", first.name, spawn.task);
        for (_, next) in &steps[1..] {
            chain.push_str(&format!(", which spawns `{}`", next.task));
        }
        format!("{chain}, each on every path through its body: the recursion never ends")
    };
    let mut diag = Diagnostic::warning(Lint::UnboundedRecursion, spawn.task.span(), message);
    for (task, spawn) in &steps[1..] {
        if file.is_local(task) {
            diag = diag.with_label(
                spawn.task.span(),
                format!("`{}` spawns `{}` on every path", task.name, spawn.task),
            );
        }
    }
    diag.with_hint(
        "put the recursive spawn under a condition that eventually fails (`if n > 0 { spawn t(n - 1); }`), \
         or end the body before it: each node spawns the next, and none ever completes, since a \
         node completes only after its children",
    )
}

/// The spawns `task`'s body surely runs, and that nothing may stop.
fn must_spawn<'a>(file: &FileScope<'a>, task: &'a Task) -> Vec<&'a Spawn> {
    let scope = file.body(task);
    let mut terminates = false;
    let mut named = Vec::new();
    for stmt in &scope.stmts {
        if let Tdl::Constrain(it, _) = stmt {
            if matches!(
                it.constraint.kind,
                ConstraintKind::Trigger {
                    then: Then::Terminate,
                    ..
                }
            ) {
                terminates = true;
            }
            if let Some(named_def) = scope.named(&it.tag) {
                named.push(named_def.def);
            }
        }
    }
    for it in &scope.node_uses {
        if let Ok(tag) = &it.tag {
            if let Some(named_def) = scope.named(tag) {
                named.push(named_def.def);
            }
        }
    }
    // A body that terminates nodes by hand may stop any of them.
    if terminates || by_hand(&task.body) {
        return Vec::new();
    }
    let mut walk = Must {
        spawns: Vec::new(),
        exited: false,
        groups: Vec::new(),
    };
    walk.block(&task.body);
    walk.spawns
        .into_iter()
        .filter(|spawn| {
            let id = scope.spawn_id(spawn);
            let group_named = scope.spawn_def(spawn).is_some_and(|def| {
                def.groups
                    .iter()
                    .any(|g| named.iter().any(|n| matches!(n, Def::Group(it) if it == g)))
            });
            !group_named
                && !named
                    .iter()
                    .any(|n| matches!(n, Def::Spawn(it) if Some(*it) == id))
        })
        .collect()
}

/// The walk of a body for the spawns it surely runs.
struct Must<'a> {
    /// The spawns surely run so far that no constraint may stop.
    spawns: Vec<&'a Spawn>,
    /// Something before may have ended the body.
    exited: bool,
    /// The constraints of the enclosing `with` groups.
    groups: Vec<&'a [Constraint]>,
}

impl<'a> Must<'a> {
    fn block(&mut self, block: &'a Block) {
        for stmt in &block.stmts {
            if self.exited {
                return;
            }
            self.stmt(stmt);
        }
    }

    /// A branch walked on its own: the spawns it surely runs, and whether it may end the body.
    fn branch(&self, block: &'a Block) -> (Vec<&'a Spawn>, bool) {
        let mut walk = Must {
            spawns: Vec::new(),
            exited: false,
            groups: self.groups.clone(),
        };
        walk.block(block);
        (walk.spawns, walk.exited)
    }

    /// Keeps the spawns every branch runs (by task; the first branch's spawn stands for them),
    /// and notes whether any branch may end the body.
    fn branches(&mut self, branches: Vec<(Vec<&'a Spawn>, bool)>) {
        let mut iter = branches.into_iter();
        let Some((first, mut exited)) = iter.next() else {
            return;
        };
        let mut common = first;
        for (spawns, branch_exited) in iter {
            exited |= branch_exited;
            common.retain(|s| spawns.iter().any(|t| t.task == s.task));
        }
        self.spawns.extend(common);
        self.exited |= exited;
    }

    fn stmt(&mut self, stmt: &'a Stmt) {
        match stmt {
            Stmt::Spawn(spawn) => {
                let code = spawn
                    .args
                    .iter()
                    .map(ToTokens::to_token_stream)
                    .chain(spawn.constraints.iter().map(constraint_code))
                    .any(may_exit);
                if code {
                    self.exited = true;
                    return;
                }
                let own = spawn.constraints.iter();
                let stoppable = self
                    .groups
                    .iter()
                    .flat_map(|it| it.iter())
                    .chain(own)
                    .any(|c| stops(&c.kind));
                if !stoppable {
                    self.spawns.push(spawn);
                }
                let waits_value = spawn.binding.is_some()
                    && !spawn
                        .constraints
                        .iter()
                        .any(|c| matches!(c.kind, ConstraintKind::Outcome));
                if waits_value {
                    self.exited = true;
                }
            }
            Stmt::With(group) => {
                self.groups.push(&group.constraints);
                self.block(&group.body);
                self.groups.pop();
            }
            Stmt::Rust(it) => self.exited |= may_exit(it.tokens.clone()),
            Stmt::Bind(it) => self.exited |= may_exit(it.expr.to_token_stream()),
            Stmt::Set(it) => self.exited |= may_exit(it.value.to_token_stream()),
            Stmt::Log(it) => self.exited |= may_exit(it.format_args()),
            Stmt::Raise(it) => {
                if let crate::ast::ExternalName::Expr(expr) = &it.name {
                    self.exited |= may_exit(expr.to_token_stream());
                }
            }
            Stmt::Constrain(_) | Stmt::Trigger(_) | Stmt::Resource(_) => {}
            Stmt::Succeed(_) | Stmt::Fail(_) | Stmt::Bypass(_) | Stmt::Retry(_) => {
                self.exited = true;
            }
            Stmt::If(it) => {
                let mut branches = Vec::new();
                let mut at = it;
                loop {
                    if may_exit(at.cond.to_token_stream()) {
                        self.exited = true;
                        return;
                    }
                    branches.push(self.branch(&at.then_branch));
                    match at.else_branch.as_deref() {
                        Some(Else::If(next)) => at = next,
                        Some(Else::Block(block)) => {
                            branches.push(self.branch(block));
                            break;
                        }
                        None => {
                            branches.push((Vec::new(), false));
                            break;
                        }
                    }
                }
                self.branches(branches);
            }
            Stmt::Match(it) => {
                let guards = it.arms.iter().filter_map(|arm| arm.guard.as_ref());
                if may_exit(it.expr.to_token_stream())
                    || guards.map(ToTokens::to_token_stream).any(may_exit)
                {
                    self.exited = true;
                    return;
                }
                let branches = it.arms.iter().map(|arm| self.branch(&arm.body)).collect();
                self.branches(branches);
            }
            // A loop may run no iteration: what it spawns does not count, what may end the body
            // in it does.
            Stmt::For(it) => {
                self.exited |= may_exit(it.expr.to_token_stream()) || self.branch(&it.body).1;
            }
            Stmt::While(it) => {
                self.exited |= may_exit(it.cond.to_token_stream()) || self.branch(&it.body).1;
            }
            Stmt::Loop(it) => self.exited |= self.branch(&it.body).1,
            Stmt::Block(it) => self.block(it),
        }
    }
}

/// Whether a spawn constraint may keep the node from ever running or stop it: a termination,
/// or an enablement on an outcome or an external event.
fn stops(kind: &ConstraintKind) -> bool {
    match kind {
        ConstraintKind::Trigger {
            then: Then::Terminate,
            ..
        } => true,
        ConstraintKind::Trigger {
            when: When::External(_),
            ..
        } => true,
        ConstraintKind::Trigger {
            when: When::Event(event) | When::After(_, event),
            then: Then::Enable(_),
        } => event.point.is_outcome(),
        // A condition may never hold, or skip or fail the node.
        ConstraintKind::Trigger {
            when: When::Condition(_),
            then: Then::Enable(_) | Then::Skip | Then::Invariant,
        } => true,
        _ => false,
    }
}

/// The Rust expressions of a constraint.
fn constraint_code(constraint: &Constraint) -> TokenStream {
    let mut out = TokenStream::new();
    match &constraint.kind {
        ConstraintKind::Name(expr) | ConstraintKind::Parent(expr) => expr.to_tokens(&mut out),
        ConstraintKind::ExceptionHandler(it) => {
            for arg in &it.args {
                arg.to_tokens(&mut out);
            }
        }
        ConstraintKind::OnTerminate(it) => {
            for arg in &it.args {
                arg.to_tokens(&mut out);
            }
        }
        _ => {}
    }
    out
}

/// Whether Rust code may end the body: `return`, `?`, or a macro or function that panics or
/// exits.
fn may_exit(tokens: TokenStream) -> bool {
    const EXITS: &[&str] = &[
        "return",
        "panic",
        "unreachable",
        "todo",
        "unimplemented",
        "assert",
        "assert_eq",
        "assert_ne",
        "exit",
        "abort",
    ];
    tokens.into_iter().any(|tt| match tt {
        TokenTree::Ident(ident) => EXITS.iter().any(|it| ident == it),
        TokenTree::Punct(punct) => punct.as_char() == '?',
        TokenTree::Group(group) => may_exit(group.stream()),
        TokenTree::Literal(_) => false,
    })
}

/// Whether the body's Rust code terminates nodes by hand (`ctx.terminate(…)`).
fn by_hand(block: &Block) -> bool {
    fn tokens(stream: TokenStream) -> bool {
        stream.into_iter().any(|tt| match tt {
            TokenTree::Ident(ident) => ident == "terminate",
            TokenTree::Group(group) => tokens(group.stream()),
            _ => false,
        })
    }
    block.stmts.iter().any(|stmt| match stmt {
        Stmt::Rust(it) => tokens(it.tokens.clone()),
        Stmt::Spawn(it) => it.args.iter().any(|a| tokens(a.to_token_stream())),
        Stmt::With(it) => by_hand(&it.body),
        Stmt::Bind(it) => tokens(it.expr.to_token_stream()),
        Stmt::Set(it) => tokens(it.value.to_token_stream()),
        Stmt::Log(it) => tokens(it.format_args()),
        Stmt::If(it) => {
            let mut at = it;
            loop {
                if tokens(at.cond.to_token_stream()) || by_hand(&at.then_branch) {
                    return true;
                }
                match at.else_branch.as_deref() {
                    Some(Else::If(next)) => at = next,
                    Some(Else::Block(block)) => return by_hand(block),
                    None => return false,
                }
            }
        }
        Stmt::Match(it) => {
            tokens(it.expr.to_token_stream()) || it.arms.iter().any(|arm| by_hand(&arm.body))
        }
        Stmt::For(it) => by_hand(&it.body),
        Stmt::While(it) => by_hand(&it.body),
        Stmt::Loop(it) => by_hand(&it.body),
        Stmt::Block(it) => by_hand(it),
        Stmt::Constrain(_)
        | Stmt::Succeed(_)
        | Stmt::Fail(_)
        | Stmt::Bypass(_)
        | Stmt::Trigger(_)
        | Stmt::Resource(_)
        | Stmt::Raise(_)
        | Stmt::Retry(_) => false,
    })
}
