//! Work beside the tree (docs/semantics.md, "Work beside the tree"): a task of the program that an
//! action wakes runs before the next action, as TCM's agenda dispatched external input between
//! any two actions, when it is spawned through the run's `EventHandle::spawn`.

use crate::util::run_checked;
use std::sync::{Arc, Mutex};
use tcm::{Constraint, Facet, RunOutcome, Runtime, State, Task, TraceKind};

type Log = Arc<Mutex<Vec<&'static str>>>;

fn note(log: &Log, what: &'static str) {
    log.lock().expect("log").push(what);
}

/// Commands `x`, then `y` after `x`, then `z` after `y`, all ending at once; `x` wakes a task of
/// the program (as a message on a socket would), which notes it and raises an event.
fn chain(log: &Log, tx: tokio::sync::mpsc::UnboundedSender<()>) -> Task {
    let (lx, ly, lz) = (log.clone(), log.clone(), log.clone());
    Task::goal("g", move |ctx| async move {
        ctx.spawn(Task::command("x", move |_| async move {
            note(&lx, "x");
            let _ = tx.send(());
            Ok(())
        }))
        .start()?;
        ctx.spawn(Task::command("y", move |_| async move {
            note(&ly, "y");
            Ok(())
        }))
        .with(Constraint::sequential_previous())
        .start()?;
        ctx.spawn(Task::command("z", move |_| async move {
            note(&lz, "z");
            Ok(())
        }))
        .with(Constraint::sequential_previous())
        .start()?;
        Ok(())
    })
}

/// The program's task waits for one message, notes it and raises `heard`.
async fn listener(
    log: Log,
    mut rx: tokio::sync::mpsc::UnboundedReceiver<()>,
    events: tcm::EventHandle,
) {
    if rx.recv().await.is_some() {
        note(&log, "heard");
        let _ = events.raise("heard");
    }
}

#[tokio::test(start_paused = true)]
async fn a_task_spawned_beside_the_run_runs_between_the_actions_that_woke_it_and_the_next() {
    let log: Log = Arc::default();
    let (tx, rx) = tokio::sync::mpsc::unbounded_channel();
    let rt = Runtime::new();
    let events = rt.events();
    events
        .spawn(listener(log.clone(), rx, events.clone()))
        .expect("inside a runtime");
    drop(events);
    let (report, trace) = run_checked(rt, chain(&log, tx)).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(*log.lock().expect("log"), ["x", "heard", "y", "z"]);
    // The event it raised comes between `x`'s end and `y`'s in the trace too (`y` is active
    // already: the engine starts a node at the end that releases it, before its action runs).
    let display = |name: &str| {
        trace.iter().find_map(|r| match &r.kind {
            TraceKind::Spawned { node, name: n, .. } if n == name => Some(*node),
            _ => None,
        })
    };
    let (x, y) = (display("x"), display("y"));
    let at = |what: &dyn Fn(&TraceKind) -> bool| trace.iter().position(|r| what(&r.kind));
    let ended = |n: Option<u64>| move |k: &TraceKind| completed(k, n);
    let heard = at(&|k| matches!(k, TraceKind::External { name, .. } if name == "heard"));
    assert!(heard.is_some());
    assert!(at(&ended(x)) < heard && heard < at(&ended(y)));
}

/// Whether `k` is the completion of node `n`'s execution.
fn completed(k: &TraceKind, n: Option<u64>) -> bool {
    match k {
        TraceKind::Transition {
            node, facet, to, ..
        } => Some(*node) == n && *facet == Facet::Execution && *to == State::Completed,
        _ => false,
    }
}

/// The difference `EventHandle::spawn` makes: a task spawned with plain `tokio::spawn` is not
/// counted, so on the current-thread runtime it waits until the actions that end without
/// awaiting let the thread go.
#[tokio::test(start_paused = true)]
async fn a_plain_tokio_task_waits_for_the_actions_that_end_at_once() {
    let log: Log = Arc::default();
    let (tx, rx) = tokio::sync::mpsc::unbounded_channel();
    let rt = Runtime::new();
    let events = rt.events();
    tokio::spawn(listener(log.clone(), rx, events.clone()));
    drop(events);
    let (report, _) = run_checked(rt, chain(&log, tx)).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(*log.lock().expect("log"), ["x", "y", "z", "heard"]);
}

#[test]
fn spawning_beside_a_run_outside_a_runtime_is_an_error() {
    let rt = Runtime::new();
    let events = rt.events();
    let err = events.spawn(async {}).expect_err("no runtime here");
    assert!(matches!(err, tcm::Error::NoRuntime), "{err}");
}
