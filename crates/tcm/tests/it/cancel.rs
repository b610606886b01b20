//! Cancellation that reaches the other side (issue 17, point 5; docs/semantics.md,
//! "Termination"): an action that looks at its cancellation signal (`Ctx::cancelled`,
//! `Ctx::is_cancelled`) is signalled when its node is terminated and runs on, for its grace period
//! at most, to cancel what it started outside; its node is terminated once it returned, or once it
//! was dropped at the end of the period (with a warning). An action that never looked is dropped
//! at once, as before.

use crate::util::{assert_order, only, run_checked, story};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tcm::testing::{assert_checked, lines, run_checked_allowing_panics};
use tcm::{Ctx, Failure, Recorder, RunOutcome, Runtime, Task, TraceEvent, TraceKind};

fn ms(n: u64) -> Duration {
    Duration::from_millis(n)
}

fn secs(n: u64) -> Duration {
    Duration::from_secs(n)
}

/// What the actions of a test did, with the virtual time at which they did it.
#[derive(Clone, Default)]
struct Log(Arc<Mutex<Vec<(&'static str, Duration)>>>);

impl Log {
    fn push(&self, what: &'static str, ctx: &Ctx) {
        self.0.lock().expect("log").push((what, ctx.now()));
    }

    fn entries(&self) -> Vec<(&'static str, Duration)> {
        self.0.lock().expect("log").clone()
    }
}

/// Sets its flag when dropped: tells whether an action's future was dropped.
struct Dropped(Arc<AtomicBool>);

impl Drop for Dropped {
    fn drop(&mut self) {
        self.0.store(true, Ordering::SeqCst);
    }
}

/// The warnings of a trace: their time in milliseconds and message.
fn warnings(trace: &[TraceEvent]) -> Vec<(u64, String)> {
    trace
        .iter()
        .filter_map(|r| match &r.kind {
            TraceKind::Warning { message, .. } => Some((r.t / 1_000_000, message.clone())),
            _ => None,
        })
        .collect()
}

/// A goal that spawns `task`, terminated 3 s after it starts.
fn terminated_at_3s(task: Task) -> Task {
    Task::goal("g", move |ctx| async move {
        ctx.spawn(task).terminate_in(secs(3)).start()?;
        Ok(())
    })
}

/// A command that sends a goal to a server, then, if terminated, cancels it: the cancel request
/// and its acknowledgement take `cleanup`.
fn navigate(log: Log, cleanup: Duration) -> Task {
    Task::command("navigate", move |ctx| async move {
        log.push("goal sent", &ctx);
        tokio::select! {
            () = tokio::time::sleep(secs(100)) => log.push("goal reached", &ctx),
            () = ctx.cancelled() => {
                assert!(ctx.is_cancelled());
                log.push("cancel sent", &ctx);
                tokio::time::sleep(cleanup).await;
                log.push("cancel acknowledged", &ctx);
            }
        }
        Ok(())
    })
}

#[tokio::test(start_paused = true)]
async fn an_action_awaiting_its_cancellation_cleans_up_before_its_node_is_terminated() {
    let log = Log::default();
    let (report, trace) = run_checked(
        Runtime::new(),
        terminated_at_3s(navigate(log.clone(), ms(300))),
    )
    .await;
    assert_eq!(
        log.entries(),
        [
            ("goal sent", Duration::ZERO),
            ("cancel sent", secs(3)),
            ("cancel acknowledged", ms(3300)),
        ]
    );
    // Terminating at 3 s, terminated when the action returned, 300 ms later, within its grace.
    assert_eq!(
        only(&story(&trace), &["navigate"]),
        [
            "0 navigate execution enabled",
            "0 navigate handling enabled",
            "0 navigate handling active",
            "0 navigate execution active",
            "3 navigate terminating",
            "3 navigate handling completed",
            "3.3 navigate execution completed",
            "3.3 navigate terminated",
        ]
    );
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(report.elapsed, ms(3300));
    assert_eq!(warnings(&trace), []);
    assert!(report.is_clean(), "{report}");
}

#[tokio::test(start_paused = true)]
async fn an_action_that_does_not_stop_within_its_grace_period_is_dropped_with_a_warning() {
    let log = Log::default();
    let dropped = Arc::new(AtomicBool::new(false));
    let guard = Dropped(dropped.clone());
    // It looks at the signal, then takes far longer than its 2 s to act on it.
    let slow = navigate(log.clone(), secs(60)).grace(secs(2));
    let task = Task::goal("g", move |ctx| async move {
        let _guard = guard;
        ctx.spawn(slow).terminate_in(secs(3)).start()?;
        Ok(())
    });
    let (report, trace) = run_checked(Runtime::new(), task).await;
    assert_eq!(
        log.entries(),
        [("goal sent", Duration::ZERO), ("cancel sent", secs(3))],
        "dropped before its cleanup ended"
    );
    assert!(dropped.load(Ordering::SeqCst));
    assert_eq!(
        warnings(&trace),
        [(
            5000,
            "Action of navigate {2} did not stop within its grace period (2s) after \
             termination: dropped"
                .to_string()
        )]
    );
    assert_order(
        &story(&trace),
        &["3 navigate terminating", "5 navigate terminated"],
    );
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(report.elapsed, secs(5));
    assert_eq!(report.warnings, 1);
}

#[tokio::test(start_paused = true)]
async fn the_runtime_default_grace_applies_to_tasks_that_set_none() {
    // `is_cancelled` is a look too: a polling action gets the grace period.
    let ignores = Task::command("poll", |ctx| async move {
        let _ = ctx.is_cancelled();
        std::future::pending::<()>().await;
        Ok(())
    });
    let rt = Runtime::new().default_grace(ms(250));
    let (report, trace) = run_checked(rt, terminated_at_3s(ignores)).await;
    assert_order(
        &story(&trace),
        &["3 poll terminating", "3.25 poll terminated"],
    );
    assert_eq!(warnings(&trace).len(), 1);
    assert_eq!(report.elapsed, ms(3250));
}

#[tokio::test(start_paused = true)]
async fn an_action_without_a_grace_period_is_dropped_at_once() {
    // Never looks at the signal: dropped at once under the default grace of one second.
    let dropped = Arc::new(AtomicBool::new(false));
    let guard = Dropped(dropped.clone());
    let blind = Task::command("blind", move |_| async move {
        let _guard = guard;
        std::future::pending::<()>().await;
        Ok(())
    });
    // Looks, but its task has no grace period.
    let log = Log::default();
    let graceless = navigate(log.clone(), ms(300)).grace(Duration::ZERO);
    // Looks, but the runtime gives none.
    let log2 = Log::default();
    let task = Task::goal("g", move |ctx| async move {
        ctx.spawn(blind).terminate_in(secs(3)).start()?;
        ctx.spawn(graceless).terminate_in(secs(3)).start()?;
        Ok(())
    });
    let (report, trace) = run_checked(Runtime::new(), task).await;
    assert!(dropped.load(Ordering::SeqCst));
    assert_eq!(
        log.entries(),
        [("goal sent", Duration::ZERO)],
        "no cleanup ran"
    );
    assert_order(
        &story(&trace),
        &["3 blind terminated", "3 navigate terminated"],
    );
    assert_eq!(report.elapsed, secs(3));
    assert_eq!(warnings(&trace), [], "no grace period, nothing overdue");

    let rt = Runtime::new().default_grace(Duration::ZERO);
    let (report, trace) = run_checked(rt, terminated_at_3s(navigate(log2.clone(), ms(300)))).await;
    assert_eq!(log2.entries(), [("goal sent", Duration::ZERO)]);
    assert_order(&story(&trace), &["3 navigate terminated"]);
    assert_eq!(report.elapsed, secs(3));
}

#[tokio::test(start_paused = true)]
async fn what_a_cancelled_action_returns_is_ignored_but_its_panic_is_reported() {
    let fails = Task::command("fails", |ctx| async move {
        ctx.cancelled().await;
        tokio::time::sleep(ms(100)).await;
        Err::<(), _>(Failure::new("CancelRefused", "the server said no"))
    });
    let panics = Task::command("panics", |ctx| async move {
        ctx.cancelled().await;
        tokio::time::sleep(ms(200)).await;
        panic!("lost the server while cancelling");
        #[allow(unreachable_code)]
        Ok(())
    });
    let task = Task::goal("g", move |ctx| async move {
        ctx.spawn(fails).terminate_in(secs(3)).start()?;
        ctx.spawn(panics).terminate_in(secs(3)).start()?;
        Ok(())
    });
    let (report, trace) = run_checked_allowing_panics(Runtime::new(), task).await;
    assert_order(
        &story(&trace),
        &["3.1 fails terminated", "3.2 panics terminated"],
    );
    assert_eq!(only(&story(&trace), &["failed"]), Vec::<String>::new());
    assert_eq!(report.failures, 0, "a terminated node does not fail");
    assert_eq!(report.panics.len(), 1);
    assert_eq!(report.panics[0].name, "panics");
    assert_eq!(report.panics[0].message, "lost the server while cancelling");
    assert_eq!(report.outcome, RunOutcome::Completed);
}

#[tokio::test(start_paused = true)]
async fn a_cancelling_action_keeps_the_run_busy_not_stuck() {
    let rec = Recorder::new();
    let session = Runtime::new()
        .with_sink(rec.clone())
        .start()
        .expect("inside a tokio runtime");
    let log = Log::default();
    let l = log.clone();
    let never = session.external("never").expect("external");
    // Parked in a wait on a child that waits for an event nobody raises, until cancelled.
    let waiter = Task::goal("waiter", move |ctx| async move {
        let child = ctx
            .spawn(Task::command("child", |_| async { Ok(()) }))
            .with(tcm::Constraint::disable(
                tcm::Facet::Handling,
                tcm::When::External(never),
            ))
            .start()?;
        // Biased: the termination also ends the child, which answers the wait at the same time.
        tokio::select! {
            biased;
            () = ctx.cancelled() => {
                tokio::time::sleep(ms(500)).await;
                l.push("cleaned up", &ctx);
            }
            _ = ctx.wait(child) => l.push("child done", &ctx),
        }
        Ok(())
    });
    let node = session.spawn(waiter).expect("spawn");
    session.quiescent().await.expect("quiescent");
    assert_eq!(session.now(), Duration::ZERO, "parked at once");
    session.terminate(node).expect("terminate");
    // Not quiescent while the action cleans up: it is running, not parked.
    session.quiescent().await.expect("quiescent");
    assert_eq!(log.entries(), [("cleaned up", ms(500))]);
    assert_eq!(session.now(), ms(500));
    assert_eq!(session.info(node).expect("info"), None, "terminated");
    let report = session.finish().await.expect("finish");
    assert_eq!(report.outcome, RunOutcome::Terminated);
    let trace = rec.events();
    assert_checked(&trace);
    assert_order(
        &story(&trace),
        &["0 waiter terminating", "0.5 waiter terminated"],
    );
    assert_eq!(warnings(&trace), []);
}

#[test]
fn two_virtual_runs_with_cancellations_give_the_same_trace() {
    let run = || {
        let program = Task::goal("g", |ctx| async move {
            ctx.spawn(navigate(Log::default(), ms(300)))
                .terminate_in(secs(3))
                .start()?;
            // A grace period given at the spawn, as `Task::grace` gives one to every spawn.
            ctx.spawn(navigate(Log::default(), secs(60)))
                .grace(secs(2))
                .terminate_in(secs(4))
                .start()?;
            Ok(())
        });
        let run = async { Ok::<_, tcm::Error>(run_checked(Runtime::new(), program).await) };
        tcm::block_on_virtual(run).expect("a tokio runtime")
    };
    let (a, ta) = run();
    let (b, tb) = run();
    assert_eq!(a.outcome, RunOutcome::Completed);
    assert_eq!(
        a.elapsed,
        secs(6),
        "dropped 2 s after its termination at 4 s"
    );
    assert_eq!(a.warnings, 1);
    assert_eq!(b.elapsed, a.elapsed);
    assert_eq!(lines(&ta), lines(&tb));
}

#[tokio::test(start_paused = true)]
async fn a_monitor_activation_has_the_grace_period_of_its_monitor() {
    let log = Log::default();
    let l = log.clone();
    // Activated at once (polling); its activation cancels what it started, too slowly.
    let monitor = Task::monitor(
        "watch",
        tcm::Monitor {
            period: Some(secs(60)),
            ..Default::default()
        },
        move |ctx| {
            let l = l.clone();
            async move {
                ctx.cancelled().await;
                l.push("cancel sent", &ctx);
                tokio::time::sleep(ms(300)).await;
                l.push("cancel acknowledged", &ctx);
                Ok(())
            }
        },
    )
    .grace(ms(200));
    let (report, trace) = run_checked(Runtime::new(), terminated_at_3s(monitor)).await;
    assert_eq!(log.entries(), [("cancel sent", secs(3))]);
    let warned = warnings(&trace);
    assert_eq!(warned.len(), 1, "{warned:?}");
    assert_eq!(warned[0].0, 3200);
    assert!(warned[0].1.starts_with("Action of ACT-watch"), "{warned:?}");
    assert_order(
        &story(&trace),
        &[
            "3 watch terminating",
            "3.2 ACT-watch terminated",
            "3.2 watch terminated",
        ],
    );
    assert_eq!(report.elapsed, ms(3200));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn on_real_time_and_several_threads_the_cleanup_runs_before_the_node_is_terminated() {
    let log = Log::default();
    let task = Task::goal("g", {
        let log = log.clone();
        move |ctx| async move {
            ctx.spawn(navigate(log, ms(20)))
                .terminate_in(ms(30))
                .start()?;
            Ok(())
        }
    });
    let (report, trace) = run_checked(Runtime::new(), task).await;
    let done: Vec<&str> = log.entries().iter().map(|(what, _)| *what).collect();
    assert_eq!(done, ["goal sent", "cancel sent", "cancel acknowledged"]);
    assert!(report.elapsed >= ms(50), "{report}");
    assert_eq!(warnings(&trace), []);
    let terminated = trace
        .iter()
        .find(|r| matches!(r.kind, TraceKind::Terminated { .. }))
        .map(|r| Duration::from_nanos(r.t));
    let acknowledged = log.entries()[2].1;
    assert!(
        terminated >= Some(acknowledged),
        "{terminated:?} {acknowledged:?}"
    );
}
