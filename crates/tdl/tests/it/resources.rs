//! Resources in TDL (docs/language.md, "Resources"): `resource` declarations, task-level and
//! spawn-level `uses`, `priority`, `deny if busy`, handlers of `ResourceDenied` and
//! `ResourceDropped` named without a declaration, `reserve`, `lock` and `unlock`, release on
//! every way a task ends, and a wait cycle over a resource that ends the run stuck with the cycle
//! named. Every run's trace goes through the checker.

use crate::util::{only, run_checked, story};
use std::cell::RefCell;
use std::time::Duration;
use tdl::testing::handler_choices;
use tdl::{RunOutcome, Runtime};

thread_local! {
    static SEEN: RefCell<Vec<String>> = const { RefCell::new(Vec::new()) };
}

fn secs(s: f64) -> Duration {
    Duration::from_secs_f64(s)
}

async fn sleep(s: f64) {
    tdl::tokio::time::sleep(secs(s)).await;
}

tdl::tdl! {
    // An exception of the program's own: handlers of the runtime's exceptions still need no
    // declaration.
    exception Stalled;

    resource base(1);
    resource arm(2) pending 1;
    resource camera(1);
    /// One heavy planner at a time.
    resource cpu(1);

    command work(s: f64) { sleep(s).await; }
    command plan_route(s: f64) with uses cpu { sleep(s).await; }
    command stall() { sleep(1.0).await; fail Stalled; }
    command forever() { sleep(3600.0).await; }

    // Capacity: three users of two arms.
    goal three_arms() {
        spawn work(3.0) with uses arm, name "a";
        spawn work(5.0) with uses arm, name "b";
        spawn work(1.0) with uses arm, name "c";
    }

    // Priority: lower first, then the order of the requests; a task-level use.
    goal priorities() {
        spawn plan_route(2.0) with name "holder";
        spawn plan_route(1.0) with name "x", priority 5;
        spawn plan_route(1.0) with name "y", priority 1;
        spawn plan_route(1.0) with name "z", priority 1;
    }

    // All or nothing: `fetch` waits for the arms without holding the base meanwhile.
    goal all_or_nothing() {
        spawn work(5.0) with uses arm(2), name "wave";
        spawn work(1.0) with uses base, arm(2), name "fetch";
        spawn work(2.0) with uses base, priority -1, name "patrol";
    }

    // Reserve and lock: `reserve base;` keeps the base for this task's subtree until it ends,
    // `lock camera;` from everyone until `unlock camera;` (the same as `ctx.lock_resource(…)`).
    goal reserving() {
        reserve base;
        spawn work(1.0) with uses base, name "own_move";
    }
    goal reserve_story() {
        spawn reserving();
        spawn work(1.0) with uses base, name "stranger", disable for 0.5s;
    }
    command unlock_camera() { unlock camera; }
    goal lock_story() {
        lock camera;
        spawn work(1.0) with uses camera, name "snap";
        spawn unlock_camera() with disable for 3s;
    }

    // The pending limit (one request may wait for the arms) and a denial, each taken by a handler.
    handler requeue() handles ResourceDropped as dropped {
        if let Some(d) = dropped.data() {
            SEEN.with(|s| s.borrow_mut().push(format!("dropped {}", d.resource)));
        }
    }
    handler retake() handles ResourceDenied as denied {
        if let Some(d) = denied.data() {
            SEEN.with(|s| s.borrow_mut().push(format!("denied {}: {}", d.resource, d.reason)));
        }
    }
    goal refusals() {
        spawn work(5.0) with uses arm(2), name "holder";
        spawn work(1.0) with uses arm, name "first", exception handler requeue();
        spawn work(1.0) with uses arm, name "second";
        spawn work(1.0) with uses camera, name "video";
        spawn work(1.0) with uses camera, deny if busy, name "snap", exception handler retake();
    }

    // Released when a task fails, is terminated while it runs, or while it waits.
    handler shrug() handles Stalled {}
    goal releases() {
        spawn stall() with uses base, exception handler shrug();
        spawn forever() with uses base, terminate in 3s;
        spawn work(1.0) with uses base, terminate in 2s, name "cancelled";
        spawn work(1.0) with uses base, name "last";
    }

    // A goal holding the base whose child needs it, and whose body waits for that child.
    command drive() with uses base { sleep(1.0).await; }
    goal plan() with uses base {
        spawn drive() with wait;
    }
}

/// The lines of a story about resources, failures and terminations.
fn resource_lines(trace: &[tdl::TraceEvent]) -> Vec<String> {
    only(
        &story(trace),
        &[
            "requests",
            "granted",
            "released",
            "withdrawn",
            "denied",
            "dropped",
            "reserved",
            "locked",
            "failed",
            "terminat",
        ],
    )
}

