//! The polls of actions the replay's inputs wait for ([`ActionPoll`], rule 3); the journal as
//! the run's clock while it replays is the clock's (`clock/feed.rs`, rule 2).

use crate::host::Shared;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

/// Whether some replay ran in this process: only then do actions' polls mark themselves.
pub(super) static REPLAYS: AtomicBool = AtomicBool::new(false);

thread_local! {
    // How deep this thread is in polls of actions, and the run whose inputs wait for the end of
    // the outermost one.
    static IN_ACTION: std::cell::Cell<u32> = const { std::cell::Cell::new(0) };
    static WAITING: std::cell::RefCell<Option<Arc<Shared>>> = const { std::cell::RefCell::new(None) };
}

/// The poll of an action, while a replay runs: the inputs the run has come to wait for its end,
/// as in the run, where an input came between polls, never in the middle of one (rule 3).
pub(crate) struct ActionPoll(bool);

impl ActionPoll {
    #[inline(always)]
    pub(crate) fn begin() -> ActionPoll {
        if !REPLAYS.load(Ordering::Relaxed) {
            return ActionPoll(false);
        }
        IN_ACTION.with(|d| d.set(d.get() + 1));
        ActionPoll(true)
    }
}

impl Drop for ActionPoll {
    fn drop(&mut self) {
        if !self.0 {
            return;
        }
        let outermost = IN_ACTION.with(|d| {
            d.set(d.get().saturating_sub(1));
            d.get() == 0
        });
        if !outermost {
            return;
        }
        if let Some(shared) = WAITING.with(|w| w.borrow_mut().take()) {
            // An access ends with its effects carried out, and so the inputs given.
            drop(shared.enter());
        }
    }
}

/// Whether an action is being polled on this thread (then `shared`'s inputs wait for its end).
pub(super) fn in_action(shared: &Arc<Shared>) -> bool {
    if IN_ACTION.with(|d| d.get()) == 0 {
        return false;
    }
    WAITING.with(|w| *w.borrow_mut() = Some(shared.clone()));
    true
}
