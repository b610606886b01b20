//! Exceptions declared in TDL and raised with `fail`: the failing node fails with the exception's
//! name (no handlers yet), and the generated types carry their data and parent.

use crate::util::{assert_order, run_checked, story};
use tdl::{RunOutcome, Runtime};

async fn sleep_s(s: u64) {
    tokio::time::sleep(std::time::Duration::from_secs(s)).await;
}

tdl::tdl! {
    exception HardwareFailure;
    exception Overheating : HardwareFailure { temperature: f64 }
    exception NoPath { from: u32, to: u32 }

    command plan(to: u32) -> u32 {
        sleep_s(1).await;
        if to > 10 {
            fail NoPath { from: 0, to };
        }
        to * 2
    }

    command drive(steps: u32) { assert!(steps > 0); sleep_s(2).await; }

    goal go_to(to: u32) {
        spawn plan(to) with wait;
        spawn drive(1);
    }

    goal go_and_use(to: u32) {
        let steps = spawn plan(to) with wait;
        spawn drive(steps);
    }

    command overheat(t: f64) {
        fail Overheating { temperature: t };
    }
}

#[tokio::test(start_paused = true)]
async fn fail_fails_the_node_with_the_exception() {
    let (report, trace) = run_checked(Runtime::new(), go_to(99)).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let st = story(&trace);
    // No handler: the child is marked failed and the parent goes on (TCM's default).
    assert_order(
        &st,
        &[
            "1 plan failed NoPath",
            "1 drive handling active",
            "3 go_to execution completed",
        ],
    );
}

#[tokio::test(start_paused = true)]
async fn a_waited_value_flows_and_a_failed_one_fails_the_waiter() {
    let (report, trace) = run_checked(Runtime::new(), go_and_use(3)).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_order(
        &story(&trace),
        &[
            "1 drive handling active",
            "3 go_and_use execution completed",
        ],
    );

    let (report, trace) = run_checked(Runtime::new(), go_and_use(42)).await;
    let RunOutcome::TaskFailed(failure) = report.outcome else {
        panic!(
            "expected the waiting goal to fail, got {:?}",
            report.outcome
        );
    };
    assert!(failure.message.contains("NoPath"), "{failure}");
    assert!(!story(&trace).iter().any(|l| l.contains("drive")));
}

#[tokio::test(start_paused = true)]
async fn a_failing_top_level_task_reports_its_exception_and_data() {
    let (report, _) = run_checked(Runtime::new(), overheat(95.5)).await;
    let RunOutcome::TaskFailed(failure) = report.outcome else {
        panic!("expected a failure, got {:?}", report.outcome);
    };
    assert_eq!(failure.exception, "Overheating");
    assert_eq!(failure.message, "Overheating { temperature: 95.5 }");
}

#[test]
fn exceptions_are_error_types_that_know_their_parent() {
    assert_eq!(Overheating::PARENT, Some("HardwareFailure"));
    assert_eq!(HardwareFailure::PARENT, None);
    let e = NoPath { from: 1, to: 2 };
    let err: &dyn std::error::Error = &e;
    assert_eq!(err.to_string(), "NoPath { from: 1, to: 2 }");
    assert_eq!(format!("{:?}", HardwareFailure {}), "HardwareFailure");
}
