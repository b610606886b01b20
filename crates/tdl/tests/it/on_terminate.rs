//! On-terminate tasks: several on one task, and labels on those of a spawn, which name the node
//! inserted when the spawned node is terminated while running, or are dead once it ended
//! otherwise (docs/language.md, "Tags, `previous` and groups").

use crate::util::{assert_order, only, run_checked, story};
use tdl::{RunOutcome, Runtime, TraceKind};

async fn sleep_s(s: u64) {
    tokio::time::sleep(std::time::Duration::from_secs(s)).await;
}

/// Drives to a goal; when its node is terminated, cancels the goal on the (simulated) server, which
/// takes 300 ms: the cancellation signal reaches a TDL body through its `ctx`.
async fn drive_until_cancelled(ctx: &tdl::Ctx) {
    tokio::select! {
        () = sleep_s(100) => {}
        () = ctx.cancelled() => tokio::time::sleep(std::time::Duration::from_millis(300)).await,
    }
}

tdl::tdl! {
    command release() { sleep_s(1).await; }
    command stow() { sleep_s(1).await; }
    command hold() { std::future::pending::<()>().await; }
    command brief() { sleep_s(1).await; }
    command report() { sleep_s(1).await; }
    command after_brief() { sleep_s(1).await; }

    command grip() with on terminate spawn release(), on terminate stow() {
        std::future::pending::<()>().await;
    }

    goal hold_briefly() {
        spawn grip() with terminate in 2s;
    }

    command drive() { drive_until_cancelled(&ctx).await; }

    goal drive_briefly() {
        spawn drive() with terminate in 2s;
    }

    goal careful() {
        spawn report() with sequential execution one;
        g: spawn hold() with on terminate one: spawn release(), on terminate two: spawn stow(),
            terminate in 2s;
        two serial one;
        spawn brief() with on terminate gone: spawn release();
        spawn after_brief() with sequential execution gone;
    }
}

#[tokio::test(start_paused = true)]
async fn every_task_level_on_terminate_task_runs() {
    let (report, trace) = run_checked(Runtime::new(), hold_briefly()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_order(
        &story(&trace),
        &[
            "2 grip terminating",
            "2 release handling active",
            "2 stow handling active",
            "3 release execution completed",
            "3 stow execution completed",
            "3 grip terminated",
        ],
    );
}

#[tokio::test(start_paused = true)]
async fn a_body_awaiting_its_cancellation_cancels_before_its_node_is_terminated() {
    let (report, trace) = run_checked(Runtime::new(), drive_briefly()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_order(
        &story(&trace),
        &["2 drive terminating", "2.3 drive terminated"],
    );
    assert!(report.is_clean(), "{report}");
}

#[tokio::test(start_paused = true)]
async fn an_on_terminate_label_names_the_cleanup_or_dies_with_its_node() {
    let (report, trace) = run_checked(Runtime::new(), careful()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    // `one` and `two` are the cleanups of `hold`, terminated at 2: `two serial one` orders them,
    // and `report` waits for `one`. `brief` ends normally at 1, so its label `gone` is dead then
    // and `after_brief` starts.
    assert_eq!(
        only(&story(&trace), &["handling active", " dead"]),
        [
            "0 careful handling active",
            "0 hold handling active",
            "0 brief handling active",
            "1 release dead",
            "1 after_brief handling active",
            "2 release handling active",
            "3 report handling active",
            "3 stow handling active",
        ]
    );
    // The labels' reservations are the cleanup nodes, under `hold`.
    let reserved: Vec<u64> = trace
        .iter()
        .filter_map(|ev| match &ev.kind {
            TraceKind::Reserved { node, .. } => Some(*node),
            _ => None,
        })
        .collect();
    let hold = trace.iter().find_map(|ev| match &ev.kind {
        TraceKind::Spawned { node, name, .. } if name == "hold" => Some(*node),
        _ => None,
    });
    let cleanups: Vec<(u64, Option<u64>)> = trace
        .iter()
        .filter_map(|ev| match &ev.kind {
            TraceKind::Spawned {
                node, parent, name, ..
            } if name == "release" || name == "stow" => Some((*node, Some(*parent))),
            _ => None,
        })
        .collect();
    assert_eq!(
        cleanups,
        [(reserved[0], hold), (reserved[1], hold)],
        "{reserved:?}"
    );
}
