//! Panics in tests (issue 11, point 19): outside tests a panicking action only fails its node; in
//! `tcm::testing::run_checked` it fails the test with the panic's message, and
//! `run_checked_allowing_panics` opts out.

use std::time::Duration;
use tcm::testing::{run_checked, run_checked_allowing_panics};
use tcm::{RunOutcome, Runtime, Task};

fn asserting() -> Task {
    Task::goal("g", |ctx| async move {
        ctx.spawn(Task::command("check", |_| async {
            tokio::time::sleep(Duration::from_secs(1)).await;
            assert_eq!(1 + 1, 3, "arithmetic is broken");
            Ok(())
        }))
        .start()?;
        Ok(())
    })
}

fn message(p: Box<dyn std::any::Any + Send>) -> String {
    match p.downcast::<String>() {
        Ok(s) => *s,
        Err(p) => p
            .downcast::<&str>()
            .map(|s| s.to_string())
            .unwrap_or_default(),
    }
}

#[tokio::test(start_paused = true)]
async fn a_failed_assert_in_an_action_fails_run_checked_with_its_message() {
    let res = tokio::spawn(run_checked(Runtime::new(), asserting())).await;
    let Err(err) = res else {
        panic!("run_checked returned although an action panicked");
    };
    assert!(err.is_panic());
    let text = message(err.into_panic());
    assert!(
        text.starts_with("action check {2} (g/check) panicked: assertion `left == right` failed: arithmetic is broken"),
        "{text}"
    );
    assert!(text.contains("story:"), "{text}");
}

#[tokio::test(start_paused = true)]
async fn allowing_panics_keeps_the_old_behaviour_and_reports_them() {
    let (report, trace) = run_checked_allowing_panics(Runtime::new(), asserting()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(report.panics.len(), 1);
    assert_eq!(report.panics[0].path, "g/check");
    assert!(trace.iter().any(|e| matches!(
        &e.kind,
        tcm::TraceKind::Failed { exception, .. } if exception == "ActionPanicked"
    )));
}

#[tokio::test(start_paused = true)]
async fn a_panicking_callback_is_reported_too() {
    let task = Task::goal("g", |ctx| async move {
        ctx.invoke_after("boom", Duration::from_secs(1), |_| {
            panic!("callback exploded")
        })?;
        ctx.spawn(Task::command("wait", |_| async { Ok(()) }))
            .disable_for(tcm::Facet::Handling, Duration::from_secs(2))
            .start()?;
        Ok(())
    });
    let (report, _) = run_checked_allowing_panics(Runtime::new(), task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let text: Vec<String> = report.panics.iter().map(ToString::to_string).collect();
    assert_eq!(text, ["callback boom {1} (g) panicked: callback exploded"]);
}
