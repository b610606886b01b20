//! Running actions inline: an action that ends without awaiting costs no tokio task, and nothing
//! of the run observes the difference: the trace is the one tasks give, record for record.
//!
//! # Ground rules
//!
//! 1. **Who pumps.** Only the end of a job's own task pumps, on the thread of a current-thread
//!    runtime (`pumps`). Everywhere else (an action's body spawning, the program's session, an
//!    event handle, the driver loop, a blocking action's thread, any multi-thread runtime, where
//!    each action is a task so that actions run in parallel) actions start as tokio tasks.
//! 2. **Only when a task would run next.** A started action goes to the pump only when nothing of
//!    the run is queued (`nothing_queued`): the run's tasks, the driver loop and the waits on the
//!    engine are wrapped in [`Tracked`], which counts those woken and not yet polled, and a task
//!    aborted and not yet dropped counts too (`Cancels::aborted`). Otherwise it is spawned, behind
//!    what is queued. A future that `block_on` polls (a test's body, the driver of
//!    `Runtime::run`) is not counted: tokio polls it between tasks.
//! 3. **The lock.** The engine's lock (`Shared::enter`) is never held while a future is polled or
//!    a synchronous action runs. A batch of launches is taken under it
//!    (`Inner::settle_and_take_launches`) and run outside it; each end is reported under it.
//! 4. **A batch, in start order.** Each launch is polled once (an async action's future) or called
//!    (a synchronous action, `Task::command_now`). One that is done has its end reported under the
//!    lock before the next launch of the batch runs (`report_now`), and what that end starts is
//!    handed to the host then, the code in an action's closure included; the last end of a batch
//!    is reported by the pump's next access to the engine, before anything else runs.
//! 5. **Pending futures are parked.** A future left pending has no task until its first wake-up
//!    ([`Parked`]); then it is spawned, queued where its task, idle until then, would be queued by
//!    that wake-up. Parked futures are recorded under the lock with the next end reported, or
//!    every `REPORT_EVERY`.
//! 6. **Wake-ups keep the tasks' order.** A wake-up of one of the run's tasks (or parked futures)
//!    by a launch of the batch is held back (`hold_wake`) until the ends before that launch are
//!    reported and what they release has started; what the engine wakes under its lock is not
//!    held back. Each end hands what it starts to the host before the next end is reported, or
//!    the future that took the lock is served (`flush`); so do the stops reported first by
//!    whoever takes the lock (`host::stops_first`).
//! 7. **Cancellation keeps its meaning.** A job cancelled before its turn stays in its batch and
//!    is dropped unpolled in its turn, as tokio drops an aborted task when it reaches it; its stop
//!    is reported by whatever reports next, or handed over as a dropped task's
//!    (`Inner::hand_over_stops`) when nothing of its batch follows. One cancelled after a poll that
//!    left it pending is spawned and cancelled as any running task (signalled with its grace
//!    period, or aborted); one that returned is reported as returned, and the engine terminates
//!    its node. A panic fails its node.
//! 8. **One clock reading per batch.** A report reads the clock only if it needs the time
//!    (`Engine::at_clock`); when the engine wants it at once (`Engine::wants_time`), the ends of one
//!    batch share a reading, taken afresh every `REPORT_EVERY` ends (`PumpState::clock`): on virtual
//!    time the clock does not move while a batch runs.
//! 9. **Never recursive.** What the reported ends start is pumped in turn, in a loop. While the
//!    pump runs, the driver is not woken merely to hand trace records to the sinks (it is woken
//!    once at the end).
//!
//! # What holds them
//!
//! Random programs (ending, synchronously or not, sleeping, yielding, failing, retrying, spawning,
//! waking one another through channels and engine watches, terminating one another, polling,
//! sharing a resource, running code in their closures that others' futures look at) give the same
//! trace as tasks, record for record, the same pumped trace on every run, and with each
//! synchronous action the trace of its async twin (`tests/random.rs`; the programs the proptest
//! once found are kept in `programs_once_found_giving_another_order_give_the_same_trace`); the
//! other tests of the pump are in `tests.rs`. The limits:
//! - tokio delivers a deferred wake-up (`tokio::task::yield_now`) when its queue is empty, or after
//!   61 tasks (its event interval): the pump's inline actions are no tasks to count, so past 61
//!   actions in one go a future that yielded resumes later than with tasks. A runtime built with a
//!   larger event interval, as the tests here are, gives the same trace;
//! - a task of the program's own, woken at the same instant by something outside the run, is not
//!   counted.

