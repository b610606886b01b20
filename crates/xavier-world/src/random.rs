//! Seeded randomness: ChaCha8 streams and the few draws the world needs, built from raw `u64`s
//! so that a seed gives the same numbers on every machine and every release of `rand_chacha`
//! (its ChaCha output is specified bit for bit; `rand`'s distributions are not promised stable).

use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::{RngCore, SeedableRng};
use std::time::Duration;

/// Independent random streams of one seed, so that (say) turning traffic off leaves the mail
/// delays unchanged.
pub(crate) mod stream {
    pub(crate) const TRAFFIC: u64 = 0;
    pub(crate) const MAIL: u64 = 1;
    pub(crate) const DOORS: u64 = 2;
    pub(crate) const SENSOR: u64 = 3;
}

/// A ChaCha8 stream of `seed`; identical on every machine and release of `rand_chacha`.
pub(crate) fn rng(seed: u64, stream: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(stream);
    rng
}

/// A uniform draw from `[0, 1)` built from the top 53 bits, with no library distribution involved.
pub(crate) fn unit(rng: &mut ChaCha8Rng) -> f64 {
    (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64
}

/// A uniform duration from `[lo_ms, hi_ms)`, whole milliseconds so that clock sums stay exact.
pub(crate) fn millis_between(rng: &mut ChaCha8Rng, lo_ms: u64, hi_ms: u64) -> Duration {
    Duration::from_millis(lo_ms + (unit(rng) * (hi_ms - lo_ms) as f64) as u64)
}
