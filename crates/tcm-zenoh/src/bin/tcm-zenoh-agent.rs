//! A small agent process, for tests and trials of distribution across processes: it joins a
//! system on 127.0.0.1, offers a few tasks, and prints one line per event on stdout (`ready`,
//! `start <task> <node>`, `cleanup <task> <node>`), until it is killed.
//!
//! Its log (`tracing`: the messages it ignores, a link it cannot use) goes to stderr, filtered by
//! `RUST_LOG` (default `warn`).
//!
//! Usage: `tcm-zenoh-agent <system> <agent> <executive port> [<port>...]` (the other ports: peers
//! on 127.0.0.1 to connect to as well). Offered tasks:
//! - `sleep` (milliseconds): a command that sleeps, then returns the milliseconds;
//! - `echo` (any JSON): a command that returns its arguments;
//! - `noop` (null): a command that returns at once.

use std::io::Write;
use std::time::Duration;
use tcm_zenoh::{Agent, Json, RemoteCtx, RemoteFailure};

fn say(line: &str) {
    let mut out = std::io::stdout().lock();
    // The test reading this may be gone: nothing to do then.
    let _ = writeln!(out, "{line}");
    let _ = out.flush();
}

fn usage() -> ! {
    eprintln!("usage: tcm-zenoh-agent <system> <agent> <executive port> [<port>...]");
    std::process::exit(2)
}

#[tokio::main(flavor = "multi_thread", worker_threads = 2)]
async fn main() {
    tcm_zenoh::log_to_stderr();
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [system, name, ports @ ..] = args.as_slice() else {
        usage()
    };
    let Ok(ports) = ports
        .iter()
        .map(|p| p.parse::<u16>().map(tcm_zenoh::config::endpoint))
        .collect::<Result<Vec<_>, _>>()
    else {
        usage()
    };
    if ports.is_empty() {
        usage()
    }
    let config = match tcm_zenoh::config::peer(&[], &ports) {
        Ok(c) => c,
        Err(e) => {
            eprintln!("tcm-zenoh-agent: {e}");
            std::process::exit(1)
        }
    };
    let agent = Agent::builder(system.clone(), name.clone())
        .command("sleep", |ctx: RemoteCtx, ms: u64| async move {
            say(&format!("start sleep {}", ctx.node()));
            tokio::time::sleep(Duration::from_millis(ms)).await;
            Ok::<_, RemoteFailure>(ms)
        })
        .on_terminate("sleep", |ms: u64| async move {
            say(&format!("cleanup sleep {ms}"));
        })
        .command("echo", |ctx: RemoteCtx, v: Json| async move {
            say(&format!("start echo {}", ctx.node()));
            Ok::<_, RemoteFailure>(v)
        })
        .command("noop", |_: RemoteCtx, (): ()| async {
            Ok::<_, RemoteFailure>(())
        })
        .start(config)
        .await;
    let _agent = match agent {
        Ok(a) => a,
        Err(e) => {
            eprintln!("tcm-zenoh-agent: {e}");
            std::process::exit(1)
        }
    };
    say("ready");
    std::future::pending::<()>().await;
}
