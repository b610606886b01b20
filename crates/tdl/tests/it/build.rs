//! A `.tdl` file compiled by `tdl-build` in this crate's `build.rs`, included and run.

use crate::util::{assert_order, only, run_checked, story};
use tdl::{RunOutcome, Runtime};

mod patrol {
    use std::cell::RefCell;

    thread_local! {
        // Per test thread: tokio's test runtime runs every action on the test's thread.
        pub(super) static SKIPPED: RefCell<Vec<u32>> = const { RefCell::new(Vec::new()) };
    }

    async fn sleep_s(s: u64) {
        tokio::time::sleep(std::time::Duration::from_secs(s)).await;
    }

    fn note_skipped(room: u32) {
        SKIPPED.with(|s| s.borrow_mut().push(room));
    }

    /// The battery level after `checks` checks: it drains slowly and never gets low here.
    fn battery(checks: u32) -> f64 {
        1.0 - f64::from(checks) * 0.01
    }

    include!(concat!(env!("OUT_DIR"), "/patrol.rs"));
    include!(concat!(env!("OUT_DIR"), "/patrol_faults.rs"));
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
            "0 watch_battery handling active",
            "4 visit failed DoorLocked",
            "4 skip_room handling active",
            "6 report handling active",
            "7 watch_battery terminated",
            "7 patrol_rooms execution completed",
        ],
    );
    assert_eq!(patrol::SKIPPED.with(|s| s.borrow().clone()), [1]);
}
