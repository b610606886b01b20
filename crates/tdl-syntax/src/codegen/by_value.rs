//! Task arguments by value, as TDL copies them: an argument that is a variable (or a field of
//! one) that the body names again later is cloned, so the program need not write `.clone()`.
//!
//! "Later" is what runs after the argument is evaluated: the rest of its spawn's arguments (a
//! handler's and an `on terminate` task's included), the statements after its statement in
//! each enclosing block, the whole body of each enclosing loop (its next iteration), and, for a
//! task-level handler or `on terminate`, the task's body, which captures the task's arguments.
//! A branch of an `if` or a `match` is not later than the other branches. The arguments of a
//! `with` group's handlers and `on terminate` tasks are evaluated for each member, so they are
//! cloned whenever they are variables. An argument the body never names again is moved, so one
//! that is not `Clone` can still be given once; to move a variable that is named again, write
//! `{x}`.
//!
//! What a statement names is every identifier of its tokens ([`crate::ast::Block::mentions`]),
//! a word in a string included: at worst a `Clone` value is cloned once too often. A variable of
//! a loop's pattern, or one a top-level `let` of the loop's body binds, is a new one each
//! iteration, so the loop's repetition does not count for it.

use crate::ast::{
    Block, ConstraintKind, HandlerRef, OnTerminate, Spawn, Stmt, Task, TaskConstraintKind,
};
use proc_macro2::TokenStream;
use quote::{ToTokens, quote};
use std::collections::{BTreeSet, HashSet};

/// The arguments to clone, by address in the program's syntax tree.
#[derive(Default)]
pub(crate) struct Clones(HashSet<*const syn::Expr>);

type Words = BTreeSet<String>;

impl Clones {
    /// What to clone in `task`: its task-level handlers' and `on terminate` tasks' arguments,
    /// and every argument in its body.
    pub(crate) fn of(task: &Task) -> Clones {
        let mut out = Clones::default();
        let body: Words = task.body.mentions.iter().flatten().cloned().collect();
        let mut lists: Vec<&[syn::Expr]> = Vec::new();
        for c in &task.constraints {
            match &c.kind {
                TaskConstraintKind::ExceptionHandler(h) => lists.push(&h.args),
                TaskConstraintKind::OnTerminate(t) => lists.push(&t.args),
                _ => {}
            }
        }
        out.args(&lists, &body);
        out.block(&task.body, &Words::new());
        out
    }