#[tdl::tokio::test(crate = "tdl::tokio", start_paused = true)]
async fn a_third_user_of_two_arms_waits() {
    let (report, trace) = run_checked(Runtime::new(), three_arms()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(report.elapsed, secs(5.0));
    assert_eq!(
        only(&story(&trace), &["granted"]),
        ["0 a granted arm", "0 b granted arm", "3 c granted arm"]
    );
}

#[tdl::tokio::test(crate = "tdl::tokio", start_paused = true)]
async fn lower_priority_first_then_request_order() {
    let (_, trace) = run_checked(Runtime::new(), priorities()).await;
    assert_eq!(
        only(&story(&trace), &["granted"]),
        [
            "0 holder granted cpu",
            "2 y granted cpu",
            "3 z granted cpu",
            "4 x granted cpu",
        ]
    );
}

#[tdl::tokio::test(crate = "tdl::tokio", start_paused = true)]
async fn a_task_needing_base_and_arms_holds_neither_while_it_waits() {
    let (_, trace) = run_checked(Runtime::new(), all_or_nothing()).await;
    assert_eq!(
        only(&story(&trace), &["granted", "released"]),
        [
            "0 wave granted arm(2)",
            "0 patrol granted base",
            "2 patrol released base",
            "5 wave released arm(2)",
            "5 fetch granted base, arm(2)",
            "6 fetch released base, arm(2)",
        ]
    );
}

#[tdl::tokio::test(crate = "tdl::tokio", start_paused = true)]
async fn reserve_and_lock_from_a_body() {
    let (_, trace) = run_checked(Runtime::new(), reserve_story()).await;
    assert_eq!(
        resource_lines(&trace),
        [
            "0 base reserved for reserving",
            "0 own_move requests base",
            "0 own_move granted base",
            "0.5 stranger requests base",
            "1 own_move released base",
            "1 base unreserved",
            "1 stranger granted base",
            "2 stranger released base",
        ]
    );
    let (_, trace) = run_checked(Runtime::new(), lock_story()).await;
    assert_eq!(
        resource_lines(&trace),
        [
            "0 camera locked",
            "0 snap requests camera",
            "3 camera unlocked",
            "3 snap granted camera",
            "4 snap released camera",
        ]
    );
}

#[tdl::tokio::test(crate = "tdl::tokio", start_paused = true)]
async fn a_dropped_and_a_denied_request_are_handled_by_name() {
    SEEN.with(|s| s.borrow_mut().clear());
    let (report, trace) = run_checked(Runtime::new(), refusals()).await;
    assert!(report.unhandled.is_empty(), "{report}");
    assert_eq!(
        handler_choices(&trace),
        ["requeue<-ResourceDropped", "retake<-ResourceDenied"]
    );
    assert_eq!(
        SEEN.with(|s| s.borrow().clone()),
        [
            "dropped arm",
            "denied camera: 1 of 1 of `camera` are held by video {5}"
        ]
    );
    assert_eq!(
        only(&story(&trace), &["dropped", "denied", "failed"]),
        [
            "0 first dropped arm",
            "0 first failed ResourceDropped",
            "0 snap denied camera",
            "0 snap failed ResourceDenied",
        ]
    );
}

#[tdl::tokio::test(crate = "tdl::tokio", start_paused = true)]
async fn released_on_failure_termination_while_running_and_while_waiting() {
    let (_, trace) = run_checked(Runtime::new(), releases()).await;
    assert_eq!(
        resource_lines(&trace),
        [
            "0 stall requests base",
            "0 stall granted base",
            "0 forever requests base",
            "0 cancelled requests base",
            "0 last requests base",
            "1 stall failed Stalled",
            "1 stall released base",
            "1 forever granted base",
            "2 cancelled terminating",
            "2 cancelled withdrawn",
            "2 cancelled terminated",
            "3 forever terminating",
            "3 forever released base",
            "3 forever terminated",
            "3 last granted base",
            "4 last released base",
        ]
    );
}

#[tdl::tokio::test(crate = "tdl::tokio", start_paused = true)]
async fn a_wait_cycle_over_the_base_ends_the_run_stuck_with_the_cycle_named() {
    let (report, _) = run_checked(Runtime::new(), plan()).await;
    let RunOutcome::Stuck(blocked) = report.outcome else {
        panic!("expected stuck, got {:?}", report.outcome);
    };
    let text: Vec<String> = blocked.iter().map(ToString::to_string).collect();
    assert_eq!(
        text,
        [
            "plan {1} handling is active and waits for its action, which awaits drive {2} \
             execution completed",
            "drive {2} handling is enabled and waits for resource `base`, held by plan {1} \
             (1 of 1), in the wait cycle: drive {2} needs `base`, held by plan {1}; plan {1}'s \
             action awaits drive {2}",
        ]
    );
}
