//! Runs the navigation once on virtual time and prints the servers' log.
//!
//! `cargo run -p nav2 -- [clear|blocked|stuck|bad-path] [--faults FILE] [--trace FILE]`: a clear
//! way (the default), a controller blocked four times (recoveries in turn), one blocked for good
//! (retries run out), an invalid path (no recovery can help). `--faults` injects the faults of a
//! file into the run (docs/semantics.md, "Steering a run"; the format is `tcm::read_faults`'s),
//! `--trace` writes the run's trace as JSON lines.

use nav2::servers::{Nav, NavError};
use std::path::PathBuf;

const USAGE: &str = "usage: nav2 [clear|blocked|stuck|bad-path] [--faults FILE] [--trace FILE]";

fn main() {
    if let Err(e) = run() {
        eprintln!("nav2: {e}");
        std::process::exit(2);
    }
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let mut scenario = None;
    let mut faults = None;
    let mut trace = None;
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--faults" => faults = Some(PathBuf::from(args.next().ok_or(USAGE)?)),
            "--trace" => trace = Some(PathBuf::from(args.next().ok_or(USAGE)?)),
            _ if arg.starts_with('-') || scenario.is_some() => {
                return Err(format!("unexpected `{arg}`; {USAGE}").into());
            }
            _ => scenario = Some(arg),
        }
    }
    let nav = Nav::new(5.0);
    match scenario.as_deref().unwrap_or("clear") {
        "clear" => {}
        "blocked" => nav.fail_controller([NavError::FailedToMakeProgress; 4]),
        "stuck" => nav.fail_controller([NavError::FailedToMakeProgress; 40]),
        "bad-path" => nav.fail_controller([NavError::InvalidPath]),
        other => {
            return Err(format!(
                "unknown scenario `{other}`; use clear, blocked, stuck or bad-path"
            )
            .into());
        }
    }
    let mut rt = tdl::Runtime::new();
    if let Some(path) = &faults {
        for fault in tdl::read_faults(path)? {
            rt = rt.inject(fault);
        }
    }
    if let Some(path) = &trace {
        let file = std::fs::File::create(path)
            .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
        rt = rt.with_sink(tdl::JsonLines(std::io::BufWriter::new(file)));
    }
    let report =
        tdl::block_on_virtual(rt.run(nav2::navigate_to_pose(nav.clone(), nav.recoveries())))?;
    for e in nav.log() {
        println!("{:>7.2}s  {}", e.at.as_secs_f64(), e.what);
    }
    if !report.is_clean() {
        println!("\n{report}");
    }
    Ok(())
}
