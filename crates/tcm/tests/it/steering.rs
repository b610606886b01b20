//! A run steered through its `Control` handle (docs/semantics.md, "Steering a run"): a paused
//! run is not stuck and goes on when resumed; a 1 kHz monitor keeps its schedule across a pause
//! (on tokio's paused clock and on the real clock); approvals given and refused; a breakpoint
//! and a fault. Every trace through the checker.

use std::time::Duration;
use tcm::testing::assert_checked;
use tcm::{
    Approval, BreakAt, Breakpoint, Failure, Fault, FaultOutcome, Matcher, Monitor, Task,
    TraceEvent, TraceKind, WatchOutcome,
};

/// Longer than any run here: a run that does not end fails instead of hanging `cargo test`.
const NEVER: Duration = Duration::from_secs(24 * 3600);

use crate::util::recorded_session as start;

fn quick(name: &'static str) -> Task {
    Task::command(name, |_| async {
        tokio::time::sleep(Duration::from_secs(1)).await;
        Ok(())
    })
}

/// When (run time) each node named `name` started.
fn starts(trace: &[TraceEvent], name: &str) -> Vec<Duration> {
    let names: std::collections::BTreeMap<u64, &str> = trace
        .iter()
        .filter_map(|e| match &e.kind {
            TraceKind::Spawned { node, name, .. } => Some((*node, name.as_str())),
            _ => None,
        })
        .collect();
    trace
        .iter()
        .filter(|e| {
            matches!(e.kind, TraceKind::Transition { node, facet: tcm::Facet::Handling, to: tcm::State::Active, .. } if names.get(&node) == Some(&name))
        })
        .map(|e| Duration::from_nanos(e.t))
        .collect()
}

#[tokio::test(start_paused = true)]
async fn a_paused_run_is_not_stuck_and_goes_on_when_resumed() {
    let (session, rec) = start();
    let control = session.control();
    assert!(control.pause("operator").expect("pause"));
    let node = control.spawn(quick("first")).expect("spawn");
    let later = control.clone();
    tokio::spawn(async move {
        tokio::time::sleep(Duration::from_secs(5)).await;
        later.resume("operator").expect("resume");
    });
    let outcome = tokio::time::timeout(NEVER, control.wait(node))
        .await
        .expect("ends")
        .expect("wait");
    assert!(matches!(outcome, WatchOutcome::Reached), "{outcome:?}");
    session.finish().await.expect("finish");
    let trace = rec.events();
    assert_checked(&trace);
    assert_eq!(starts(&trace, "first"), vec![Duration::from_secs(5)]);
    assert!(trace.iter().any(|e| e.kind
        == TraceKind::Resumed {
            held_ns: 5_000_000_000
        }));
}

/// A 1 kHz monitor run for `total` with a pause of `pause` from `at`; its activation times.
async fn monitored(total: Duration, at: Duration, pause: Duration) -> (Vec<u64>, Vec<TraceEvent>) {
    let (session, rec) = start();
    let control = session.control();
    let params = Monitor {
        period: Some(Duration::from_millis(1)),
        ..Monitor::default()
    };
    let tick = control
        .spawn(Task::monitor("tick", params, |_| async { Ok(()) }))
        .expect("spawn");
    tokio::time::sleep(at).await;
    control.pause("operator").expect("pause");
    tokio::time::sleep(pause).await;
    control.resume("operator").expect("resume");
    tokio::time::sleep(total - at - pause).await;
    control.terminate(tick).expect("terminate");
    session.finish().await.expect("finish");
    let trace = rec.events();
    let times = trace
        .iter()
        .filter(|e| matches!(e.kind, TraceKind::Activated { .. }))
        .map(|e| e.t)
        .collect();
    (times, trace)
}

#[tokio::test(start_paused = true)]
async fn a_pause_keeps_a_1khz_monitors_schedule_on_virtual_time() {
    let ms = Duration::from_millis;
    let (times, trace) = monitored(ms(300), ms(100), ms(100)).await;
    assert_checked(&trace);
    // Polls at 0..=100 ms, none while paused, then on the shifted schedule: no burst.
    let gaps: Vec<u64> = times.windows(2).map(|w| w[1] - w[0]).collect();
    let long: Vec<&u64> = gaps.iter().filter(|g| **g != 1_000_000).collect();
    assert_eq!(long.len(), 1, "one gap, the pause: {long:?}");
    assert!(*long[0] >= 100_000_000, "{long:?}");
    assert!((199..=202).contains(&times.len()), "{}", times.len());
}

#[tokio::test(flavor = "current_thread")]
async fn a_pause_keeps_a_1khz_monitors_schedule_on_the_real_clock() {
    let ms = Duration::from_millis;
    // 600 ms, paused for 300 of them: about 300 activations. Without the schedule held, the
    // polls due during the pause would come at once on resuming, about 600 in all.
    let (times, trace) = monitored(ms(600), ms(150), ms(300)).await;
    assert_checked(&trace);
    assert!(
        (150..=420).contains(&times.len()),
        "{} activations",
        times.len()
    );
    // Nothing within the pause (the resume comes at least 300 ms after the pause).
    let gaps = times.windows(2).map(|w| w[1] - w[0]);
    assert!(gaps.max().unwrap_or(0) >= 290_000_000);
}

