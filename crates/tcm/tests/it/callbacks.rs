//! Timer callbacks (issue 11, point 16): TCM's `InvokeWhen` and `InvokeAfter`, a function run at an
//! event of a node or after a delay. They are no task nodes; a pending timed one keeps the run
//! alive, a pending event one does not (docs/semantics.md, "Run outcome").

use crate::util::{assert_order, run_checked, story};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tcm::{
    Constraint, Event, Facet, Point, RunOutcome, Runtime, Task, TraceKind, WatchOutcome, When,
};

fn secs(s: u64) -> Duration {
    Duration::from_secs(s)
}

/// Longer than any run here: a run that does not end fails instead of hanging `cargo test`.
const NEVER: Duration = Duration::from_secs(24 * 3600);

#[tokio::test(start_paused = true)]
async fn invoke_after_runs_later_and_keeps_the_run_alive_meanwhile() {
    // `enter` waits for an event only the callback raises: without the pending callback, the run
    // would be stuck at 0 s.
    let task = Task::goal("g", |ctx| async move {
        let door = ctx.external("door_open")?;
        ctx.spawn(Task::command("enter", |_| async { Ok(()) }))
            .with(Constraint::disable(Facet::Handling, When::External(door)))
            .start()?;
        ctx.invoke_after("open the door", secs(5), |ctx| {
            let _ = ctx.raise("door_open");
        })?;
        Ok(())
    });
    let (report, trace) = tokio::time::timeout(NEVER, run_checked(Runtime::new(), task))
        .await
        .expect("the run ends");
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_order(
        &story(&trace),
        &[
            "0 g handling completed",
            "5 callback open the door ran",
            "5 enter handling active",
            "5 g execution completed",
        ],
    );
    // A callback is no node: no `spawned` record names it.
    let spawned = trace
        .iter()
        .filter(|e| matches!(e.kind, TraceKind::Spawned { .. }))
        .count();
    assert_eq!(spawned, 2);
    assert!(trace.iter().any(|e| matches!(
        &e.kind,
        TraceKind::CallbackSet { name, node: Some(1), when: tcm_trace::TraceWhen::At(5_000_000_000), .. }
        if name == "open the door"
    )));
}

