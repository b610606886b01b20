//! Issue 17's retry bugs: a retry is the same task again (it keeps its handlers and constraints),
//! a waiter sees the final outcome (a retry's value, or the child's typed failure), a re-raised
//! exception can be retried, and a waited spawn's value can be assigned to an existing variable.

use crate::util::{assert_order, run_checked, story};
use std::cell::Cell;
use tdl::testing::handler_choices as chosen;
use tdl::{RunOutcome, Runtime, TraceKind};

thread_local! {
    static RUNS: Cell<u32> = const { Cell::new(0) };
    static SEEN: Cell<u32> = const { Cell::new(0) };
}

/// Counts the runs of a task that fails on its first run only.
fn nth_run() -> u32 {
    RUNS.with(|r| {
        r.set(r.get() + 1);
        r.get()
    })
}

tdl::tdl! {
    exception Flaky;
    exception Jammed;
    exception Escalated;

    // Bug 1: `flaky_goal` fails on its first run and is retried; the retry's child fails with
    // `Jammed`, which the goal's own task-level handler takes *at the retry* (it kept it).
    goal flaky_goal() with exception handler unjam() {
        if nth_run() == 1 {
            fail Flaky;
        }
        spawn jam();
    }
    command jam() { fail Jammed; }
    handler unjam() handles Jammed {}
    handler retry_once() handles Flaky with maximum activate 1 { retry; }
    goal run_flaky_goal() {
        spawn flaky_goal() with exception handler retry_once();
    }

    // Bug 2: the waiter gets the value of the retry that succeeded.
    command flaky_value() -> u32 {
        if nth_run() == 1 {
            fail Flaky;
        }
        42
    }
    goal wait_for_value() {
        let v = spawn flaky_value() with wait, exception handler retry_once();
        SEEN.set(v);
    }

    // Bug 2: a waiter failing because its child failed fails with the child's exception, so a
    // handler of that type takes it.
    goal waits_on_jam() with exception handler unjam_waiter() {
        let _: () = spawn jam() with wait;
        SEEN.set(1);
    }
    handler unjam_waiter() handles Jammed {
        SEEN.set(7);
    }

    // Bug 3: an inner handler re-raises; the outer handler's `retry` runs the original task again.
    command flaky_move() {
        if nth_run() == 1 {
            fail Flaky;
        }
    }
    handler escalate() handles Flaky { fail Escalated; }
    handler retry_escalated() handles Escalated with maximum activate 1 { retry; }
    goal escalating() with exception handler retry_escalated() {
        spawn flaky_move() with exception handler escalate();
    }

    // Bug 4: a waited spawn's value assigned to an existing variable.
    command double(x: u32) -> u32 { x * 2 }
    goal assigns() {
        let mut total = 1;
        total = spawn double(total + 2) with wait;
        total = spawn double(total) with wait;
        SEEN.set(total);
    }
}

fn reset() {
    RUNS.set(0);
    SEEN.set(0);
}

#[tokio::test(start_paused = true)]
async fn a_retried_goal_keeps_its_task_level_handlers() {
    reset();
    let (report, trace) = run_checked(Runtime::new(), run_flaky_goal()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert!(report.unhandled.is_empty(), "{:?}", report.unhandled);
    assert_eq!(chosen(&trace), ["retry_once<-Flaky", "unjam<-Jammed"]);
    let retry = trace
        .iter()
        .find_map(|e| match e.kind {
            TraceKind::Retried { node, .. } => Some(node),
            _ => None,
        })
        .expect("a retry");
    // `unjam` is found at the retry itself, not only further up at the first run.
    let attached = trace.iter().find_map(|e| match &e.kind {
        TraceKind::HandlerChosen {
            attached, handler, ..
        } if handler == "unjam" => Some(*attached),
        _ => None,
    });
    assert_eq!(attached, Some(retry));
}

#[tokio::test(start_paused = true)]
async fn a_waiter_gets_the_value_of_the_retry_that_succeeded() {
    reset();
    let (report, _) = run_checked(Runtime::new(), wait_for_value()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(SEEN.get(), 42);
}

#[tokio::test(start_paused = true)]
async fn a_waiter_fails_with_its_childs_typed_exception() {
    reset();
    let (report, trace) = run_checked(Runtime::new(), waits_on_jam()).await;
    assert_eq!(chosen(&trace), ["unjam_waiter<-Jammed"]);
    assert_eq!(
        SEEN.get(),
        7,
        "the waiter's handler of the child's type ran"
    );
    // The child's failure went to its waiter, which failed with it: taken once, not twice.
    assert!(report.unhandled.is_empty(), "{:?}", report.unhandled);
}

#[tokio::test(start_paused = true)]
async fn an_outer_handler_retries_the_task_an_inner_handler_escalated() {
    reset();
    let (report, trace) = run_checked(Runtime::new(), escalating()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert!(report.unhandled.is_empty(), "{:?}", report.unhandled);
    assert_eq!(
        chosen(&trace),
        ["escalate<-Flaky", "retry_escalated<-Escalated"]
    );
    assert_eq!(RUNS.get(), 2, "flaky_move ran again");
    assert_order(
        &story(&trace),
        &[
            "0 flaky_move failed Flaky",
            "0 escalate failed Escalated",
            "0 retry_escalated handling active",
            "0 flaky_move handling active",
            "0 escalating execution completed",
        ],
    );
}

#[tokio::test(start_paused = true)]
async fn a_waited_value_is_assigned_to_an_existing_variable() {
    reset();
    let (report, _) = run_checked(Runtime::new(), assigns()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(SEEN.get(), 12);
}
