//! Running actions inline: an action that ends without awaiting costs no tokio task, and nothing
//! of the run observes the difference.
//!
//! When a job's task ends, its end is reported under the engine's lock and the nodes it releases
//! start (`host.rs`). On a current-thread runtime (virtual time, tests, `tcm-bench`) the host may
//! then hand their futures to the *pump* of the thread, which polls each once, outside the lock,
//! right after the end that released it. A future that is done then never becomes a task: its end
//! is reported at once, under the lock, before the next future of its batch is polled, as its
//! task's end would be (`report_now`; the last of a batch by the pump's next access to the engine,
//! before anything else runs), and what it starts is handed to the host then, the code in an
//! action's closure included. A future that is not done is *parked* ([`Parked`]): it has no task
//! until it is first woken, and is spawned as a task then, queued where its task, idle until then,
//! would be queued by that wake-up; parked futures are recorded under the lock with the next end
//! reported, or every `REPORT_EVERY`. What the reported ends start is pumped in turn, in a loop,
//! never recursively. Reading the clock is a large part of a report, so a report reads it only if
//! it needs the time (`Engine::at_clock`: a traced run, a pending timer, a timer or monitor it
//! starts). When the engine wants the time at once (`Engine::wants_time`), the ends reported while
//! one batch is polled share a clock reading, taken afresh every `REPORT_EVERY` ends
//! (`PumpState::now`): on virtual time the clock does not move while a batch is polled.
//!
//! **The same order as tasks.** A task spawned on a current-thread runtime runs after every task
//! already queued. So a released action is pumped only when nothing of the run is queued: the
//! run's tasks, the driver loop and the waits on the engine are wrapped in [`Tracked`], which counts
//! those woken and not yet polled by a task, and a task aborted and not yet dropped counts too
//! (`Cancels::aborted`). Then the task would have run next anyway, and the trace is the one tasks
//! give, record for record (`tests` below compares them). Otherwise the action is spawned as a
//! task, behind what is queued. A future that `block_on` polls (the driver of `Runtime::run` in a
//! test, a test's own body) is not counted: tokio polls it between tasks, and it changes nothing
//! of the engine's order (the stops of dropped tasks are reported by whoever takes the lock next,
//! `Shared::enter`, not only by the driver). While the pump runs, the driver is not woken merely
//! to hand trace records to the sinks (it is woken once at the end), since that changes nothing
//! of the engine. A wake-up of one of the run's tasks (or parked futures) by a future of the batch
//! is held back (`hold_wake`) and delivered once the ends polled before that future are reported
//! and what they release has started, as tasks would order them (`a_wake_within_a_batch_gives_the_same_trace_with_and_without_the_pump`);
//! what the engine wakes under its lock is not held back. Each end reported hands what it starts
//! to the host before the next end is reported, or the future that took the lock is served
//! (`flush`), as a task's end does; so do the stops reported first by whoever takes the lock
//! (`host::stops_first`).
//!
//! Cancellation keeps its meaning. A job cancelled before its poll stays in its batch and is
//! dropped unpolled in its turn (a job polled before it may cancel it), as tokio drops an aborted
//! task when it reaches it in its queue; its stop is reported by whatever reports next, and when
//! nothing of its batch comes after it and nothing is started, or the next batch reports nothing
//! (its futures all left pending), by whoever runs next (the stop is handed over as a dropped
//! task's, `Inner::hand_over_stops`), not by the pump. A wake-up held
//! back goes before such stops (a stop is reported by the next end, after what the future polled
//! meanwhile woke). One cancelled after a poll that left it pending is spawned and then cancelled
//! as any running task (signalled with its grace period, or aborted); one that returned is
//! reported as returned, and the engine, which asked for its stop, terminates its node. A
//! panicking future fails its node, as in a task.
//!
//! Random programs (ending, sleeping, yielding, failing, retrying, spawning, waking one another
//! through channels and engine watches, terminating one another, polling, sharing a resource,
//! running code in their closures that others' futures look at) give the same trace as tasks,
//! record for record, and the same pumped trace on every run
//! (`random_programs_give_the_same_trace_with_and_without_the_pump`; 500,000 cases passed once,
//! 200,000 with the closures' code, and the programs it found on the way are kept in
//! `programs_once_found_giving_another_order_give_the_same_trace`). The limits:
//! - tokio delivers a deferred wake-up (`tokio::task::yield_now`) when its queue is empty, or after
//!   61 tasks (its event interval): the pump's inline actions are no tasks to count, so past 61
//!   actions in one go a future that yielded resumes later than with tasks. A runtime built with a
//!   larger event interval, as the tests here are, gives the same trace;
//! - a task of the program's own, woken at the same instant by something outside the run, is not
//!   counted.
//!
//! Only the end of a job's own task pumps, on the runtime's thread. Elsewhere (an action's body
//! spawning, the program's session, an event handle, the driver loop, a blocking action's thread)
//! actions start as tokio tasks, as before; so they do on a multi-thread runtime, where each action
//! is a task of its own so that actions run in parallel on its workers.

