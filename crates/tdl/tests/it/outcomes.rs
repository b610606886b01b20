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
    static RAN: std::cell::RefCell<Vec<u32>> = const { std::cell::RefCell::new(Vec::new()) };
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

    // Outcome events: a fallback (try the first, else the second, else the third) and a watchdog
    // stopped when the first attempt succeeds.
    command attempt(n: u32, works: bool) {
        tokio::time::sleep(std::time::Duration::from_secs(1)).await;
        RAN.with(|r| r.borrow_mut().push(n));
        if !works {
            fail Flaky;
        }
    }
    command watchdog() {
        tokio::time::sleep(std::time::Duration::from_secs(3600)).await;
    }
    goal fallback(first: bool, second: bool) {
        a: spawn attempt(1, first);
        b: spawn attempt(2, second) with disable execution until a failed;
        spawn attempt(3, true) with disable execution until b failed;
        spawn watchdog() with terminate at a succeeded, terminate at b succeeded;
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

fn ran() -> Vec<u32> {
    RAN.with(|r| std::mem::take(&mut *r.borrow_mut()))
}

/// `X failed`, `X succeeded`: a fallback runs the next attempt only when the previous one failed;
/// an attempt whose predecessor ended otherwise can never be enabled, so it is terminated without
/// running; `terminate at a succeeded` stops the watchdog at that instant.
#[tokio::test(start_paused = true)]
async fn outcome_events_make_a_fallback() {
    reset();
    ran();
    let (report, trace) = run_checked(Runtime::new(), fallback(false, true)).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(ran(), [1, 2]);
    let st = story(&trace);
    assert_order(
        &st,
        &[
            "1 attempt failed Flaky",
            "2 attempt execution completed",
            "2 watchdog execution completed",
            "2 fallback execution completed",
        ],
    );
    // The third attempt waited for `b failed`; b succeeded, so it was terminated unstarted.
    let started = trace
        .iter()
        .filter(|e| {
            matches!(
                &e.kind,
                TraceKind::Transition {
                    facet: tdl::Facet::Handling,
                    to: tdl::State::Active,
                    ..
                }
            )
        })
        .count();
    assert_eq!(
        started,
        4,
        "fallback, two attempts and the watchdog started:\n{}",
        st.join("\n")
    );

    let (_, trace) = run_checked(Runtime::new(), fallback(true, true)).await;
    assert_eq!(ran(), [1]);
    // The watchdog is terminated when the first attempt succeeds, at 1 s, not after an hour.
    assert_order(
        &story(&trace),
        &[
            "1 attempt execution completed",
            "1 fallback execution completed",
        ],
    );

    let (_, _) = run_checked(Runtime::new(), fallback(false, false)).await;
    assert_eq!(ran(), [1, 2, 3]);
}
