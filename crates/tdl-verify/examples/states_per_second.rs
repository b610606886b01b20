//! The benchmark of docs/verification.md: states explored per second on the Xavier mission
//! (`crates/xavier/src/mission.tdl`, its commands as choices, the default bounds).
//!
//! `cargo run --release -p tdl-verify --example states_per_second [-- RUNS]` verifies the mission
//! RUNS times (default 1: a run takes minutes) and prints, per run and for the best one, the states explored, the
//! distinct states, the time and the rate; the target is 100,000 states per second.

use std::path::Path;

/// The allocator of the `tdl` binary (crates/tdl-cli/src/main.rs), so that the figure is the one
/// `tdl verify` reaches.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() -> anyhow::Result<()> {
    let runs: usize = std::env::args()
        .nth(1)
        .map(|a| a.parse())
        .transpose()?
        .unwrap_or(1);
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../xavier/src/mission.tdl");
    let src = std::fs::read_to_string(&path)?;
    let program = tdl_verify::Program::load(&[("mission.tdl".into(), src)])?;
    let task = program.root_task(None)?;
    let options = tdl_verify::Options::default();
    let mut best = 0.0f64;
    for run in 1..=runs.max(1) {
        let report = tdl_verify::verify(
            &program,
            &task,
            &options,
            &[],
            None,
            &tdl_verify::Control::default(),
        );
        println!(
            "run {run}: {} states explored, {} distinct, depth {}, {:.2} s: {:.0} states/s (complete: {})",
            report.explored,
            report.unique,
            report.depth,
            report.elapsed.as_secs_f64(),
            report.rate(),
            report.complete
        );
        for r in &report.results {
            let v = match &r.verdict {
                tdl_verify::Verdict::Holds => "holds".to_owned(),
                tdl_verify::Verdict::Violated(c) => {
                    format!("VIOLATED ({} steps): {}", c.len(), c.summary)
                }
                tdl_verify::Verdict::Unknown(why) => why.clone(),
            };
            println!("  {}: {v}", r.property);
        }
        best = best.max(report.rate());
    }
    println!("best: {best:.0} states/s (target 100000)");
    Ok(())
}
