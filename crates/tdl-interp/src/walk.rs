//! Walking the lowered trees ([`Node`]): whether something holds anywhere in a statement, a
//! block or an expression, closures and nested blocks included. The interpreter asks it, once
//! per block, whether a statement may await (it then runs as a future, else synchronously) and,
//! once per task, whether a body may make children (it then holds them, as generated code does).

use crate::ir::{Block, ConstrainSt, Ex, LoopKind, LoopSt, St};

/// A statement or an expression.
#[derive(Clone, Copy)]
pub(crate) enum Node<'a> {
    St(&'a St),
    Ex(&'a Ex),
}

/// Whether `f` holds for a node of `b`.
pub(crate) fn block(b: &Block, f: &dyn Fn(Node<'_>) -> bool) -> bool {
    b.stmts.iter().any(|s| st(s, f)) || b.tail.as_ref().is_some_and(|e| ex(e, f))
}

fn loop_st(l: &LoopSt, f: &dyn Fn(Node<'_>) -> bool) -> bool {
    let head = match &l.kind {
        LoopKind::For(_, e) | LoopKind::While(e) => ex(e, f),
        LoopKind::Loop => false,
    };
    head || block(&l.body, f)
}

/// Whether `f` holds for `s` or a node inside it.
pub(crate) fn st(s: &St, f: &dyn Fn(Node<'_>) -> bool) -> bool {
    if f(Node::St(s)) {
        return true;
    }
    let all = |es: &[Ex]| es.iter().any(|e| ex(e, f));
    match s {
        St::Let(_, init, els) => {
            init.as_ref().is_some_and(|e| ex(e, f)) || els.as_deref().is_some_and(|b| block(b, f))
        }
        St::Expr(e) | St::Bind(_, e) => ex(e, f),
        St::Spawn(sp) => match &sp.task {
            crate::ir::TaskCall::Tdl(_, args) | crate::ir::TaskCall::Rust(_, args, _) => all(args),
            crate::ir::TaskCall::Remote { agent, args, .. } => ex(agent, f) || all(args),
        },
        St::With(w) => block(&w.body, f),
        St::Retry(args) => args.as_deref().is_some_and(all),
        St::Set(_, Some(e)) | St::Log(e) => ex(e, f),
        St::Loop(l) => loop_st(l, f),
        St::Fail(fs) => fs.fields.iter().any(|(_, e)| ex(e, f)),
        St::Constrain(_)
        | St::Succeed
        | St::Bypass
        | St::Trigger
        | St::Resource(..)
        | St::Set(_, None)
        | St::Raise(_) => false,
    }
}

/// Whether `f` holds for `e` or a node inside it.
pub(crate) fn ex(e: &Ex, f: &dyn Fn(Node<'_>) -> bool) -> bool {
    if f(Node::Ex(e)) {
        return true;
    }
    let all = |es: &[Ex]| es.iter().any(|e| ex(e, f));
    match e {
        Ex::Lit(_)
        | Ex::Local(_)
        | Ex::Ctx
        | Ex::Break(_)
        | Ex::Continue(_)
        | Ex::State(..)
        | Ex::Node(_) => false,
        Ex::Not(a) | Ex::Neg(a) | Ex::Await(a) | Ex::Try(a) | Ex::Cast(a, _) => ex(a, f),
        Ex::Field(a, _) | Ex::TupleField(a, _) => ex(a, f),
        Ex::Bin(_, l, r) | Ex::And(l, r) | Ex::Or(l, r) | Ex::Index(l, r) => ex(l, f) || ex(r, f),
        Ex::Call(_, args) | Ex::Tuple(args) | Ex::List(args) | Ex::Format(_, args) => all(args),
        Ex::Method { recv, args, .. } => ex(recv, f) || all(args),
        Ex::Record(_, fields) => fields.iter().any(|(_, e)| ex(e, f)),
        Ex::Range(lo, hi, _) => {
            lo.as_deref().is_some_and(|e| ex(e, f)) || hi.as_deref().is_some_and(|e| ex(e, f))
        }
        Ex::If(c, then, els) => {
            ex(c, f) || block(then, f) || els.as_deref().is_some_and(|e| ex(e, f))
        }
        Ex::Match(s, arms) => {
            ex(s, f)
                || arms
                    .iter()
                    .any(|a| ex(&a.body, f) || a.guard.as_ref().is_some_and(|g| ex(g, f)))
        }
        Ex::Block(b) => block(b, f),
        Ex::Closure(c) => ex(&c.body, f),
        Ex::Let(_, a) | Ex::Assign(_, a) | Ex::AssignOp(_, _, a) => ex(a, f),
        Ex::Return(a) => a.as_deref().is_some_and(|e| ex(e, f)),
        Ex::Loop(l) => loop_st(l, f),
    }
}

/// Whether a node makes the body wait: an `.await`, a loop (it may yield), a waited spawn,
/// `wait`, `retry`.
pub(crate) fn awaits(n: Node<'_>) -> bool {
    match n {
        Node::Ex(e) => matches!(e, Ex::Await(_) | Ex::Loop(_)),
        Node::St(s) => match s {
            St::Spawn(sp) => sp.wait || sp.binding.is_some(),
            St::Constrain(c) => matches!(**c, ConstrainSt::Wait(_)),
            St::Retry(_) | St::Loop(_) => true,
            _ => false,
        },
    }
}

/// Whether a node may make children of the body's node: a spawn, a group, a retry, or `ctx`
/// (what a registered function given it may do).
pub(crate) fn makes_children(n: Node<'_>) -> bool {
    matches!(
        n,
        Node::Ex(Ex::Ctx) | Node::St(St::Spawn(_) | St::With(_) | St::Retry(_))
    )
}
