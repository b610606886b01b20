//! State variables and conditions written in TDL (issue 42; docs/language.md, "State and
//! conditions"): `state` declarations, every condition form (`disable until`, `terminate when`,
//! `activate when`, `activate on change of`, `skip if`, `invariant`, `pause while`), `set`,
//! `raise` and `state!(x)`, run on virtual time. The variables change only by `set` statements of
//! the program itself; the trace checker re-evaluates every condition from the recorded values.

use crate::util::{only, run_checked, story};
use std::cell::RefCell;
use std::time::Duration;
use tdl::{RunOutcome, Runtime, TraceKind};

thread_local! {
    // Per test thread: tokio's test runtime runs every action on the test's thread.
    static SEEN: RefCell<Vec<String>> = const { RefCell::new(Vec::new()) };
}

async fn sleep_ms(ms: u64) {
    tokio::time::sleep(Duration::from_millis(ms)).await;
}

fn seen(what: String) {
    SEEN.with(|s| s.borrow_mut().push(what));
}

tdl::tdl! {
    state healthy: bool = false;
    state battery: float = 100;
    state errors: int = 0;
    state position: float;
    state mode: string = "auto";

    command work(s: u64) { sleep_ms(s * 1000).await; }
    command heal(s: u64) { sleep_ms(s * 1000).await; set healthy = true; }
    command sicken(s: u64) { sleep_ms(s * 1000).await; set healthy = false; }
    command drain(s: u64, level: f64) { sleep_ms(s * 1000).await; set battery = level; }
    command fault(s: u64) {
        sleep_ms(s * 1000).await;
        set errors = state!(errors).unwrap_or(0) + 1;
    }
    command modes() {
        sleep_ms(1000).await;
        set mode = "manual";
        sleep_ms(1000).await;
        set mode = "manual";
        sleep_ms(1000).await;
        set mode = "off";
    }
    command locate() { set position = 2.5; }
    command forget() { set position = unknown; }
    command report() {
        seen(format!(
            "{:?} {:?} {:?} {:?} {:?}",
            state!(healthy),
            state!(battery),
            state!(errors),
            state!(position),
            state!(mode)
        ));
    }
    command go() { sleep_ms(3000).await; raise "go"; }
    monitor tick() { seen(format!("tick {}", ctx.now().as_secs_f64())); }

    goal wait_until_healthy() {
        spawn heal(2);
        spawn work(1) with disable until healthy && battery > 20.5;
    }

    // A condition that already holds does not wait; one on a facet holds that facet.
    goal already_holds() {
        spawn work(1) with disable execution until battery >= 100 && !healthy;
    }

    goal cut_off() {
        spawn work(10) with terminate when battery < 20.0;
        spawn drain(1, 50.0);
        spawn drain(3, 10.0);
    }

    goal watched() {
        spawn tick() with activate when errors > 0 && errors % 2 == 1, maximum activate 2;
        spawn fault(1);
        spawn fault(2);
        spawn fault(3);
    }

    goal on_change() {
        w: spawn tick() with maximum activate 2;
        w activate on change of mode;
        spawn modes();
    }

    goal skipping() {
        spawn work(1) with skip if !is_known(position);
        spawn locate() with sequential execution previous;
        spawn work(1) with skip if !is_known(position), sequential execution previous;
        spawn forget() with sequential execution previous;
        spawn report() with sequential execution previous;
    }

    goal guarded() {
        spawn heal(0);
        let o = spawn work(5) with invariant battery > 20.0 || healthy, outcome;
        seen(format!("work failed: {}", o.failed()));
    }

    goal invariant_breaks() {
        spawn heal(0);
        spawn sicken(1);
        spawn drain(2, 10.0);
        spawn work(5) with invariant battery > 20.0 || healthy;
    }

    goal paused() {
        spawn heal(0);
        spawn sicken(1);
        spawn heal(4);
        with (pause while !healthy) {
            spawn work(2);
            spawn work(1) with sequential execution previous;
        }
    }

    goal raising() {
        spawn go();
        spawn work(1) with disable until external "go";
    }
}