    /// `args` as generated: a variable or field to clone as `Clone::clone(&x)` (which clippy's
    /// `clone_on_copy` does not flag for a `Copy` argument), any other as written.
    pub(crate) fn values(&self, args: &[syn::Expr]) -> Vec<TokenStream> {
        args.iter()
            .map(|e| {
                if self.0.contains(&std::ptr::from_ref(e)) {
                    quote!(::core::clone::Clone::clone(&#e))
                } else {
                    e.to_token_stream()
                }
            })
            .collect()
    }

    fn block(&mut self, block: &Block, after: &Words) {
        let mut later = after.clone();
        for (i, stmt) in block.stmts.iter().enumerate().rev() {
            self.stmt(stmt, &later);
            if let Some(m) = block.mentions.get(i) {
                later.extend(m.iter().cloned());
            }
        }
    }

    fn stmt(&mut self, stmt: &Stmt, later: &Words) {
        match stmt {
            Stmt::Spawn(s) => self.spawn(s, later),
            Stmt::Retry(r) => {
                if let Some(args) = &r.args {
                    self.args(&[args], later);
                }
            }
            Stmt::With(g) => {
                for c in &g.constraints {
                    match &c.kind {
                        ConstraintKind::ExceptionHandler(h) => self.always(&h.args),
                        ConstraintKind::OnTerminate(t) => self.always(&t.args),
                        _ => {}
                    }
                }
                self.block(&g.body, later);
            }
            Stmt::If(it) => self.if_stmt(it, later),
            Stmt::For(it) => {
                let fresh = pattern_words(&it.pat);
                self.looped(&it.body, later, fresh);
            }
            Stmt::While(it) => self.looped(&it.body, later, Words::new()),
            Stmt::Loop(it) => self.looped(&it.body, later, Words::new()),
            Stmt::Match(m) => {
                for arm in &m.arms {
                    self.block(&arm.body, later);
                }
            }
            Stmt::Block(b) => self.block(b, later),
            _ => {}
        }
    }

    fn if_stmt(&mut self, it: &crate::ast::If, later: &Words) {
        self.block(&it.then_branch, later);
        match it.else_branch.as_deref() {
            Some(crate::ast::Else::If(e)) => self.if_stmt(e, later),
            Some(crate::ast::Else::Block(b)) => self.block(b, later),
            None => {}
        }
    }

    /// A loop's body runs again after itself: what it names is later for all of it, but for the
    /// variables each iteration binds anew.
    fn looped(&mut self, body: &Block, later: &Words, mut fresh: Words) {
        for stmt in &body.stmts {
            match stmt {
                Stmt::Rust(r) => fresh.extend(let_words(&r.tokens)),
                Stmt::Spawn(Spawn {
                    binding: Some(b), ..
                }) => {
                    if let crate::ast::BindTarget::Let(p) = &b.target {
                        fresh.extend(pattern_words(p));
                    }
                }
                _ => {}
            }
        }
        let mut again = later.clone();
        again.extend(
            body.mentions
                .iter()
                .flatten()
                .filter(|w| !fresh.contains(*w))
                .cloned(),
        );
        self.block(body, &again);
    }

    fn spawn(&mut self, s: &Spawn, later: &Words) {
        let mut lists: Vec<&[syn::Expr]> = vec![&s.args];
        for c in &s.constraints {
            match &c.kind {
                ConstraintKind::ExceptionHandler(HandlerRef { args, .. })
                | ConstraintKind::OnTerminate(OnTerminate { args, .. }) => lists.push(args),
                _ => {}
            }
        }
        self.args(&lists, later);
    }

    /// Arguments evaluated in order: each is cloned if it is a variable that the arguments after
    /// it, or what comes `later`, name.
    fn args(&mut self, lists: &[&[syn::Expr]], later: &Words) {
        let all: Vec<&syn::Expr> = lists.iter().flat_map(|l| l.iter()).collect();
        for (i, e) in all.iter().enumerate() {
            let Some(var) = variable(e) else {
                continue;
            };
            let after_it = all[i + 1..].iter().any(|a| names(a, &var));
            if after_it || later.contains(&var) {
                self.0.insert(std::ptr::from_ref(*e));
            }
        }
    }

    fn always(&mut self, args: &[syn::Expr]) {
        for e in args {
            if variable(e).is_some() {
                self.0.insert(std::ptr::from_ref(e));
            }
        }
    }
}

/// The variable an argument is, or is a field of: `x`, `x.y`, `self.y.z`.
fn variable(e: &syn::Expr) -> Option<String> {
    match e {
        syn::Expr::Path(p) if p.qself.is_none() && p.path.segments.len() == 1 => {
            Some(p.path.segments[0].ident.to_string())
        }
        syn::Expr::Field(f) => variable(&f.base),
        _ => None,
    }
}

/// Whether `e` names `var`.
fn names(e: &syn::Expr, var: &str) -> bool {
    crate::parser::idents(e.to_token_stream())
        .iter()
        .any(|w| w == var)
}

/// The variables a pattern binds (every identifier of it: at worst one too many).
fn pattern_words(p: &syn::Pat) -> Words {
    crate::parser::idents(p.to_token_stream())
        .into_iter()
        .collect()
}

/// The variables a `let` statement binds: the identifiers before its `=` or `:`.
fn let_words(tokens: &TokenStream) -> Words {
    let mut it = tokens.clone().into_iter();
    match it.next() {
        Some(proc_macro2::TokenTree::Ident(i)) if i == "let" => {}
        _ => return Words::new(),
    }
    let pat: TokenStream = it
        .take_while(|tt| {
            !matches!(tt, proc_macro2::TokenTree::Punct(p) if p.as_char() == '=' || p.as_char() == ':')
        })
        .collect();
    crate::parser::idents(pat).into_iter().collect()
}
