//! A `.tdl` file compiled by `tdl-build` in this crate's `build.rs`, included and run.

use crate::util::{assert_order, only, run_checked, story};
use tdl::{RunOutcome, Runtime};

mod patrol {
    async fn sleep_s(s: u64) {
        tokio::time::sleep(std::time::Duration::from_secs(s)).await;
    }

    include!(concat!(env!("OUT_DIR"), "/patrol.rs"));
}

#[tokio::test(start_paused = true)]
async fn a_tdl_file_compiled_by_tdl_build_runs() {
    let (report, trace) = run_checked(Runtime::new(), patrol::patrol_rooms(3)).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let st = story(&trace);
    assert_eq!(
        only(&st, &["visit handling active"]),
        [
            "0 visit handling active",
            "2 visit handling active",
            "4 visit handling active"
        ]
    );
    assert_order(
        &st,
        &[
            "6 report handling active",
            "7 patrol_rooms execution completed",
        ],
    );
}
