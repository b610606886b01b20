//! The runtime's one source of time: tokio's clock (paused in tests, for virtual time) read as the
//! engine's [`Time`] since the run's start, and back.

use std::sync::OnceLock;
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
}

impl Clock {
    /// A clock whose time zero is its first reading.
    pub(crate) fn new() -> Clock {
        Clock {
            origin: OnceLock::new(),
        }
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

    /// The engine's time now.
    pub(crate) fn now(&self) -> Time {
        let d = Instant::now().saturating_duration_since(self.origin().0);
        Time::from_nanos(u64::try_from(d.as_nanos()).unwrap_or(u64::MAX))
    }

    /// The instant of the engine's time `t`, for tokio's timers.
    pub(crate) fn instant(&self, t: Time) -> Instant {
        self.origin().0 + t.since_start()
    }

    /// The engine's time of the next `secs` seconds after midnight (UTC) on the wall clock: today's,
    /// or now if that moment has passed (see [`crate::Ctx::time_of_day`]).
    pub(crate) fn time_of_day(&self, secs: f64) -> Time {
        const DAY: f64 = 86_400.0;
        let now = self.now();
        let wall = self.origin().1 + now.since_start();
        let since_epoch = wall
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0.0, |d| d.as_secs_f64());
        let today = since_epoch - since_epoch.rem_euclid(DAY);
        let ahead = (today + secs.clamp(0.0, DAY) - since_epoch).max(0.0);
        now + Duration::from_secs_f64(ahead)
    }
}
