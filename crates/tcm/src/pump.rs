//! Running actions inline: an action that ends without awaiting costs no tokio task, and nothing
//! of the run observes the difference.
//!
//! When a job's task ends, its end is reported under the engine's lock and the nodes it releases
//! start (`host.rs`). On a current-thread runtime (virtual time, tests, `tcm-bench`) the host may
//! then hand their futures to the *pump* of the thread, which polls each once, outside the lock,
//! right after the end that released it. A future that is done then never becomes a task: its end
//! is kept on the pump and reported with the others the next time the lock is taken (once for a
//! whole batch, or earlier: the moment one of the next futures touches the engine, so that nothing
//! of the engine ever sees an action run before the end of one polled before it was reported, and
//! every `REPORT_EVERY` ends of a wide batch, so that the ends kept stay few). A
//! future that is not done is spawned as a task, as before (its first poll had a no-op waker: the
//! task polls it again at once, which registers its own). What the reported ends start is pumped in
//! turn, in a loop, never recursively.
//!
//! **The same order as tasks.** A task spawned on a current-thread runtime runs after every task
//! already queued. So a released action is pumped only when nothing of the run is queued: the
//! run's tasks, the driver loop and the waits on the engine are wrapped in [`Tracked`], which counts
//! those woken and not yet polled by a task. Then the task would have run next anyway, and the
//! trace is the one tasks give, record for record (`tests` below compares them). Otherwise the
//! action is spawned as a task, behind what is queued. A future that `block_on` polls (the driver of
//! `Runtime::run` in a test, a test's own body) is not counted: tokio polls it once its queue of
//! tasks is empty. While the pump runs, the driver is not woken merely to hand trace records to the
//! sinks (it is woken once at the end), since that changes nothing of the engine. The limits: a task
//! of the program's own, woken at the same instant by something outside the run, is not counted;
//! and the ends of a batch are reported after the batch was polled, so when an action of the batch
//! wakes one that awaits (a channel, a `Ctx::wait`), what an *earlier* end of the batch releases runs
//! after the woken one, where tasks would run it before (and likewise for a future of the batch
//! left pending, whose task is spawned when the batch is reported). Both orders are runs of the
//! same program and the pumped one is the same on every run (`tests`,
//! `a_wake_within_a_batch_may_reorder_two_actions_and_the_pumped_trace_is_reproducible`); an exact
//! order would need each end reported right after its poll (a lock per end of a wide batch), or
//! a pending future's task spawned only once it is woken. A second limit, found with a release
//! wider than `REPORT_EVERY`: when an action of the release terminates sleeping siblings, the
//! stops of those siblings are reported after the ends of a chain the pump ran meanwhile, where
//! tasks report them before; again both are runs of the program and the pumped one is
//! reproducible (`terminations_in_a_wide_release_may_reorder_stops_and_the_pumped_trace_is_reproducible`).
//!
//! Cancellation keeps its meaning: a job cancelled before its poll is dropped unpolled and reported
//! stopped; one cancelled after a poll that left it pending is spawned and then cancelled as any
//! running task (signalled with its grace period, or aborted); one that returned is reported as
//! returned, and the engine, which asked for its stop, terminates its node. A panicking future fails
//! its node, as in a task.
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
use tcm_core::Job;

/// The pump of one thread, for one run.
pub(crate) struct PumpState {
    shared: Arc<Shared>,
    // Ends polled but not reported yet, in the order the jobs started.
    done: Vec<Ended>,
    // Futures left pending by their first poll, to spawn as tasks under the lock.
    pending: Vec<(Job, ActionFuture)>,
    // Futures to drop outside the lock (their drop may run code that takes it).
    to_drop: Vec<ActionFuture>,
    // The driver has trace records to take: woken when the pump ends.
    wake_driver: bool,
}