#[tokio::test(start_paused = true)]
async fn held_nodes_start_when_approved_and_fail_when_refused() {
    let (session, rec) = start();
    let control = session.control();
    control
        .require_approval(
            Approval {
                on: Matcher::Task("arm".into()),
                timeout: None,
            },
            "operator",
        )
        .expect("rule");
    let first = control.spawn(quick("arm")).expect("spawn");
    let second = control.spawn(quick("arm")).expect("spawn");
    tokio::time::sleep(Duration::from_secs(2)).await;
    assert_eq!(control.held().expect("held"), vec![first, second]);
    control.approve(first, "operator").expect("approve");
    control
        .refuse(second, "operator", "the gripper is open")
        .expect("refuse");
    assert!(
        control.approve(second, "operator").is_err(),
        "no longer held"
    );
    let done = tokio::time::timeout(NEVER, control.wait(first)).await;
    assert!(matches!(done, Ok(Ok(WatchOutcome::Reached))));
    session.finish().await.expect("finish");
    let trace = rec.events();
    assert_checked(&trace);
    assert_eq!(starts(&trace, "arm"), vec![Duration::from_secs(2)]);
    assert!(trace.iter().any(|e| matches!(&e.kind,
        TraceKind::Failed { exception, message, .. } if exception == "ApprovalRefused" && message == "not approved: the gripper is open")));
}

#[tokio::test(start_paused = true)]
async fn a_breakpoint_and_a_fault_from_the_control_handle() {
    let (session, rec) = start();
    let control = session.control();
    control
        .add_breakpoint(
            Breakpoint {
                at: BreakAt::Start,
                on: Matcher::Path("second".into()),
            },
            "operator",
        )
        .expect("breakpoint");
    control
        .inject(
            Fault {
                on: Matcher::Task("first".into()),
                times: 1,
                outcome: FaultOutcome::Fail(Failure::new("Blocked", "injected")),
            },
            "operator",
        )
        .expect("fault");
    control.spawn(quick("first")).expect("spawn");
    let second = control.spawn(quick("second")).expect("spawn");
    tokio::time::sleep(Duration::from_secs(3)).await;
    assert!(control.is_paused().expect("paused"));
    control.step("operator").expect("step");
    tokio::time::sleep(Duration::from_secs(3)).await;
    assert!(control.is_paused().expect("paused after the step"));
    control.resume("operator").expect("resume");
    let b = tokio::time::timeout(NEVER, control.wait(second)).await;
    assert!(matches!(b, Ok(Ok(WatchOutcome::Reached))), "{b:?}");
    session.finish().await.expect("finish");
    let trace = rec.events();
    assert_checked(&trace);
    assert_eq!(starts(&trace, "first"), vec![Duration::ZERO]);
    assert_eq!(starts(&trace, "second"), vec![Duration::from_secs(3)]);
    assert!(
        trace
            .iter()
            .any(|e| matches!(&e.kind, TraceKind::Injected { node: 1, .. }))
    );
    assert!(trace.iter().any(|e| matches!(&e.kind,
        TraceKind::Failed { node: 1, exception, .. } if exception == "Blocked")));
}

/// A typed value stands for a command's: the goal waiting for it reads the fault's.
#[tokio::test(start_paused = true)]
async fn a_fault_value_is_what_a_waiting_body_reads() {
    let (session, rec) = start();
    let control = session.control();
    control
        .inject(
            Fault {
                on: Matcher::Task("measure".into()),
                times: 1,
                outcome: FaultOutcome::Succeed(Some(tcm::FaultValue::of(0.5f64))),
            },
            "operator",
        )
        .expect("fault");
    let read = std::sync::Arc::new(std::sync::Mutex::new(None));
    let seen = read.clone();
    let goal = Task::goal("survey", move |ctx| {
        let seen = seen.clone();
        async move {
            let measure = Task::command("measure", |_| async { Ok(10.0f64) });
            let range: f64 = ctx.spawn(measure).wait_value().await?;
            *seen.lock().expect("seen") = Some(range);
            Ok(())
        }
    });
    let node = control.spawn(goal).expect("spawn");
    let done = tokio::time::timeout(NEVER, control.wait(node)).await;
    assert!(matches!(done, Ok(Ok(WatchOutcome::Reached))), "{done:?}");
    session.finish().await.expect("finish");
    assert_eq!(*read.lock().expect("read"), Some(0.5));
    let trace = rec.events();
    assert_checked(&trace);
    assert!(trace.iter().any(|e| matches!(&e.kind,
        TraceKind::Injected { outcome, .. } if outcome == "succeed with 0.5")));
}
