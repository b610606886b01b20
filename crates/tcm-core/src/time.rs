//! Virtual time of the core: nanoseconds since the run started.
//!
//! The core never reads a clock. The shell (`tcm`) maps tokio's clock, real or paused, onto [`Time`]
//! and passes it with every input, so the same inputs always give the same trace.

use std::fmt;
use std::ops::{Add, Sub};
use std::time::Duration;

/// A point in virtual time, in nanoseconds since the start of the run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Time(u64);

impl Time {
    /// The start of the run.
    pub const ZERO: Time = Time(0);
    /// A time that never comes.
    pub const NEVER: Time = Time(u64::MAX);

    /// Builds a time from nanoseconds since the start of the run.
    pub const fn from_nanos(ns: u64) -> Time {
        Time(ns)
    }

    /// Nanoseconds since the start of the run.
    pub const fn as_nanos(self) -> u64 {
        self.0
    }

    /// The time elapsed since the start of the run.
    pub fn since_start(self) -> Duration {
        Duration::from_nanos(self.0)
    }

    /// `self + d`, saturating at [`Time::NEVER`].
    pub fn saturating_add(self, d: Duration) -> Time {
        let ns = u64::try_from(d.as_nanos()).unwrap_or(u64::MAX);
        Time(self.0.saturating_add(ns))
    }
}

impl Add<Duration> for Time {
    type Output = Time;
    fn add(self, d: Duration) -> Time {
        self.saturating_add(d)
    }
}

impl Sub for Time {
    type Output = Duration;
    fn sub(self, earlier: Time) -> Duration {
        Duration::from_nanos(self.0.saturating_sub(earlier.0))
    }
}

impl fmt::Display for Time {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let d = self.since_start();
        write!(f, "{}.{:09}s", d.as_secs(), d.subsec_nanos())
    }
}

/// A shell's clock as the engine reads it when it needs the time ([`crate::Engine::with_clock`]):
/// the engine stays free of I/O, the shell says how time is read.
pub type Clock = std::sync::Arc<dyn Fn(u64) -> Time + Send + Sync>;
