//! The demo as it runs when watched: actions on a multi-threaded runtime, on the real clock scaled
//! by the pacing speed (`Runtime::time_scale`, `SharedWorld::scaled`). It delivers what the same
//! round delivers on virtual time, its simulated time is about the same, and its trace passes the
//! checker; bounds on the real clock are generous.

use crate::util::{log_of, setup};
use std::time::{Duration, Instant};
use tdl::{Recorder, RunOutcome};
use xavier::mission::Mission;
use xavier::summary::Summary;
use xavier_world::{Scenario, SharedWorld, World};

#[test]
fn a_scaled_real_time_round_on_a_multi_threaded_runtime_delivers_as_on_virtual_time() {
    let s = setup(1, Scenario::Nominal, &[3]);
    let scale = 50.0;
    let world = SharedWorld::scaled(World::new(s.seed, s.scenario), scale);
    let rec = Recorder::new();
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .expect("a tokio runtime");
    let wall = Instant::now();
    let done = rt
        .block_on(xavier::run_scaled(
            &s,
            Mission::new(world),
            vec![Box::new(rec.clone())],
            scale,
        ))
        .expect("the run");
    let wall = wall.elapsed();
    let trace = rec.events();
    let log = log_of(&trace);
    if let Err(violations) = tcm_trace::check(&trace) {
        let text: Vec<String> = violations.iter().map(|v| v.to_string()).collect();
        panic!(
            "trace checker found violations:\n{}\n{log}",
            text.join("\n")
        );
    }
    let summary = Summary::new(&s, &done, &trace);
    assert_eq!(summary.outcome, RunOutcome::Completed, "{log}");
    assert_eq!(summary.delivered, [3], "{summary}\n{log}");
    // On virtual time the same round takes its simulated time exactly; scaled, about the same.
    let (virtual_summary, _, _) = crate::util::run_checked(&s);
    let (a, b) = (summary.simulated, virtual_summary.simulated);
    assert!(
        a > b / 2 && a < b * 2,
        "simulated {a:?} scaled against {b:?} on virtual time"
    );
    assert!(
        wall < b.div_f64(scale) + Duration::from_secs(20),
        "{wall:?} of the real clock for {a:?} at ×{scale}"
    );
}
