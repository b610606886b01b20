//! `xavier`: the TDL paper's mail-delivery robot on a simulated office floor. Runs the mission of
//! `src/mission.tdl` and shows the live task tree, on a multi-threaded runtime with the real clock
//! scaled by `--speed` (or unscaled with `--real-time`); when stdout is not a terminal and no
//! viewer watches, on virtual time as fast as it goes, with a plain event log. Then a summary.
//! With `--view --control`, the run goes through a session whose control handle the viewer gets,
//! so the page can steer it (`--approve TASK`, `--pause-at-start`; docs/viewer.md).
//! With `--distributed`, the robot's commands run in agent processes over zenoh (`distributed.rs`);
//! `xavier robot-agent ...` is the robot agent those runs start (`robot_agent.rs`).

#[cfg(feature = "distributed")]
mod distributed;
#[cfg(feature = "distributed")]
mod robot_agent;

/// Without the feature `distributed`: the agents cannot be started, and the command says how to
/// build them in.
#[cfg(not(feature = "distributed"))]
mod distributed {
    use xavier::Setup;
    use xavier::robot::Robot;

    /// What a distributed run holds (never made in this build).
    pub(crate) struct Distributed {
        pub(crate) robot: Robot,
        pub(crate) voice: String,
        pub(crate) exec: NoExecutive,
    }

    /// No executive: this build has no zenoh.
    pub(crate) struct NoExecutive;

    impl NoExecutive {
        pub(crate) async fn close(&self) {}
        pub(crate) fn resume_from(&self, _journal: &tcm_journal::Journal) {}
    }

    pub(crate) async fn join(_system: &str, _port: u16, _id: &str) -> anyhow::Result<Distributed> {
        start(&Setup::default(), 1.0, false).await
    }

    pub(crate) async fn start(
        _setup: &Setup,
        _speed: f64,
        _python: bool,
    ) -> anyhow::Result<Distributed> {
        anyhow::bail!(
            "this xavier was built without the feature `distributed` (zenoh): run it with \
             `cargo run --release -p xavier --features distributed -- --distributed`"
        )
    }
}

mod durable;

#[cfg(not(feature = "distributed"))]
const NO_AGENT: &str = "xavier: this build has no robot agent (the feature `distributed` is off): \
build it with `--features distributed`";

use anyhow::Context as _;
use clap::{Parser, ValueEnum};
use std::fs::File;
use std::io::{BufWriter, IsTerminal, Write};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;
use tdl::{JsonLines, Recorder, TextLogSink, TraceSink};
use xavier::display::{EventLog, LiveTree};
use xavier::mission::Mission;
use xavier::summary::Summary;
use xavier::{Done, Setup, run_journaled, run_steered};
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

    /// Run on the real clock, unscaled: the run then takes as long as it simulates, about two
    /// minutes for the default round.
    #[arg(long)]
    real_time: bool,

    /// On a terminal or with --view: run on the real clock scaled to this many simulated seconds
    /// per wall second, actions on a multi-threaded runtime (0: on virtual time, as fast as
    /// possible). Ignored with --real-time. When stdout is not a terminal and no viewer watches,
    /// the run is on virtual time, single-threaded and the same on every run, as fast as possible.
    #[arg(long, default_value_t = 40.0)]
    speed: f64,

    /// Write the trace as JSON lines to FILE (docs/trace-format.md).
    #[arg(long, value_name = "FILE")]
    trace: Option<PathBuf>,

    /// Serve the task-tree viewer while the mission runs (and after it, until Ctrl-C): prints the
    /// page's address (http://127.0.0.1:7878/, or a free port if that one is taken). The run is
    /// paced at --speed so it can be watched.
    #[arg(long)]
    view: bool,

    /// With --view: listen on this address instead (a warning is printed when it is not loopback).
    #[arg(long, value_name = "ADDR", requires = "view")]
    listen: Option<std::net::SocketAddr>,

    /// With --view: let the page steer the run (pause, step, breakpoints, injected exceptions,
    /// approvals; docs/viewer.md, "Steering a run"). Prints the page's address with the run's
    /// token in it (`control: http://…`); only a page opened from it can steer.
    #[arg(long, requires = "view")]
    control: bool,

    /// With --control: hold each node of task TASK (as the trace names it, e.g. notify_sender)
    /// until it is approved from the page. May be given several times.
    #[arg(long, value_name = "TASK", requires = "control")]
    approve: Vec<String>,

    /// With --control: pause the run before its first start, until the page continues it.
    #[arg(long, requires = "control")]
    pause_at_start: bool,

    /// Write TCM's text log of the run to FILE.
    #[arg(long, value_name = "FILE")]
    log: Option<PathBuf>,

    /// Run the robot's commands in a separate agent process over zenoh on 127.0.0.1 (started and
    /// stopped by this run), and `speak` in the Python agent when a Python with eclipse-zenoh is
    /// found (docs/distributed.md). Always on the real clock, scaled by --speed.
    #[arg(long)]
    distributed: bool,

    /// With --distributed: serve `speak` from the robot agent, not from Python.
    #[arg(long, requires = "distributed")]
    no_python: bool,

    /// With --distributed: join the robot agent listening on this port of 127.0.0.1 (started
    /// apart, `xavier robot-agent --listen PORT`, and outliving this run) instead of starting
    /// one; `speak` is the robot agent's.
    #[arg(long, value_name = "PORT", requires_all = ["distributed", "system"])]
    agent_port: Option<u16>,

    /// With --agent-port: the system the robot agent joined.
    #[arg(long, value_name = "NAME", requires = "agent_port")]
    system: Option<String>,

    /// With --agent-port: the executive's id, the same for a run and its resumption, so that the
    /// robot agent lets the resumed run re-attach to the commands it holds.
    #[arg(
        long,
        value_name = "ID",
        default_value = "xavier",
        requires = "agent_port"
    )]
    exec_id: String,

    /// With --agent-port: keep a journal of the run's inputs in FILE (a new file), to resume it
    /// after a crash (docs/semantics.md, "Durable runs").
    #[arg(
        long,
        value_name = "FILE",
        requires = "agent_port",
        conflicts_with = "resume"
    )]
    journal: Option<PathBuf>,

    /// With --agent-port: resume the run this journal recorded after the executive crashed, with
    /// the seed, scenario and rooms it was started with; commands still running on the robot
    /// agent are re-attached, and the journal goes on.
    #[arg(long, value_name = "FILE", requires = "agent_port")]
    resume: Option<PathBuf>,

    /// How the journal reaches the disk: `every` record synced, `group:MS`, or `acting:MS` (group
    /// commit, and everything synced before a command starts or is cancelled).
    #[arg(long, value_name = "HOW", default_value = "every")]
    journal_sync: String,
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

