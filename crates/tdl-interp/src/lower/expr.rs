//! Rust expressions and statements of the interpreted subset, lowered to `Ex` and `St`: literals,
//! locals, arithmetic, comparison and logic, calls of registered and built-in functions, method
//! calls, field and index access, `?` and `.await`, tuples and arrays, struct literals (of
//! declared exceptions), `format!`, ranges, `if`, `match`, blocks, loops, closures as arguments of
//! the methods that call them, `as` casts, assignment, `return`, `break`, `continue`, and the
//! macros `node!`, `state!`, `format!`, `vec!`.

use std::sync::Arc;

use proc_macro2::{Span, TokenStream};
use syn::parse::Parser;
use syn::spanned::Spanned;

use super::Lower;
use crate::builtin;
use crate::format::{self, ArgRef, Piece};
use crate::ir::{Bin, Block, Callee, Closure, Ex, LoopKind, LoopSt, Place, St};
use crate::ty::Ty;
use crate::value::Value;

impl Lower<'_, '_> {
    /// The statements of a Rust statement of a TDL body (its tokens), in the current scope.
    pub(crate) fn rust_stmts(&mut self, tokens: &TokenStream, span: Span, out: &mut Block) {
        let stmts = match syn::Block::parse_within.parse2(tokens.clone()) {
            Ok(stmts) => stmts,
            Err(e) => {
                self.error(
                    span,
                    format!("this Rust statement does not parse: {e}"),
                    "write it as Rust".into(),
                );
                return;
            }
        };
        for stmt in &stmts {
            self.stmt(stmt, out);
        }
    }

    /// One Rust statement into `out` (a tail expression becomes the block's tail).
    pub(crate) fn stmt(&mut self, stmt: &syn::Stmt, out: &mut Block) {
        if let Some(tail) = out.tail.take() {
            out.stmts.push(St::Expr(tail));
        }
        match stmt {
            syn::Stmt::Local(local) => {
                let init = local.init.as_ref().map(|it| self.expr(&it.expr));
                let els = local
                    .init
                    .as_ref()
                    .and_then(|it| it.diverge.as_ref())
                    .map(|(_, e)| {
                        let e = self.expr(e);
                        Box::new(Block {
                            tail: Some(e),
                            ..Block::default()
                        })
                    });
                // The pattern's names are in scope after the initialiser.
                let pat = self.pat(&local.pat);
                out.stmts.push(St::Let(pat, init, els));
            }
            syn::Stmt::Item(item) => self.unsupported(item.span(), "an item inside a body"),
            syn::Stmt::Expr(e, semi) => {
                let ex = self.expr(e);
                if semi.is_some() || !is_value_position(e) {
                    out.stmts.push(St::Expr(ex));
                } else {
                    out.tail = Some(ex);
                }
            }
            syn::Stmt::Macro(m) => {
                let ex = self.mac(&m.mac);
                if m.semi_token.is_some() {
                    out.stmts.push(St::Expr(ex));
                } else {
                    out.tail = Some(ex);
                }
            }
        }
    }

    /// A Rust block in a new scope.
    pub(crate) fn block(&mut self, block: &syn::Block) -> Block {
        self.push_scope();
        let mut out = Block::default();
        for stmt in &block.stmts {
            self.stmt(stmt, &mut out);
        }
        self.pop_scope();
        out
    }

