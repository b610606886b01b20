//! The navigation's intent, asserted on virtual time (issue 17's acceptance): replanning at 1 Hz
//! while following, without restarting the follower; bounded retries; recoveries in turn, from the
//! first again after a success; an immediate failure for errors recovery cannot help; preemption
//! of a recovery by a new goal at that instant. Every trace goes through the trace checker.

use nav2::servers::{Entry, Nav, NavError};
use std::time::Duration;
use tdl::testing::run_checked;
use tdl::{Facet, Report, RunOutcome, Runtime, State, TraceEvent, TraceKind};

async fn navigate(nav: &Nav) -> (Report, Vec<TraceEvent>) {
    run_checked(
        Runtime::new(),
        nav2::navigate_to_pose(nav.clone(), nav.recoveries()),
    )
    .await
}

/// The log lines starting with `prefix`, with their times.
fn lines(log: &[Entry], prefix: &str) -> Vec<(Duration, String)> {
    log.iter()
        .filter(|e| e.what.starts_with(prefix))
        .map(|e| (e.at, e.what.clone()))
        .collect()
}

fn whats(log: &[Entry], prefix: &str) -> Vec<String> {
    lines(log, prefix).into_iter().map(|(_, w)| w).collect()
}

fn print(log: &[Entry]) -> String {
    log.iter()
        .map(|e| format!("{:>7.2}s {}", e.at.as_secs_f64(), e.what))
        .collect::<Vec<_>>()
        .join("\n")
}

/// How many nodes named `name` started (their handling went active).
fn started(trace: &[TraceEvent], name: &str) -> usize {
    let nodes: Vec<u64> = trace
        .iter()
        .filter_map(|e| match &e.kind {
            TraceKind::Spawned { node, name: n, .. } if n == name => Some(*node),
            _ => None,
        })
        .collect();
    trace
        .iter()
        .filter(|e| {
            matches!(&e.kind, TraceKind::Transition { node, facet: Facet::Handling, to: State::Active, .. } if nodes.contains(node))
        })
        .count()
}

#[tokio::test(start_paused = true)]
async fn replans_at_one_hertz_while_following_without_restarting_the_follower() {
    let nav = Nav::new(5.0);
    let (report, trace) = navigate(&nav).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert!(report.is_clean(), "{report}");
    let log = nav.log();
    let plans = lines(&log, "plan ");
    // 5 m at 1 m/s: a plan at 0, 1, 2, 3, 4 and 5 s (each after 100 ms of planning).
    assert!(plans.len() >= 5, "{}", print(&log));
    for pair in plans.windows(2) {
        assert_eq!(
            pair[1].0 - pair[0].0,
            Duration::from_secs(1),
            "{}",
            print(&log)
        );
    }
    // One follower, which took up each new path.
    assert_eq!(started(&trace, "follow_path"), 1);
    assert_eq!(whats(&log, "follow"), {
        let mut v = vec!["follow".to_owned()];
        v.extend((1..=plans.len()).map(|n| format!("following path {n}")));
        v
    });
    assert_eq!(
        whats(&log, "navigation"),
        ["navigation succeeded"],
        "{}",
        print(&log)
    );
    assert_eq!(nav.position(), 5.0);
}

#[tokio::test(start_paused = true)]
async fn retries_are_bounded_and_the_failure_keeps_its_type() {
    let nav = Nav::new(5.0);
    // The controller never gets through: each pipeline run fails twice (once more after clearing
    // the local costmap).
    nav.fail_controller([NavError::FailedToMakeProgress; 40]);
    let (report, trace) = navigate(&nav).await;
    let log = nav.log();
    // The first run and six retries of the pipeline, each with one retry of the follower.
    assert_eq!(
        started(&trace, "navigate_with_replanning"),
        7,
        "{}",
        print(&log)
    );
    assert_eq!(started(&trace, "follow_path"), 14);
    // Each pipeline run: the follower's own retry after clearing the local costmap, then a
    // round of the recoveries, in turn: six rounds.
    let inner = "recovery clear_local";
    let expected = [
        vec![inner, "recovery clear_local", "recovery clear_global"],
        vec![inner, "recovery spin"],
        vec![inner, "recovery wait"],
        vec![inner, "recovery back_up"],
        vec![inner, "recovery clear_local", "recovery clear_global"],
        vec![inner, "recovery spin"],
        vec![inner],
    ]
    .concat();
    assert_eq!(whats(&log, "recovery"), expected, "{}", print(&log));
    // The failure reaches the top with its type.
    assert_eq!(whats(&log, "navigation"), ["navigation failed Recoverable"]);
    assert_eq!(report.unhandled.len(), 1, "{report}");
    assert_eq!(report.unhandled[0].failure.exception, "Recoverable");
}