mod parked;
mod tracked;

pub(crate) use parked::Parked;
use parked::Spare;
pub(crate) use tracked::{MaybeTracked, Tracked};

use crate::ctx::Ctx;
use crate::host::{CatchUnwind, Ended, Inner, Shared};
use crate::task::{ActionFuture, Launch, RunNow};
use std::cell::RefCell;
use std::future::Future;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::task::{Context, Poll, Waker};
use tcm_core::{Job, NodeId};

/// The pump of one thread, for one run.
pub(crate) struct PumpState {
    shared: Arc<Shared>,
    // Ends polled but not reported yet, in the order the jobs started.
    done: Vec<Ended>,
    // Wake-ups of the run's tasks (and parked futures) by a future the pump polled, held back
    // until the ends polled before it are reported: after how many of `done`, and the waker.
    wakes: Vec<(usize, Waker)>,
    // Futures left pending by their first poll, to spawn as tasks under the lock (wiretap checks,
    // which are not cancellable).
    pending: Vec<(Job, ActionFuture)>,
    // Futures left pending by their first poll and parked, to record under the lock.
    parked: Vec<(Job, Arc<Parked>)>,
    // Futures to drop outside the lock (their drop may run code that takes it).
    to_drop: Vec<ActionFuture>,
    // The driver has trace records to take: woken when the pump ends.
    wake_driver: bool,
    // While a batch is polled: the clock reading its ends are reported at, and how many more
    // ends may use it.
    clock: Option<(tcm_core::Time, u32)>,
}

impl PumpState {
    /// The time the ends of the batch being polled are reported at: one reading for up to
    /// `REPORT_EVERY` of them; a fresh one outside a batch.
    fn now(&mut self) -> tcm_core::Time {
        match &mut self.clock {
            Some((t, left)) if *left > 0 => {
                *left -= 1;
                *t
            }
            Some(c) => {
                let t = self.shared.now();
                *c = (t, REPORT_EVERY as u32 - 1);
                t
            }
            None => self.shared.now(),
        }
    }
}

