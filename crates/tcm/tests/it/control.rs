//! A run extended and controlled from outside while it runs (`Session::control`): handlers
//! attached to a task's live nodes and those to come, then detached; wiretaps added and removed;
//! operations noted in the trace. Virtual time; every trace through the checker.

use std::time::Duration;
use tcm::testing::assert_checked;
use tcm::{Attached, Failure, Handler, TapWhen, Task, TraceKind, WatchOutcome};

/// Longer than any run here: a run that does not end fails instead of hanging `cargo test`.
const NEVER: Duration = Duration::from_secs(24 * 3600);

/// A move that is blocked after `secs` seconds.
fn blocked_move(secs: u64) -> Task {
    Task::command("move", move |_| async move {
        tokio::time::sleep(Duration::from_secs(secs)).await;
        Err::<(), _>(Failure::new("Blocked", "an obstacle"))
    })
}

fn back_off() -> Attached {
    Attached::new(
        "move",
        Handler::new("back_off", "Blocked", |_| async { Ok(()) }),
    )
}

use crate::util::recorded_session as start;

async fn wait(control: &tcm::Control, node: tcm::NodeId) -> WatchOutcome {
    tokio::time::timeout(NEVER, control.wait(node))
        .await
        .expect("the node ends")
        .expect("wait")
}

fn handled(o: &WatchOutcome) -> bool {
    matches!(o, WatchOutcome::Handled(_))
}

#[tokio::test(start_paused = true)]
async fn a_handler_attached_while_the_run_runs_takes_the_next_failure_and_no_more_once_detached() {
    let (session, rec) = start();
    let control = session.control();
    let first = control.spawn(blocked_move(1)).expect("spawn");
    assert!(matches!(
        wait(&control, first).await,
        WatchOutcome::Failed(_)
    ));

    // Attached while a move runs: that live move takes it, and so does the next one.
    let live = control.spawn(blocked_move(5)).expect("spawn");
    tokio::time::sleep(Duration::from_secs(1)).await;
    let id = control.attach(back_off()).expect("attach");
    control.note("attach back_off", "operator").expect("note");
    assert!(handled(&wait(&control, live).await), "the live move");
    let next = control.spawn(blocked_move(1)).expect("spawn");
    assert!(handled(&wait(&control, next).await), "a move spawned after");

    assert!(control.detach(id).expect("detach"));
    assert!(
        !control.detach(id).expect("detach twice"),
        "already detached"
    );
    let last = control.spawn(blocked_move(1)).expect("spawn");
    assert!(matches!(
        wait(&control, last).await,
        WatchOutcome::Failed(_)
    ));
    session.finish().await.expect("finish");

    let trace = rec.events();
    assert_checked(&trace);
    let chosen: Vec<u64> = trace
        .iter()
        .filter_map(|e| match &e.kind {
            TraceKind::HandlerChosen { node, .. } => Some(*node),
            _ => None,
        })
        .collect();
    assert_eq!(chosen.len(), 2, "two failures handled: {chosen:?}");
    let attached = trace
        .iter()
        .position(|e| matches!(&e.kind, TraceKind::HandlerAttached { task, handler, .. } if task == "move" && handler == "back_off"))
        .expect("the attachment is recorded");
    let detached = trace
        .iter()
        .position(
            |e| matches!(e.kind, TraceKind::HandlerDetached { attach } if attach == id.number()),
        )
        .expect("the removal is recorded");
    assert!(attached < detached);
    assert!(trace.iter().any(|e| matches!(&e.kind, TraceKind::Control { what, by } if what == "attach back_off" && by == "operator")));
    // The time of the attachment is the run's time when it was made.
    assert_eq!(trace[attached].t, Duration::from_secs(2).as_nanos() as u64);
}

#[tokio::test(start_paused = true)]
async fn a_wiretap_added_while_the_run_runs_checks_the_next_nodes_until_removed() {
    let (session, rec) = start();
    let control = session.control();
    let ok = |name| {
        Task::command(name, |_| async {
            tokio::time::sleep(Duration::from_secs(1)).await;
            Ok(())
        })
    };
    let a = control.spawn(ok("scan")).expect("spawn");
    wait(&control, a).await;
    let tap = control
        .wiretap("scan", TapWhen::Before, |_| async {
            Err::<(), _>(Failure::new("Unsafe", "vetoed"))
        })
        .expect("tap");
    let b = control.spawn(ok("scan")).expect("spawn");
    assert!(
        matches!(wait(&control, b).await, WatchOutcome::Failed(f) if f.exception == "Unsafe"),
        "the tap vetoes the next scan"
    );
    assert!(control.untap(tap).expect("untap"));
    assert!(!control.untap(tap).expect("untap twice"));
    let c = control.spawn(ok("scan")).expect("spawn");
    assert_eq!(wait(&control, c).await, WatchOutcome::Reached);
    session.finish().await.expect("finish");

    let trace = rec.events();
    assert_checked(&trace);
    let tapped = trace
        .iter()
        .filter(|e| matches!(e.kind, TraceKind::Tapped { .. }))
        .count();
    assert_eq!(tapped, 1, "one check, on the scan between add and removal");
    assert!(trace.iter().any(|e| matches!(&e.kind, TraceKind::TapAdded { task, when, instance: false, .. } if task == "scan" && when == "before")));
    assert!(
        trace
            .iter()
            .any(|e| matches!(e.kind, TraceKind::TapRemoved { tap: t } if t == tap.number()))
    );
}

#[tokio::test(start_paused = true)]
async fn a_task_with_a_version_names_it_in_its_spawned_record_and_control_ends_with_the_run() {
    let (session, rec) = start();
    let control = session.control();
    let v: std::sync::Arc<str> = "3f2a".into();
    let a = control
        .spawn(Task::command("scan", |_| async { Ok(()) }).version(v))
        .expect("spawn");
    wait(&control, a).await;
    assert_eq!(control.top_level().expect("top level"), vec![]);
    assert_eq!(control.stats().expect("stats").live_nodes, 1, "the root");
    session.finish().await.expect("finish");
    assert!(
        matches!(control.raise("late"), Err(tcm::Error::RunEnded)),
        "the run ended: control says so"
    );
    let trace = rec.events();
    assert_checked(&trace);
    let line = trace
        .iter()
        .find(|e| matches!(e.kind, TraceKind::Spawned { .. }))
        .map(tcm_trace_line)
        .expect("spawned");
    assert!(line.contains(r#""version":"3f2a""#), "{line}");
}

fn tcm_trace_line(e: &tcm::TraceEvent) -> String {
    serde_json::to_string(e).expect("a record is JSON")
}