#[tokio::test(start_paused = true)]
async fn recoveries_run_in_turn_and_start_again_from_the_first_after_a_success()
-> Result<(), tdl::Error> {
    let nav = Nav::new(3.0);
    let turn = nav.recoveries();
    // First navigation: two pipeline runs fail (each failing twice), the third gets through.
    nav.fail_controller([NavError::PatienceExceeded; 4]);
    let (report, _) = run_checked(
        Runtime::new(),
        nav2::navigate_to_pose(nav.clone(), turn.clone()),
    )
    .await;
    assert!(report.is_clean(), "{report}");
    let inner = "recovery clear_local";
    let first = [
        inner,
        "recovery clear_local",
        "recovery clear_global",
        inner,
        "recovery spin",
    ];
    assert_eq!(
        whats(&nav.log(), "recovery"),
        first,
        "{}",
        print(&nav.log())
    );
    // The success reset the turn: the next navigation's first round clears the costmaps again,
    // not the `wait` that came next.
    assert_eq!(turn.next_index(), 0);
    nav.new_goal(0.0, |_| Ok(()))?;
    nav.fail_controller([NavError::PatienceExceeded; 2]);
    let (report, _) = run_checked(
        Runtime::new(),
        nav2::navigate_to_pose(nav.clone(), turn.clone()),
    )
    .await;
    assert!(report.is_clean(), "{report}");
    let log = nav.log();
    assert_eq!(
        whats(&log, "recovery")[first.len()..],
        [inner, "recovery clear_local", "recovery clear_global"],
        "{}",
        print(&log)
    );
    assert_eq!(
        whats(&log, "navigation"),
        ["navigation succeeded", "navigation succeeded"]
    );
    assert_eq!(nav.position(), 0.0);
    Ok(())
}

#[tokio::test(start_paused = true)]
async fn an_error_recovery_cannot_help_fails_the_navigation_at_once() {
    let nav = Nav::new(5.0);
    nav.fail_controller([NavError::InvalidPath]);
    let (report, trace) = navigate(&nav).await;
    let log = nav.log();
    // No recovery ran, no retry: the failure went straight to the top, typed.
    assert!(whats(&log, "recovery").is_empty(), "{}", print(&log));
    assert_eq!(started(&trace, "follow_path"), 1);
    assert_eq!(started(&trace, "navigate_with_replanning"), 1);
    assert_eq!(
        whats(&log, "navigation"),
        ["navigation failed Unrecoverable"]
    );
    let failed = lines(&log, "controller failed");
    assert_eq!(failed.len(), 1);
    assert_eq!(
        lines(&log, "navigation")[0].0,
        failed[0].0,
        "at the same instant"
    );
    assert_eq!(report.unhandled.len(), 1);
    assert_eq!(report.unhandled[0].failure.exception, "Unrecoverable");
    let data = report.unhandled[0].failure.data::<nav2::Unrecoverable>();
    assert_eq!(data.map(|d| d.error), Some(NavError::InvalidPath));

    // The planner's: the goal is outside the map.
    let nav = Nav::new(5.0);
    nav.fail_planner([NavError::GoalOutsideMap]);
    let (report, _) = navigate(&nav).await;
    assert!(whats(&nav.log(), "recovery").is_empty());
    assert_eq!(report.unhandled[0].failure.exception, "Unrecoverable");
}

#[tokio::test(start_paused = true)]
async fn a_planner_failure_is_retried_after_clearing_the_global_costmap() {
    let nav = Nav::new(2.0);
    nav.fail_planner([NavError::NoValidPath]);
    let (report, trace) = navigate(&nav).await;
    assert!(report.is_clean(), "{report}");
    let log = nav.log();
    assert_eq!(
        whats(&log, "recovery"),
        ["recovery clear_global"],
        "{}",
        print(&log)
    );
    // Recovered inside the planner: the pipeline was never retried.
    assert_eq!(started(&trace, "navigate_with_replanning"), 1);
    assert_eq!(whats(&log, "navigation"), ["navigation succeeded"]);
}

#[tokio::test(start_paused = true)]
async fn a_new_goal_preempts_the_running_recovery_at_once() -> Result<(), tdl::Error> {
    let nav = Nav::new(5.0);
    // Fail through to the `wait` recovery (5 s): third round.
    nav.fail_controller([NavError::FailedToMakeProgress; 6]);
    let rt = Runtime::new();
    let events = rt.events();
    let goals = nav.clone();
    let new_goal = tdl::tokio::spawn(async move {
        // Wait until the `wait` recovery runs, then send a new goal.
        loop {
            tdl::tokio::time::sleep(Duration::from_millis(50)).await;
            if goals.log().iter().any(|e| e.what == "recovery wait") {
                break;
            }
        }
        tdl::tokio::time::sleep(Duration::from_millis(500)).await;
        let raised = goals.new_goal(-2.0, |n| events.raise(n));
        drop(events);
        raised
    });
    let (report, trace) =
        run_checked(rt, nav2::navigate_to_pose(nav.clone(), nav.recoveries())).await;
    new_goal.await.expect("the goal sender ran")?;
    assert!(report.is_clean(), "{report}");
    let log = nav.log();
    let goal_at = lines(&log, "goal -2.0")[0].0;
    // The recovery was terminated at the instant the goal came: its node's termination is
    // traced at that time, and the next pipeline run started then too.
    let ns = goal_at.as_nanos() as u64;
    let terminated_then = trace
        .iter()
        .any(|e| e.t == ns && matches!(&e.kind, TraceKind::Terminated { .. }));
    assert!(terminated_then, "{}", print(&log));
    let follows = lines(&log, "follow");
    assert!(
        follows
            .iter()
            .any(|(at, w)| *at == goal_at && w == "follow"),
        "{}",
        print(&log)
    );
    // No round after `wait`: the preempted round counted as done, and the navigation went on to
    // the new goal.
    assert_eq!(
        whats(&log, "recovery").last().map(String::as_str),
        Some("recovery wait")
    );
    assert!(
        lines(&log, "plan ")
            .iter()
            .any(|(_, w)| w.ends_with("to -2.0"))
    );
    assert_eq!(whats(&log, "navigation"), ["navigation succeeded"]);
    assert_eq!(nav.position(), -2.0);
    Ok(())
}