    /// One expression.
    pub(crate) fn expr(&mut self, e: &syn::Expr) -> Ex {
        use syn::Expr as E;
        match e {
            E::Lit(l) => self.lit(&l.lit),
            E::Paren(p) => self.expr(&p.expr),
            E::Group(g) => self.expr(&g.expr),
            E::Reference(r) => self.expr(&r.expr),
            E::Unary(u) => {
                let inner = self.expr(&u.expr);
                match u.op {
                    syn::UnOp::Not(_) => Ex::Not(Box::new(inner)),
                    syn::UnOp::Neg(_) => match inner {
                        Ex::Lit(Value::Int(i)) => Ex::Lit(Value::Int(-i)),
                        Ex::Lit(Value::Float(x)) => Ex::Lit(Value::Float(-x)),
                        other => Ex::Neg(Box::new(other)),
                    },
                    // `*x`: values are not references.
                    _ => inner,
                }
            }
            E::Binary(b) => self.binary(b),
            E::Path(p) => self.path_expr(p),
            E::Call(c) => self.call(c),
            E::MethodCall(m) => self.method(m),
            E::Field(f) => {
                let base = Box::new(self.expr(&f.base));
                match &f.member {
                    syn::Member::Named(name) => Ex::Field(base, Arc::from(name.to_string())),
                    syn::Member::Unnamed(i) => Ex::TupleField(base, i.index as usize),
                }
            }
            E::Index(i) => Ex::Index(Box::new(self.expr(&i.expr)), Box::new(self.expr(&i.index))),
            E::Await(a) => {
                let base = self.expr(&a.base);
                if let Ex::Call(Callee::Registered(f), _) = &base {
                    if !f.is_async {
                        self.error(
                            a.span(),
                            "`.await` on a function registered as not `async`".into(),
                            "register it with `Registry::async_function`, or drop the `.await`"
                                .into(),
                        );
                    }
                }
                Ex::Await(Box::new(base))
            }
            E::Try(t) => Ex::Try(Box::new(self.expr(&t.expr))),
            E::Tuple(t) => {
                let items: Vec<Ex> = t.elems.iter().map(|it| self.expr(it)).collect();
                if items.is_empty() {
                    Ex::Lit(Value::Unit)
                } else {
                    Ex::Tuple(items)
                }
            }
            E::Array(a) => Ex::List(a.elems.iter().map(|it| self.expr(it)).collect()),
            E::Struct(s) => self.struct_lit(s),
            E::Range(r) => Ex::Range(
                r.start.as_ref().map(|it| Box::new(self.expr(it))),
                r.end.as_ref().map(|it| Box::new(self.expr(it))),
                matches!(r.limits, syn::RangeLimits::Closed(_)),
            ),
            E::If(i) => self.if_expr(i),
            E::Match(m) => {
                let scrutinee = Box::new(self.expr(&m.expr));
                let arms = m
                    .arms
                    .iter()
                    .map(|arm| {
                        self.push_scope();
                        let (pat, guard) = match &arm.pat {
                            syn::Pat::Guard(g) => (self.pat(&g.pat), Some(self.expr(&g.guard))),
                            other => (self.pat(other), None),
                        };
                        let body = self.expr(&arm.body);
                        self.pop_scope();
                        crate::ir::Arm { pat, guard, body }
                    })
                    .collect();
                Ex::Match(scrutinee, arms)
            }
            E::Block(b) if b.label.is_none() => Ex::Block(Box::new(self.block(&b.block))),
            E::Closure(c) => self.closure(c),
            E::Cast(c) => Ex::Cast(Box::new(self.expr(&c.expr)), self.ty(&c.ty)),
            E::Let(l) => {
                let value = self.expr(&l.expr);
                let pat = self.pat(&l.pat);
                Ex::Let(Box::new(pat), Box::new(value))
            }
            E::Return(r) => Ex::Return(r.expr.as_ref().map(|it| Box::new(self.expr(it)))),
            E::Break(b) => {
                if b.expr.is_some() {
                    self.unsupported(b.span(), "`break` with a value");
                }
                Ex::Break(b.label.as_ref().map(|l| Arc::from(l.ident.to_string())))
            }
            E::Continue(c) => {
                Ex::Continue(c.label.as_ref().map(|l| Arc::from(l.ident.to_string())))
            }
            E::Assign(a) => {
                let value = self.expr(&a.right);
                match self.place(&a.left) {
                    Some(place) => Ex::Assign(Box::new(place), Box::new(value)),
                    None => Ex::Lit(Value::Unit),
                }
            }
            E::Macro(m) => self.mac(&m.mac),
            E::ForLoop(f) => {
                let iter = self.expr(&f.expr);
                self.push_scope();
                let pat = self.pat(&f.pat);
                let body = self.block(&f.body);
                self.pop_scope();
                self.rust_loop(f.label.as_ref(), LoopKind::For(pat, iter), body, f.span())
            }
            E::While(w) => {
                self.push_scope();
                let cond = self.expr(&w.cond);
                let body = self.block(&w.body);
                self.pop_scope();
                self.rust_loop(w.label.as_ref(), LoopKind::While(cond), body, w.span())
            }
            E::Loop(l) => {
                let body = self.block(&l.body);
                self.rust_loop(l.label.as_ref(), LoopKind::Loop, body, l.span())
            }
            other => {
                self.unsupported(other.span(), &describe(other));
                Ex::Lit(Value::Unit)
            }
        }
    }

