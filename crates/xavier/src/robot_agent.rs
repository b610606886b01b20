//! `xavier robot-agent`: the robot agent of `xavier --distributed` (docs/distributed.md, "The
//! distributed Xavier"), the same binary in another mode, so the demo always finds it. It holds the simulated world of a seed and scenario, joins the system on
//! 127.0.0.1 as the agent `robot`, offers the robot's commands and answers the mission's queries
//! (`xavier::robot::serve`, `serve_queries`). It prints `ready` once it serves, and exits when its
//! standard input closes (the demo that started it ended, however it ended), printing what it did
//! (`agent: started N, …`). Started apart (`--listen`), it holds the commands of an executive that
//! went for `--hold` seconds, for the executive to come back and re-attach to them.

use clap::Parser;
use std::io::{Read, Write};
use std::process::ExitCode;
use tcm_zenoh::Agent;
use xavier_world::{Scenario, SharedWorld, World};

/// The robot agent of `xavier --distributed`: the simulated world, served over zenoh on
/// 127.0.0.1.
#[derive(Parser, Debug)]
#[command(name = "xavier robot-agent", version)]
pub(crate) struct Cli {
    /// The system to join.
    #[arg(long)]
    system: String,
    /// The agent's name.
    #[arg(long, default_value = "robot")]
    name: String,
    /// The executive's port on 127.0.0.1, if it listens (without it, give --listen: executives
    /// connect to the agent).
    #[arg(long, required_unless_present = "listen")]
    port: Option<u16>,
    /// How long, in seconds of the real clock, the commands of an executive that went keep
    /// running for it to come back, resumed from its journal, and re-attach to them
    /// (docs/distributed.md, "An executive that comes back").
    #[arg(long, default_value_t = 30.0)]
    hold: f64,
    /// A port on 127.0.0.1 to listen on, for agents that query the world (the voice).
    #[arg(long)]
    listen: Option<u16>,
    /// The world's seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// The world's scenario (nominal, blocked-corridor, no-path, overheat).
    #[arg(long, default_value = "nominal")]
    scenario: Scenario,
    /// World seconds per second of the real clock (the executive's time scale).
    #[arg(long, default_value_t = 1.0)]
    speed: f64,
}

/// Runs the robot agent with the command line `args` (after `robot-agent`).
pub(crate) fn main(args: impl Iterator<Item = std::ffi::OsString>) -> ExitCode {
    let cli = Cli::parse_from(std::iter::once("xavier robot-agent".into()).chain(args));
    let rt = match tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
    {
        Ok(rt) => rt,
        Err(e) => {
            eprintln!("xavier robot-agent: cannot start the tokio runtime: {e}");
            return ExitCode::FAILURE;
        }
    };
    match rt.block_on(serve(cli)) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("xavier robot-agent: {e}");
            ExitCode::FAILURE
        }
    }
}

async fn serve(cli: Cli) -> Result<(), String> {
    let world = SharedWorld::scaled(World::new(cli.seed, cli.scenario), cli.speed);
    use tcm_zenoh::config::endpoint;
    let listen: Vec<String> = cli.listen.map(endpoint).into_iter().collect();
    let connect: Vec<String> = cli.port.map(endpoint).into_iter().collect();
    let config = tcm_zenoh::config::peer(&listen, &connect).map_err(|e| e.to_string())?;
    let hold = std::time::Duration::try_from_secs_f64(cli.hold)
        .map_err(|e| format!("--hold {}: {e}", cli.hold))?;
    let builder =
        xavier::robot::serve(&world, Agent::builder(cli.system.clone(), cli.name)).hold(hold);
    let agent = builder.start(config).await.map_err(|e| e.to_string())?;
    let _queries = xavier::robot::serve_queries(agent.session(), &cli.system, &world, cli.speed)
        .await
        .map_err(|e| e.to_string())?;
    {
        let mut out = std::io::stdout().lock();
        // The demo reading this may be gone: it then closes our stdin too.
        let _ = writeln!(out, "ready");
        let _ = out.flush();
    }
    // Until stdin closes: the demo holds its end for as long as it runs.
    let (tx, rx) = tokio::sync::oneshot::channel::<()>();
    std::thread::spawn(move || {
        let mut sink = [0u8; 64];
        let mut stdin = std::io::stdin();
        while matches!(stdin.read(&mut sink), Ok(n) if n > 0) {}
        let _ = tx.send(());
    });
    let _ = rx.await;
    // What the agent did, for a person or a test reading it: bodies started, re-attached by an
    // executive that came back, and aborted for want of one.
    let stats = agent.stats();
    {
        let mut out = std::io::stdout().lock();
        let _ = writeln!(
            out,
            "agent: started {}, ended {}, cancelled {}, reattached {}, orphaned {}, duplicates {}",
            stats.started,
            stats.ended,
            stats.cancelled,
            stats.reattached,
            stats.orphaned,
            stats.duplicates
        );
        let _ = out.flush();
    }
    agent.close().await;
    Ok(())
}
