//! `ambler [SEED] [ARCS]`: the Ambler walks a terrain drawn from SEED (default 7) with ARCS arcs
//! (default 4) on virtual time, and prints a summary.
#![deny(warnings)]

use ambler::world::{Recovery, Terrain, Walker};
use std::process::ExitCode;

fn main() -> ExitCode {
    let mut args = std::env::args().skip(1);
    let parse = |arg: Option<String>, default: u64, what: &str| -> Result<u64, String> {
        arg.map_or(Ok(default), |a| {
            a.parse().map_err(|e| format!("{what} {a:?}: {e}"))
        })
    };
    let (seed, arcs) = match (parse(args.next(), 7, "seed"), parse(args.next(), 4, "arcs")) {
        (Ok(s), Ok(a)) => (s, a),
        (Err(e), _) | (_, Err(e)) => {
            eprintln!("usage: ambler [SEED] [ARCS]\nerror: {e}");
            return ExitCode::from(2);
        }
    };
    let arcs = u32::try_from(arcs).unwrap_or(u32::MAX).min(100);
    let terrain = Terrain::generate(seed, arcs);
    let steps = terrain.steps();
    let walker = Walker::new(terrain);
    let run = ambler::monitored(&walker).run(ambler::walk(walker.clone()));
    let report = match tdl::block_on_virtual(run) {
        Ok(report) => report,
        Err(e) => {
            eprintln!("error: the run failed: {e}");
            return ExitCode::FAILURE;
        }
    };
    let log = walker.log();
    let used = |r: Recovery| log.recoveries.iter().filter(|x| x.2 == r).count();
    println!("terrain: seed {seed}, {arcs} arcs, {steps} steps");
    println!(
        "walked: {} of {steps} steps ({} leg moves, {} body moves) in {:.0} s of virtual time",
        log.body_moves,
        log.leg_moves,
        log.body_moves,
        report.elapsed.as_secs_f64()
    );
    println!(
        "terrain contacts: {}; recoveries: {} raise-leg, {} replan, {} shuffle",
        log.contacts.len(),
        used(Recovery::RaiseLeg),
        used(Recovery::Replan),
        used(Recovery::Shuffle)
    );
    println!(
        "monitors: {} stability checks, {} footfall checks",
        log.stability_checks, log.footfall_checks
    );
    let complete = log.body_moves == steps;
    println!(
        "outcome: {:?}, walk {}",
        report.outcome,
        if complete { "complete" } else { "incomplete" }
    );
    if complete {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    }
}
