//! `xavier`: the TDL paper's mail-delivery robot on a simulated office floor. Runs the mission of
//! `src/mission.tdl` on virtual time (or real time), shows the live task tree (or, when stdout is
//! not a terminal, a plain event log), then a summary of the run.

use anyhow::Context as _;
use clap::{Parser, ValueEnum};
use std::fs::File;
use std::io::{BufWriter, IsTerminal, Write};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;
use tdl::{JsonLines, Recorder, TextLogSink, TraceSink};
use xavier::display::{EventLog, LiveTree, Pace};
use xavier::mission::Mission;
use xavier::summary::Summary;
use xavier::{Setup, run_in};
use xavier_world::{Scenario, SharedWorld, World};

/// Xavier, the mail-delivery robot of the TDL paper (Simmons & Apfelbaum 1998), on a simulated
/// office floor.
///
/// Runs the mission written in TDL (crates/xavier/src/mission.tdl): for each room, navigate (plan
/// a path, then turns and guarded moves), centre on the door, announce, and wait for the letter to
/// be taken (the paper's Figures 4 and 6), recovering from blocked corridors, unreachable rooms and
/// a hot motor. The live task tree is shown while it runs (a plain event log when stdout is not a
/// terminal), then a summary: rooms delivered, rooms given up and why, every exception and how it
/// was handled, simulated and wall time.
#[derive(Parser, Debug)]
#[command(name = "xavier", version)]
struct Cli {
    /// Seed of the world's randomness (passers-by, pickup delays, door positions, sensor noise);
    /// the same seed gives the same run.
    #[arg(long, default_value_t = 1)]
    seed: u64,

    /// The rooms to deliver to, in order, comma-separated (the floor has rooms 1 to 12).
    #[arg(long, value_delimiter = ',', default_value = "3,7,12",
          value_parser = clap::value_parser!(u32).range(1..=12))]
    rooms: Vec<u32>,

    /// What is special about the floor: nominal (passers-by only), blocked-corridor (a cart blocks
    /// the south corridor: the guarded move fails, the robot detours), no-path (room 12 cannot be
    /// reached: it is given up, the others are delivered), overheat (the motor heats fast: the motor
    /// monitor keeps the base, and motion waits for it, until the motor cools).
    #[arg(long, value_enum, default_value_t = ScenarioArg::Nominal)]
    scenario: ScenarioArg,

    /// Run on the real clock (a multi-threaded tokio runtime) instead of virtual time: the run
    /// then takes as long as it simulates, about two minutes for the default round.
    #[arg(long)]
    real_time: bool,

    /// On virtual time, pace the live tree at this many simulated seconds per wall second (0: as
    /// fast as possible). Ignored with --real-time and when stdout is not a terminal.
    #[arg(long, default_value_t = 40.0)]
    speed: f64,

    /// Write the trace as JSON lines to FILE (docs/trace-format.md).
    #[arg(long, value_name = "FILE")]
    trace: Option<PathBuf>,

    /// Serve the task-tree viewer while the mission runs (and after it, until Ctrl-C): prints the
    /// page's address (http://127.0.0.1:7878/, or a free port if that one is taken). On virtual
    /// time the run is paced at --speed so it can be watched.
    #[arg(long)]
    view: bool,

    /// With --view: listen on this address instead (a warning is printed when it is not loopback).
    #[arg(long, value_name = "ADDR", requires = "view")]
    listen: Option<std::net::SocketAddr>,

    /// Write TCM's text log of the run to FILE.
    #[arg(long, value_name = "FILE")]
    log: Option<PathBuf>,
}

/// The scenarios, as the command line spells them.
#[derive(Clone, Copy, Debug, ValueEnum)]
enum ScenarioArg {
    Nominal,
    BlockedCorridor,
    NoPath,
    Overheat,
}

impl From<ScenarioArg> for Scenario {
    fn from(s: ScenarioArg) -> Scenario {
        match s {
            ScenarioArg::Nominal => Scenario::Nominal,
            ScenarioArg::BlockedCorridor => Scenario::BlockedCorridor,
            ScenarioArg::NoPath => Scenario::NoPath,
            ScenarioArg::Overheat => Scenario::Overheat,
        }
    }
}

fn create(path: &PathBuf) -> anyhow::Result<BufWriter<File>> {
    let file = File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
    Ok(BufWriter::new(file))
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::FAILURE,
        Err(e) => {
            eprintln!("xavier: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// Runs the mission; `Ok(false)` when the run ended stuck, fatal or failed.
fn run(cli: Cli) -> anyhow::Result<bool> {
    let setup = Setup {
        seed: cli.seed,
        scenario: cli.scenario.into(),
        rooms: cli.rooms,
    };
    let world = SharedWorld::new(World::new(setup.seed, setup.scenario));
    let mission = Mission::new(world.clone());
    let recorder = Recorder::new();
    let mut sinks: Vec<Box<dyn TraceSink>> = vec![Box::new(recorder.clone())];
    if let Some(path) = &cli.trace {
        sinks.push(Box::new(JsonLines(create(path)?)));
    }
    if let Some(path) = &cli.log {
        sinks.push(Box::new(TextLogSink::new(create(path)?)));
    }
    let clock = if cli.real_time {
        "real time"
    } else {
        "virtual time"
    };
    let title = format!(
        "Xavier delivers mail: seed {}, scenario {}, rooms {:?}, {clock}",
        setup.seed, setup.scenario, setup.rooms
    );
    let viewer = if cli.view {
        if let Some(warning) = cli.listen.as_ref().and_then(tcm_view::exposure_warning) {
            eprintln!("xavier: {warning}");
        }
        let viewer = tcm_view::Viewer::start(cli.listen)?;
        println!("viewer: {}", viewer.url());
        sinks.push(Box::new(viewer.live(title.clone())));
        Some(viewer)
    } else {
        None
    };
    let stdout = std::io::stdout();
    let paced = !cli.real_time && cli.speed > 0.0;
    if viewer.is_some() && paced && !stdout.is_terminal() {
        sinks.push(Box::new(Pace::new(cli.speed)));
    }
    if stdout.is_terminal() {
        let pace = (!cli.real_time && cli.speed > 0.0).then_some(cli.speed);
        sinks.push(Box::new(LiveTree::new(
            stdout,
            title,
            world,
            setup.rooms.clone(),
            pace,
        )));
    } else {
        println!("{title}");
        sinks.push(Box::new(EventLog::new(stdout)));
    }

    let wall = Instant::now();
    let future = run_in(&setup, mission, sinks);
    let done = if cli.real_time {
        tokio::runtime::Builder::new_multi_thread()
            .enable_all()
            .build()
            .context("cannot start the tokio runtime")?
            .block_on(future)
    } else {
        tdl::block_on_virtual(future)
    }
    .context("the runtime failed")?;
    let wall = wall.elapsed();

    let summary = Summary::new(&setup, &done, &recorder.events());
    let mut out = std::io::stdout().lock();
    writeln!(out)?;
    writeln!(out, "{summary}")?;
    writeln!(out, "  wall time:       {:.3} s", wall.as_secs_f64())?;
    out.flush()?;
    if !summary.ok() {
        eprintln!("xavier: the run did not complete: {:?}", summary.outcome);
    }
    if let Some(viewer) = viewer {
        println!(
            "viewer: the run is over; its page stays at {} until Ctrl-C",
            viewer.url()
        );
        std::io::stdout().flush()?;
        viewer.wait();
    }
    Ok(summary.ok())
}
