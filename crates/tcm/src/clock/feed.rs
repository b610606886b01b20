//! The journal as the run's clock while it replays ([`Feed`]; `replay.rs`, rule 2): each reading
//! of the clock the run took is given back at the same step.

use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use tcm_core::Time;
use tcm_journal::{Entry, Input};

/// What an entry is to the feed.
#[derive(Clone, Copy)]
pub(crate) enum Entered {
    // Its time, and the run's steps when it was read.
    Reading(u64, u64),
    Aside,
    Input,
}

/// The journal as the run's clock while it replays (rule 2).
pub(crate) struct Feed {
    pub(crate) replaying: AtomicBool,
    state: Mutex<FeedState>,
}

struct FeedState {
    // Each entry: a clock reading (its time), an entry no input (a body's recorded value), or an
    // input; by entry number.
    readings: Vec<Entered>,
    // The next entry.
    pos: usize,
    // The latest time given.
    latest: u64,
    // Readings the replay took that the journal does not have there, and the reverse.
    extra: u64,
    missed: u64,
}

impl Feed {
    pub(crate) fn new(entries: &[Entry]) -> Feed {
        Feed {
            replaying: AtomicBool::new(true),
            state: Mutex::new(FeedState {
                readings: entries
                    .iter()
                    .map(|e| match e.input {
                        Input::Clock => Entered::Reading(e.t, e.at),
                        // The replay's body gives it again.
                        _ if e.body => Entered::Aside,
                        Input::Recorded { .. } => Entered::Aside,
                        _ => Entered::Input,
                    })
                    .collect(),
                pos: 0,
                latest: 0,
                extra: 0,
                missed: 0,
            }),
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, FeedState> {
        self.state
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// The latest time given, while replaying.
    pub(crate) fn latest(&self) -> Option<Time> {
        if !self.replaying.load(Ordering::Relaxed) {
            return None;
        }
        Some(Time::from_nanos(self.lock().latest))
    }

    /// The engine's reading at its `steps`, while replaying: the journal's next, if it is a
    /// reading the run took at as many steps; the readings of earlier steps before it, which the
    /// replay did not take, are passed (their times count). A reading the journal does not have
    /// there gives the latest time.
    pub(crate) fn reading(&self, steps: u64) -> Option<Time> {
        if !self.replaying.load(Ordering::Relaxed) {
            return None;
        }
        let mut s = self.lock();
        let mut pos = s.pos;
        loop {
            match s.readings.get(pos).copied() {
                Some(Entered::Aside) => pos += 1,
                Some(Entered::Reading(t, at)) if at < steps => {
                    s.missed += 1;
                    s.latest = s.latest.max(t);
                    pos += 1;
                    s.pos = pos;
                }
                Some(Entered::Reading(t, at)) if at == steps => {
                    s.pos = pos + 1;
                    s.latest = s.latest.max(t);
                    break;
                }
                _ => {
                    s.extra += 1;
                    break;
                }
            }
        }
        Some(Time::from_nanos(s.latest))
    }

    /// The next entry that is no reading, from the next entry on; its number.
    pub(crate) fn next_input(&self) -> usize {
        let s = self.lock();
        let mut pos = s.pos;
        while let Some(Entered::Reading(..) | Entered::Aside) = s.readings.get(pos) {
            pos += 1;
        }
        pos
    }

    /// Entry `pos`, at `t`, was given: the readings before it that the replay did not take are
    /// passed (their times count).
    pub(crate) fn given(&self, pos: usize, t: u64) {
        let mut s = self.lock();
        while s.pos < pos {
            if let Some(Entered::Reading(r, _)) = s.readings.get(s.pos).copied() {
                s.missed += 1;
                s.latest = s.latest.max(r);
            }
            s.pos += 1;
        }
        s.pos = pos + 1;
        s.latest = s.latest.max(t);
    }

    /// The replay is over.
    pub(crate) fn stop(&self) -> Time {
        self.replaying.store(false, Ordering::Relaxed);
        Time::from_nanos(self.lock().latest)
    }
}
