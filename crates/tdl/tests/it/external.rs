//! External events written in TDL (issue 17): `disable … until external "name"`, `terminate at
//! external "name"` and `activate at external "name"`, raised by the program from outside the run
//! through an event handle while it goes on (docs/semantics.md, "Events").

use crate::util::{assert_order, only, run_checked, story};
use std::cell::RefCell;
use std::time::Duration;
use tdl::{RunOutcome, Runtime, TraceEvent, TraceKind};

thread_local! {
    // Per test thread: tokio's test runtime runs every action on the test's thread.
    static TICKS: RefCell<Vec<Duration>> = const { RefCell::new(Vec::new()) };
}

async fn sleep_ms(ms: u64) {
    tokio::time::sleep(Duration::from_millis(ms)).await;
}

tdl::tdl! {
    command pause(s: u64) { sleep_ms(s * 1000).await; }
    command drive() { sleep_ms(1000).await; }
    // A long action, as Nav2's path following: it only ends when preempted.
    command follow_path() { std::future::pending::<()>().await; }
    command spin() { sleep_ms(100_000).await; }

    goal wait_for_go() {
        spawn drive() with disable execution until external "go";
    }

    // The constraint is applied at 5 s; a raise before then still counts (latched).
    goal go_before_the_constraint() {
        spawn pause(5) with wait;
        spawn drive() with disable execution until external "go";
    }

    // The same, as constraint statements: before the spawn (a forward reference) and after.
    goal go_on_tags() {
        later disable until external "go";
        later: spawn drive();
        now: spawn drive();
        now disable execution until external (format!("{}o", "g"));
    }

    goal navigate() {
        spawn follow_path() with terminate at external "goal_updated";
        s: spawn spin();
        s terminate at external "goal_updated";
    }

    monitor on_tick() {
        TICKS.with(|t| t.borrow_mut().push(ctx.now()));
    }

    goal ticking() {
        spawn pause(1) with wait;
        spawn on_tick() with activate at external "tick", maximum activate 3;
    }
}

/// Raises each `(milliseconds, name)` of `schedule` at that virtual time from the start, from a
/// task outside the run, then closes the handle (while it is open the run waits for it).
fn raise_at(rt: &Runtime, schedule: &[(u64, &'static str)]) {
    let events = rt.events();
    let schedule = schedule.to_vec();
    let start = tokio::time::Instant::now();
    tokio::spawn(async move {
        for (ms, name) in schedule {
            tokio::time::sleep_until(start + Duration::from_millis(ms)).await;
            events.raise(name).expect("the run takes the raise");
        }
    });
}

fn raised(trace: &[TraceEvent]) -> Vec<(u64, String)> {
    trace
        .iter()
        .filter_map(|e| match &e.kind {
            TraceKind::External { name } => Some((e.t / 1_000_000, name.clone())),
            _ => None,
        })
        .collect()
}

#[tokio::test(start_paused = true)]
async fn a_task_disabled_until_an_external_event_starts_when_it_is_raised() {
    let rt = Runtime::new();
    raise_at(&rt, &[(4000, "go")]);
    let (report, trace) = run_checked(rt, wait_for_go()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(raised(&trace), [(4000, "go".to_owned())]);
    let st = story(&trace);
    assert_eq!(
        only(&st, &["drive handling"]),
        [
            "4 drive handling enabled",
            "4 drive handling active",
            "5 drive handling completed"
        ]
    );
}

#[tokio::test(start_paused = true)]
async fn an_external_event_raised_before_the_constraint_counts() {
    let rt = Runtime::new();
    raise_at(&rt, &[(2000, "go")]);
    let (report, trace) = run_checked(rt, go_before_the_constraint()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let st = story(&trace);
    assert_order(
        &st,
        &[
            "5 pause handling completed",
            "5 drive handling active",
            "6 drive handling completed",
        ],
    );
}

#[tokio::test(start_paused = true)]
async fn constraint_statements_wait_for_an_external_event_too() {
    let rt = Runtime::new();
    raise_at(&rt, &[(3000, "go")]);
    let (report, trace) = run_checked(rt, go_on_tags()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let st = story(&trace);
    assert_eq!(
        only(&st, &["drive handling active"]),
        ["3 drive handling active", "3 drive handling active"],
        "both drives wait for the raise"
    );
}

#[tokio::test(start_paused = true)]
async fn terminate_at_external_preempts_a_running_command_at_the_raise() {
    // Nav2's "preempt on new goal": the path following is cut off in the instant the new goal
    // comes, however long it would have run.
    let rt = Runtime::new();
    raise_at(&rt, &[(3500, "goal_updated")]);
    let (report, trace) = run_checked(rt, navigate()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(raised(&trace), [(3500, "goal_updated".to_owned())]);
    let st = story(&trace);
    assert_order(
        &st,
        &[
            "0 follow_path handling active",
            "0 spin handling active",
            "3.5 follow_path terminating",
            "3.5 spin terminating",
            "3.5 follow_path terminated",
            "3.5 spin terminated",
            "3.5 navigate execution completed",
        ],
    );
    assert!(
        !st.iter()
            .any(|l| l.starts_with("3.5 ") && l.contains("failed")),
        "preemption is no failure:\n{}",
        st.join("\n")
    );
}

#[tokio::test(start_paused = true)]
async fn activate_at_external_activates_a_monitor_once_per_raise() {
    // The raise at 0.5 s comes before the monitor is spawned (at 1 s): activations are not
    // latched, so it activates nothing. Each later raise activates the monitor once, and the
    // third activation is its last.
    let rt = Runtime::new();
    raise_at(
        &rt,
        &[
            (500, "tick"),
            (2000, "tick"),
            (3000, "tick"),
            (4500, "tick"),
        ],
    );
    let (report, trace) = run_checked(rt, ticking()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let activated: Vec<u64> = trace
        .iter()
        .filter_map(|e| match &e.kind {
            TraceKind::Activated { .. } => Some(e.t / 1_000_000),
            _ => None,
        })
        .collect();
    assert_eq!(activated, [2000, 3000, 4500]);
    let ticks = TICKS.with(|t| t.borrow().clone());
    assert_eq!(
        ticks,
        [2000, 3000, 4500].map(Duration::from_millis),
        "one body run per raise"
    );
    assert_order(&story(&trace), &["4.5 on_tick execution completed"]);
}
