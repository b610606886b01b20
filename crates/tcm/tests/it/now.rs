//! Synchronous actions (`Task::command_now`, `Task::goal_now`; issue 41, item 2): an action that
//! ends without awaiting, written as a plain function, runs where its async twin's future would be
//! polled and gives the same trace, record for record, on a current-thread runtime (where the pump
//! calls it without making a future; the pump's random programs compare it with tasks too), and
//! reaches the same points on a multi-thread one (where it runs in a task).

use tcm::testing::{run_checked, run_checked_allowing_panics};
use tcm::{Failure, Handler, NodeRef, RunOutcome, Runtime, Task, TraceKind};

/// A mission whose goal spawns a sequence of steps and a pair released together, one step failing
/// into the goal's handler, written with synchronous actions (`now`) or async ones.
fn mission(now: bool) -> Task {
    let step = move |name: &'static str, fails: bool| {
        let end = move || {
            if fails {
                Err(Failure::new("Slipped", format!("{name} slipped")))
            } else {
                Ok(name.len())
            }
        };
        if now {
            Task::command_now(name, move |ctx| {
                ctx.log(format!("{name} runs"))?;
                end()
            })
        } else {
            Task::command(name, move |ctx| async move {
                ctx.log(format!("{name} runs"))?;
                end()
            })
        }
    };
    let body = move |ctx: &tcm::Ctx| -> Result<(), Failure> {
        ctx.spawn(step("undock", false)).start()?;
        ctx.spawn(step("drive", false))
            .serial(NodeRef::Previous)
            .start()?;
        let grasp = ctx
            .spawn(step("grasp", true))
            .serial(NodeRef::Previous)
            .start()?;
        for name in ["look", "listen"] {
            ctx.spawn(step(name, false)).serial(grasp).start()?;
        }
        Ok(())
    };
    let recover = Handler::new("recover", "Slipped", |_| async { Ok(()) });
    if now {
        Task::goal_now("mission", move |ctx| body(&ctx)).handler(recover)
    } else {
        Task::goal("mission", move |ctx| async move { body(&ctx) }).handler(recover)
    }
}

/// The trace's records without the run's identity (`run_started` carries a fresh one).
fn records(trace: &[tcm::TraceEvent]) -> Vec<String> {
    trace
        .iter()
        .filter(|e| !matches!(e.kind, TraceKind::RunStarted { .. }))
        .map(|e| format!("{} {:?}", e.t, e.kind))
        .collect()
}

#[tokio::test(start_paused = true)]
async fn a_synchronous_action_gives_the_trace_of_its_async_twin() {
    let (now_report, now) = run_checked(Runtime::new(), mission(true)).await;
    let (async_report, written_async) = run_checked(Runtime::new(), mission(false)).await;
    assert_eq!(now_report.outcome, RunOutcome::Completed);
    assert_eq!(async_report.outcome, RunOutcome::Completed);
    assert_eq!(records(&now), records(&written_async));
    // The steps ran, logged, and the failing one was handled.
    let logs = now
        .iter()
        .filter(|e| matches!(e.kind, TraceKind::Log { .. }))
        .count();
    assert_eq!(logs, 5);
    assert!(now.iter().any(
        |e| matches!(&e.kind, TraceKind::HandlerChosen { handler, .. } if handler == "recover")
    ));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn on_a_multi_thread_runtime_a_synchronous_action_runs_in_a_task_and_ends_alike() {
    let (report, trace) = run_checked(Runtime::new(), mission(true)).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let (_, written_async) = run_checked(Runtime::new(), mission(false)).await;
    // Each node reaches the same points (the interleaving of a parallel run may differ).
    let mut now: Vec<String> = records(&trace).into_iter().map(untimed).collect();
    let mut twin: Vec<String> = records(&written_async).into_iter().map(untimed).collect();
    now.sort();
    twin.sort();
    assert_eq!(now, twin);
}

/// A record without its time stamp.
fn untimed(r: String) -> String {
    r.split_once(' ').map_or(r.clone(), |(_, k)| k.to_string())
}

#[tokio::test(start_paused = true)]
async fn a_panicking_synchronous_action_fails_its_node_not_the_run() {
    let task = Task::goal_now("g", |ctx| {
        ctx.spawn(Task::command_now("boom", |_| -> Result<(), Failure> {
            panic!("the arm hit the table")
        }))
        .start()?;
        Ok(())
    });
    let (report, trace) = run_checked_allowing_panics(Runtime::new(), task).await;
    // The command's failure is its own (no handler, not propagated): the run goes on and ends.
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert!(
        trace.iter().any(
            |e| matches!(&e.kind, TraceKind::Failed { exception, message, .. }
            if exception == "ActionPanicked" && message.contains("the arm hit the table"))
        ),
        "{trace:#?}"
    );
}