    fn rust_loop(
        &mut self,
        label: Option<&syn::Label>,
        kind: LoopKind,
        body: Block,
        span: Span,
    ) -> Ex {
        Ex::Loop(Box::new(LoopSt {
            label: label.map(|l| Arc::from(l.name.ident.to_string())),
            kind,
            body,
            counter: None,
            loc: self.loc(span),
        }))
    }

    fn lit(&mut self, lit: &syn::Lit) -> Ex {
        let v = match lit {
            syn::Lit::Int(i) => match i.base10_parse::<i64>() {
                Ok(n) => match i.suffix() {
                    "f64" | "f32" =>
                    {
                        #[allow(clippy::cast_precision_loss, reason = "a float literal")]
                        Value::Float(n as f64)
                    }
                    _ => Value::Int(n),
                },
                Err(_) => {
                    self.error(
                        i.span(),
                        format!("the integer {i} does not fit an `i64`"),
                        "interpreted integers are `i64`".into(),
                    );
                    Value::Unit
                }
            },
            syn::Lit::Float(f) => Value::Float(f.base10_parse::<f64>().unwrap_or(f64::NAN)),
            syn::Lit::Str(s) => Value::str(s.value()),
            syn::Lit::Bool(b) => Value::Bool(b.value),
            syn::Lit::Char(c) => Value::str(c.value().to_string()),
            other => {
                self.unsupported(other.span(), "this literal");
                Value::Unit
            }
        };
        Ex::Lit(v)
    }

    fn binary(&mut self, b: &syn::ExprBinary) -> Ex {
        use syn::BinOp as B;
        let l = self.expr(&b.left);
        let r = self.expr(&b.right);
        let bin = |op| Ex::Bin(op, Box::new(l.clone()), Box::new(r.clone()));
        let assign = |me: &mut Self, op| match me.place(&b.left) {
            Some(place) => Ex::AssignOp(op, Box::new(place), Box::new(r.clone())),
            None => Ex::Lit(Value::Unit),
        };
        match b.op {
            B::And(_) => Ex::And(Box::new(l), Box::new(r)),
            B::Or(_) => Ex::Or(Box::new(l), Box::new(r)),
            B::Add(_) => bin(Bin::Add),
            B::Sub(_) => bin(Bin::Sub),
            B::Mul(_) => bin(Bin::Mul),
            B::Div(_) => bin(Bin::Div),
            B::Rem(_) => bin(Bin::Rem),
            B::Eq(_) => bin(Bin::Eq),
            B::Ne(_) => bin(Bin::Ne),
            B::Lt(_) => bin(Bin::Lt),
            B::Le(_) => bin(Bin::Le),
            B::Gt(_) => bin(Bin::Gt),
            B::Ge(_) => bin(Bin::Ge),
            B::BitAnd(_) => bin(Bin::BitAnd),
            B::BitOr(_) => bin(Bin::BitOr),
            B::BitXor(_) => bin(Bin::BitXor),
            B::Shl(_) => bin(Bin::Shl),
            B::Shr(_) => bin(Bin::Shr),
            B::AddAssign(_) => assign(self, Bin::Add),
            B::SubAssign(_) => assign(self, Bin::Sub),
            B::MulAssign(_) => assign(self, Bin::Mul),
            B::DivAssign(_) => assign(self, Bin::Div),
            B::RemAssign(_) => assign(self, Bin::Rem),
            _ => {
                self.unsupported(b.op.span(), "this operator");
                Ex::Lit(Value::Unit)
            }
        }
    }

