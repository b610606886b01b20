//! The engine's lock held ([`Locked`]), and the timer callbacks that come due under it: when the
//! lock is let go, they run at once on that thread, outside the lock, before anything else of the
//! run does. TCM ran a callback on an event when the event was signalled, before the next action;
//! so does this: the end that released the next action made the callback due, and the callback
//! runs before that action's first poll (on a current-thread runtime; on a multi-thread one,
//! actions on other workers go on meanwhile). A callback on an event already past runs inside the
//! action that set it, before `Ctx::invoke_when` returns. The driver's turn takes the callbacks
//! that its timers made due and runs them itself (`runtime/run_loop.rs`).

use super::{DueCallback, Inner, Shared, carry_out, panic_message, panicked};
use crate::Error;
use crate::ctx::Ctx;
use std::sync::{Arc, MutexGuard};

/// The engine's lock, held. Given by [`lock`] and inside [`super::Access`].
pub(crate) struct Locked<'a> {
    // `None` only while its drop runs the callbacks that came due, the lock let go.
    guard: Option<MutexGuard<'a, Inner>>,
    shared: &'a Arc<Shared>,
}

/// The engine's lock. On a thread whose pump runs for this run, the ends it keeps are reported
/// first (`pump.rs`): whatever looks at the engine sees them.
#[inline]
pub(crate) fn lock(shared: &Arc<Shared>) -> Result<Locked<'_>, Error> {
    let mut inner = shared.inner.lock().map_err(|_| Error::Poisoned)?;
    crate::pump::flush(&mut inner, shared);
    Ok(Locked {
        guard: Some(inner),
        shared,
    })
}

/// The engine's lock as it is: for the one caller that must not report the pump's ends first
/// (`pump::report_now`, which reports one of them itself).
#[inline]
pub(crate) fn lock_as_is(shared: &Arc<Shared>) -> Result<Locked<'_>, Error> {
    let inner = shared.inner.lock().map_err(|_| Error::Poisoned)?;
    Ok(Locked {
        guard: Some(inner),
        shared,
    })
}

impl std::ops::Deref for Locked<'_> {
    type Target = Inner;
    #[inline(always)]
    fn deref(&self) -> &Inner {
        match &self.guard {
            Some(g) => g,
            None => unreachable!("the lock is let go only in its drop"),
        }
    }
}

impl std::ops::DerefMut for Locked<'_> {
    #[inline(always)]
    fn deref_mut(&mut self) -> &mut Inner {
        match &mut self.guard {
            Some(g) => g,
            None => unreachable!("the lock is let go only in its drop"),
        }
    }
}

impl Drop for Locked<'_> {
    #[inline(always)]
    fn drop(&mut self) {
        if self.guard.as_ref().is_some_and(|g| !g.due.is_empty()) {
            self.run_due();
        }
    }
}

impl Locked<'_> {
    /// Lets the lock go and runs the callbacks that came due under it (rare: off the path of
    /// every other access).
    #[cold]
    #[inline(never)]
    fn run_due(&mut self) {
        let Some(g) = self.guard.as_mut() else {
            return;
        };
        if g.ended || std::thread::panicking() {
            g.due.clear();
            return;
        }
        let due = take_due(g, self.shared);
        drop(self.guard.take());
        for d in due {
            run_callback(self.shared, d);
        }
    }
}

/// Takes the callbacks that came due, traced as run (`callback_ran`), their records handed on.
#[cold]
#[inline(never)]
fn take_due(inner: &mut Inner, shared: &Arc<Shared>) -> Vec<DueCallback> {
    let due = std::mem::take(&mut inner.due);
    for d in &due {
        inner.engine.callback_ran(d.token, &d.name);
    }
    carry_out(inner, shared);
    due
}

/// Runs a timer callback outside the lock (it may call the engine), with a context of the node
/// that set it. A panic is recorded, like an action's, and the run goes on.
pub(crate) fn run_callback(shared: &Arc<Shared>, due: DueCallback) {
    let DueCallback {
        name,
        node,
        f,
        outcome,
        ..
    } = due;
    let ctx = Ctx {
        shared: shared.clone(),
        node,
        purpose: None,
        job: None,
        args: lock(shared).ok().and_then(|i| i.args.get(&node).cloned()),
        signal: Default::default(),
    };
    let res = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| f(ctx, outcome)));
    if let Err(panic) = res {
        if let Ok(mut inner) = lock(shared) {
            let by = (node != inner.engine.root()).then_some(node);
            let message = panic_message(panic.as_ref());
            let record = panicked(&inner.engine, by, name.to_string(), true, message);
            inner.panics.push(record);
        }
    }
}
