//! TDL programs as a TCM programmer ports them (issue 11): terminating what already ended is no
//! failure, and activations fire on the completion of a terminated node.

use crate::util::{run_checked, story};
use tdl::{RunOutcome, Runtime, TraceKind};

async fn sleep_s(s: u64) {
    tokio::time::sleep(std::time::Duration::from_secs(s)).await;
}

tdl::tdl! {
    command quick() { sleep_s(1).await; }
    command slow() { sleep_s(100).await; }

    goal tidy_up() {
        q: spawn quick() with wait;
        // `q` completed and is gone: TCM warned and went on; so does this body.
        q terminate;
        q terminate;
        spawn slow() with terminate in 2s;
    }

    monitor on_end() with maximum activate 2 {
        ctx.trigger()?;
    }

    goal watch_ends() {
        a: spawn slow() with terminate in 1s;
        b: spawn slow() with disable for 5s, terminate in 2s;
        spawn on_end() with activate at a completed, activate at b completed;
    }
}

#[tokio::test(start_paused = true)]
async fn terminating_a_completed_task_warns_and_the_body_goes_on() {
    let (report, trace) = run_checked(Runtime::new(), tidy_up()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let warnings: Vec<&String> = trace
        .iter()
        .filter_map(|r| match &r.kind {
            TraceKind::Warning { message, .. } => Some(message),
            _ => None,
        })
        .collect();
    assert_eq!(warnings.len(), 2, "{warnings:?}");
    assert!(
        warnings
            .iter()
            .all(|w| w.starts_with("Trying to terminate already dead node")),
        "{warnings:?}"
    );
    let st = story(&trace);
    assert!(st.contains(&"3 slow terminated".to_string()), "{st:#?}");
}

#[tokio::test(start_paused = true)]
async fn activate_at_completed_fires_when_the_task_was_terminated() {
    let (report, trace) = run_checked(Runtime::new(), watch_ends()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let activations: Vec<u64> = trace
        .iter()
        .filter_map(|r| match &r.kind {
            TraceKind::Activated { .. } => Some(r.t / 1_000_000_000),
            _ => None,
        })
        .collect();
    assert_eq!(activations, [1, 2]);
}