/// The clock a run is on.
#[derive(Clone, Copy, Debug)]
enum Clock {
    /// Tokio's real clock, the run's time this many times as fast.
    Real(f64),
    /// Tokio's paused clock: virtual time, single-threaded.
    Virtual,
}

fn create(path: &PathBuf) -> anyhow::Result<BufWriter<File>> {
    let file = File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
    Ok(BufWriter::new(file))
}

fn main() -> ExitCode {
    // tcm-zenoh's warnings, for this process and the robot agent alike.
    #[cfg(feature = "distributed")]
    tcm_zenoh::log_to_stderr();
    if std::env::args_os()
        .nth(1)
        .is_some_and(|a| a == "robot-agent")
    {
        #[cfg(feature = "distributed")]
        return robot_agent::main(std::env::args_os().skip(2));
        #[cfg(not(feature = "distributed"))]
        {
            eprintln!("{NO_AGENT}");
            return ExitCode::FAILURE;
        }
    }
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
    let stdout = std::io::stdout();
    // Watched runs (a terminal, the viewer) go at --speed on the real clock, with real
    // concurrency; the others on virtual time (docs/semantics.md, "Time").
    let watched = stdout.is_terminal() || cli.view;
    if cli.distributed && !cli.real_time && cli.speed <= 0.0 {
        anyhow::bail!("--distributed runs on the real clock: give --speed above 0");
    }
    let clock = if cli.real_time {
        Clock::Real(1.0)
    } else if (watched || cli.distributed) && cli.speed > 0.0 {
        Clock::Real(cli.speed)
    } else {
        Clock::Virtual
    };
    let scale = match clock {
        Clock::Real(scale) => scale,
        Clock::Virtual => 1.0,
    };
    let rt = match clock {
        Clock::Real(_) => Some(
            tokio::runtime::Builder::new_multi_thread()
                .enable_all()
                .build()
                .context("cannot start the tokio runtime")?,
        ),
        Clock::Virtual => None,
    };
    let world = SharedWorld::scaled(World::new(setup.seed, setup.scenario), scale);
    let dist = match (&rt, cli.distributed, cli.agent_port) {
        (Some(rt), true, Some(port)) => {
            let system = cli.system.clone().unwrap_or_default();
            Some(rt.block_on(distributed::join(&system, port, &cli.exec_id))?)
        }
        (Some(rt), true, None) => {
            Some(rt.block_on(distributed::start(&setup, scale, !cli.no_python))?)
        }
        _ => None,
    };
    let journaling = durable::journaling(&cli.journal, &cli.resume, &cli.journal_sync, &setup)?;
    if let (Some(d), Some(j)) = (&dist, &journaling) {
        if let Some(journal) = j.resumed() {
            d.exec.resume_from(journal);
        }
    }
    let mission = match &dist {
        Some(d) => Mission::with_robot(d.robot.clone()),
        None => Mission::new(world.clone()),
    };
    let recorder = Recorder::new();
    let mut sinks: Vec<Box<dyn TraceSink>> = vec![Box::new(recorder.clone())];
    if let Some(path) = &cli.trace {
        sinks.push(Box::new(JsonLines(create(path)?)));
    }
    if let Some(path) = &cli.log {
        sinks.push(Box::new(TextLogSink::new(create(path)?)));
    }
    let clock_name = match clock {
        Clock::Real(scale) => {
            if scale == 1.0 {
                "real time".to_owned()
            } else {
                format!("real time ×{scale}")
            }
        }
        Clock::Virtual => "virtual time".to_owned(),
    };
    let mut title = format!(
        "Xavier delivers mail: seed {}, scenario {}, rooms {:?}, {clock_name}",
        setup.seed, setup.scenario, setup.rooms
    );
    if let Some(d) = &dist {
        title.push_str(&format!(", distributed: {}", d.voice));
    }
    let viewer = if cli.view {
        if let Some(warning) = cli.listen.as_ref().and_then(tcm_view::exposure_warning) {
            eprintln!("xavier: {warning}");
        }
        let viewer = tcm_view::Viewer::start(cli.listen)?;
        println!("viewer: {}", viewer.url());
        let live = viewer.live(title.clone());
        let id = live.id();
        sinks.push(Box::new(live));
        Some((viewer, id))
    } else {
        None
    };
    if stdout.is_terminal() && dist.is_none() {
        // The clock paces the run: the tree need not. (A distributed run's world is in the
        // robot agent: it gets the event log.)
        sinks.push(Box::new(LiveTree::new(
            stdout,
            title,
            world,
            setup.rooms.clone(),
            None,
        )));
    } else {
        println!("{title}");
        sinks.push(Box::new(EventLog::new(stdout)));
    }

    let wall = Instant::now();
    let future: std::pin::Pin<Box<dyn Future<Output = anyhow::Result<Done>> + '_>> =
        match (&viewer, cli.control) {
            (Some((viewer, id)), true) => {
                let (approve, pause) = (&cli.approve, cli.pause_at_start);
                let before =
                    move |control: &tdl::Control| steer(approve, pause, viewer, *id, control);
                Box::pin(run_steered(&setup, mission, sinks, scale, before))
            }
            _ => Box::pin(async {
                Ok(run_journaled(&setup, mission, sinks, scale, journaling).await?)
            }),
        };
    // A journaled run drives its tree on one thread, so that the inputs alone decide the order of
    // its bodies' requests (docs/semantics.md, "Durable runs"); zenoh stays on `rt`.
    let future: std::pin::Pin<Box<dyn Future<Output = anyhow::Result<Done>> + '_>> =
        match (&rt, durable::one_thread(&cli.journal, &cli.resume)) {
            (Some(_), true) => {
                let tree = tokio::runtime::Builder::new_current_thread()
                    .enable_all()
                    .build()
                    .context("cannot start the tree's runtime")?;
                let done = tree.block_on(future);
                drop(tree);
                Box::pin(async move { done })
            }
            _ => future,
        };
    let done = match &rt {
        Some(rt) => rt.block_on(async {
            let done = future.await?;
            if let Some(d) = &dist {
                // The world is the robot agent's: what it achieved is read from there.
                if let Err(e) = done.mission.robot.fetch_summary().await {
                    eprintln!("xavier: cannot read the robot's summary: {e}");
                }
                d.exec.close().await;
            }
            Ok::<_, anyhow::Error>(done)
        }),
        None => tdl::block_on_virtual(future),
    }
    .context("the runtime failed")?;
    let wall = wall.elapsed();
    // The agent processes are stopped.
    drop(dist);

    let summary = Summary::new(&setup, &done, &recorder.events());
    let mut out = std::io::stdout().lock();
    writeln!(out)?;
    writeln!(out, "{summary}")?;
    writeln!(out, "  wall time:       {:.3} s", wall.as_secs_f64())?;
    out.flush()?;
    if !summary.ok() {
        eprintln!("xavier: the run did not complete: {:?}", summary.outcome);
    }
    if let Some((viewer, _)) = viewer {
        println!(
            "viewer: the run is over; its page stays at {} until Ctrl-C",
            viewer.url()
        );
        std::io::stdout().flush()?;
        viewer.wait();
    }
    Ok(summary.ok())
}

/// Before the mission starts (`--control`): the approval rules and the pause asked for, and the
/// run handed to the viewer, whose steering address is printed.
fn steer(
    approve: &[String],
    pause_at_start: bool,
    viewer: &tcm_view::Viewer,
    run: usize,
    control: &tdl::Control,
) -> anyhow::Result<()> {
    for task in approve {
        let rule = tdl::Approval {
            on: tdl::Matcher::Task(task.clone().into()),
            timeout: None,
        };
        control.require_approval(rule, "xavier --approve")?;
    }
    if pause_at_start {
        control.pause("xavier --pause-at-start")?;
    }
    viewer.steer(run, control.clone())?;
    let url = viewer
        .control_url(run)
        .context("the viewer lost the run's control")?;
    println!("control: {url}");
    std::io::stdout().flush()?;
    Ok(())
}