#[tokio::test(start_paused = true)]
async fn invoke_when_runs_at_the_event_with_how_the_node_got_there() {
    let seen = Arc::new(Mutex::new(Vec::new()));
    let (s1, s2, s3) = (seen.clone(), seen.clone(), seen.clone());
    let task = Task::goal("g", move |ctx| async move {
        let mv = ctx
            .spawn(Task::command("move", |_| async {
                tokio::time::sleep(secs(2)).await;
                Ok(())
            }))
            .start()?;
        let grip = ctx
            .spawn(Task::command("grip", |_| async {
                std::future::pending::<()>().await;
                Ok(())
            }))
            .terminate_in(secs(3))
            .start()?;
        ctx.invoke_when(
            "moved",
            Event::on(mv, Facet::Execution, Point::Completed),
            move |ctx, out| s1.lock().expect("seen").push(("moved", ctx.now(), out)),
        )?;
        ctx.invoke_when(
            "gripped",
            Event::on(grip, Facet::Execution, Point::Completed),
            move |ctx, out| s2.lock().expect("seen").push(("gripped", ctx.now(), out)),
        )?;
        // An event that already happened: the callback runs at once.
        ctx.invoke_when(
            "started",
            Event::on(ctx.node(), Facet::Handling, Point::Active),
            move |ctx, out| s3.lock().expect("seen").push(("started", ctx.now(), out)),
        )?;
        Ok(())
    });
    let (report, trace) = run_checked(Runtime::new(), task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(
        *seen.lock().expect("seen"),
        [
            ("started", secs(0), WatchOutcome::Reached),
            ("moved", secs(2), WatchOutcome::Reached),
            ("gripped", secs(3), WatchOutcome::Terminated),
        ]
    );
    assert_order(
        &story(&trace),
        &[
            "0 callback started ran",
            "2 move execution completed",
            "2 callback moved ran",
            "3 grip terminating",
            "3 callback gripped ran",
        ],
    );
}

#[tokio::test(start_paused = true)]
async fn a_pending_invoke_when_does_not_keep_the_run_alive() {
    // As in TCM, a requested event does not keep the agenda running: nothing can raise `never`,
    // so the run is stuck, and the callback never ran.
    let ran = Arc::new(Mutex::new(false));
    let r = ran.clone();
    let task = Task::goal("g", move |ctx| async move {
        let never = ctx.external("never")?;
        let blocked = ctx
            .spawn(Task::command("blocked", |_| async { Ok(()) }))
            .with(Constraint::disable(Facet::Handling, When::External(never)))
            .start()?;
        ctx.invoke_when(
            "after blocked",
            Event::on(blocked, Facet::Execution, Point::Completed),
            move |_, _| *r.lock().expect("ran") = true,
        )?;
        Ok(())
    });
    let (report, trace) = tokio::time::timeout(NEVER, run_checked(Runtime::new(), task))
        .await
        .expect("the run ends");
    let RunOutcome::Stuck(blocked) = report.outcome else {
        panic!("expected stuck, got {:?}", report.outcome);
    };
    assert_eq!(
        blocked.iter().map(ToString::to_string).collect::<Vec<_>>(),
        ["blocked {2} handling waits for external event `never`"]
    );
    assert!(!*ran.lock().expect("ran"));
    assert!(!story(&trace).iter().any(|l| l.contains("callback")));
}

#[tokio::test(start_paused = true)]
async fn callbacks_due_at_one_time_run_in_the_order_they_were_set() {
    let order = Arc::new(Mutex::new(Vec::new()));
    let task = {
        let order = order.clone();
        Task::goal("g", move |ctx| async move {
            for (name, d) in [("b", 2), ("a", 1), ("c", 2), ("d", 1)] {
                let o = order.clone();
                ctx.invoke_after(name, secs(d), move |_| o.lock().expect("order").push(name))?;
            }
            // The run stays alive for them: `g` waits on a node that ends after all of them.
            ctx.spawn(Task::command("late", |_| async { Ok(()) }))
                .disable_for(Facet::Handling, secs(3))
                .wait()
                .await?;
            Ok(())
        })
    };
    let (report, _) = run_checked(Runtime::new(), task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(*order.lock().expect("order"), ["a", "d", "b", "c"]);
}

/// A callback runs when its event happens, before the next action (TCM ran it when the event was
/// signalled): commands `x`, then `y` after `x`, then `z` after `y`, all ending at once; a
/// callback on "x execution completed" runs before `y`'s action, not after `z`'s. One set on an
/// event already past runs at once, inside the action that set it, before `invoke_when` returns.
/// (With every action a task, the trace is the same: `pump/tests.rs`.)
#[tokio::test(start_paused = true)]
async fn a_callback_runs_when_its_event_happens_before_the_next_action() {
    let log: Arc<Mutex<Vec<&'static str>>> = Arc::default();
    let l = log.clone();
    let task = Task::goal("g", move |ctx| async move {
        let note = |l: &Arc<Mutex<Vec<&'static str>>>, what| l.lock().expect("log").push(what);
        let (lx, ly, lz) = (l.clone(), l.clone(), l.clone());
        let x = ctx
            .spawn(Task::command("x", move |_| async move {
                note(&lx, "x");
                Ok(())
            }))
            .start()?;
        let y = ctx
            .spawn(Task::command("y", move |ctx| async move {
                note(&ly, "y");
                // `x` completed already: this callback runs before `invoke_when` returns.
                let lp = ly.clone();
                ctx.invoke_when(
                    "x was done",
                    Event::on(x, Facet::Execution, Point::Completed),
                    move |_, _| note(&lp, "past callback"),
                )?;
                note(&ly, "y after invoke_when");
                Ok(())
            }))
            .with(Constraint::sequential_previous())
            .start()?;
        ctx.spawn(Task::command("z", move |_| async move {
            note(&lz, "z");
            Ok(())
        }))
        .with(Constraint::Sequential(Facet::Execution, y.into()))
        .start()?;
        let lc = l.clone();
        ctx.invoke_when(
            "x done",
            Event::on(x, Facet::Execution, Point::Completed),
            move |_, _| note(&lc, "callback"),
        )?;
        Ok(())
    });
    let (report, trace) = run_checked(Runtime::new(), task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(
        *log.lock().expect("log"),
        [
            "x",
            "callback",
            "y",
            "past callback",
            "y after invoke_when",
            "z"
        ],
    );
    assert_order(
        &story(&trace),
        &[
            "0 x execution completed",
            "0 callback x done ran",
            "0 z handling active",
        ],
    );
}
