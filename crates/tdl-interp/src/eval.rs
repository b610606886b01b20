//! Evaluating expressions in a body's frame ([`Frame`]): synchronously ([`Frame::eval`]) for
//! the expressions that never await, which is nearly all of them, and as a future
//! ([`Frame::eval_async`]) for those that contain an `.await` (a call of an `async` function,
//! `ctx.sleep`). Control leaves an expression as a [`Flow`]: `return`, `break`, `continue`, or a
//! failure of the node (`?` on an error, a value of the wrong kind, a budget used up).
//! Operators, comparisons and the methods of plain values are in `eval/ops.rs`.

mod ops;

use std::future::Future;
use std::pin::Pin;
use std::sync::Arc;

use tdl::{Ctx, Failure, NodeId};

use crate::builtin;
use crate::ir::{Callee, Ex, Pat, Place};
use crate::program::Shared;
use crate::registry::Call;
use crate::value::Value;

pub(crate) use ops::compare;

/// How control leaves an expression or statement other than by its value.
pub(crate) enum Flow {
    Return(Value),
    Break(Option<Arc<str>>),
    Continue(Option<Arc<str>>),
    Fail(Failure),
}

impl From<Failure> for Flow {
    fn from(f: Failure) -> Flow {
        Flow::Fail(f)
    }
}

impl From<tdl::Error> for Flow {
    fn from(e: tdl::Error) -> Flow {
        Flow::Fail(Failure::from(e))
    }
}

pub(crate) type R<T> = Result<T, Flow>;

/// A TDL slot's value: the body's bookkeeping of nodes (`ir.rs`).
#[derive(Clone, Debug, Default)]
pub(crate) enum TdlVal {
    #[default]
    Empty,
    Node(NodeId),
    Map(std::collections::BTreeMap<Vec<i64>, NodeId>),
    Nodes(Vec<NodeId>),
    /// `previous`, or a tag bound at run time: `None` before anything.
    Maybe(Option<Vec<NodeId>>),
    Count(i64),
}

/// One run of a body: its context, its locals and TDL slots, and the program.
pub(crate) struct Frame {
    /// The action's context; none while a task is built (its constraints' arguments computed).
    pub(crate) ctx: Option<Ctx>,
    pub(crate) locals: Vec<Value>,
    pub(crate) tdl: Vec<TdlVal>,
    pub(crate) shared: Arc<Shared>,
    /// Steps taken since the body last yielded to the runtime, and in all.
    pub(crate) since_yield: u32,
    pub(crate) steps: u64,
}

/// A boxed future of a value.
pub(crate) type BoxFut<'f, T> = Pin<Box<dyn Future<Output = R<T>> + Send + 'f>>;

impl Frame {
    /// The action's context.
    pub(crate) fn ctx(&self) -> R<&Ctx> {
        self.ctx.as_ref().ok_or_else(|| {
            Flow::Fail(Failure::new(
                "Interpreter",
                "`ctx` is not available where a task is built (in its constraints' arguments)",
            ))
        })
    }

    pub(crate) fn local(&self, slot: u32) -> Value {
        self.locals.get(slot as usize).cloned().unwrap_or_default()
    }

    pub(crate) fn set_local(&mut self, slot: u32, v: Value) {
        if let Some(it) = self.locals.get_mut(slot as usize) {
            *it = v;
        }
    }