    /// A path in value position: a local, `ctx`, a constant, a unit variant.
    fn path_expr(&mut self, p: &syn::ExprPath) -> Ex {
        let text = path_text(&p.path);
        if let Some(ident) = p.path.get_ident() {
            let name = ident.to_string();
            if let Some(slot) = self.local(&name) {
                self.used.insert(slot);
                return Ex::Local(slot);
            }
            if name == "ctx" {
                return Ex::Ctx;
            }
        }
        if let Some(v) = self.registry.constants.get(&text) {
            return Ex::Lit(v.clone());
        }
        if let Some(v) = builtin::constant(&text) {
            return Ex::Lit(v);
        }
        // A unit variant of a registered enum, written `Enum::Variant`.
        let span = p.span();
        let offered: Vec<&str> = self.registry.constants.keys().map(String::as_str).collect();
        self.error(
            span,
            format!(
                "cannot find `{text}`: not a local, a parameter, nor a constant the registry offers"
            ),
            if offered.is_empty() {
                "register it with `Registry::constant`".into()
            } else {
                format!(
                    "register it with `Registry::constant`; the registry offers {}",
                    list(&offered)
                )
            },
        );
        Ex::Lit(Value::Unit)
    }

    fn call(&mut self, c: &syn::ExprCall) -> Ex {
        let syn::Expr::Path(p) = &*c.func else {
            self.unsupported(c.func.span(), "a call of a computed function");
            return Ex::Lit(Value::Unit);
        };
        let text = path_text(&p.path);
        let args: Vec<Ex> = c.args.iter().map(|a| self.expr(a)).collect();
        if let Some(f) = self.registry.functions.get(&text) {
            if f.arity != args.len() {
                self.error(
                    c.span(),
                    format!(
                        "`{text}` takes {} argument(s), given {}",
                        f.arity,
                        args.len()
                    ),
                    format!("its parameters: {}", f.params.join(", ")),
                );
            }
            return Ex::Call(Callee::Registered(f.clone()), args);
        }
        if let Some(b) = builtin::function(&text, args.len()) {
            return Ex::Call(Callee::Builtin(b), args);
        }
        // A variant with fields of a registered enum, or a record the program declares.
        let offered = self.registry.function_names();
        self.error(
            c.func.span(),
            format!("cannot find the function `{text}`: the registry offers no such function"),
            if offered.is_empty() {
                "register it with `Registry::function`".into()
            } else {
                format!(
                    "register it with `Registry::function`; the registry offers {}",
                    list(&offered)
                )
            },
        );
        Ex::Lit(Value::Unit)
    }

    fn method(&mut self, m: &syn::ExprMethodCall) -> Ex {
        let recv = self.expr(&m.receiver);
        let name = m.method.to_string();
        let turbofish = m.turbofish.as_ref().and_then(|t| match t.args.first() {
            Some(syn::GenericArgument::Type(ty)) => match self.ty(ty) {
                Ty::Named(n) => Some(n),
                _ => None,
            },
            _ => None,
        });
        let args: Vec<Ex> = m.args.iter().map(|a| self.expr(a)).collect();
        let registered = self.registry.methods.keys().any(|(_, n)| *n == name);
        if !registered && !builtin::is_method(&name) {
            self.error(
                m.method.span(),
                format!("no method `{name}` is known to the interpreter or offered by the registry"),
                "register it with `Registry::method` for its host type, or see the methods of plain values in docs/language.md, \"Running programs without compiling them\"".into(),
            );
        }
        Ex::Method {
            recv: Box::new(recv),
            name: Arc::from(name.as_str()),
            args,
            turbofish,
        }
    }

    fn struct_lit(&mut self, s: &syn::ExprStruct) -> Ex {
        let name = path_text(&s.path);
        if s.rest.is_some() {
            self.unsupported(s.span(), "a struct literal with `..`");
        }
        let fields = s
            .fields
            .iter()
            .filter_map(|f| match &f.member {
                syn::Member::Named(n) => Some((Arc::from(n.to_string()), self.expr(&f.expr))),
                syn::Member::Unnamed(_) => {
                    self.unsupported(f.span(), "a numbered field");
                    None
                }
            })
            .collect();
        Ex::Record(Arc::from(name.as_str()), fields)
    }