thread_local! {
    static PUMP: RefCell<Option<PumpState>> = const { RefCell::new(None) };
    // Whether the pump of this thread is polling a future: a wake-up of the run's tasks is held
    // back (`hold_wake`).
    static POLLING: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// While the pump of this thread polls a future, holds back a wake-up of one of the run's tasks
/// (or parked futures) until the ends polled before that future are reported, and what they
/// release has started: a task would have been woken only after them (the future's own task runs
/// after theirs). Returns whether it did; the caller wakes at once otherwise.
pub(crate) fn hold_wake(waker: impl FnOnce() -> Waker) -> bool {
    if !POLLING.with(std::cell::Cell::get) {
        return false;
    }
    PUMP.with(|p| {
        let Ok(mut p) = p.try_borrow_mut() else {
            return false;
        };
        match p.as_mut() {
            Some(st) => {
                // After the ends kept, but before the stops of jobs dropped unpolled since the
                // last of them: a stop is reported by the next end (`Reporter`), after what the
                // future polled meanwhile woke.
                let dropped = st
                    .done
                    .iter()
                    .rev()
                    .take_while(|e| matches!(e, Ended::Dropped(_)))
                    .count();
                let at = st.done.len() - dropped;
                st.wakes.push((at, waker()));
                true
            }
            None => false,
        }
    })
}

/// Sets whether this thread's pump is polling a future (around each poll; cleared while the
/// engine's lock is held), returning what it was.
#[inline(always)]
pub(crate) fn polling(on: bool) -> bool {
    POLLING.with(|c| c.replace(on))
}

/// Whether nothing of the run is queued (a task spawned now would run next): then an action that
/// starts now is left to the pump of this thread, if it pumps for the run ([`pumps`]).
pub(crate) fn nothing_queued(shared: &Shared) -> bool {
    shared.queued.load(Ordering::SeqCst) == 0
}

/// Whether the pump of this thread runs for `shared`.
pub(crate) fn pumps(shared: &Shared) -> bool {
    PUMP.with(|p| {
        p.try_borrow()
            .is_ok_and(|p| p.as_ref().is_some_and(|st| same(&st.shared, shared)))
    })
}

/// While the pump of this thread runs for `shared`, the driver is woken for its trace records
/// when the pump ends, not now; returns whether it took the wake-up.
pub(crate) fn defer_wake(shared: &Shared) -> bool {
    PUMP.with(|p| {
        let Ok(mut p) = p.try_borrow_mut() else {
            return false;
        };
        match p.as_mut().filter(|st| same(&st.shared, shared)) {
            Some(st) => {
                st.wake_driver = true;
                true
            }
            None => false,
        }
    })
}

fn same(a: &Arc<Shared>, b: &Shared) -> bool {
    std::ptr::eq(Arc::as_ptr(a), b)
}

/// Under the lock of `shared` (taken by `host::lock`): reports the ends the pump of this thread
/// keeps, and spawns the futures it left pending, if it runs for this run.
pub(crate) fn flush(inner: &mut Inner, shared: &Arc<Shared>) {
    PUMP.with(|cell| {
        let Ok(mut p) = cell.try_borrow_mut() else {
            return;
        };
        let Some(st) = p.as_mut().filter(|st| same(&st.shared, shared)) else {
            return;
        };
        if !st.pending.is_empty() {
            for (job, fut) in st.pending.drain(..) {
                if let Some(fut) = inner.spawn_job(&st.shared, job, fut) {
                    st.to_drop.push(fut);
                }
            }
        }
        if !st.parked.is_empty() {
            for (job, parked) in st.parked.drain(..) {
                if let Some(fut) = inner.park_job(&st.shared, job, parked) {
                    st.to_drop.push(fut);
                }
            }
        }
        if !st.wakes.is_empty() {
            // Rare: reported end by end, each wake-up after the ends before it and what they
            // started, which needs the pump's state let go of (the host looks at it).
            let done = std::mem::take(&mut st.done);
            let wakes = std::mem::take(&mut st.wakes);
            let shared = st.shared.clone();
            drop(p);
            let (done, wakes) = report_with_wakes(inner, &shared, done, wakes);
            // The buffers go back, for the next batch.
            if let Ok(mut p) = cell.try_borrow_mut() {
                if let Some(st) = p.as_mut() {
                    if st.done.is_empty() {
                        st.done = done;
                    }
                    if st.wakes.is_empty() {
                        st.wakes = wakes;
                    }
                }
            }
            return;
        }
        if !st.done.is_empty() {
            // Each end's effects are handed to the host before the next end is reported, and
            // before whatever took the lock looks at the engine, as a task's end would be: an
            // action an end starts is running when a later end, or the future that took the
            // lock, cancels it. The host is told that this thread pumps for the run, so that it
            // does not look at the pump's state, borrowed here.
            // One clock reading for the batch if the reports need the time; else each report
            // reads it only if it turns out to need it.
            let now = inner.shares_readings().then(|| st.now());
            for ended in st.done.drain(..) {
                inner.ended_job(now, ended);
                inner.start_effects_pumping(shared, Some(true));
            }
        }
    });
}

/// Reports `done` in order, delivering each held wake-up once the ends before it are reported and
/// their effects carried out; gives the buffers back, empty.
fn report_with_wakes(
    inner: &mut Inner,
    shared: &Arc<Shared>,
    mut done: Vec<Ended>,
    mut wakes: Vec<(usize, Waker)>,
) -> (Vec<Ended>, Vec<(usize, Waker)>) {
    let was = polling(false);
    let now = inner.shares_readings().then(|| shared.now());
    let mut next = wakes.drain(..).peekable();
    for (i, ended) in done.drain(..).enumerate() {
        if next.peek().is_some_and(|(at, _)| *at <= i) {
            crate::host::carry_out(inner, shared);
            while let Some((_, w)) = next.next_if(|(at, _)| *at <= i) {
                w.wake();
            }
        }
        inner.ended_job(now, ended);
        // What it starts goes to the host before the next end is reported, as in `flush`.
        inner.start_effects(shared);
    }
    if next.peek().is_some() {
        crate::host::carry_out(inner, shared);
        for (_, w) in next.by_ref() {
            w.wake();
        }
    }
    drop(next);
    polling(was);
    (done, wakes)
}

/// The largest batch buffer the pump keeps from one batch to the next.
const KEEP_BATCH: usize = 64;

/// How many futures left pending the pump keeps at most before it records them under the lock,
/// and how many ends of a batch share one clock reading.
const REPORT_EVERY: usize = 64;

/// The pump of this thread, while it runs for one run; the previous one (of another run, if any)
/// comes back when it ends.
pub(crate) struct Guard {
    saved: Option<PumpState>,
    // False when this thread already pumps for this run: the outer pump does the work.
    owner: bool,
}

impl Guard {
    pub(crate) fn enter(shared: &Arc<Shared>) -> Guard {
        PUMP.with(|p| {
            let Ok(mut p) = p.try_borrow_mut() else {
                return Guard {
                    saved: None,
                    owner: false,
                };
            };
            if p.as_ref().is_some_and(|st| same(&st.shared, shared)) {
                return Guard {
                    saved: None,
                    owner: false,
                };
            }
            let saved = p.replace(PumpState {
                shared: shared.clone(),
                done: Vec::new(),
                wakes: Vec::new(),
                pending: Vec::new(),
                parked: Vec::new(),
                to_drop: Vec::new(),
                wake_driver: false,
                clock: None,
            });
            Guard { saved, owner: true }
        })
    }

    /// Polls what the reported ends started, and what those start in turn, until nothing is left.
    pub(crate) fn pump(&self) {
        if !self.owner {
            return;
        }
        let Some(shared) = PUMP.with(|p| {
            p.try_borrow()
                .ok()
                .and_then(|p| p.as_ref().map(|st| st.shared.clone()))
        }) else {
            return;
        };
        // Where a parked future's task is spawned when it is woken.
        // The slot of every first poll (see `Parked`).
        let mut spare = Spare::take();
        // One buffer for every batch (swapped with the host's, `Inner::take_launches`).
        let mut batch = Vec::new();
        // Those to drop unpolled when the run ended (rare), likewise.
        let mut dropped = Vec::new();
        // The nodes of the batch's jobs cancelled before their poll (rare), dropped unpolled in
        // their turn.
        let mut skip: Vec<NodeId> = Vec::new();
        // Whether the pump dropped a job unpolled since the last batch (rare).
        let mut unpolled = false;
        loop {
            // Jobs dropped unpolled after the last poll (rare): they are tasks aborted last in
            // the queue, whose stops whoever runs next reports.
            let mut trailing = if std::mem::take(&mut unpolled) {
                take_trailing_drops()
            } else {
                Vec::new()
            };
            match shared.enter() {
                Ok(mut inner) => {
                    inner.settle_and_take_launches(&mut batch, &mut dropped, &mut skip);
                    if !trailing.is_empty() {
                        if batch.is_empty() && dropped.is_empty() {
                            // Nothing runs after them here: the scheduler's next task, or the
                            // driver, reports them, as it would their tasks' drops.
                            inner.hand_over_stops(&shared, trailing.drain(..));
                        } else {
                            // What this batch polls runs after them: reported first, by the
                            // first of its ends reported or access to the engine. If none comes,
                            // they are still last at the next look, and handed over then.
                            let _ =
                                push(|st| st.done.extend(trailing.drain(..).map(Ended::Dropped)));
                            unpolled = true;
                        }
                    }
                }
                Err(_) => return,
            }
            // Cancelled before their poll: dropped unpolled, outside the lock, and reported stopped.
            if !dropped.is_empty() {
                drop_unpolled(&mut dropped);
                unpolled = true;
            }
            if batch.is_empty() {
                if self.idle() {
                    return;
                }
                continue;
            }
            // In start order: reversed, then popped (cheaper than a drain for a batch of one).
            batch.reverse();
            // The ends this batch reports share a reading, taken at the first (`PumpState::now`).
            let _ = push(|st| st.clock = Some((tcm_core::Time::ZERO, 0)));
            let mut stale = false;
            let mut cancels = shared.inline_cancels.load(Ordering::Relaxed);
            while let Some((job, launch)) = batch.pop() {
                // A job of this batch cancelled before its turn (rare) is dropped unpolled in its
                // turn, as its task would be, aborted before it ran.
                if shared.inline_cancels.load(Ordering::Relaxed) != cancels {
                    batch.push((job, launch));
                    match shared.enter() {
                        Ok(mut inner) => inner.cancelled_in(&batch, &mut skip),
                        Err(_) => return,
                    }
                    cancels = shared.inline_cancels.load(Ordering::Relaxed);
                    continue;
                }
                if !skip.is_empty() {
                    if let Some(i) = skip.iter().position(|n| *n == job.node()) {
                        skip.swap_remove(i);
                        drop(launch);
                        let _ = push(|st| st.done.push(Ended::Dropped(job)));
                        unpolled = true;
                        continue;
                    }
                }
                // A synchronous action runs where its future would be polled: no future, no
                // waker, and it is always done.
                let first = match launch {
                    Launch::Future(mut fut) => {
                        let slot = spare.slot();
                        polling(true);
                        let first = poll_once(&mut fut, &slot.1);
                        polling(false);
                        spare.settle_after(&first);
                        match first {
                            Poll::Ready(res) => Ok(res),
                            Poll::Pending => Err(fut),
                        }
                    }
                    Launch::Now(f, args) => {
                        polling(true);
                        let res = run_now(f, Ctx::of_job(shared.clone(), job, args));
                        polling(false);
                        Ok(res)
                    }
                };
                let (kept, to_drop) = match first {
                    Ok(res) if !batch.is_empty() => {
                        // Reported before the next job of the batch runs, as its task's end
                        // would be: what it starts (the code in an action's closure included)
                        // runs before that job.
                        match report_now(&shared, job, res) {
                            Ok(true) => self.drop_stale(),
                            Ok(false) => {}
                            Err(_) => return,
                        }
                        continue;
                    }
                    Ok(res) => {
                        // The last of its batch: reported by the next access, which comes before
                        // anything else runs.
                        push(|st| st.done.push(Ended::Returned(job, res)))
                    }
                    Err(fut) => match spare.park(&shared, job, fut) {
                        Ok(p) => push(|st| st.parked.push((job, p))),
                        Err(fut) => push(|st| st.pending.push((job, fut))),
                    },
                };
                // Futures left pending (and the last end) are recorded every `REPORT_EVERY`, as
                // if one of the batch's futures touched the engine, so that what the pump keeps
                // stays small however wide the batch.
                stale |= to_drop;
                if kept >= REPORT_EVERY {
                    match shared.enter() {
                        Ok(inner) => drop(inner),
                        Err(_) => return,
                    }
                    self.drop_stale();
                    stale = false;
                }
            }
            // Past the batch, a report reads the clock.
            let _ = push(|st| st.clock = None);
            // Kept only while small (a chain releases one action at a time): a wide release's
            // buffer goes back to the allocator, which then serves the next allocations from it.
            if batch.capacity() > KEEP_BATCH {
                batch = Vec::new();
            }
            if stale {
                self.drop_stale();
            }
        }
    }

    /// Whether the pump has nothing left to report or spawn (dropping what it was asked to drop).
    fn idle(&self) -> bool {
        self.drop_stale();
        PUMP.with(|p| {
            p.try_borrow().is_ok_and(|p| {
                p.as_ref().is_none_or(|st| {
                    st.done.is_empty() && st.pending.is_empty() && st.parked.is_empty()
                })
            })
        })
    }

    /// Drops, outside the lock, the futures a flush set aside.
    fn drop_stale(&self) {
        let stale = PUMP.with(|p| {
            p.try_borrow_mut()
                .ok()
                .and_then(|mut p| p.as_mut().map(|st| std::mem::take(&mut st.to_drop)))
        });
        drop(stale);
    }
}

/// Reports the end of a job of the batch being polled, and hands what it starts to the host:
/// under the lock, directly when the pump keeps nothing else (the usual case), else after what it
/// keeps (`flush`). Returns whether the pump's state was flushed (futures may have been set aside
/// to drop).
fn report_now(shared: &Arc<Shared>, job: Job, res: ActionResult) -> Result<bool, crate::Error> {
    let mut ended = Some(Ended::Returned(job, res));
    PUMP.with(|p| {
        let mut p = p.try_borrow_mut().ok()?;
        let st = p.as_mut()?;
        if !(st.done.is_empty()
            && st.pending.is_empty()
            && st.parked.is_empty()
            && st.wakes.is_empty())
        {
            st.done.extend(ended.take());
        }
        Some(())
    });
    let (mut inner, flushed) = match ended {
        Some(ended) => {
            let mut inner = crate::host::lock_as_is(shared)?;
            // The batch's clock reading if the report needs the time; else the report reads the
            // clock only if it turns out to need it.
            let now = inner.shares_readings().then(|| {
                PUMP.with(|p| {
                    let mut p = p.try_borrow_mut().ok()?;
                    Some(p.as_mut()?.now())
                })
                .unwrap_or_else(|| shared.now())
            });
            inner.ended_job(now, ended);
            inner.start_effects_pumping(shared, Some(true));
            (inner, false)
        }
        None => (crate::host::lock(shared)?, true),
    };
    if shared.stops.load(Ordering::Relaxed) > 0 {
        crate::host::stops_first(&mut inner, shared);
    }
    Ok(flushed)
}

/// Takes the jobs dropped unpolled at the end of the ends the pump keeps (none, almost always).
fn take_trailing_drops() -> Vec<Job> {
    PUMP.with(|p| {
        let Ok(mut p) = p.try_borrow_mut() else {
            return Vec::new();
        };
        let Some(st) = p.as_mut() else {
            return Vec::new();
        };
        if !matches!(st.done.last(), Some(Ended::Dropped(_))) {
            return Vec::new();
        }
        let from = st
            .done
            .iter()
            .rposition(|e| !matches!(e, Ended::Dropped(_)))
            .map_or(0, |i| i + 1);
        st.done
            .drain(from..)
            .filter_map(|e| match e {
                Ended::Dropped(job) => Some(job),
                Ended::Returned(..) => None,
            })
            .collect()
    })
}

/// Drops, outside the lock, futures cancelled before their poll, and keeps their stops to report.
fn drop_unpolled(dropped: &mut Vec<(Job, Launch)>) {
    for (job, launch) in dropped.drain(..) {
        drop(launch);
        let _ = push(|st| st.done.push(Ended::Dropped(job)));
    }
}

/// Polls a job's future once, as a task would: with no budget taken from the task that ended.
#[inline(always)]
fn poll_once(fut: &mut ActionFuture, waker: &Waker) -> Poll<ActionResult> {
    let mut cx = Context::from_waker(waker);
    let once = tokio::task::unconstrained(CatchUnwind(fut.as_mut()));
    std::pin::pin!(once).poll(&mut cx)
}

/// Runs a synchronous action where its future would be polled once: its result, or its panic.
#[inline(always)]
fn run_now(f: Box<dyn RunNow>, ctx: Ctx) -> ActionResult {
    // While a replay runs, its inputs wait for the end of this run (`replay.rs`, rule 3).
    let _run = crate::replay::ActionPoll::begin();
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| f.run(ctx)))
}

