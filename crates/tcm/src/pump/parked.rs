//! The pump's futures without a task: a future polled once and left pending, parked until its
//! first wake-up ([`Parked`]), and the spare slot whose waker polls each future (`Spare`).

use super::hold_wake;
use crate::host::Shared;
use crate::task::ActionFuture;
use std::cell::RefCell;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::task::{Wake, Waker};
use tcm_core::Job;

/// The slot the pump polls the next future with (its waker), one per thread, kept from one pump
/// to the next: taken by a pump while it runs, and put back when it ends.
pub(super) struct Spare(Option<(Arc<Parked>, Waker)>);

thread_local! {
    static SPARE: RefCell<Option<(Arc<Parked>, Waker)>> = const { RefCell::new(None) };
}

impl Spare {
    pub(super) fn take() -> Spare {
        Spare(SPARE.with(|p| p.try_borrow_mut().ok().and_then(|mut p| p.take())))
    }

    #[inline(always)]
    pub(super) fn slot(&mut self) -> &(Arc<Parked>, Waker) {
        self.0.get_or_insert_with(Parked::spare)
    }

    /// After a poll: when it returned, the slot serves the next poll (`settle`); left pending,
    /// the future is parked in it (`park`).
    #[inline(always)]
    pub(super) fn settle_after<T>(&mut self, poll: &std::task::Poll<T>) {
        if poll.is_ready() {
            self.settle();
        }
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
    pub(super) fn park(
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