    fn if_expr(&mut self, i: &syn::ExprIf) -> Ex {
        self.push_scope();
        let cond = self.expr(&i.cond);
        let then = self.block(&i.then_branch);
        self.pop_scope();
        let els = i.else_branch.as_ref().map(|(_, e)| Box::new(self.expr(e)));
        Ex::If(Box::new(cond), Box::new(then), els)
    }

    fn closure(&mut self, c: &syn::ExprClosure) -> Ex {
        self.push_scope();
        let params = c.inputs.iter().map(|p| self.pat(p)).collect();
        let body = self.expr(&c.body);
        self.pop_scope();
        Ex::Closure(Arc::new(Closure { params, body }))
    }

    /// A place assigned to: a local, a field or an element of one.
    pub(crate) fn place(&mut self, e: &syn::Expr) -> Option<Place> {
        match e {
            syn::Expr::Paren(p) => self.place(&p.expr),
            syn::Expr::Unary(u) if matches!(u.op, syn::UnOp::Deref(_)) => self.place(&u.expr),
            syn::Expr::Path(p) => {
                let name = p.path.get_ident().map(ToString::to_string);
                match name.as_deref().and_then(|n| self.local(n)) {
                    Some(slot) => Some(Place::Local(slot)),
                    None => {
                        self.error(
                            p.span(),
                            format!("cannot assign to `{}`: not a local", path_text(&p.path)),
                            "declare it with `let mut`".into(),
                        );
                        None
                    }
                }
            }
            syn::Expr::Field(f) => {
                let base = self.place(&f.base)?;
                Some(match &f.member {
                    syn::Member::Named(n) => Place::Field(Box::new(base), Arc::from(n.to_string())),
                    syn::Member::Unnamed(i) => Place::TupleField(Box::new(base), i.index as usize),
                })
            }
            syn::Expr::Index(i) => {
                let base = self.place(&i.expr)?;
                let index = self.expr(&i.index);
                Some(Place::Index(Box::new(base), Box::new(index)))
            }
            other => {
                self.unsupported(other.span(), "assigning to this expression");
                None
            }
        }
    }

    /// A macro call: `format!`, `vec!`, `node!`, `state!`.
    fn mac(&mut self, m: &syn::Macro) -> Ex {
        let name = path_text(&m.path);
        match name.as_str() {
            "format" => self.format(m),
            "vec" => {
                let parser =
                    syn::punctuated::Punctuated::<syn::Expr, syn::Token![,]>::parse_terminated;
                match parser.parse2(m.tokens.clone()) {
                    Ok(items) => Ex::List(items.iter().map(|it| self.expr(it)).collect()),
                    Err(_) => {
                        self.unsupported(m.span(), "this form of `vec!`");
                        Ex::Lit(Value::Unit)
                    }
                }
            }
            "node" => match tdl_syntax::parse_tag_tokens(m.tokens.clone()) {
                Ok(tag) => match self.node_of(&tag) {
                    Some(node) => Ex::Node(Box::new(node)),
                    None => Ex::Lit(Value::Unit),
                },
                Err(e) => {
                    self.error(
                        m.span(),
                        format!("`node!`: {e}"),
                        "write `node!(tag)`".into(),
                    );
                    Ex::Lit(Value::Unit)
                }
            },
            "state" => {
                let var = syn::parse2::<syn::Ident>(m.tokens.clone())
                    .ok()
                    .and_then(|id| self.names.states.get(&id.to_string()).cloned());
                match var {
                    Some((var, ty)) => Ex::State(var, ty),
                    None => Ex::Lit(Value::none()),
                }
            }
            _ => {
                self.unsupported(m.span(), &format!("the macro `{name}!`"));
                Ex::Lit(Value::Unit)
            }
        }
    }

