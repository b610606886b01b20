//! Issue 17, points 1 and 2: a waited spawn yields the child's outcome (`with outcome`), a child
//! spawned `with propagate` fails its parent (a behaviour-tree sequence), and a handler on the
//! parent retries the whole subtree, with its arguments changed or not, a bounded number of
//! times.

use crate::util::{assert_order, run_checked, story};
use std::cell::RefCell;
use std::time::Duration;
use tdl::testing::handler_choices as chosen;
use tdl::{RunOutcome, Runtime, TraceKind};

thread_local! {
    static RAN: RefCell<Vec<u32>> = const { RefCell::new(Vec::new()) };
    static SAW: RefCell<Vec<String>> = const { RefCell::new(Vec::new()) };
}

fn ran(n: u32) {
    RAN.with(|r| r.borrow_mut().push(n));
}

fn saw(s: String) {
    SAW.with(|r| r.borrow_mut().push(s));
}

fn take() -> (Vec<u32>, Vec<String>) {
    (
        RAN.with(|r| std::mem::take(&mut *r.borrow_mut())),
        SAW.with(|r| std::mem::take(&mut *r.borrow_mut())),
    )
}

/// How a waited child ended, as the tests compare it.
fn describe<T: std::fmt::Debug>(o: &tdl::Ended<T>) -> String {
    match o {
        tdl::Ended::Succeeded(v) => format!("succeeded {v:?}"),
        tdl::Ended::Failed(f) => {
            let at = f.data::<Blocked>().map_or(0, |b| b.at);
            format!("failed {} at {at}", f.exception)
        }
        tdl::Ended::Terminated => "terminated".to_owned(),
        tdl::Ended::Skipped => "skipped".to_owned(),
    }
}

tdl::tdl! {
    exception Blocked { at: u32 }

    command step(n: u32, fails: bool) {
        tdl::tokio::time::sleep(Duration::from_secs(1)).await;
        ran(n);
        if fails {
            fail Blocked { at: n };
        }
    }
    command slow() {
        tdl::tokio::time::sleep(Duration::from_secs(100)).await;
        ran(100);
    }
    command double(x: u32) -> u32 { x * 2 }

    // A sequence: each step after the previous; a step's failure is the sequence's.
    goal sequence(fail_at: u32) {
        spawn step(1, fail_at == 1) with propagate;
        spawn step(2, fail_at == 2) with propagate, sequential execution previous;
        spawn step(3, fail_at == 3) with propagate, sequential execution previous;
    }
    goal observe(fail_at: u32) {
        let o = spawn sequence(fail_at) with outcome;
        saw(describe(&o));
    }

    // The whole subtree again: the handler on the sequence retries it, at most twice.
    handler again() handles Blocked with maximum activate 2 {
        saw(format!("again after {}", failing));
        retry;
    }
    goal retried(fail_at: u32) {
        let o = spawn sequence(fail_at) with outcome, exception handler again();
        saw(describe(&o));
    }
    // The subtree again with other arguments: the retry passes the failed step.
    handler skip() handles Blocked with maximum activate 1 {
        retry with (0u32);
    }
    goal skipping(fail_at: u32) {
        spawn sequence(fail_at) with exception handler skip();
    }

    // A parent still running when its child fails: its body stops where it waits.
    goal busy_parent() {
        spawn step(1, true) with propagate;
        spawn slow() with wait;
        ran(999);
    }
    goal observe_busy() {
        let o = spawn busy_parent() with outcome;
        saw(describe(&o));
    }

    // A child with its own retry: when the retry fails too, the failure is the parent's, not
    // that of the handler the retry runs under.
    handler once_more() handles Blocked with maximum activate 1 { retry; }
    goal with_inner_retry() {
        spawn step(1, true) with propagate, exception handler once_more();
        spawn step(2, false) with propagate, sequential execution previous;
    }
    goal observe_inner() {
        let o = spawn with_inner_retry() with outcome;
        saw(describe(&o));
    }

    // Each outcome, as a value.
    goal outcomes() {
        let a = spawn double(4) with outcome;
        saw(describe(&a));
        let b = spawn step(7, true) with outcome;
        saw(describe(&b));
        saw(format!("failed with Blocked: {}", b.failed_with::<Blocked>()));
        let c = spawn slow() with outcome, terminate in 2s;
        saw(describe(&c));
    }
}

