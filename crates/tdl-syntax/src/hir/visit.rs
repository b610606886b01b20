//! One walk over a body's statements: the control flow that every reader of a body follows the
//! same way (the branches of an `if … else if … else` chain or of a `match`, loop bodies, `with`
//! groups, blocks), so that each reader says only what it does at the statements it cares about.
//!
//! A reader implements [`Visit`]: [`Visit::stmt`] sees every statement in source order, nested
//! ones included, and calls [`walk_stmt`] to go into a compound one; the other methods see the
//! parts of compound statements and default to walking into them. The resolver (`body.rs`),
//! `previous` (`previous.rs`) and the diagnosis of waits (`diagnose/flow.rs`) are readers.

use proc_macro2::TokenStream;
use quote::ToTokens;

use crate::ast::{Block, Else, If, Stmt, WithGroup};

/// One branch of an `if` chain or of a `match`.
pub struct Branch<'a> {
    /// The Rust code that chooses it: an `if`'s condition, a match arm's guard (empty when it has
    /// none); `None` for an `else`.
    pub code: Option<TokenStream>,
    /// Its statements.
    pub block: &'a Block,
}

/// A reader of a body's statements.
pub trait Visit<'a> {
    /// A statement. The default goes into a compound statement ([`walk_stmt`]).
    fn stmt(&mut self, stmt: &'a Stmt) {
        walk_stmt(self, stmt);
    }

    /// A block: each statement in turn.
    fn block(&mut self, block: &'a Block) {
        for stmt in &block.stmts {
            self.stmt(stmt);
        }
    }

    /// The branches of an `if` chain or of a `match`, in source order; `exhaustive` when one of
    /// them surely runs (the chain ends with `else`, or the `match` has an arm). The default walks
    /// each in turn.
    fn branches(&mut self, branches: Vec<Branch<'a>>, exhaustive: bool) {
        let _ = exhaustive;
        for branch in branches {
            self.branch(branch);
        }
    }

    /// One branch: the code that chooses it, then its block.
    fn branch(&mut self, branch: Branch<'a>) {
        if let Some(code) = branch.code {
            self.code(code);
        }
        self.block(branch.block);
    }

    /// The body of a `for`, `while` or `loop`, after the code that drives it.
    fn looped(&mut self, body: &'a Block) {
        self.block(body);
    }

    /// A `with` group's statements.
    fn group(&mut self, group: &'a WithGroup) {
        self.block(&group.body);
    }

    /// Rust code that chooses a branch or drives a loop: a condition, a `match`'s scrutinee or an
    /// arm's guard, a `for`'s iterator. Nothing by default.
    fn code(&mut self, code: TokenStream) {
        let _ = code;
    }
}

/// Goes into a compound statement: an `if` chain's or a `match`'s branches (after a `match`'s
/// scrutinee), a loop's body (after its iterator or condition), a group, a block. Other
/// statements have nothing inside.
pub fn walk_stmt<'a, V: Visit<'a> + ?Sized>(v: &mut V, stmt: &'a Stmt) {
    match stmt {
        Stmt::If(it) => {
            let mut branches = Vec::new();
            let exhaustive = if_chain(it, &mut branches);
            v.branches(branches, exhaustive);
        }
        Stmt::Match(it) => {
            v.code(it.expr.to_token_stream());
            let branches = it
                .arms
                .iter()
                .map(|arm| Branch {
                    code: Some(arm.guard.to_token_stream()),
                    block: &arm.body,
                })
                .collect();
            v.branches(branches, !it.arms.is_empty());
        }
        Stmt::For(it) => {
            v.code(it.expr.to_token_stream());
            v.looped(&it.body);
        }
        Stmt::While(it) => {
            v.code(it.cond.to_token_stream());
            v.looped(&it.body);
        }
        Stmt::Loop(it) => v.looped(&it.body),
        Stmt::With(it) => v.group(it),
        Stmt::Block(it) => v.block(it),
        Stmt::Rust(_)
        | Stmt::Spawn(_)
        | Stmt::Constrain(_)
        | Stmt::Bind(_)
        | Stmt::Succeed(_)
        | Stmt::Fail(_)
        | Stmt::Bypass(_)
        | Stmt::Trigger(_)
        | Stmt::Retry(_)
        | Stmt::Resource(_)
        | Stmt::Set(_)
        | Stmt::Log(_)
        | Stmt::Raise(_) => {}
    }
}

/// The branches of an `if … else if … else` chain into `out`; whether it ends with `else`.
fn if_chain<'a>(it: &'a If, out: &mut Vec<Branch<'a>>) -> bool {
    out.push(Branch {
        code: Some(it.cond.to_token_stream()),
        block: &it.then_branch,
    });
    match it.else_branch.as_deref() {
        Some(Else::If(next)) => if_chain(next, out),
        Some(Else::Block(block)) => {
            out.push(Branch { code: None, block });
            true
        }
        None => false,
    }
}