    fn format(&mut self, m: &syn::Macro) -> Ex {
        let parser = syn::punctuated::Punctuated::<syn::Expr, syn::Token![,]>::parse_terminated;
        let Ok(parts) = parser.parse2(m.tokens.clone()) else {
            self.unsupported(m.span(), "this form of `format!`");
            return Ex::Lit(Value::Unit);
        };
        let mut parts = parts.into_iter();
        let Some(syn::Expr::Lit(syn::ExprLit {
            lit: syn::Lit::Str(s),
            ..
        })) = parts.next()
        else {
            self.unsupported(m.span(), "`format!` without a literal format string");
            return Ex::Lit(Value::Unit);
        };
        let mut fmt = match format::parse(&s.value()) {
            Ok(f) => f,
            Err(e) => {
                self.error(
                    s.span(),
                    format!("format string: {e}"),
                    SUPPORTED_FMT.into(),
                );
                return Ex::Lit(Value::Unit);
            }
        };
        // Positional arguments first, then `name = expr` ones, then inline names.
        let mut args = Vec::new();
        let mut named: Vec<(String, usize)> = Vec::new();
        for part in parts {
            match part {
                syn::Expr::Assign(a) => {
                    if let syn::Expr::Path(p) = &*a.left {
                        if let Some(id) = p.path.get_ident() {
                            named.push((id.to_string(), args.len()));
                            args.push(self.expr(&a.right));
                            continue;
                        }
                    }
                    args.push(self.expr(&syn::Expr::Assign(a)));
                }
                other => args.push(self.expr(&other)),
            }
        }
        let mut next = 0;
        for piece in &mut fmt.pieces {
            let Piece::Hole(h) = piece else { continue };
            let index = match &h.arg {
                ArgRef::Next => {
                    next += 1;
                    next - 1
                }
                ArgRef::Index(i) => *i,
                ArgRef::Name(n) => match named.iter().find(|(name, _)| name == n) {
                    Some((_, i)) => *i,
                    None => {
                        let found = self.local(n);
                        if let Some(slot) = found {
                            self.used.insert(slot);
                        }
                        let Some(slot) = found else {
                            self.error(
                                s.span(),
                                format!("format string: `{n}` is not a local nor a named argument"),
                                SUPPORTED_FMT.into(),
                            );
                            continue;
                        };
                        named.push((n.clone(), args.len()));
                        args.push(Ex::Local(slot));
                        args.len() - 1
                    }
                },
            };
            h.arg = ArgRef::Index(index);
        }
        Ex::Format(Arc::new(fmt), args)
    }
}

const SUPPORTED_FMT: &str =
    "holes are `{}`, `{0}`, `{name}` with `?`, fill and alignment, `+`, `0`, width and precision";

/// Whether a statement expression without `;` is the block's value (a block-like expression,
/// `if`, `match`, a loop, is a statement unless it is last).
fn is_value_position(_e: &syn::Expr) -> bool {
    true
}

/// A path as written, segments joined by `::`, generic arguments left out.
pub(crate) fn path_text(path: &syn::Path) -> String {
    path.segments
        .iter()
        .map(|s| s.ident.to_string())
        .collect::<Vec<_>>()
        .join("::")
}

/// Names for a message: the first ten, then how many more.
pub(crate) fn list(names: &[&str]) -> String {
    let shown: Vec<String> = names.iter().take(10).map(|n| format!("`{n}`")).collect();
    if names.len() > 10 {
        format!("{} and {} more", shown.join(", "), names.len() - 10)
    } else {
        shown.join(", ")
    }
}

/// What an expression outside the subset is, for the message.
fn describe(e: &syn::Expr) -> String {
    use syn::Expr as E;
    match e {
        E::Async(_) => "an `async` block".into(),
        E::Const(_) => "a `const` block".into(),
        E::Unsafe(_) => "an `unsafe` block".into(),
        E::Yield(_) => "`yield`".into(),
        E::TryBlock(_) => "a `try` block".into(),
        E::Repeat(_) => "an array repeat expression".into(),
        E::Block(_) => "a labelled block".into(),
        _ => "this expression".into(),
    }
}