#[tokio::test(start_paused = true)]
async fn a_failing_child_fails_its_sequence_and_the_rest_never_runs() {
    take();
    let (report, trace) = run_checked(Runtime::new(), observe(2)).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    // The waiter took the failure: nothing is unhandled.
    assert!(report.unhandled.is_empty(), "{:?}", report.unhandled);
    let (ran, saw) = take();
    assert_eq!(ran, [1, 2]);
    assert_eq!(saw, ["failed Blocked at 2"]);
    assert_order(
        &story(&trace),
        &[
            "2 step failed Blocked",
            "2 sequence failed Blocked",
            "2 step terminating",
            "2 step terminated",
            "2 observe execution completed",
        ],
    );

    // Without a failure, the sequence succeeds.
    let (report, _) = run_checked(Runtime::new(), observe(0)).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(take(), (vec![1, 2, 3], vec!["succeeded ()".to_owned()]));
}

#[tokio::test(start_paused = true)]
async fn a_handler_on_the_parent_retries_the_whole_subtree_a_bounded_number_of_times() {
    take();
    // Fails at step 2 every time: the sequence runs three times (the first and two retries),
    // then its failure reaches the waiter.
    let (report, trace) = run_checked(Runtime::new(), retried(2)).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let (ran, saw) = take();
    assert_eq!(ran, [1, 2, 1, 2, 1, 2]);
    assert_eq!(saw.len(), 3, "{saw:?}");
    assert!(saw[0].starts_with("again after"), "{saw:?}");
    assert_eq!(saw[2], "failed Blocked at 2");
    assert_eq!(chosen(&trace), ["again<-Blocked", "again<-Blocked"]);
    let retries = trace
        .iter()
        .filter(|e| matches!(e.kind, TraceKind::Retried { .. }))
        .count();
    assert_eq!(retries, 2);
}

#[tokio::test(start_paused = true)]
async fn a_subtree_retried_with_changed_arguments_succeeds() {
    take();
    let (report, trace) = run_checked(Runtime::new(), skipping(1)).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert!(report.unhandled.is_empty(), "{:?}", report.unhandled);
    assert_eq!(take().0, [1, 1, 2, 3]);
    assert_eq!(chosen(&trace), ["skip<-Blocked"]);
}

#[tokio::test(start_paused = true)]
async fn a_parent_still_running_stops_when_its_child_fails() {
    take();
    let (report, trace) = run_checked(Runtime::new(), observe_busy()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let (ran, saw) = take();
    // The body, waiting for `slow`, never went on; `slow` was terminated.
    assert_eq!(ran, [1]);
    assert_eq!(saw, ["failed Blocked at 1"]);
    let end = trace.last().map_or(0, |e| e.t);
    assert!(end < 2_000_000_000, "ended at {end} ns, not after `slow`");
}

#[tokio::test(start_paused = true)]
async fn a_waited_spawn_yields_each_outcome() {
    take();
    let (report, _) = run_checked(Runtime::new(), outcomes()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert!(report.unhandled.is_empty(), "{:?}", report.unhandled);
    assert_eq!(
        take().1,
        [
            "succeeded 8",
            "failed Blocked at 7",
            "failed with Blocked: true",
            "terminated",
        ]
    );
}

#[tokio::test(start_paused = true)]
async fn a_failed_retry_of_a_child_fails_the_childs_parent() {
    take();
    let (report, trace) = run_checked(Runtime::new(), observe_inner()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert!(report.unhandled.is_empty(), "{:?}", report.unhandled);
    assert_eq!(take(), (vec![1, 1], vec!["failed Blocked at 1".to_owned()]));
    let st = story(&trace);
    assert_order(&st, &["2 with_inner_retry failed Blocked"]);
    assert!(
        !st.iter().any(|l| l.contains("once_more failed")),
        "{}",
        st.join("\n")
    );
}
