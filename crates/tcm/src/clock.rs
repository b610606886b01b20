//! The runtime's one source of time: tokio's clock (paused in tests, for virtual time) read as the
//! engine's [`Time`] since the run's start, and back; optionally scaled, so that a simulation runs
//! faster than real time on the real clock (`Runtime::time_scale`). While a run replays its
//! journal (`replay.rs`), the journal is its clock: the engine's readings are the journal's, in
//! order, and the shell reads the latest; after it, a resumed run's time goes on from the
//! journal's last.

mod feed;

pub(crate) use feed::Feed;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::{Duration, SystemTime};
use tcm_core::Time;
use tokio::time::Instant;

/// The clock of one run. Every reading and every deadline of the runtime goes through it.
///
/// Its time zero is taken on the first reading, which the runtime makes when the run starts,
/// inside the tokio runtime that drives it: a `Runtime` made before that runtime existed (as in
/// `block_on_virtual(run(Runtime::new(), …))`) would otherwise count the real time between the two
/// into every virtual time, and two runs of one program would differ by microseconds.
pub(crate) struct Clock {
    // Tokio's instant and the wall clock at time zero (the wall clock for times of day).
    origin: OnceLock<(Instant, SystemTime)>,
    // The run's time per unit of tokio's time (an `f64`'s bits; 1 unless `Runtime::time_scale`
    // set it before the run started).
    scale: AtomicU64,
    // The journal a replay reads its time from, while it replays (`replay.rs`).
    feed: OnceLock<Arc<Feed>>,
    // Nanoseconds added to tokio's time since time zero: a resumed run goes on from its journal's
    // last time.
    offset: AtomicU64,
}

impl Clock {
    /// A clock whose time zero is its first reading.
    pub(crate) fn new() -> Clock {
        Clock {
            origin: OnceLock::new(),
            scale: AtomicU64::new(1f64.to_bits()),
            feed: OnceLock::new(),
            offset: AtomicU64::new(0),
        }
    }

    /// Runs the clock `scale` times as fast as tokio's (a finite, positive number).
    pub(crate) fn set_scale(&self, scale: f64) {
        if scale.is_finite() && scale > 0.0 {
            self.scale.store(scale.to_bits(), Ordering::Relaxed);
        }
    }

    fn scale(&self) -> f64 {
        f64::from_bits(self.scale.load(Ordering::Relaxed))
    }

    fn origin(&self) -> (Instant, SystemTime) {
        *self
            .origin
            .get_or_init(|| (Instant::now(), SystemTime::now()))
    }

    /// Fixes time zero now, if no reading did yet (the run starts).
    pub(crate) fn start(&self) {
        self.origin();
    }

    /// Reads the time from `feed` while it replays.
    pub(crate) fn replay_from(&self, feed: Arc<Feed>) {
        let _ = self.feed.set(feed);
    }

    /// The replay ended at the journal's time `last`: the time goes on from it.
    pub(crate) fn go_on_from(&self, last: Time) {
        let raw = self.raw().as_nanos();
        self.offset
            .store(last.as_nanos().saturating_sub(raw), Ordering::Relaxed);
    }

    /// The engine's time now (while a replay runs, the journal's latest).
    pub(crate) fn now(&self) -> Time {
        if let Some(t) = self.feed.get().and_then(|f| f.latest()) {
            return t;
        }
        Time::from_nanos(
            self.raw()
                .as_nanos()
                .saturating_add(self.offset.load(Ordering::Relaxed)),
        )
    }

    /// A reading for the engine (`Engine::set_clock`), at its `steps`: while a replay runs, the
    /// journal's reading of that step.
    pub(crate) fn engine_reading(&self, steps: u64) -> Time {
        if let Some(t) = self.feed.get().and_then(|f| f.reading(steps)) {
            return t;
        }
        self.now()
    }

    /// Tokio's time since time zero, scaled.
    fn raw(&self) -> Time {
        let d = Instant::now().saturating_duration_since(self.origin().0);
        let scale = self.scale();
        let d = if scale == 1.0 { d } else { d.mul_f64(scale) };
        Time::from_nanos(u64::try_from(d.as_nanos()).unwrap_or(u64::MAX))
    }

    /// The instant of the engine's time `t`, for tokio's timers (while a replay runs, now: what
    /// waits for a time of the run waits for no time of tokio's).
    pub(crate) fn instant(&self, t: Time) -> Instant {
        if self.feed.get().is_some_and(|f| f.latest().is_some()) {
            return Instant::now();
        }
        let scale = self.scale();
        let t = t
            .as_nanos()
            .saturating_sub(self.offset.load(Ordering::Relaxed));
        let d = Duration::from_nanos(t);
        let d = if scale == 1.0 { d } else { d.div_f64(scale) };
        self.origin().0 + d
    }

    /// The engine's time of the next `secs` seconds after midnight (UTC) on the wall clock: today's,
    /// or now if that moment has passed (see [`crate::Ctx::time_of_day`]).
    pub(crate) fn time_of_day(&self, secs: f64) -> Time {
        const DAY: f64 = 86_400.0;
        let (origin, wall_origin) = self.origin();
        let now = self.now();
        let wall = wall_origin + Instant::now().saturating_duration_since(origin);
        let since_epoch = wall
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0.0, |d| d.as_secs_f64());
        let today = since_epoch - since_epoch.rem_euclid(DAY);
        let ahead = (today + secs.clamp(0.0, DAY) - since_epoch).max(0.0);
        // Seconds of the wall clock, in the run's time.
        now + Duration::from_secs_f64(ahead * self.scale())
    }
}
