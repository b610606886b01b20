//! Loops spawning `move_by[i]` and `turn[i]`, constrained on the previous iteration's spawns by
//! iteration-indexed tags (`[i - 1]`, `[.]`).

use crate::util::{assert_order, only, run_checked, story};
use tdl::{RunOutcome, Runtime};

async fn sleep_s(s: u64) {
    tokio::time::sleep(std::time::Duration::from_secs(s)).await;
}

tdl::tdl! {
    command move_by(dist: f64) { assert!(dist > 0.0); sleep_s(1).await; }
    command turn(deg: f64) { assert!(deg > 0.0); sleep_s(1).await; }

    goal square(side: f64) {
        for i in 0..4 {
            // A forward reference to this iteration's `move_by`, on the previous one's `turn`.
            if i > 0 {
                move_by[i] sequential execution turn[i - 1];
            }
            spawn move_by(side);
            spawn turn(90.0) with sequential execution move_by[.];
        }
    }

    goal unconstrained(side: f64) {
        for _ in 0..3 {
            spawn move_by(side);
        }
    }
}

#[tokio::test(start_paused = true)]
async fn each_iteration_waits_for_the_previous_ones_spawns() {
    let (report, trace) = run_checked(Runtime::new(), square(2.0)).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let st = story(&trace);
    assert_eq!(
        only(&st, &["handling active"])
            .into_iter()
            .filter(|l| !l.contains("square"))
            .collect::<Vec<_>>(),
        [
            "0 move_by handling active",
            "1 turn handling active",
            "2 move_by handling active",
            "3 turn handling active",
            "4 move_by handling active",
            "5 turn handling active",
            "6 move_by handling active",
            "7 turn handling active",
        ]
    );
    assert_order(&st, &["8 square execution completed"]);
}

#[tokio::test(start_paused = true)]
async fn without_tags_loop_spawns_run_in_parallel() {
    let (_, trace) = run_checked(Runtime::new(), unconstrained(1.0)).await;
    let st = story(&trace);
    assert_eq!(only(&st, &["move_by handling active"]).len(), 3);
    assert!(
        only(&st, &["move_by handling active"])
            .iter()
            .all(|l| l.starts_with("0 "))
    );
    assert_order(&st, &["1 unconstrained execution completed"]);
}