/// The story lines of `trace` that contain one of `needles`, the run checked and complete.
async fn run(task: tdl::Task, needles: &[&str]) -> Vec<String> {
    SEEN.with(|s| s.borrow_mut().clear());
    let (report, trace) = run_checked(Runtime::new(), task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    only(&story(&trace), needles)
}

fn seen_lines() -> Vec<String> {
    SEEN.with(|s| s.borrow().clone())
}

#[tokio::test(start_paused = true)]
async fn disable_until_a_condition_starts_the_node_when_a_set_makes_it_true() {
    assert_eq!(
        run(
            wait_until_healthy(),
            &[
                "set healthy",
                "work handling active",
                "work handling completed"
            ]
        )
        .await,
        [
            "2 set healthy = true",
            "2 work handling active",
            "3 work handling completed"
        ]
    );
}

#[tokio::test(start_paused = true)]
async fn a_condition_that_already_holds_does_not_wait() {
    assert_eq!(
        run(already_holds(), &["work handling active"]).await,
        ["0 work handling active"]
    );
}

#[tokio::test(start_paused = true)]
async fn terminate_when_cuts_a_node_off_at_the_set_that_makes_it_true() {
    assert_eq!(
        run(cut_off(), &["set battery", "work terminat"]).await,
        [
            "1 set battery = 50.0",
            "3 set battery = 10.0",
            "3 work terminating",
            "3 work terminated"
        ]
    );
}

#[tokio::test(start_paused = true)]
async fn activate_when_activates_a_monitor_each_time_the_condition_becomes_true() {
    // errors 1 (odd: true), 2 (false), 3 (true again): two rising edges.
    run(watched(), &[]).await;
    assert_eq!(seen_lines(), ["tick 1", "tick 3"]);
}

#[tokio::test(start_paused = true)]
async fn activate_on_change_of_activates_on_each_change_of_value_only() {
    // "manual" at 1, "manual" again at 2 (no change), "off" at 3.
    let lines = run(on_change(), &["set mode"]).await;
    assert_eq!(
        lines,
        [
            "1 set mode = \"manual\"",
            "2 set mode = \"manual\"",
            "3 set mode = \"off\""
        ]
    );
    assert_eq!(seen_lines(), ["tick 1", "tick 3"]);
}

#[tokio::test(start_paused = true)]
async fn skip_if_skips_a_node_while_a_value_is_unknown_and_state_reads_it() {
    assert_eq!(
        run(skipping(), &["skipped", "work handling active"]).await,
        ["0 work skipped", "0 work handling active"]
    );
    assert_eq!(
        seen_lines(),
        ["Some(false) Some(100.0) Some(0) None Some(\"auto\")"]
    );
}

#[tokio::test(start_paused = true)]
async fn an_invariant_that_holds_lets_the_node_run() {
    assert_eq!(
        run(guarded(), &["work failed", "work handling completed"]).await,
        ["5 work handling completed"]
    );
    assert_eq!(seen_lines(), ["work failed: false"]);
}

#[tokio::test(start_paused = true)]
async fn an_invariant_that_turns_false_fails_the_node_with_invariant_failed() {
    assert_eq!(
        run(invariant_breaks(), &["set", "work failed"]).await,
        [
            "0 set healthy = true",
            "1 set healthy = false",
            "2 set battery = 10.0",
            "2 work failed InvariantFailed"
        ]
    );
}

#[tokio::test(start_paused = true)]
async fn pause_while_holds_back_the_group_and_resumes_it_when_healthy_again() {
    // `healthy` starts false: the group's spawns are paused as they are made and resumed by
    // `heal(0)` in the same instant. At 1 they are paused again: the first `work`, started, runs
    // on; the second, due at 2, starts only when `heal(4)` resumes it.
    assert_eq!(
        run(
            paused(),
            &["work suspended", "work unsuspended", "work handling active"]
        )
        .await,
        [
            "0 work suspended",
            "0 work suspended",
            "0 work unsuspended",
            "0 work unsuspended",
            "0 work handling active",
            "1 work suspended",
            "1 work suspended",
            "4 work unsuspended",
            "4 work handling active"
        ]
    );
}

#[tokio::test(start_paused = true)]
async fn raise_in_tdl_raises_the_external_event_the_constraint_waits_for() {
    let (report, trace) = run_checked(Runtime::new(), raising()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let raised: Vec<(u64, String)> = trace
        .iter()
        .filter_map(|e| match &e.kind {
            TraceKind::External { name } => Some((e.t / 1_000_000, name.clone())),
            _ => None,
        })
        .collect();
    assert_eq!(raised, [(3000, "go".to_owned())]);
    assert_eq!(
        only(&story(&trace), &["work handling active"]),
        ["3 work handling active"]
    );
}