/// What a job's future returns, or its panic.
type ActionResult =
    Result<Result<crate::task::Value, tcm_core::Failure>, Box<dyn std::any::Any + Send>>;

/// Hands `f` the pump of this thread; returns how many ends and pending futures it then keeps,
/// and whether a flush left it futures to drop (`Guard::drop_stale`).
fn push(f: impl FnOnce(&mut PumpState)) -> (usize, bool) {
    PUMP.with(|p| {
        let Ok(mut p) = p.try_borrow_mut() else {
            return (0, false);
        };
        p.as_mut().map_or((0, false), |st| {
            f(st);
            (
                st.done.len() + st.pending.len() + st.parked.len(),
                !st.to_drop.is_empty(),
            )
        })
    })
}

impl Drop for Guard {
    fn drop(&mut self) {
        if !self.owner {
            return;
        }
        let left = PUMP.with(|p| match p.try_borrow_mut() {
            Ok(mut p) => std::mem::replace(&mut *p, self.saved.take()),
            Err(_) => None,
        });
        if let Some(st) = left.as_ref().filter(|st| st.wake_driver) {
            st.shared.wake.notify_one();
        }
        // Normally empty: the pump reported everything before it stopped. A pump cut short (the
        // lock poisoned) drops what it held here, outside the lock.
        drop(left);
    }
}

#[cfg(test)]
mod tests;