thread_local! {
    static PUMP: RefCell<Option<PumpState>> = const { RefCell::new(None) };
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
pub(crate) fn flush(inner: &mut Inner, shared: &Shared) {
    PUMP.with(|p| {
        let Ok(mut p) = p.try_borrow_mut() else {
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
        if !st.done.is_empty() {
            let now = shared.now();
            for ended in st.done.drain(..) {
                inner.ended_job(now, ended);
            }
        }
    });
}

/// The largest batch buffer the pump keeps from one batch to the next.
const KEEP_BATCH: usize = 64;

/// How many ends (and futures left pending) the pump keeps at most before it reports them.
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
                pending: Vec::new(),
                to_drop: Vec::new(),
                wake_driver: false,
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
        let waker = Waker::noop();
        let mut cx = Context::from_waker(waker);
        // One buffer for every batch (swapped with the host's, `Inner::take_launches`).
        let mut batch = Vec::new();
        // Those cancelled before their poll (rare), likewise.
        let mut dropped = Vec::new();
        loop {
            match shared.enter() {
                Ok(mut inner) => inner.settle_and_take_launches(&mut batch, &mut dropped),
                Err(_) => return,
            }
            // Cancelled before their poll: dropped unpolled, outside the lock, and reported stopped.
            if !dropped.is_empty() {
                for (job, fut) in dropped.drain(..) {
                    drop(fut);
                    let _ = push(|st| st.done.push(Ended::Dropped(job)));
                }
            }
            if batch.is_empty() {
                if self.idle() {
                    return;
                }
                continue;
            }
            // In start order: reversed, then popped (cheaper than a drain for a batch of one).
            batch.reverse();
            let mut stale = false;
            while let Some((job, mut fut)) = batch.pop() {
                // Polled as a task would be: with no budget taken from the task that ended.
                let once = tokio::task::unconstrained(CatchUnwind(fut.as_mut()));
                let (kept, to_drop) = match std::pin::pin!(once).poll(&mut cx) {
                    Poll::Ready(res) => push(|st| st.done.push(Ended::Returned(job, res))),
                    Poll::Pending => push(|st| st.pending.push((job, fut))),
                };
                // A wide batch reports its ends every `REPORT_EVERY`, as if one of its futures
                // touched the engine: what they start is polled after this batch all the same,
                // and the ends kept stay few (and in the cache) however wide the batch.
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
                p.as_ref()
                    .is_none_or(|st| st.done.is_empty() && st.pending.is_empty())
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

/// Hands `f` the pump of this thread; returns how many ends and pending futures it then keeps,
/// and whether a flush left it futures to drop (`Guard::drop_stale`).
fn push(f: impl FnOnce(&mut PumpState)) -> (usize, bool) {
    PUMP.with(|p| {
        let Ok(mut p) = p.try_borrow_mut() else {
            return (0, false);
        };
        p.as_mut().map_or((0, false), |st| {
            f(st);
            (st.done.len() + st.pending.len(), !st.to_drop.is_empty())
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
    use crate::{Failure, Handler, Monitor, NodeKind, NodeRef, Runtime, Task};
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

    fn trace_of(rt: Runtime, task: Task) -> Vec<String> {
        let run = async { Ok::<_, crate::Error>(run_checked_allowing_panics(rt, task).await) };
        let (_, trace) = crate::block_on_virtual(run).expect("a tokio runtime");
        lines(&trace)
    }

    #[test]
    fn each_program_gives_the_same_trace_with_and_without_the_pump() {
        type Program = (&'static str, fn() -> Task);
        let programs: [Program; 5] = [
            ("tie", tie),
            ("waits", waits),
            ("failures", failures),
            ("terminations", terminations),
            ("monitor", monitor),
        ];
        for (name, program) in programs {
            let pumped = trace_of(Runtime::new(), program());
            let tasks = trace_of(Runtime::new().without_pump(), program());
            assert!(pumped.len() > 10, "{name}: a real trace");
            assert_eq!(pumped, tasks, "{name}: the same trace");
        }
    }

    /// A batch in which one action wakes another that awaits: `b` (released with `a`) wakes `w`,
    /// and `a`'s end releases `x`. Plain tasks run `x` before `w`; the pump reports `a`'s end
    /// after polling `b`, so `w`, woken meanwhile, runs first (the limit named in the module's
    /// documentation). Both orders are runs of the same program, and the pumped one is the same
    /// on every run.
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
    fn a_wake_within_a_batch_may_reorder_two_actions_and_the_pumped_trace_is_reproducible() {
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
        let again = trace_of(Runtime::new(), wake_in_batch());
        let tasks = trace_of(Runtime::new().without_pump(), wake_in_batch());
        assert_eq!(pumped, again, "the pumped run is reproducible");
        assert_eq!(
            pumped.len(),
            tasks.len(),
            "the same records, in another order"
        );
        assert_eq!(warnings(&tasks), ["x ran", "w woke"]);
        assert_eq!(warnings(&pumped), ["w woke", "x ran"]);
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

    /// The second limit of the pump, found with the program above: when actions of a wide
    /// release are terminated, the stops of the terminated sleepers are reported after the ends
    /// of a chain the pump ran meanwhile, where with every action a task they come before. Both
    /// orders are runs of the same program (the same records, every trace through the checker),
    /// and the pumped one is the same on every run. Without the terminator, or with 60 children,
    /// the two traces are the same record for record.
    #[test]
    fn terminations_in_a_wide_release_may_reorder_stops_and_the_pumped_trace_is_reproducible() {
        let pumped = trace_of(Runtime::new(), wide_with_terminations());
        let again = trace_of(Runtime::new(), wide_with_terminations());
        let tasks = trace_of(Runtime::new().without_pump(), wide_with_terminations());
        assert!(pumped.len() > 3000, "a real trace: {}", pumped.len());
        assert_eq!(pumped, again, "the pumped run is reproducible");
        let sorted = |t: &[String]| {
            let mut v: Vec<String> = t
                .iter()
                .map(|l| {
                    l.split_once(",\"t\"")
                        .map_or(l.clone(), |(_, rest)| rest.to_string())
                })
                .collect();
            v.sort();
            v
        };
        assert_eq!(
            sorted(&pumped),
            sorted(&tasks),
            "the same records, in another order"
        );
        let stop = |t: &[String]| t.iter().position(|l| l.contains("\"ev\":\"terminated\""));
        let chain_end = |t: &[String]| {
            t.iter()
                .rposition(|l| l.contains("\"ev\":\"reclaimed\"") && l.contains("\"node\":307}"))
        };
        assert!(
            stop(&tasks) < chain_end(&tasks),
            "tasks: the stops come first"
        );
        assert!(
            stop(&pumped) > chain_end(&pumped),
            "pumped: the chain's ends come first"
        );
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