    /// The value of an expression that does not await.
    pub(crate) fn eval(&mut self, ex: &Ex) -> R<Value> {
        Ok(match ex {
            Ex::Lit(v) => v.clone(),
            Ex::Local(slot) => self.local(*slot),
            Ex::Ctx => Value::Ctx(self.ctx()?.clone()),
            Ex::Not(e) => ops::not(&self.eval(e)?)?,
            Ex::Neg(e) => ops::neg(&self.eval(e)?)?,
            Ex::Bin(op, l, r) => {
                let l = self.eval(l)?;
                let r = self.eval(r)?;
                ops::binary(*op, &l, &r)?
            }
            Ex::And(l, r) => Value::Bool(self.truth(l)? && self.truth(r)?),
            Ex::Or(l, r) => Value::Bool(self.truth(l)? || self.truth(r)?),
            Ex::Call(callee, args) => {
                let args = self.eval_all(args)?;
                match self.call(callee, args) {
                    Call::Ready(r) => r?,
                    // An `async` function called without `.await`: a future dropped unpolled, as in Rust.
                    Call::Pending(_) => Value::Unit,
                }
            }
            Ex::Method {
                recv,
                name,
                args,
                turbofish,
            } => {
                let recv = self.eval(recv)?;
                if builtin::CLOSURE_METHODS.contains(&&**name) {
                    return self.closure_method(&recv, name, args);
                }
                let args = self.eval_all(args)?;
                match self.method(&recv, name, &args, turbofish.as_deref())? {
                    Call::Ready(r) => r?,
                    Call::Pending(_) => Value::Unit,
                }
            }
            Ex::Field(base, name) => {
                let base = self.eval(base)?;
                self.field(&base, name)?
            }
            Ex::TupleField(base, i) => ops::tuple_field(&self.eval(base)?, *i)?,
            Ex::Index(base, index) => {
                let base = self.eval(base)?;
                let index = self.eval(index)?;
                ops::index(&base, &index)?
            }
            Ex::Await(_) => {
                return Err(Flow::Fail(Failure::new(
                    "Interpreter",
                    "an `.await` evaluated outside an asynchronous statement",
                )));
            }
            Ex::Try(e) => {
                let v = self.eval(e)?;
                ops::try_value(v)?
            }
            Ex::Tuple(items) => Value::tuple(self.eval_all(items)?),
            Ex::List(items) => Value::list(self.eval_all(items)?),
            Ex::Record(name, fields) => {
                let mut out = Vec::with_capacity(fields.len());
                for (n, e) in fields {
                    out.push((n.clone(), self.eval(e)?));
                }
                Value::Record(Arc::new(crate::value::Record {
                    name: name.clone(),
                    fields: out,
                }))
            }
            Ex::Format(fmt, args) => {
                let args = self.eval_all(args)?;
                ops::format(fmt, &args)
            }
            Ex::Range(lo, hi, closed) => {
                let lo = match lo {
                    Some(e) => Some(self.eval(e)?),
                    None => None,
                };
                let hi = match hi {
                    Some(e) => Some(self.eval(e)?),
                    None => None,
                };
                ops::range(lo.as_ref(), hi.as_ref(), *closed)?
            }
            Ex::If(cond, then, els) => {
                if self.truth(cond)? {
                    self.block_sync(then)?
                } else if let Some(els) = els {
                    self.eval(els)?
                } else {
                    Value::Unit
                }
            }
            Ex::Match(scrutinee, arms) => {
                let v = self.eval(scrutinee)?;
                for arm in arms {
                    if !self.bind(&arm.pat, &v) {
                        continue;
                    }
                    if let Some(guard) = &arm.guard {
                        if !self.truth(guard)? {
                            continue;
                        }
                    }
                    return self.eval(&arm.body);
                }
                return Err(Flow::Fail(Failure::new(
                    "NoMatch",
                    format!("no arm of the `match` takes `{v:?}`"),
                )));
            }
            Ex::Block(b) => self.block_sync(b)?,
            Ex::Closure(_) => {
                return Err(Flow::Fail(Failure::new(
                    "Interpreter",
                    "a closure is only an argument of a method that calls it",
                )));
            }
            Ex::Cast(e, ty) => ops::cast(self.eval(e)?, ty)?,
            Ex::Let(pat, e) => {
                let v = self.eval(e)?;
                Value::Bool(self.bind(pat, &v))
            }
            Ex::Return(e) => {
                let v = match e {
                    Some(e) => self.eval(e)?,
                    None => Value::Unit,
                };
                return Err(Flow::Return(v));
            }
            Ex::Break(l) => return Err(Flow::Break(l.clone())),
            Ex::Continue(l) => return Err(Flow::Continue(l.clone())),
            Ex::Assign(place, e) => {
                let v = self.eval(e)?;
                self.assign(place, v)?;
                Value::Unit
            }
            Ex::AssignOp(op, place, e) => {
                let r = self.eval(e)?;
                let l = self.read_place(place)?;
                let v = ops::binary(*op, &l, &r)?;
                self.assign(place, v)?;
                Value::Unit
            }
            Ex::Node(node) => Value::Node(self.node_sync(node)?),
            Ex::State(var, ty) => {
                let ctx = self.ctx()?;
                let v = match ty {
                    tcm_expr::Type::Bool => ctx.read_state::<bool>(var)?.map(Value::Bool),
                    tcm_expr::Type::Int => ctx.read_state::<i64>(var)?.map(Value::Int),
                    tcm_expr::Type::Float => ctx.read_state::<f64>(var)?.map(Value::Float),
                    tcm_expr::Type::Str => ctx.read_state::<String>(var)?.map(Value::str),
                };
                Value::option(v)
            }
            Ex::Loop(l) => {
                self.loop_sync(l)?;
                Value::Unit
            }
        })
    }

