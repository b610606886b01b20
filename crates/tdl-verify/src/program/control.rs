//! The Rust control flow that holds TDL statements, as the checker runs it: `if` (a condition it
//! cannot evaluate is a choice of both branches), `for` over a counted range or array or an
//! unknown iterator, and the loops' tests, exits and `break`s.

use tdl_syntax::ast;

use super::body::{BodyCompiler, LoopFrame};
use super::{LoadError, line_of};
use crate::ir::{Iter, Op};
use crate::value::VExpr;

impl BodyCompiler<'_, '_, '_> {
    pub(super) fn if_(&mut self, it: &ast::If) -> Result<(), LoadError> {
        let line = line_of(it.span);
        let cond = match &it.cond {
            syn::Expr::Let(_) => VExpr::Unknown,
            c => self.b.lower(c),
        };
        let at = self.emit(Op::If { cond, else_pc: 0 }, line);
        self.block(&it.then_branch.stmts)?;
        let jump = self.emit(Op::Jump(0), line);
        let else_pc = self.pc();
        match it.else_branch.as_deref() {
            Some(ast::Else::If(next)) => self.if_(next)?,
            Some(ast::Else::Block(bl)) => self.block(&bl.stmts)?,
            None => {}
        }
        let end = self.pc();
        self.body.ops[jump] = Op::Jump(end);
        if let Op::If { else_pc: e, .. } = &mut self.body.ops[at] {
            *e = else_pc;
        }
        Ok(())
    }

    pub(super) fn for_iter(&mut self, pat: &syn::Pat, expr: &syn::Expr) -> Iter {
        let var = match pat {
            syn::Pat::Ident(p) => Some(self.b.sym(&p.ident.to_string())),
            _ => None,
        };
        let mut e = expr;
        while let syn::Expr::Paren(p) = e {
            e = &p.expr;
        }
        match e {
            syn::Expr::Range(r) => match (&r.start, &r.end) {
                (Some(s), Some(t)) => Iter::Range {
                    start: self.b.lower(s),
                    end: self.b.lower(t),
                    inclusive: matches!(r.limits, syn::RangeLimits::Closed(_)),
                    var,
                },
                _ => Iter::Unknown,
            },
            syn::Expr::Array(a) if var.is_none() || !a.elems.is_empty() => {
                Iter::Count(u32::try_from(a.elems.len()).unwrap_or(u32::MAX))
            }
            _ => Iter::Unknown,
        }
    }

    pub(super) fn looped(
        &mut self,
        iter: Iter,
        label: Option<String>,
        body: &ast::Block,
        line: u32,
    ) -> Result<(), LoadError> {
        let id = self.n_loops;
        self.n_loops += 1;
        // The loop variable is not followed unless the range is counted.
        self.emit(Op::LoopStart { id, iter }, line);
        let test = self.emit(Op::LoopTest { id, exit: 0 }, line);
        self.loops.push(LoopFrame {
            id,
            label,
            test: u32::try_from(test).unwrap_or(u32::MAX),
            breaks: Vec::new(),
        });
        self.block(&body.stmts)?;
        self.emit(Op::Jump(u32::try_from(test).unwrap_or(u32::MAX)), line);
        let exit = self.pc();
        let frame = self.loops.pop();
        if let Op::LoopTest { exit: e, .. } = &mut self.body.ops[test] {
            *e = exit;
        }
        for b in frame.map(|f| f.breaks).unwrap_or_default() {
            if let Op::Exit(x) = &mut self.body.ops[b] {
                if let Some((_, pc)) = &mut x.brk {
                    *pc = exit;
                }
            }
        }
        Ok(())
    }
}
