//! A planetary lander's day in TDL (`src/day.tdl`), written as a PLEXIL user would plan it
//! (docs/from-plexil.md): the robot's state in state variables, and the plan's steps held while
//! the lander is unhealthy, a step skipped while a value is unknown, a goal repeated while a
//! fault persists with a timeout per try, an invariant, and monitors that stop when the plan is
//! done. No Rust code turns values into events: the world (here a script of telemetry) sets
//! `battery` and `temperature`, the steps set what they learn.
//!
//! ```
//! use lander::{Telemetry, World};
//!
//! let world = World::new(Some(12.5), vec![]);
//! let (report, _trace) = tdl::block_on_virtual(lander::run_day(world.clone(), Telemetry::none()))?;
//! assert_eq!(report.outcome, tdl::RunOutcome::Completed);
//! assert_eq!(world.notes(), ["dug", "sampled"]);
//! # Ok::<(), tdl::Error>(())
//! ```
#![deny(warnings)]

mod world;

pub use world::{Telemetry, World};

use std::time::Duration;
#[allow(unused_imports)]
use tdl::InvariantFailed;
use tdl::{Recorder, Report, Runtime, TraceEvent};

/// Waits `n` seconds of the run's time.
pub async fn seconds(n: u64) {
    tokio::time::sleep(Duration::from_secs(n)).await;
}

/// Generated from `src/day.tdl`.
mod plan {
    use super::*;
    include!(concat!(env!("OUT_DIR"), "/day.rs"));
}

pub use plan::{Day, day};

/// Runs the day with the world's telemetry played at its times, and returns the report and the
/// trace (checked by the trace checker).
pub async fn run_day(
    world: World,
    telemetry: Telemetry,
) -> Result<(Report, Vec<TraceEvent>), tdl::Error> {
    let rec = Recorder::new();
    let rt = Runtime::new().with_sink(rec.clone());
    let feed = telemetry.play(rt.events());
    let report = rt.run(day(world)).await;
    feed.abort();
    let trace = rec.events();
    tdl::testing::assert_checked(&trace);
    Ok((report?, trace))
}