use crate::host::{CatchUnwind, Ended, Inner, Shared};
use crate::task::ActionFuture;
use std::cell::RefCell;
use std::future::Future;
use std::pin::Pin;
use std::sync::atomic::{AtomicBool, AtomicU8, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll, Wake, Waker};
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
            let now = inner.engine.wants_time().then(|| st.now());
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
    let now = inner.engine.wants_time().then(|| shared.now());
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
            while let Some((job, mut fut)) = batch.pop() {
                // A job of this batch cancelled before its turn (rare) is dropped unpolled in its
                // turn, as its task would be, aborted before it ran.
                if shared.inline_cancels.load(Ordering::Relaxed) != cancels {
                    batch.push((job, fut));
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
                        drop(fut);
                        let _ = push(|st| st.done.push(Ended::Dropped(job)));
                        unpolled = true;
                        continue;
                    }
                }
                let slot = spare.slot();
                polling(true);
                let first = poll_once(&mut fut, &slot.1);
                polling(false);
                let (kept, to_drop) = match first {
                    Poll::Ready(res) if !batch.is_empty() => {
                        spare.settle();
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
                    Poll::Ready(res) => {
                        // The last of its batch: reported by the next access, which comes before
                        // anything else runs.
                        spare.settle();
                        push(|st| st.done.push(Ended::Returned(job, res)))
                    }
                    Poll::Pending => match spare.park(&shared, job, fut) {
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
            let mut inner = shared.inner.lock().map_err(|_| crate::Error::Poisoned)?;
            // The batch's clock reading if the report needs the time; else the report reads the
            // clock only if it turns out to need it.
            let now = inner.engine.wants_time().then(|| {
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
fn drop_unpolled(dropped: &mut Vec<(Job, ActionFuture)>) {
    for (job, fut) in dropped.drain(..) {
        drop(fut);
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

/// What a job's future returns, or its panic.
type ActionResult =
    Result<Result<crate::task::Value, tcm_core::Failure>, Box<dyn std::any::Any + Send>>;

/// The slot the pump polls the next future with (its waker), one per thread, kept from one pump
/// to the next: taken by a pump while it runs, and put back when it ends.
struct Spare(Option<(Arc<Parked>, Waker)>);

thread_local! {
    static SPARE: RefCell<Option<(Arc<Parked>, Waker)>> = const { RefCell::new(None) };
}

impl Spare {
    fn take() -> Spare {
        Spare(SPARE.with(|p| p.try_borrow_mut().ok().and_then(|mut p| p.take())))
    }

    #[inline(always)]
    fn slot(&mut self) -> &(Arc<Parked>, Waker) {
        self.0.get_or_insert_with(Parked::spare)
    }

    /// After a poll that returned: the slot serves the next poll, unless something kept a clone
    /// of its waker (only the slot and its waker should hold it), whose late wake-up must not be
    /// taken for the next future's.
    #[inline(always)]
    fn settle(&mut self) {
        if let Some((p, _)) = &self.0 {
            if Arc::strong_count(p) != 2 {
                self.0 = None;
            } else if p.woken.load(Ordering::Relaxed) {
                p.woken.store(false, Ordering::Relaxed);
            }
        }
    }

    /// After a poll that left a cancellable job's future pending: the future is parked in the
    /// slot, whose waker is what it waits on (a new slot serves the next poll). A wiretap check
    /// (not cancellable), or a future with no runtime to spawn it on later, is given back, to
    /// spawn as a task under the lock.
    fn park(
        &mut self,
        shared: &Arc<Shared>,
        job: Job,
        fut: ActionFuture,
    ) -> Result<Arc<Parked>, ActionFuture> {
        let rt = match tokio::runtime::Handle::try_current() {
            Ok(rt) if job.cancellable() => rt,
            _ => return Err(fut),
        };
        let Some((p, _)) = self.0.take() else {
            return Err(fut);
        };
        p.park(shared, &rt, job, fut);
        Ok(p)
    }
}

impl Drop for Spare {
    fn drop(&mut self) {
        if let Some(slot) = self.0.take() {
            let _ = SPARE.try_with(|p| {
                if let Ok(mut p) = p.try_borrow_mut() {
                    *p = Some(slot);
                }
            });
        }
    }
}

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

/// A future the pump polled once and that was left pending: it is parked, with no task, until its
/// first wake-up, and only then spawned as a task, queued where a task woken then would be. A task
/// spawned at once would be queued for a second poll meanwhile, and an abort while it waits there
/// would drop it earlier than it drops a task that was idle (found with
/// `terminations_in_a_wide_release_give_the_same_trace_with_and_without_the_pump`); a second poll
/// at once would end a future that yielded (`tokio::task::yield_now`) before its turn.
///
/// It is also the waker of that first poll: the pump polls every future with a spare slot's waker
/// (`Spare`), used again for the next future while nothing kept a clone of it, so a future that
/// returns costs no allocation. A wake-up during the poll is noted, and the future spawned as soon
/// as it is parked, as a task woken during its poll is queued again.
pub(crate) struct Parked {
    state: Mutex<ParkState>,
    // Woken before it was parked (during its first poll).
    woken: AtomicBool,
}

enum ParkState {
    // A spare slot (not parked yet).
    Empty,
    Parked(Box<ParkedJob>),
    // Woken (or aborted) and spawned.
    Task(tokio::task::AbortHandle),
    // Taken at the end of the run.
    Gone,
}

/// A parked job, and where to spawn its task.
struct ParkedJob {
    job: Job,
    fut: ActionFuture,
    shared: Arc<Shared>,
    rt: tokio::runtime::Handle,
}

impl Parked {
    fn spare() -> (Arc<Parked>, Waker) {
        let p = Arc::new(Parked {
            state: Mutex::new(ParkState::Empty),
            woken: AtomicBool::new(false),
        });
        let waker = Waker::from(p.clone());
        (p, waker)
    }

    /// Parks `fut`, left pending by its first poll; spawns it at once if it was woken meanwhile.
    fn park(&self, shared: &Arc<Shared>, rt: &tokio::runtime::Handle, job: Job, fut: ActionFuture) {
        let Ok(mut st) = self.state.lock() else {
            return;
        };
        *st = ParkState::Parked(Box::new(ParkedJob {
            job,
            fut,
            shared: shared.clone(),
            rt: rt.clone(),
        }));
        if self.woken.load(Ordering::SeqCst) {
            Parked::spawn(&mut st);
        }
    }

    /// Spawns the parked future as a task (its wake-ups counted, `pump.rs`), if it is parked.
    fn spawn(st: &mut ParkState) -> Option<tokio::task::AbortHandle> {
        match std::mem::replace(st, ParkState::Gone) {
            ParkState::Parked(p) => {
                let ParkedJob {
                    job,
                    fut,
                    shared,
                    rt,
                } = *p;
                let h = crate::host::spawn_task(&shared, Some(&rt), job, fut).abort_handle();
                *st = ParkState::Task(h.clone());
                Some(h)
            }
            other => {
                *st = other;
                None
            }
        }
    }

    /// Aborts the job: a parked future is spawned and its task aborted at once, so that it is
    /// dropped where a task aborted now would be, and its stop reported the same way. Returns
    /// whether a stop will be reported.
    pub(crate) fn abort(&self) -> bool {
        let Ok(mut st) = self.state.lock() else {
            return false;
        };
        if let Some(h) = Parked::spawn(&mut st) {
            h.abort();
            return true;
        }
        match &*st {
            ParkState::Task(h) => {
                h.abort();
                true
            }
            _ => false,
        }
    }

    /// The run ended: the parked future, to drop outside the engine's lock.
    pub(crate) fn take(&self) -> Option<ActionFuture> {
        let mut st = self.state.lock().ok()?;
        match std::mem::replace(&mut *st, ParkState::Gone) {
            ParkState::Parked(p) => Some(p.fut),
            other => {
                *st = other;
                None
            }
        }
    }
}

impl Wake for Parked {
    fn wake(self: Arc<Self>) {
        self.wake_by_ref();
    }

    fn wake_by_ref(self: &Arc<Self>) {
        {
            let Ok(st) = self.state.lock() else {
                return;
            };
            match *st {
                ParkState::Empty => {
                    // Woken during its first poll.
                    self.woken.store(true, Ordering::SeqCst);
                    return;
                }
                ParkState::Parked(_) => {}
                ParkState::Task(_) | ParkState::Gone => return,
            }
        }
        if hold_wake(|| Waker::from(self.clone())) {
            return;
        }
        if let Ok(mut st) = self.state.lock() {
            Parked::spawn(&mut st);
        }
    }
}

/// What a [`Tracked`] future is: idle (polled, not woken since), queued (woken or new, not polled
/// yet: counted), or dropped (a late wake-up counts for nothing).
const IDLE: u8 = 0;
const QUEUED: u8 = 1;
const DROPPED: u8 = 2;

/// The waker a [`Tracked`] future polls its inner future with.
struct Track {
    state: AtomicU8,
    // Whether it was last polled by a task: only a task waits in the runtime's queue, in order. A
    // future polled by `block_on` (the driver of `Runtime::run` in a test) is polled once that
    // queue is empty, so its wake-ups are not counted.
    in_task: AtomicBool,
    // The run's count of queued tracked futures (`Shared::queued`).
    count: Arc<AtomicUsize>,
    // The waker of the task that polls the tracked future, as of its last poll.
    waker: Mutex<Option<Waker>>,
}

impl Wake for Track {
    fn wake(self: Arc<Self>) {
        self.wake_by_ref();
    }

    fn wake_by_ref(self: &Arc<Self>) {
        if self.in_task.load(Ordering::SeqCst) && hold_wake(|| Waker::from(self.clone())) {
            return;
        }
        if self.in_task.load(Ordering::SeqCst)
            && self
                .state
                .compare_exchange(IDLE, QUEUED, Ordering::SeqCst, Ordering::SeqCst)
                .is_ok()
        {
            self.count.fetch_add(1, Ordering::SeqCst);
        }
        let waker = self.waker.lock().ok().and_then(|w| w.clone());
        if let Some(w) = waker {
            w.wake();
        }
    }
}

/// A future whose wake-ups the run counts (see the module documentation): an action's task, the
/// driver loop, a wait on the engine.
pub(crate) struct Tracked<F> {
    fut: F,
    track: Arc<Track>,
    waker: Waker,
}

impl<F> Tracked<F> {
    /// Tracks `fut`; `queued` when it is about to be polled without a wake-up (a new task).
    pub(crate) fn new(fut: F, count: &Arc<AtomicUsize>, queued: bool) -> Tracked<F> {
        if queued {
            count.fetch_add(1, Ordering::SeqCst);
        }
        let track = Arc::new(Track {
            state: AtomicU8::new(if queued { QUEUED } else { IDLE }),
            in_task: AtomicBool::new(queued),
            count: count.clone(),
            waker: Mutex::new(None),
        });
        let waker = Waker::from(track.clone());
        Tracked { fut, track, waker }
    }
}

impl<F: Future + Unpin> Future for Tracked<F> {
    type Output = F::Output;

    fn poll(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<F::Output> {
        let this = &mut *self;
        this.track
            .in_task
            .store(tokio::task::try_id().is_some(), Ordering::SeqCst);
        if this.track.state.swap(IDLE, Ordering::SeqCst) == QUEUED {
            this.track.count.fetch_sub(1, Ordering::SeqCst);
        }
        if let Ok(mut w) = this.track.waker.lock() {
            if !w.as_ref().is_some_and(|w| w.will_wake(cx.waker())) {
                *w = Some(cx.waker().clone());
            }
        }
        let mut inner = Context::from_waker(&this.waker);
        Pin::new(&mut this.fut).poll(&mut inner)
    }
}

/// A future tracked only where the pump runs (a current-thread runtime): elsewhere nothing reads
/// the count, so the future is polled as it is.
pub(crate) enum MaybeTracked<F> {
    Plain(F),
    Tracked(Tracked<F>),
}

impl<F> MaybeTracked<F> {
    /// `fut`, tracked if the run pumps (`Shared::inline`); see [`Tracked::new`].
    pub(crate) fn new(shared: &Shared, fut: F, queued: bool) -> MaybeTracked<F> {
        if shared.inline.load(Ordering::Relaxed) {
            MaybeTracked::Tracked(Tracked::new(fut, &shared.queued, queued))
        } else {
            MaybeTracked::Plain(fut)
        }
    }
}

impl<F: Future + Unpin> Future for MaybeTracked<F> {
    type Output = F::Output;

    fn poll(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<F::Output> {
        match &mut *self {
            MaybeTracked::Plain(f) => Pin::new(f).poll(cx),
            MaybeTracked::Tracked(f) => Pin::new(f).poll(cx),
        }
    }
}

impl<F> Drop for Tracked<F> {
    fn drop(&mut self) {
        if self.track.state.swap(DROPPED, Ordering::SeqCst) == QUEUED {
            self.track.count.fetch_sub(1, Ordering::SeqCst);
        }
    }
}

#[cfg(test)]
mod tests {
    //! The pump changes nothing observable: each program gives the same trace, record for record,
    //! with released actions run inline and with every action a task; and it does run them inline.

    use crate::testing::{lines, run_checked_allowing_panics};
    use crate::{Failure, FailurePolicy, Handler, Monitor, NodeKind, NodeRef, Runtime, Task};
    use proptest::prelude::*;
    use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
    use std::sync::{Arc, Mutex};
    use std::time::Duration;

    fn ms(n: u64) -> Duration {
        Duration::from_millis(n)
    }

    fn noop(name: &'static str) -> Task {
        Task::command(name, |_| async { Ok(()) })
    }

    fn sleeper(name: &'static str, d: u64) -> Task {
        Task::command(name, move |_| async move {
            tokio::time::sleep(ms(d)).await;
            Ok(())
        })
    }

    /// Two actions wake at the same instant; the end of the first releases one that ends at once.
    fn tie() -> Task {
        Task::goal("tie", |ctx| async move {
            ctx.spawn(sleeper("a", 10)).start()?;
            ctx.spawn(noop("c")).serial(NodeRef::Previous).start()?;
            ctx.spawn(sleeper("b", 10)).start()?;
            ctx.spawn(noop("d")).serial(NodeRef::Previous).start()?;
            Ok(())
        })
    }

    /// Waits, values, children started at once, a fan-out of actions that end at once.
    fn waits() -> Task {
        Task::goal("waits", |ctx| async move {
            let v: u32 = ctx
                .spawn(Task::command("value", |_| async { Ok(7u32) }))
                .wait_value()
                .await?;
            ctx.hold_children(false)?;
            for _ in 0..v {
                ctx.spawn(noop("fan")).start()?;
            }
            ctx.spawn(sleeper("slow", 5)).wait().await?;
            ctx.spawn(Task::goal("inner", |ctx| async move {
                for _ in 0..3 {
                    ctx.spawn(noop("step")).serial(NodeRef::Previous).start()?;
                }
                Ok(())
            }))
            .wait()
            .await?;
            Ok(())
        })
    }

    /// Failures handled three levels up, a retry, a panic, an unhandled failure.
    fn failures() -> Task {
        let tries = Arc::new(Mutex::new(0u32));
        Task::goal("top", |ctx| async move {
            ctx.spawn(Task::goal("mid", |ctx| async move {
                for _ in 0..3 {
                    ctx.spawn(Task::command("boom", |_| async {
                        Err::<(), _>(Failure::new("Boom", "at once"))
                    }))
                    .start()?;
                }
                ctx.spawn(Task::command("oops", |_| async {
                    if true {
                        panic!("an action that panics");
                    }
                    Ok(())
                }))
                .start()?;
                ctx.spawn(Task::command("lone", |_| async {
                    Err::<(), _>(Failure::new("Lone", "nobody handles it"))
                }))
                .start()?;
                Ok(())
            }))
            .start()?;
            ctx.spawn(
                Task::retryable(NodeKind::Command, "flaky", move |_| {
                    let tries = tries.clone();
                    async move {
                        let n = {
                            let mut t = tries.lock().map_err(|_| Failure::new("Lock", ""))?;
                            *t += 1;
                            *t
                        };
                        if n < 3 {
                            Err(Failure::new("Flaky", "again"))
                        } else {
                            Ok(())
                        }
                    }
                })
                .handler(Handler::new("again", "Flaky", |ctx| async move {
                    let retry = ctx.retry()?;
                    ctx.wait(retry).await?;
                    Ok(())
                })),
            )
            .start()?;
            Ok(())
        })
        .handler(Handler::new("recover", "Boom", |_| async { Ok(()) }))
    }

    /// Terminations: of a sleeping action, of one that looks at its signal and cleans up in its
    /// grace period, of one released at the same time as the action that terminates it, and of
    /// one not started yet.
    fn terminations() -> Task {
        Task::goal("cancel", |ctx| async move {
            ctx.spawn(sleeper("long", 1000))
                .terminate_in(ms(5))
                .start()?;
            ctx.spawn(Task::command("careful", |ctx| async move {
                tokio::select! {
                    () = tokio::time::sleep(ms(1000)) => {}
                    () = ctx.cancelled() => tokio::time::sleep(ms(3)).await,
                }
                Ok(())
            }))
            .terminate_in(ms(7))
            .start()?;
            let victim = ctx.spawn(sleeper("victim", 50)).start()?;
            let later = ctx.reserve("later")?;
            ctx.spawn(Task::command("killer", move |ctx| async move {
                ctx.terminate(victim)?;
                ctx.terminate(later)?;
                Ok(())
            }))
            .start()?;
            ctx.spawn(noop("late")).fulfils(later).start()?;
            Ok(())
        })
    }

    /// Actions that yield once (woken during their first poll) beside a chain that ends at once.
    fn yields() -> Task {
        Task::goal("yield", |ctx| async move {
            for name in ["y1", "y2"] {
                ctx.spawn(Task::command(name, move |ctx| async move {
                    tokio::task::yield_now().await;
                    ctx.warn(format!("{name} resumed"))?;
                    Ok(())
                }))
                .start()?;
            }
            for _ in 0..3 {
                ctx.spawn(Task::command("c", |ctx| async move {
                    ctx.warn("chain")?;
                    Ok(())
                }))
                .serial(NodeRef::Previous)
                .start()?;
            }
            Ok(())
        })
    }

    /// A polling monitor whose activations end at once, beside a sleeper.
    fn monitor() -> Task {
        Task::goal("watch", |ctx| async move {
            let params = Monitor {
                max_activations: Some(4),
                period: Some(ms(2)),
                ..Monitor::default()
            };
            ctx.spawn(Task::monitor("poll", params, |_| async { Ok(()) }))
                .start()?;
            ctx.spawn(sleeper("beside", 4)).start()?;
            Ok(())
        })
    }

    /// The trace of `task` run on virtual time. The tokio runtime delivers deferred wake-ups
    /// (`tokio::task::yield_now`) only when its queue is empty, not every 61 tasks as by default:
    /// the pump's inline actions are no tasks to count (the module's documentation).
    fn trace_of(rt: Runtime, task: Task) -> Vec<String> {
        let run = async { Ok::<_, crate::Error>(run_checked_allowing_panics(rt, task).await) };
        let tokio = tokio::runtime::Builder::new_current_thread()
            .enable_time()
            .start_paused(true)
            .event_interval(u32::MAX)
            .build()
            .expect("a tokio runtime");
        let (_, trace) = tokio.block_on(run).expect("a run");
        lines(&trace)
    }

    #[test]
    fn each_program_gives_the_same_trace_with_and_without_the_pump() {
        type Program = (&'static str, fn() -> Task);
        let programs: [Program; 6] = [
            ("tie", tie),
            ("waits", waits),
            ("failures", failures),
            ("terminations", terminations),
            ("monitor", monitor),
            ("yields", yields),
        ];
        for (name, program) in programs {
            let pumped = trace_of(Runtime::new(), program());
            let tasks = trace_of(Runtime::new().without_pump(), program());
            assert!(pumped.len() > 10, "{name}: a real trace");
            assert_eq!(pumped, tasks, "{name}: the same trace");
        }
    }

    /// A batch in which one action wakes another that awaits: `b` (released with `a`) wakes `w`,
    /// and `a`'s end releases `x`. Plain tasks run `x` before `w`. The pump reports `a`'s end
    /// after polling `b`; it holds `w`'s wake-up back until then (`hold_wake`), so that `x` runs
    /// first there too (without that, `w` ran first).
    fn wake_in_batch() -> Task {
        Task::goal("wake", |ctx| async move {
            ctx.hold_children(false)?;
            let (tx, rx) = tokio::sync::oneshot::channel::<()>();
            let tx = Arc::new(Mutex::new(Some(tx)));
            ctx.spawn(Task::command("w", move |ctx| async move {
                let _ = rx.await;
                ctx.warn("w woke")?;
                Ok(())
            }))
            .start()?;
            let p = ctx.spawn(noop("p")).start()?;
            let a = ctx.spawn(noop("a")).serial(p).start()?;
            ctx.spawn(Task::command("x", |ctx| async move {
                ctx.warn("x ran")?;
                Ok(())
            }))
            .serial(a)
            .start()?;
            ctx.spawn(Task::command("b", move |_| async move {
                if let Some(tx) = tx.lock().ok().and_then(|mut t| t.take()) {
                    let _ = tx.send(());
                }
                Ok(())
            }))
            .serial(p)
            .start()?;
            Ok(())
        })
    }

    #[test]
    fn a_wake_within_a_batch_gives_the_same_trace_with_and_without_the_pump() {
        let warnings = |trace: &[String]| -> Vec<&'static str> {
            trace
                .iter()
                .filter_map(|l| {
                    ["w woke", "x ran"]
                        .into_iter()
                        .find(|w| l.contains(w) && l.contains("warning"))
                })
                .collect()
        };
        let pumped = trace_of(Runtime::new(), wake_in_batch());
        let tasks = trace_of(Runtime::new().without_pump(), wake_in_batch());
        assert_eq!(warnings(&tasks), ["x ran", "w woke"]);
        assert_eq!(pumped, tasks, "the same trace, record for record");
    }

    /// A release wider than a batch of reported ends (`REPORT_EVERY`): 300 children, most
    /// ending at once, some failing into a handler, some sleeping, some spawning a child of their
    /// own; one released by an early end terminates two sleepers; a chain follows.
    fn wide_with_terminations() -> Task {
        Task::goal("wide", |ctx| async move {
            let mut ids = Vec::new();
            for i in 0..300u64 {
                let task = match i % 10 {
                    3 => Task::command("fails", |_| async {
                        Err::<(), _>(Failure::new("Boom", "wide"))
                    }),
                    5 => sleeper("sleeps", i % 4 + 1),
                    7 => Task::goal("parent", |ctx| async move {
                        ctx.spawn(noop("grandchild")).start()?;
                        Ok(())
                    }),
                    _ => noop("ends"),
                };
                ids.push(ctx.spawn(task).start()?);
            }
            let (early, far, near) = (ids[10], ids[295], ids[15]);
            ctx.spawn(Task::command("terminator", move |ctx| async move {
                ctx.terminate(far)?;
                ctx.terminate(near)?;
                Ok(())
            }))
            .serial(early)
            .start()?;
            for _ in 0..5 {
                ctx.spawn(noop("chained"))
                    .serial(NodeRef::Previous)
                    .start()?;
            }
            Ok(())
        })
        .handler(Handler::new("recover", "Boom", |_| async { Ok(()) }))
    }

    /// Found with the program above: the stops of the terminated sleepers came after the ends
    /// of a chain the pump ran meanwhile, where with every action a task they came before. An
    /// aborted task now counts as queued until its stop is reported, and the stop is reported by
    /// whoever takes the lock next (not only the driver), so both give the same trace.
    #[test]
    fn terminations_in_a_wide_release_give_the_same_trace_with_and_without_the_pump() {
        let pumped = trace_of(Runtime::new(), wide_with_terminations());
        let tasks = trace_of(Runtime::new().without_pump(), wide_with_terminations());
        assert!(pumped.len() > 3000, "a real trace: {}", pumped.len());
        let stop = |t: &[String]| t.iter().position(|l| l.contains("\"ev\":\"terminated\""));
        let chain_end = |t: &[String]| {
            t.iter()
                .rposition(|l| l.contains("\"ev\":\"reclaimed\"") && l.contains("\"node\":307}"))
        };
        assert!(stop(&tasks).is_some() && stop(&tasks) < chain_end(&tasks));
        assert_eq!(pumped, tasks, "the same trace, record for record");
    }

    /// One child of a random program (`random_program`).
    #[derive(Clone, Debug)]
    enum Kid {
        Ends,
        Sleeps(u64),
        Yields,
        Fails,
        Parent(u8),
        // Waits for the channel of the `Sends` with the same number, if there is one.
        Waits(u8),
        Sends(u8),
        // Terminates the child this many places before it.
        Terminates(u8),
        // Waits for the end of the child this many places before it (an engine watch).
        WaitsFor(u8),
        // Sleeps this long holding the one `base`: such children run one at a time.
        Uses(u64),
        // A monitor polling every millisecond, this many times (at least once).
        Polls(u8),
        // Fails on its first run; its handler retries it.
        Retries,
        // A goal whose child fails: the failure goes up to the program's handler.
        FailsBelow,
        // Its closure (code run when it starts, before its future) adds its place to a log.
        Marks,
        // Its future traces the log.
        Reads,
    }

    fn kid() -> impl Strategy<Value = (Kid, Option<u8>)> {
        let kid = prop_oneof![
            3 => Just(Kid::Ends),
            2 => (1u64..4).prop_map(Kid::Sleeps),
            1 => Just(Kid::Yields),
            1 => Just(Kid::Fails),
            1 => (0u8..3).prop_map(Kid::Parent),
            1 => (0u8..3).prop_map(Kid::Waits),
            1 => (0u8..3).prop_map(Kid::Sends),
            1 => (1u8..6).prop_map(Kid::Terminates),
            1 => (1u8..6).prop_map(Kid::WaitsFor),
            1 => (1u64..4).prop_map(Kid::Uses),
            1 => (1u8..4).prop_map(Kid::Polls),
            1 => Just(Kid::Retries),
            1 => Just(Kid::FailsBelow),
            1 => Just(Kid::Marks),
            1 => Just(Kid::Reads),
        ];
        (kid, proptest::option::weighted(0.5, 1u8..4))
    }

    /// A goal whose children are `kids`, each serial after the one that many places before it,
    /// if it says so (several after one are released together).
    fn random_program(kids: Vec<(Kid, Option<u8>)>) -> Task {
        type Chan = Arc<Mutex<Vec<Option<tokio::sync::oneshot::Sender<()>>>>>;
        Task::goal("random", move |ctx| {
            let kids = kids.clone();
            async move {
                ctx.hold_children(false)?;
                let mut senders = Vec::new();
                let mut receivers = Vec::new();
                for _ in 0..3 {
                    let (tx, rx) = tokio::sync::oneshot::channel::<()>();
                    senders.push(Some(tx));
                    receivers.push(Some(rx));
                }
                let senders: Chan = Arc::new(Mutex::new(senders));
                let log: Arc<Mutex<Vec<usize>>> = Arc::default();
                let mut ids = Vec::new();
                for (i, (kid, after)) in kids.into_iter().enumerate() {
                    let task = match kid {
                        Kid::Ends => noop("ends"),
                        Kid::Sleeps(d) => sleeper("sleeps", d),
                        Kid::Yields => Task::command("yields", |ctx| async move {
                            tokio::task::yield_now().await;
                            ctx.warn("resumed")?;
                            Ok(())
                        }),
                        Kid::Fails => Task::command("fails", |_| async {
                            Err::<(), _>(Failure::new("Boom", "random"))
                        }),
                        Kid::Parent(n) => Task::goal("parent", move |ctx| async move {
                            for _ in 0..n {
                                ctx.spawn(noop("grandchild")).start()?;
                            }
                            Ok(())
                        }),
                        Kid::Waits(c) => {
                            let rx = receivers[c as usize].take();
                            let rx = Arc::new(Mutex::new(rx));
                            Task::command("waits", move |ctx| {
                                let rx = rx.clone();
                                async move {
                                    let rx = rx.lock().ok().and_then(|mut r| r.take());
                                    if let Some(rx) = rx {
                                        // Bounded: its sender may come after it, or never.
                                        let _ = tokio::time::timeout(ms(20), rx).await;
                                    }
                                    ctx.warn("woke")?;
                                    Ok(())
                                }
                            })
                        }
                        Kid::Sends(c) => {
                            let senders = senders.clone();
                            Task::command("sends", move |_| {
                                let senders = senders.clone();
                                async move {
                                    let tx =
                                        senders.lock().ok().and_then(|mut s| s[c as usize].take());
                                    if let Some(tx) = tx {
                                        let _ = tx.send(());
                                    }
                                    Ok(())
                                }
                            })
                        }
                        Kid::Terminates(back) => {
                            let victim = i.checked_sub(back as usize).map(|j| ids[j]);
                            Task::command("terminates", move |ctx| async move {
                                if let Some(v) = victim {
                                    ctx.terminate(v)?;
                                }
                                Ok(())
                            })
                        }
                        Kid::WaitsFor(back) => {
                            let target = i.checked_sub(back as usize).map(|j| ids[j]);
                            Task::command("waits_for", move |ctx| async move {
                                if let Some(t) = target {
                                    ctx.wait(t).await?;
                                }
                                Ok(())
                            })
                        }
                        Kid::Uses(d) => sleeper("uses", d).uses("base", 1),
                        Kid::Polls(n) => {
                            let params = Monitor {
                                max_activations: Some(u32::from(n)),
                                period: Some(ms(1)),
                                ..Monitor::default()
                            };
                            Task::monitor("polls", params, |ctx| async move {
                                ctx.warn("polled")?;
                                Ok(())
                            })
                        }
                        Kid::Retries => {
                            let runs = Arc::new(AtomicUsize::new(0));
                            Task::retryable(NodeKind::Command, "retries", move |_| {
                                let first = runs.fetch_add(1, Ordering::SeqCst) == 0;
                                async move {
                                    if first {
                                        return Err(Failure::new("Flaky", "first run"));
                                    }
                                    Ok(())
                                }
                            })
                            .handler(Handler::new(
                                "again",
                                "Flaky",
                                |ctx| async move {
                                    ctx.retry()?;
                                    Ok(())
                                },
                            ))
                        }
                        Kid::Marks => {
                            let log = log.clone();
                            Task::command("marks", move |_| {
                                if let Ok(mut l) = log.lock() {
                                    l.push(i);
                                }
                                async { Ok(()) }
                            })
                        }
                        Kid::Reads => {
                            let log = log.clone();
                            Task::command("reads", move |ctx| {
                                let log = log.clone();
                                async move {
                                    let seen = log.lock().map(|l| format!("{l:?}")).ok();
                                    ctx.warn(format!("log {seen:?}"))?;
                                    Ok(())
                                }
                            })
                        }
                        Kid::FailsBelow => Task::goal("fails_below", |ctx| async move {
                            ctx.spawn(Task::command("fails", |_| async {
                                Err::<(), _>(Failure::new("Boom", "below"))
                            }))
                            .start()?;
                            Ok(())
                        }),
                    };
                    let spawner = ctx.spawn(task);
                    let before = after.and_then(|k| i.checked_sub(k as usize));
                    let spawner = match before {
                        Some(j) => spawner.serial(ids[j]),
                        None => spawner,
                    };
                    ids.push(spawner.start()?);
                }
                Ok(())
            }
        })
        .handler(Handler::new("recover", "Boom", |_| async { Ok(()) }))
    }

    /// The lines, without the run's number in a node's name (`node#2.0@run105`): each run has
    /// its own.
    fn without_run_ids(lines: Vec<String>) -> Vec<String> {
        lines
            .into_iter()
            .map(|l| {
                let mut out = String::with_capacity(l.len());
                let mut rest = l.as_str();
                while let Some(i) = rest.find("@run") {
                    out.push_str(&rest[..i + 4]);
                    rest = rest[i + 4..].trim_start_matches(|c: char| c.is_ascii_digit());
                }
                out.push_str(rest);
                out
            })
            .collect()
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

        /// Random programs (ending, sleeping, yielding, failing into a handler or below,
        /// retrying, spawning, waking one another through channels and engine watches,
        /// terminating one another, polling, sharing a resource, running code in their closures
        /// that others' futures look at; some after others, several released together) give the
        /// same trace with and without the pump, record for record, and the same pumped trace on
        /// every run.
        #[test]
        fn random_programs_give_the_same_trace_with_and_without_the_pump(
            kids in proptest::collection::vec(kid(), 1..40),
        ) {
            let rt = || Runtime::new().resource("base", 1);
            let pumped = trace_of(rt(), random_program(kids.clone()));
            let again = trace_of(rt(), random_program(kids.clone()));
            let tasks = trace_of(rt().without_pump(), random_program(kids));
            prop_assert_eq!(without_run_ids(pumped.clone()), without_run_ids(again));
            prop_assert_eq!(without_run_ids(pumped), without_run_ids(tasks));
        }
    }

    /// Programs the proptest above found giving another order than tasks, each fixed since: the
    /// same trace, record for record.
    #[test]
    fn programs_once_found_giving_another_order_give_the_same_trace() {
        use Kid::*;
        type Kids = Vec<(Kid, Option<u8>)>;
        // A monitor's activation dropped in its batch, a node released by its stop, and `then`
        // released with that node.
        let after_a_dropped_activation = |then: Kid| -> Kids {
            vec![
                (Ends, None),
                (Ends, None),
                (Ends, None),
                (Waits(0), None),
                (Fails, None),
                (Ends, None),
                (Polls(1), Some(2)),
                (Terminates(1), Some(3)),
                (Ends, Some(2)),
                (then, Some(2)),
                (WaitsFor(4), None),
                (Ends, Some(1)),
                (Ends, None),
                (Ends, None),
            ]
        };
        let programs: Vec<(&str, Kids)> = vec![
            // A handler about to start when a node of the same batch terminates its failed node:
            // what an end starts is started before the next end, or the future that took the
            // lock, is looked at (`flush`).
            (
                "handler started before the terminator's lock",
                vec![(Ends, None), (Fails, Some(1)), (Terminates(1), Some(2))],
            ),
            // A monitor's activation cancelled by a node of its batch polled before it: dropped
            // unpolled in its turn, its stop reported by whoever runs next.
            (
                "activation cancelled in its batch",
                vec![
                    (Ends, None),
                    (Ends, None),
                    (Ends, None),
                    (Uses(1), None),
                    (Ends, None),
                    (Polls(1), Some(2)),
                    (Terminates(1), Some(3)),
                ],
            ),
            // The same, the stop then releasing a node a later future waits for.
            (
                "stop of a dropped activation, then a send",
                after_a_dropped_activation(Sends(0)),
            ),
            // A stop reported before a node it releases is terminated by the lock that reported
            // it (`host::stops_first` starts what the stop starts).
            (
                "stop, then a termination in the same lock",
                after_a_dropped_activation(Terminates(1)),
            ),
            // Two handlers started in one batch, the second cancelled: dropped in its turn, after
            // the first ran.
            (
                "second of two handlers cancelled",
                vec![
                    (Ends, None),
                    (Fails, Some(1)),
                    (Retries, Some(2)),
                    (Terminates(1), Some(3)),
                    (Ends, Some(1)),
                    (Ends, Some(1)),
                ],
            ),
            // An end reported with a held wake-up (its future woke a waiting task) starts a node
            // the next future of its batch terminates: the start went to the host first, so the
            // node is stopped as a running action, not struck from the engine's effects.
            (
                "a start by an end reported with a wake-up, terminated in the same batch",
                vec![
                    (Sends(1), None),
                    (Ends, None),
                    (Ends, None),
                    (Ends, Some(1)),
                    (Sends(0), Some(1)),
                    (Ends, Some(1)),
                    (Terminates(1), Some(3)),
                    (Waits(0), None),
                    (Uses(1), None),
                    (Ends, Some(1)),
                    (Ends, None),
                ],
            ),
            // A handler dropped unpolled last in its batch; the next batch's one future yields
            // (no end reported): the stop is handed over then, not reported by the pump, so the
            // node it releases starts after the yielded future resumed, as with tasks.
            (
                "a stop kept past a batch that reported nothing",
                vec![
                    (Ends, None),
                    (Ends, None),
                    (Waits(0), Some(1)),
                    (Fails, Some(2)),
                    (Terminates(1), Some(2)),
                    (Yields, Some(1)),
                    (Terminates(1), Some(3)),
                ],
            ),
        ];
        for (what, kids) in programs {
            let rt = || Runtime::new().resource("base", 1);
            let pumped = trace_of(rt(), random_program(kids.clone()));
            let again = trace_of(rt(), random_program(kids.clone()));
            let tasks = trace_of(rt().without_pump(), random_program(kids));
            assert!(pumped.len() > 20, "{what}: a real trace");
            assert_eq!(
                without_run_ids(pumped.clone()),
                without_run_ids(again),
                "{what}"
            );
            assert_eq!(without_run_ids(pumped), without_run_ids(tasks), "{what}");
        }
    }

    /// Code an action runs when it starts (its closure, before its future), started by the end of
    /// an action of a batch, runs before the next action of that batch, as with tasks (the end is
    /// reported at once, `report_now`): `y` starts when `x` ends, and `z`, released with `x`, sees
    /// what `y`'s closure set.
    #[test]
    fn code_an_end_starts_runs_before_the_rest_of_its_batch() {
        let run = |rt: Runtime| {
            let started = Arc::new(AtomicBool::new(false));
            let task = Task::goal("g", move |ctx| {
                let started = started.clone();
                async move {
                    let x = ctx.spawn(noop("x")).start()?;
                    let seen = started.clone();
                    ctx.spawn(Task::command("z", move |ctx| {
                        let seen = seen.clone();
                        async move {
                            let y = if seen.load(Ordering::SeqCst) {
                                "started"
                            } else {
                                "not started"
                            };
                            ctx.warn(format!("y {y}"))?;
                            Ok(())
                        }
                    }))
                    .start()?;
                    let set = started.clone();
                    ctx.spawn(Task::command("y", move |_| {
                        set.store(true, Ordering::SeqCst);
                        async { Ok(()) }
                    }))
                    .serial(x)
                    .start()?;
                    Ok(())
                }
            });
            trace_of(rt, task)
        };
        let saw = |t: &[String], what: &str| t.iter().any(|l| l.contains(what));
        let pumped = run(Runtime::new());
        let tasks = run(Runtime::new().without_pump());
        assert!(
            saw(&tasks, "\"y started\""),
            "tasks: y started before z ran"
        );
        assert!(saw(&pumped, "\"y started\""), "pumped: likewise");
        assert_eq!(without_run_ids(pumped), without_run_ids(tasks));
    }

    /// Sets its flag when dropped.
    struct DropFlag(Arc<AtomicBool>);

    impl Drop for DropFlag {
        fn drop(&mut self) {
            self.0.store(true, Ordering::SeqCst);
        }
    }

    /// A run that ends (a fatal failure) while an action that waits for ever is parked: the
    /// parked future is dropped when the run ends, as a task would be, and the same trace results.
    #[test]
    fn a_future_parked_when_the_run_ends_is_dropped() {
        let run = |rt: Runtime| {
            let dropped = Arc::new(AtomicBool::new(false));
            let flag = dropped.clone();
            let task = Task::goal("ends", move |ctx| async move {
                let flag = flag.clone();
                ctx.spawn(Task::command("forever", move |_| async move {
                    let _guard = DropFlag(flag);
                    std::future::pending::<()>().await;
                    Ok(())
                }))
                .start()?;
                ctx.spawn(Task::command("fails", |_| async {
                    Err::<(), _>(Failure::new("Boom", "fatal"))
                }))
                .start()?;
                Ok(())
            });
            let trace = trace_of(rt.failure_policy(FailurePolicy::Fatal), task);
            (trace, dropped.load(Ordering::SeqCst))
        };
        let (pumped, pumped_dropped) = run(Runtime::new());
        let (tasks, tasks_dropped) = run(Runtime::new().without_pump());
        assert!(pumped_dropped, "the parked future was dropped");
        assert!(tasks_dropped, "the task's future was dropped");
        assert_eq!(pumped, tasks, "the same trace");
    }

    type TaskId = Option<tokio::task::Id>;

    /// The id of the tokio task the goal's body ran on, and those its children's bodies ran on.
    fn task_ids(rt: Runtime) -> (TaskId, Vec<TaskId>) {
        let ids: Arc<Mutex<Vec<TaskId>>> = Arc::default();
        let goal_id: Arc<Mutex<TaskId>> = Arc::default();
        let (i, g) = (ids.clone(), goal_id.clone());
        let task = Task::goal("g", move |ctx| async move {
            if let Ok(mut g) = g.lock() {
                *g = tokio::task::try_id();
            }
            for _ in 0..5 {
                let i = i.clone();
                ctx.spawn(Task::command("c", move |_| async move {
                    if let Ok(mut i) = i.lock() {
                        i.push(tokio::task::try_id());
                    }
                    Ok(())
                }))
                .serial(NodeRef::Previous)
                .start()?;
            }
            Ok(())
        });
        let _ = trace_of(rt, task);
        let goal = goal_id.lock().map(|g| *g).unwrap_or(None);
        let ids = ids.lock().map(|i| i.clone()).unwrap_or_default();
        (goal, ids)
    }

    #[test]
    fn released_actions_run_on_the_task_that_released_them() {
        let (goal, ids) = task_ids(Runtime::new());
        assert!(goal.is_some());
        assert_eq!(ids, vec![goal; 5], "each ran inline, on the goal's task");
        let (goal, ids) = task_ids(Runtime::new().without_pump());
        assert_eq!(ids.len(), 5);
        assert!(
            ids.iter().all(|id| id.is_some() && *id != goal),
            "tasks of their own"
        );
    }
}
