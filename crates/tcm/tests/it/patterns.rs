//! Behaviour-tree constructs of docs/from-behavior-trees.md on virtual time, each checked by the
//! trace checker: the decorators of `tcm::patterns` (a task run once, a cooldown after success)
//! and the sequence mapping.

use crate::util::{only, run_checked, story};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tcm::patterns::{Cooldown, RunOnce};
use tcm::{Constraint, Ended, Facet, Failure, Monitor, NodeRef, RunOutcome, Runtime, Task, When};

type Log = Arc<Mutex<Vec<String>>>;

fn note(log: &Log, s: String) {
    log.lock().expect("log").push(s);
}

fn how<T>(e: &Ended<T>) -> &'static str {
    match e {
        Ended::Succeeded(_) => "succeeded",
        Ended::Failed(_) => "failed",
        Ended::Terminated => "terminated",
        Ended::Skipped => "skipped",
    }
}

/// A command that takes `ms` and then succeeds, or fails with `Broken`.
fn step(name: &'static str, ms: u64, works: bool) -> Task {
    Task::command(name, move |ctx| async move {
        ctx.sleep(Duration::from_millis(ms)).await;
        if works {
            Ok(())
        } else {
            Err(Failure::new("Broken", "scripted"))
        }
    })
}

#[tokio::test(start_paused = true)]
async fn run_once_runs_its_task_to_its_end_once_then_skips_it() {
    // Calls at 0 s (runs 1 s), at 2 s and at 2 s again: one run, then two skipped nodes.
    let once = RunOnce::new();
    let log = Log::default();
    let (o, l) = (once.clone(), log.clone());
    let task = Task::goal("g", move |ctx| async move {
        for pause in [0, 1000, 0] {
            ctx.sleep(Duration::from_millis(pause)).await;
            let e = o.run::<()>(&ctx, step("init", 1000, true)).await?;
            note(&l, format!("{:?} {}", ctx.now(), how(&e)));
        }
        Ok(())
    });
    let (report, trace) = run_checked(Runtime::new(), task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(
        *log.lock().expect("log"),
        ["1s succeeded", "2s skipped", "2s skipped"]
    );
    assert_eq!(
        only(&story(&trace), &["init handling active", "init skipped"]),
        ["0 init handling active", "2 init skipped", "2 init skipped"]
    );
    assert!(once.done());
    assert_eq!(once.ended(), Some(None));
}

#[tokio::test(start_paused = true)]
async fn run_once_skips_calls_while_it_runs_counts_a_failure_and_retries_a_termination() {
    // A monitor polls every 500 ms, five times; each activation runs `init` (1.2 s) through one
    // RunOnce. The first run is terminated at 300 ms (it did not run to its end), so the poll at
    // 500 ms runs it again; the polls at 1 s and 1.5 s come while it runs, the one at 2 s after
    // it failed at 1.7 s: all skipped.
    let once = RunOnce::new();
    let log = Log::default();
    let (o, l) = (once.clone(), log.clone());
    let params = Monitor {
        max_activations: Some(5),
        period: Some(Duration::from_millis(500)),
        ..Monitor::default()
    };
    let task = Task::goal("g", move |ctx| async move {
        let m = Task::monitor("poll", params, move |ctx| {
            let (o, l) = (o.clone(), l.clone());
            async move {
                let first = ctx.activation().unwrap_or_default().0 == 1;
                let mut init = step("init", 1200, false);
                if first {
                    init = init.with(Constraint::terminate(When::In(Duration::from_millis(300))));
                }
                let e = o.run::<()>(&ctx, init).await?;
                note(&l, format!("{:?} {}", ctx.now(), how(&e)));
                Ok(())
            }
        });
        ctx.spawn(m).start()?;
        Ok(())
    });
    let (report, trace) = run_checked(Runtime::new(), task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(
        *log.lock().expect("log"),
        [
            "300ms terminated",
            "1s skipped",
            "1.5s skipped",
            "1.7s failed",
            "2s skipped"
        ]
    );
    assert_eq!(
        only(&story(&trace), &["init handling active", "init skipped"]),
        [
            "0 init handling active",
            "0.5 init handling active",
            "1 init skipped",
            "1.5 init skipped",
            "2 init skipped"
        ]
    );
    assert!(once.done());
    assert!(
        once.ended()
            .and_then(|f| f)
            .is_some_and(|f| f.is_a("Broken"))
    );
    once.reset();
    assert!(!once.done());
}

#[tokio::test(start_paused = true)]
async fn a_cooldown_skips_its_task_for_a_while_after_a_success() {
    // Every 300 ms, six times, `beep` (100 ms) through a cooldown of 1 s: it runs at 0 s, ends
    // at 100 ms; skipped until 1.1 s; runs at 1.2 s; skipped at 1.5 s.
    let cooldown = Cooldown::new(Duration::from_secs(1));
    let c = cooldown.clone();
    let params = Monitor {
        max_activations: Some(6),
        period: Some(Duration::from_millis(300)),
        ..Monitor::default()
    };
    let task = Task::monitor("every", params, move |ctx| {
        let c = c.clone();
        async move {
            c.run::<()>(&ctx, step("beep", 100, true)).await?;
            Ok(())
        }
    });
    let (report, trace) = run_checked(Runtime::new(), task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(
        only(&story(&trace), &["beep handling active", "beep skipped"]),
        [
            "0 beep handling active",
            "0.3 beep skipped",
            "0.6 beep skipped",
            "0.9 beep skipped",
            "1.2 beep handling active",
            "1.5 beep skipped"
        ]
    );
}

#[tokio::test(start_paused = true)]
async fn a_failure_starts_no_cooldown_and_a_reset_ends_one() {
    let log = Log::default();
    let l = log.clone();
    let task = Task::goal("g", move |ctx| async move {
        let cooldown = Cooldown::new(Duration::from_secs(5));
        for works in [false, false, true, true] {
            let e = cooldown.run::<()>(&ctx, step("dock", 100, works)).await?;
            note(&l, format!("{:?} {}", ctx.now(), how(&e)));
        }
        assert_eq!(cooldown.remaining(&ctx), Duration::from_secs(5));
        cooldown.reset();
        let e = cooldown.run::<()>(&ctx, step("dock", 100, true)).await?;
        note(&l, format!("{:?} {}", ctx.now(), how(&e)));
        Ok(())
    });
    let (report, _) = run_checked(Runtime::new(), task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(
        *log.lock().expect("log"),
        [
            "100ms failed",
            "200ms failed",
            "300ms succeeded",
            "300ms skipped",
            "400ms succeeded"
        ]
    );
}

/// The sequence of docs/from-behavior-trees.md: `unlock` (1 s), then the goal `pass_door`,
/// whose body reads a guard; `serial` orders it by `serial previous`, otherwise by
/// `sequential execution previous`. When `pass_door`'s body and its child start.
async fn sequence(serial: bool) -> Vec<String> {
    let task = Task::goal("through_door", move |ctx| async move {
        ctx.spawn(step("unlock", 1000, true)).propagate().start()?;
        let pass = Task::goal("pass_door", |ctx| async move {
            // A guard here (`if !door_open() { fail … }`) runs when this body does.
            ctx.spawn(step("walk", 500, true)).start()?;
            Ok(())
        });
        let s = ctx.spawn(pass).propagate();
        let s = if serial {
            s.serial(NodeRef::Previous)
        } else {
            s.sequential(Facet::Execution, NodeRef::Previous)
        };
        s.start()?;
        Ok(())
    });
    let (report, trace) = run_checked(Runtime::new(), task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    only(
        &story(&trace),
        &[
            "unlock handling completed",
            "pass_door handling active",
            "walk handling active",
        ],
    )
}

#[tokio::test(start_paused = true)]
async fn a_sequence_of_goals_is_serial_previous_not_sequential_execution_previous() {
    // `sequential execution previous` holds only the execution: the goal's body (and a guard in
    // it) runs at once, while `unlock` runs; only its child waits.
    assert_eq!(
        sequence(false).await,
        [
            "0 pass_door handling active",
            "1 unlock handling completed",
            "1 walk handling active"
        ]
    );
    // `serial previous` holds the expansion too: the body runs after `unlock` succeeded.
    assert_eq!(
        sequence(true).await,
        [
            "1 unlock handling completed",
            "1 pass_door handling active",
            "1 walk handling active"
        ]
    );
}
