//! Futures whose wake-ups the run counts ([`Tracked`]), so that the pump runs an action inline
//! only when nothing of the run is queued.

use super::hold_wake;
use crate::host::Shared;
use std::future::Future;
use std::pin::Pin;
use std::sync::atomic::{AtomicBool, AtomicU8, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll, Wake, Waker};

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
