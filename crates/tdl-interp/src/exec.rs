//! Running statements: a block's statements in order, those that never await synchronously,
//! those that may (a waited spawn, `wait`, `retry`, an `.await`, a loop) as futures. Loops run
//! as futures so that they can yield: every [`Budget::yield_every`] iterations without an await
//! the body yields to the runtime, so monitors and timers beside it keep their deadlines, and past
//! [`Budget::max_steps`] iterations in all it fails its node with `StepBudgetExceeded`, naming the
//! loop's place. The TDL statements themselves are in `exec/tdl.rs`.

mod tdl;

pub(crate) use tdl::resource as resource_ref;

use std::sync::Arc;

use ::tdl::Failure;

use crate::builtin;
use crate::eval::{BoxFut, Flow, Frame, R, TdlVal, has_await, truth};
use crate::ir::{Block, Ex, LoopKind, LoopSt, St};
use crate::value::Value;

/// How long an interpreted body may compute without waiting.
#[derive(Clone, Copy, Debug)]
pub struct Budget {
    /// Loop iterations between two yields to the runtime, in a body that does not await.
    pub yield_every: u32,
    /// Loop iterations a body may take in all; past them, its node fails.
    pub max_steps: u64,
}

impl Default for Budget {
    fn default() -> Budget {
        Budget {
            yield_every: 1024,
            max_steps: 100_000_000,
        }
    }
}

/// The failure of a body past its budget.
fn over_budget(l: &LoopSt, steps: u64) -> Flow {
    Flow::Fail(Failure::new(
        "StepBudgetExceeded",
        format!(
            "the loop at {} ran {steps} iterations without ending: past the step budget",
            l.loc
        ),
    ))
}

/// Whether a statement may await: it runs as a future.
fn st_awaits(st: &St) -> bool {
    crate::walk::st(st, &crate::walk::awaits)
}

impl Frame {
    /// Runs a block that does not await; its value.
    pub(crate) fn block_sync(&mut self, b: &Block) -> R<Value> {
        for st in &b.stmts {
            self.st_sync(st)?;
        }
        match &b.tail {
            Some(e) => self.eval(e),
            None => Ok(Value::Unit),
        }
    }

    /// Runs a block: synchronously when none of its statements awaits, else as a future.
    pub(crate) async fn block(&mut self, b: &Block) -> R<Value> {
        let flags = b
            .awaits
            .get_or_init(|| b.stmts.iter().map(st_awaits).collect());
        if !flags.iter().any(|a| *a) && !b.tail.as_ref().is_some_and(has_await) {
            return self.block_sync(b);
        }
        self.block_async(b).await
    }

    /// Runs a block; its value.
    pub(crate) fn block_async<'f>(&'f mut self, b: &'f Block) -> BoxFut<'f, Value> {
        Box::pin(async move {
            let flags = b
                .awaits
                .get_or_init(|| b.stmts.iter().map(st_awaits).collect());
            for (st, awaits) in b.stmts.iter().zip(flags) {
                if *awaits {
                    self.st_async(st).await?;
                } else {
                    self.st_sync(st)?;
                }
            }
            match &b.tail {
                Some(e) => self.eval_async(e).await,
                None => Ok(Value::Unit),
            }
        })
    }

    /// A statement that does not await.
    pub(crate) fn st_sync(&mut self, st: &St) -> R<()> {
        match st {
            St::Let(pat, init, els) => {
                let Some(init) = init else { return Ok(()) };
                let v = self.eval(init)?;
                if !self.bind(pat, &v) {
                    match els {
                        Some(els) => {
                            self.block_sync(els)?;
                            return Err(Flow::Fail(Failure::new(
                                "Interpreter",
                                "the `else` of a `let … else` did not diverge",
                            )));
                        }
                        None => {
                            return Err(Flow::Fail(Failure::new(
                                "NoMatch",
                                format!("the pattern of a `let` does not take `{v:?}`"),
                            )));
                        }
                    }
                }
            }
            St::Expr(e) => {
                self.eval(e)?;
            }
            St::Loop(l) => self.loop_sync(l)?,
            other => self.tdl_sync(other)?,
        }
        Ok(())
    }

    /// A statement that may await.
    fn st_async<'f>(&'f mut self, st: &'f St) -> BoxFut<'f, ()> {
        Box::pin(async move {
            match st {
                St::Let(pat, Some(init), els) => {
                    let v = self.eval_async(init).await?;
                    if !self.bind(pat, &v) {
                        if let Some(els) = els {
                            self.block_async(els).await?;
                        }
                        return Err(Flow::Fail(Failure::new(
                            "NoMatch",
                            format!("the pattern of a `let` does not take `{v:?}`"),
                        )));
                    }
                }
                St::Expr(e) => {
                    self.eval_async(e).await?;
                }
                St::Loop(l) => self.loop_async(l).await?,
                other => self.tdl_async(other).await?,
            }
            Ok(())
        })
    }

    /// One iteration's bookkeeping: the count of a counted loop, the budget; whether to yield.
    fn iteration(&mut self, l: &LoopSt) -> R<bool> {
        self.steps += 1;
        if self.steps
            > self
                .shared
                .max_steps
                .load(std::sync::atomic::Ordering::Relaxed)
        {
            return Err(over_budget(l, self.steps));
        }
        self.since_yield += 1;
        let yield_now = self.since_yield
            >= self
                .shared
                .yield_every
                .load(std::sync::atomic::Ordering::Relaxed);
        if yield_now {
            self.since_yield = 0;
        }
        Ok(yield_now)
    }