    /// The value of an expression that may await.
    pub(crate) fn eval_async<'f>(&'f mut self, ex: &'f Ex) -> BoxFut<'f, Value> {
        Box::pin(async move {
            if !has_await(ex) {
                return self.eval(ex);
            }
            Ok(match ex {
                Ex::Await(inner) => match &**inner {
                    Ex::Call(callee, args) => {
                        let args = self.eval_all_async(args).await?;
                        self.finish(self.call(callee, args)).await?
                    }
                    Ex::Method {
                        recv,
                        name,
                        args,
                        turbofish,
                    } => {
                        let recv = self.eval_async(recv).await?;
                        let args = self.eval_all_async(args).await?;
                        let call = self.method(&recv, name, &args, turbofish.as_deref())?;
                        self.finish(call).await?
                    }
                    other => self.eval_async(other).await?,
                },
                Ex::Try(e) => ops::try_value(self.eval_async(e).await?)?,
                Ex::Not(e) => ops::not(&self.eval_async(e).await?)?,
                Ex::Neg(e) => ops::neg(&self.eval_async(e).await?)?,
                Ex::Bin(op, l, r) => {
                    let l = self.eval_async(l).await?;
                    let r = self.eval_async(r).await?;
                    ops::binary(*op, &l, &r)?
                }
                Ex::And(l, r) => {
                    let l = truth(&self.eval_async(l).await?)?;
                    Value::Bool(l && truth(&self.eval_async(r).await?)?)
                }
                Ex::Or(l, r) => {
                    let l = truth(&self.eval_async(l).await?)?;
                    Value::Bool(l || truth(&self.eval_async(r).await?)?)
                }
                Ex::Call(callee, args) => {
                    let args = self.eval_all_async(args).await?;
                    match self.call(callee, args) {
                        Call::Ready(r) => r?,
                        Call::Pending(_) => Value::Unit,
                    }
                }
                Ex::Method {
                    recv,
                    name,
                    args,
                    turbofish,
                } => {
                    let recv = self.eval_async(recv).await?;
                    let args = self.eval_all_async(args).await?;
                    match self.method(&recv, name, &args, turbofish.as_deref())? {
                        Call::Ready(r) => r?,
                        Call::Pending(_) => Value::Unit,
                    }
                }
                Ex::Field(base, name) => {
                    let base = self.eval_async(base).await?;
                    self.field(&base, name)?
                }
                Ex::TupleField(base, i) => ops::tuple_field(&self.eval_async(base).await?, *i)?,
                Ex::Tuple(items) => Value::tuple(self.eval_all_async(items).await?),
                Ex::List(items) => Value::list(self.eval_all_async(items).await?),
                Ex::Let(pat, e) => {
                    let v = self.eval_async(e).await?;
                    Value::Bool(self.bind(pat, &v))
                }
                Ex::Assign(place, e) => {
                    let v = self.eval_async(e).await?;
                    self.assign(place, v)?;
                    Value::Unit
                }
                Ex::Return(Some(e)) => {
                    let v = self.eval_async(e).await?;
                    return Err(Flow::Return(v));
                }
                Ex::If(cond, then, els) => {
                    if truth(&self.eval_async(cond).await?)? {
                        self.block_async(then).await?
                    } else if let Some(els) = els {
                        self.eval_async(els).await?
                    } else {
                        Value::Unit
                    }
                }
                Ex::Match(scrutinee, arms) => {
                    let v = self.eval_async(scrutinee).await?;
                    for arm in arms {
                        if !self.bind(&arm.pat, &v) {
                            continue;
                        }
                        if let Some(guard) = &arm.guard {
                            if !truth(&self.eval_async(guard).await?)? {
                                continue;
                            }
                        }
                        return self.eval_async(&arm.body).await;
                    }
                    return Err(Flow::Fail(Failure::new(
                        "NoMatch",
                        format!("no arm of the `match` takes `{v:?}`"),
                    )));
                }
                Ex::Block(b) => self.block_async(b).await?,
                Ex::Loop(l) => {
                    self.loop_async(l).await?;
                    Value::Unit
                }
                Ex::Format(fmt, args) => {
                    let args = self.eval_all_async(args).await?;
                    ops::format(fmt, &args)
                }
                Ex::Record(name, fields) => {
                    let mut out = Vec::with_capacity(fields.len());
                    for (n, e) in fields {
                        out.push((n.clone(), self.eval_async(e).await?));
                    }
                    Value::Record(Arc::new(crate::value::Record {
                        name: name.clone(),
                        fields: out,
                    }))
                }
                other => {
                    return Err(Flow::Fail(Failure::new(
                        "Interpreter",
                        format!(
                            "an `.await` inside {} is not in the interpreted subset",
                            ops::what(other)
                        ),
                    )));
                }
            })
        })
    }

