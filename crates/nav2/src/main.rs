//! Runs the navigation once on virtual time and prints the servers' log.
//!
//! `cargo run -p nav2 -- [clear|blocked|stuck|bad-path]`: a clear way (the default), a controller
//! blocked four times (recoveries in turn), one blocked for good (retries run out), an invalid
//! path (no recovery can help).

use nav2::servers::{Nav, NavError};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let scenario = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "clear".to_owned());
    let nav = Nav::new(5.0);
    match scenario.as_str() {
        "clear" => {}
        "blocked" => nav.fail_controller([NavError::FailedToMakeProgress; 4]),
        "stuck" => nav.fail_controller([NavError::FailedToMakeProgress; 40]),
        "bad-path" => nav.fail_controller([NavError::InvalidPath]),
        other => {
            eprintln!("error: unknown scenario `{other}`; use clear, blocked, stuck or bad-path");
            std::process::exit(2);
        }
    }
    let report = tdl::block_on_virtual(
        tdl::Runtime::new().run(nav2::navigate_to_pose(nav.clone(), nav.recoveries())),
    )?;
    for e in nav.log() {
        println!("{:>7.2}s  {}", e.at.as_secs_f64(), e.what);
    }
    if !report.is_clean() {
        println!("\n{report}");
    }
    Ok(())
}