    fn count(&mut self, l: &LoopSt) {
        if let Some((count, iter)) = l.counter {
            let n = match self.tdl.get(count as usize) {
                Some(TdlVal::Count(n)) => *n,
                _ => 0,
            };
            self.set_tdl(iter, TdlVal::Count(n));
            self.set_tdl(count, TdlVal::Count(n + 1));
        }
    }

    pub(crate) fn set_tdl(&mut self, slot: u32, v: TdlVal) {
        if let Some(it) = self.tdl.get_mut(slot as usize) {
            *it = v;
        }
    }

    /// Whether a loop's body ended with `break` (of this loop) or goes on.
    fn after_body(l: &LoopSt, r: R<Value>) -> R<bool> {
        match r {
            Ok(_) => Ok(true),
            Err(Flow::Break(label)) if label.is_none() || label == l.label => Ok(false),
            Err(Flow::Continue(label)) if label.is_none() || label == l.label => Ok(true),
            Err(other) => Err(other),
        }
    }

    /// A loop, as a future that yields.
    pub(crate) fn loop_async<'f>(&'f mut self, l: &'f LoopSt) -> BoxFut<'f, ()> {
        Box::pin(async move {
            if let Some((count, _)) = l.counter {
                self.set_tdl(count, TdlVal::Count(0));
            }
            match &l.kind {
                LoopKind::For(pat, iter) => {
                    let items = self.iterate(iter).await?;
                    for i in 0..items.len() {
                        let it = items.get(i);
                        if self.iteration(l)? {
                            tokio::task::yield_now().await;
                        }
                        self.count(l);
                        if !self.bind(pat, &it) {
                            return Err(Flow::Fail(Failure::new(
                                "NoMatch",
                                format!("the pattern of a `for` does not take `{it:?}`"),
                            )));
                        }
                        let r = self.block(&l.body).await;
                        if !Self::after_body(l, r)? {
                            break;
                        }
                    }
                }
                LoopKind::While(cond) => loop {
                    if self.iteration(l)? {
                        tokio::task::yield_now().await;
                    }
                    if !truth(&self.eval_async(cond).await?)? {
                        break;
                    }
                    self.count(l);
                    let r = self.block(&l.body).await;
                    if !Self::after_body(l, r)? {
                        break;
                    }
                },
                LoopKind::Loop => loop {
                    if self.iteration(l)? {
                        tokio::task::yield_now().await;
                    }
                    self.count(l);
                    let r = self.block(&l.body).await;
                    if !Self::after_body(l, r)? {
                        break;
                    }
                },
            }
            Ok(())
        })
    }

    /// A loop run synchronously (inside an expression evaluated without awaiting): bounded by
    /// the budget, but it cannot yield.
    pub(crate) fn loop_sync(&mut self, l: &LoopSt) -> R<()> {
        if let Some((count, _)) = l.counter {
            self.set_tdl(count, TdlVal::Count(0));
        }
        match &l.kind {
            LoopKind::For(pat, iter) => {
                let v = self.eval(iter)?;
                let items = items_of(&v)?;
                for it in items.iter() {
                    self.iteration(l)?;
                    self.count(l);
                    self.bind(pat, it);
                    let r = self.block_sync(&l.body);
                    if !Self::after_body(l, r)? {
                        break;
                    }
                }
            }
            LoopKind::While(cond) => loop {
                self.iteration(l)?;
                if !truth(&self.eval(cond)?)? {
                    break;
                }
                self.count(l);
                let r = self.block_sync(&l.body);
                if !Self::after_body(l, r)? {
                    break;
                }
            },
            LoopKind::Loop => loop {
                self.iteration(l)?;
                self.count(l);
                let r = self.block_sync(&l.body);
                if !Self::after_body(l, r)? {
                    break;
                }
            },
        }
        Ok(())
    }

    /// What a `for` goes over: a range's integers (without making a list of them for a range
    /// written in the loop), a list's items, an option's.
    async fn iterate(&mut self, iter: &Ex) -> R<Items> {
        if let Ex::Range(Some(lo), Some(hi), closed) = iter {
            let lo = self.eval_async(lo).await?;
            let hi = self.eval_async(hi).await?;
            let (Value::Int(lo), Value::Int(hi)) = (&lo, &hi) else {
                return Err(Flow::Fail(builtin::bad("a range's bound", &lo)));
            };
            let hi = if *closed { hi.saturating_add(1) } else { *hi };
            return Ok(Items::Range(*lo, hi.max(*lo)));
        }
        let v = self.eval_async(iter).await?;
        Ok(Items::List(items_of(&v)?))
    }
}

/// What a `for` goes over.
enum Items {
    /// The integers `lo..hi`.
    Range(i64, i64),
    List(Arc<Vec<Value>>),
}

impl Items {
    fn len(&self) -> usize {
        match self {
            Items::Range(lo, hi) => usize::try_from(hi - lo).unwrap_or(0),
            Items::List(items) => items.len(),
        }
    }

    fn get(&self, i: usize) -> Value {
        match self {
            Items::Range(lo, _) => Value::Int(lo + i64::try_from(i).unwrap_or(0)),
            Items::List(items) => items.get(i).cloned().unwrap_or_default(),
        }
    }
}

fn items_of(v: &Value) -> R<Arc<Vec<Value>>> {
    builtin::items(v).ok_or_else(|| Flow::Fail(builtin::bad("a `for` loop", v)))
}