    async fn finish(&mut self, call: Call) -> R<Value> {
        match call {
            Call::Ready(r) => Ok(r?),
            Call::Pending(fut) => Ok(fut.await?),
        }
    }

    pub(crate) fn truth(&mut self, ex: &Ex) -> R<bool> {
        truth(&self.eval(ex)?)
    }

    pub(crate) fn eval_all(&mut self, exs: &[Ex]) -> R<Vec<Value>> {
        exs.iter().map(|e| self.eval(e)).collect()
    }

    pub(crate) async fn eval_all_async(&mut self, exs: &[Ex]) -> R<Vec<Value>> {
        let mut out = Vec::with_capacity(exs.len());
        for e in exs {
            out.push(self.eval_async(e).await?);
        }
        Ok(out)
    }

    fn call(&self, callee: &Callee, args: Vec<Value>) -> Call {
        match callee {
            Callee::Registered(f) => (f.call)(&args),
            Callee::Builtin(b) => builtin::call(*b, args),
        }
    }

    /// A method call on a value: `ctx`'s, a host type's from the registry, a plain value's.
    fn method(&self, recv: &Value, name: &str, args: &[Value], turbofish: Option<&str>) -> R<Call> {
        if let Value::Ctx(ctx) = recv {
            if let Some(call) = builtin::ctx_method(ctx, name, args) {
                return Ok(call);
            }
        }
        let ty = match recv {
            Value::Host(h) => Some(h.ty.to_string()),
            Value::Failure(_) | Value::Error(_) => {
                recv.as_failure().map(|f| f.exception.to_string())
            }
            Value::Record(r) => Some(r.name.to_string()),
            Value::Variant(v) => Some(v.ty.to_string()),
            _ => None,
        };
        if let Some(ty) = ty {
            if let Some(f) = self.shared.registry.methods.get(&(ty, name.to_string())) {
                let mut all = Vec::with_capacity(args.len() + 1);
                all.push(recv.clone());
                all.extend_from_slice(args);
                return Ok((f.call)(&all));
            }
        }
        Ok(Call::Ready(ops::method(
            recv,
            name,
            args,
            turbofish,
            &self.shared,
        )))
    }

    fn field(&self, base: &Value, name: &str) -> R<Value> {
        if let Value::Host(h) = base {
            let key = (h.ty.to_string(), name.to_string());
            return match self.shared.registry.fields.get(&key) {
                Some(f) => match (f.call)(std::slice::from_ref(base)) {
                    Call::Ready(r) => Ok(r?),
                    Call::Pending(_) => Err(Flow::Fail(Failure::new(
                        "Interpreter",
                        format!("the field `{name}` of `{}` is asynchronous", h.ty),
                    ))),
                },
                None => Err(Flow::Fail(Failure::new(
                    "UnknownField",
                    format!(
                        "`{}` has no field `{name}` in the registry (`Registry::field`)",
                        h.ty
                    ),
                ))),
            };
        }
        Ok(ops::field(base, name)?)
    }

    /// Runs a method whose last argument is a closure.
    fn closure_method(&mut self, recv: &Value, name: &str, args: &[Ex]) -> R<Value> {
        let mut evaluated = Vec::new();
        let mut closure = None;
        for a in args {
            match a {
                Ex::Closure(c) => closure = Some(c.clone()),
                other => evaluated.push(self.eval(other)?),
            }
        }
        let Some(c) = closure else {
            return Err(Flow::Fail(Failure::new(
                "Interpreter",
                format!("`{name}` needs a closure argument (`|x| …`)"),
            )));
        };
        let mut apply = |me: &mut Frame, args: &[Value]| -> R<Value> {
            for (p, a) in c.params.iter().zip(args) {
                if !me.bind(p, a) {
                    return Err(Flow::Fail(Failure::new(
                        "NoMatch",
                        format!("a closure parameter does not take `{a:?}`"),
                    )));
                }
            }
            me.eval(&c.body)
        };
        ops::with_closure(self, recv, name, &evaluated, &mut apply)
    }

