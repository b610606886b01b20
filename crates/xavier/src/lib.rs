//! Xavier, the mail-delivery robot of the TDL paper (Simmons & Apfelbaum 1998), delivering mail on
//! the simulated office floor of `xavier-world`: the mission written in TDL, a live task-tree view,
//! and the summary of a run read back from its trace. The `xavier` binary is the demo.
//!
//! - [`mission`]: the mission in TDL (`src/mission.tdl`: goals, commands, the two monitors and the
//!   exception handlers) and the state its tasks share.
//! - [`robot`]: the robot the mission commands: the world in this process, or a robot agent's in
//!   another (`xavier --distributed`, docs/distributed.md), with the robot agent's side.
//! - [`run`]: one mission on a fresh world, with any trace sinks; [`Setup`] says which;
//!   [`run_steered`], one a viewer can steer.
//! - [`display`]: the live tree (redrawn in place on a terminal) and the plain event log.
//! - [`summary`]: rooms delivered, rooms given up and why, exceptions and how each was handled.
//!
//! ```
//! use xavier::{Setup, run};
//! use xavier_world::Scenario;
//!
//! let setup = Setup { seed: 1, scenario: Scenario::Nominal, rooms: vec![3] };
//! let rec = tdl::Recorder::new();
//! let done = tdl::block_on_virtual(run(&setup, vec![Box::new(rec.clone())]))?;
//! let summary = xavier::summary::Summary::new(&setup, &done, &rec.events());
//! assert_eq!(summary.delivered, [3]);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![warn(missing_docs)]

pub mod display;
pub mod mission;
pub mod robot;
pub mod summary;

use mission::Mission;
use std::time::Duration;
use tdl::{Report, Runtime, TraceEvent, TraceSink};
use xavier_world::{Scenario, SharedWorld, World};

/// The rooms of the default round.
pub const DEFAULT_ROOMS: [u32; 3] = [3, 7, 12];

/// What to run: the world's seed and scenario, and the rooms to deliver to, in order.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Setup {
    /// Seed of the world's randomness (traffic, pickup delays, door positions, sensor noise).
    pub seed: u64,
    /// What is special about the floor.
    pub scenario: Scenario,
    /// The rooms, in delivery order.
    pub rooms: Vec<u32>,
}

impl Default for Setup {
    fn default() -> Setup {
        Setup {
            seed: 1,
            scenario: Scenario::Nominal,
            rooms: DEFAULT_ROOMS.to_vec(),
        }
    }
}

/// A finished run: the runtime's report and the mission's state at the end.
#[derive(Clone, Debug)]
pub struct Done {
    /// How the run ended and how long it took (simulated time on a paused clock).
    pub report: Report,
    /// The mission's shared state (world and log) as the run left it.
    pub mission: Mission,
}

/// Runs the mission of `setup` on a fresh world, with `sinks` receiving the trace, on the current
/// tokio runtime (paused clock: virtual time).
pub async fn run(setup: &Setup, sinks: Vec<Box<dyn TraceSink>>) -> Result<Done, tdl::Error> {
    let world = SharedWorld::new(World::new(setup.seed, setup.scenario));
    run_in(setup, Mission::new(world), sinks).await
}

/// Like [`run`], in a given mission (so a display can watch its world).
pub async fn run_in(
    setup: &Setup,
    mission: Mission,
    sinks: Vec<Box<dyn TraceSink>>,
) -> Result<Done, tdl::Error> {
    run_scaled(setup, mission, sinks, 1.0).await
}

/// Like [`run_in`], on a run clock `scale` times as fast as tokio's (`Runtime::time_scale`): on
/// the real clock, a simulation faster than real time; the mission's world must be made with the
/// same scale (`SharedWorld::scaled`).
pub async fn run_scaled(
    setup: &Setup,
    mission: Mission,
    sinks: Vec<Box<dyn TraceSink>>,
    scale: f64,
) -> Result<Done, tdl::Error> {
    run_journaled(setup, mission, sinks, scale, None).await
}

/// A run's journal (docs/semantics.md, "Durable runs"): written from the start, or read to
/// resume the run it recorded and written on.
pub struct Journaling {
    writer: tcm_journal::Writer,
    resume: Option<tcm_journal::Journal>,
}

impl Journaling {
    /// A new journal, `writer`'s.
    pub fn new(writer: tcm_journal::Writer) -> Journaling {
        Journaling {
            writer,
            resume: None,
        }
    }

    /// The run `journal` recorded, resumed, its journal going on through `writer`
    /// (`tcm_journal::Writer::reopen`).
    pub fn resume(writer: tcm_journal::Writer, journal: tcm_journal::Journal) -> Journaling {
        Journaling {
            writer,
            resume: Some(journal),
        }
    }

    /// The journal resumed, if the run resumes one.
    pub fn resumed(&self) -> Option<&tcm_journal::Journal> {
        self.resume.as_ref()
    }
}

/// Like [`run_scaled`], with a journal of the run's inputs when `journaling` is given, or resumed
/// from one. The tree should run on a current-thread runtime then (docs/semantics.md, "Durable
/// runs").
pub async fn run_journaled(
    setup: &Setup,
    mission: Mission,
    sinks: Vec<Box<dyn TraceSink>>,
    scale: f64,
    journaling: Option<Journaling>,
) -> Result<Done, tdl::Error> {
    let mut rt = Runtime::new().time_scale(scale);
    if let Some(j) = journaling {
        rt = rt.journal(j.writer);
        if let Some(journal) = j.resume {
            rt = rt.resume(journal);
        }
    }
    for sink in sinks {
        rt = rt.with_sink(BoxedSink(sink));
    }
    let report = rt
        .run(mission::deliver_all(mission.clone(), setup.rooms.clone()))
        .await?;
    Ok(Done { report, mission })
}

/// Like [`run_scaled`], through a [`tdl::Session`], for a run steered from outside: `steer` is
/// given the run's control handle before the mission is spawned (to hand it to a viewer, add
/// approval rules, pause the run before its first start), then the mission runs to its end.
pub async fn run_steered<E: From<tdl::Error>>(
    setup: &Setup,
    mission: Mission,
    sinks: Vec<Box<dyn TraceSink>>,
    scale: f64,
    steer: impl FnOnce(&tdl::Control) -> Result<(), E>,
) -> Result<Done, E> {
    let mut rt = Runtime::new().time_scale(scale);
    for sink in sinks {
        rt = rt.with_sink(BoxedSink(sink));
    }
    let session = rt.start()?;
    steer(&session.control())?;
    session.spawn(mission::deliver_all(mission.clone(), setup.rooms.clone()))?;
    let report = session.finish().await?;
    Ok(Done { report, mission })
}

struct BoxedSink(Box<dyn TraceSink>);

impl TraceSink for BoxedSink {
    fn record(&mut self, ev: &TraceEvent) {
        self.0.record(ev);
    }
    fn flush(&mut self) {
        self.0.flush();
    }
}

/// `d` as seconds with one decimal, e.g. `152.3 s`.
pub fn secs(d: Duration) -> String {
    format!("{:.1} s", d.as_secs_f64())
}