    /// Matches `v` against `pat`, binding its names; whether it matched.
    pub(crate) fn bind(&mut self, pat: &Pat, v: &Value) -> bool {
        match pat {
            Pat::Wild => true,
            Pat::Bind(slot, sub) => {
                if let Some(sub) = sub {
                    if !self.bind(sub, v) {
                        return false;
                    }
                }
                self.set_local(*slot, v.clone());
                true
            }
            Pat::Lit(l) | Pat::Const(l) => l == v,
            Pat::Range(lo, hi, closed) => {
                let above = lo
                    .as_ref()
                    .is_none_or(|lo| compare(v, lo).is_ok_and(|o| o.is_ge()));
                let below = hi.as_ref().is_none_or(|hi| {
                    compare(v, hi).is_ok_and(|o| if *closed { o.is_le() } else { o.is_lt() })
                });
                above && below
            }
            Pat::Tuple(pats) => match v {
                Value::Tuple(items) | Value::List(items) if items.len() == pats.len() => pats
                    .iter()
                    .zip(items.iter())
                    .all(|(p, it)| self.bind(p, it)),
                Value::Unit => pats.is_empty(),
                _ => false,
            },
            Pat::Variant(ty, name, pats) => match v {
                Value::Variant(var) => {
                    var.name == *name
                        && ty
                            .as_ref()
                            .is_none_or(|t| *t == var.ty || var.ty.is_empty())
                        && (pats.len() == var.fields.len()
                            || (pats.len() == 1 && var.fields.is_empty()))
                        && pats
                            .iter()
                            .zip(var.fields.iter().chain(std::iter::once(&Value::Unit)))
                            .all(|(p, it)| self.bind(p, it))
                }
                Value::Record(r) => r.name == *name && pats.is_empty(),
                _ => false,
            },
            Pat::Record(name, fields) => match v {
                Value::Record(r) if r.name == *name => fields.iter().all(|(f, p)| {
                    r.field(f)
                        .cloned()
                        .is_some_and(|value| self.bind(p, &value))
                }),
                _ => false,
            },
            Pat::Or(alts) => alts.iter().any(|p| self.bind(p, v)),
        }
    }

    fn read_place(&mut self, place: &Place) -> R<Value> {
        Ok(match place {
            Place::Local(slot) => self.local(*slot),
            Place::Field(base, name) => {
                let base = self.read_place(base)?;
                self.field(&base, name)?
            }
            Place::TupleField(base, i) => ops::tuple_field(&self.read_place(base)?, *i)?,
            Place::Index(base, index) => {
                let base = self.read_place(base)?;
                let index = self.eval(index)?;
                ops::index(&base, &index)?
            }
        })
    }

    pub(crate) fn assign(&mut self, place: &Place, v: Value) -> R<()> {
        match place {
            Place::Local(slot) => {
                self.set_local(*slot, v);
                Ok(())
            }
            Place::Field(base, name) => {
                let old = self.read_place(base)?;
                let new = ops::with_field(&old, name, v)?;
                self.assign(base, new)
            }
            Place::TupleField(base, i) => {
                let old = self.read_place(base)?;
                let new = ops::with_index(&old, &Value::Int(i64::try_from(*i).unwrap_or(0)), v)?;
                self.assign(base, new)
            }
            Place::Index(base, index) => {
                let old = self.read_place(base)?;
                let index = self.eval(index)?;
                let new = ops::with_index(&old, &index, v)?;
                self.assign(base, new)
            }
        }
    }
}

/// A value's truth, where a `bool` is expected.
pub(crate) fn truth(v: &Value) -> R<bool> {
    match v {
        Value::Bool(b) => Ok(*b),
        other => Err(Flow::Fail(builtin::bad("a condition", other))),
    }
}

/// Whether an expression contains an `.await` (outside closures, which cannot await).
pub(crate) fn has_await(ex: &Ex) -> bool {
    crate::walk::ex(ex, &crate::walk::awaits)
}
