//! Blocking actions (`Task::blocking`, `Ctx::blocking`): their body runs on a blocking thread and
//! ends the node with its value, failure or panic; a terminated one is signalled, never dropped,
//! and its node is terminated once the body returned; one terminated before its body started never
//! runs it. On real time, a blocking body does not hold back a monitor polling beside it, where
//! the same body as a plain async action does. `Runtime::blocking_nice` runs bodies at a lower
//! priority (Linux).

use crate::util::{only, run_checked, story};
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tcm::testing::run_checked_allowing_panics;
use tcm::{Failure, Handler, Monitor, NodeKind, RunOutcome, Runtime, Task};

#[tokio::test(start_paused = true)]
async fn a_blocking_command_gives_its_value_to_the_goal_that_waits() {
    let task = Task::goal("g", |ctx| async move {
        let sum: u64 = ctx
            .spawn(Task::blocking(NodeKind::Command, "sum", |_| {
                Ok((1..=100u64).sum::<u64>())
            }))
            .wait_value()
            .await?;
        if sum != 5050 {
            return Err(Failure::new("Wrong", format!("{sum}")));
        }
        Ok(())
    });
    let (report, trace) = run_checked(Runtime::new(), task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(
        only(
            &story(&trace),
            &["sum handling active", "sum handling completed"]
        ),
        ["0 sum handling active", "0 sum handling completed"],
        "no virtual time passes while it computes"
    );
}

#[tokio::test(start_paused = true)]
async fn a_blocking_body_fails_its_node_with_its_failure_or_its_panic() {
    let task = Task::goal("g", |ctx| async move {
        ctx.spawn(Task::blocking(NodeKind::Command, "refuse", |_| {
            Err::<(), _>(Failure::new("NoPath", "no path to room 12"))
        }))
        .start()?;
        ctx.spawn(Task::blocking(NodeKind::Command, "crash", |_| {
            if true {
                panic!("the planner crashed");
            }
            Ok(())
        }))
        .start()?;
        Ok(())
    })
    .handler(Handler::new("replan", "NoPath", |_| async { Ok(()) }));
    let (report, trace) = run_checked_allowing_panics(Runtime::new(), task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(report.failures, 2);
    assert_eq!(report.panics.len(), 1, "{:?}", report.panics);
    assert_eq!(report.panics[0].name, "crash");
    assert!(report.panics[0].message.contains("the planner crashed"));
    let s = story(&trace);
    assert!(
        s.iter()
            .any(|l| l.contains("refuse") && l.contains("failed")),
        "{s:#?}"
    );
}

/// A blocking body that works until it is cancelled (or, were the signal lost, for at most 10 s of
/// real time, so that a broken runtime fails the test instead of hanging it).
fn until_cancelled(saw: Arc<AtomicBool>) -> Task {
    Task::blocking(NodeKind::Command, "plan", move |ctx| {
        let give_up = Instant::now() + Duration::from_secs(10);
        while Instant::now() < give_up {
            if ctx.is_cancelled() {
                saw.store(true, Ordering::SeqCst);
                return Ok(());
            }
            std::thread::sleep(Duration::from_millis(1));
        }
        Ok(())
    })
}

#[tokio::test(start_paused = true)]
async fn a_terminated_blocking_action_is_signalled_and_its_node_terminated_once_it_returned() {
    let saw = Arc::new(AtomicBool::new(false));
    let s2 = saw.clone();
    let task = Task::goal("g", move |ctx| async move {
        let plan = ctx.spawn(until_cancelled(s2)).start()?;
        ctx.spawn(Task::command("stop", move |ctx| async move {
            ctx.terminate(plan)?;
            Ok(())
        }))
        .start()?;
        Ok(())
    });
    let (report, trace) = run_checked(Runtime::new(), task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert!(
        saw.load(Ordering::SeqCst),
        "the body saw its cancellation, and returned"
    );
    let s = story(&trace);
    let terminating = s.iter().position(|l| l == "0 plan terminating");
    let terminated = s.iter().position(|l| l == "0 plan terminated");
    assert!(terminating.is_some() && terminating < terminated, "{s:#?}");
}

#[tokio::test(start_paused = true)]
async fn a_blocking_action_terminated_before_its_body_started_never_runs_it() {
    let ran = Arc::new(AtomicBool::new(false));
    let r2 = ran.clone();
    let task = Task::goal("g", move |ctx| async move {
        let plan = ctx.reserve("plan")?;
        // Released together, `stop` first: it terminates `plan` after `plan` was started, before
        // its body could run.
        ctx.spawn(Task::command("stop", move |ctx| async move {
            ctx.terminate(plan)?;
            Ok(())
        }))
        .start()?;
        ctx.spawn(Task::blocking(NodeKind::Command, "plan", move |_| {
            r2.store(true, Ordering::SeqCst);
            Ok(())
        }))
        .fulfils(plan)
        .start()?;
        Ok(())
    });
    let (report, trace) = run_checked(Runtime::new(), task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert!(!ran.load(Ordering::SeqCst), "the body never ran");
    assert!(story(&trace).iter().any(|l| l == "0 plan terminated"));
}

/// Activations of a 5 ms polling monitor that happened while an action spun for 300 ms beside it,
/// on a multi-thread runtime with one async worker; `blocking`: the spin is a blocking action,
/// else a plain async action that never awaits.
fn activations_during_a_spin(blocking: bool) -> (u32, RunOutcome) {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_time()
        .build()
        .expect("a tokio runtime");
    let spin: Arc<Mutex<Option<(Instant, Instant)>>> = Arc::default();
    let stamps: Arc<Mutex<Vec<Instant>>> = Arc::default();
    let (sp, st) = (spin.clone(), stamps.clone());
    let body = move || {
        let start = Instant::now();
        while start.elapsed() < Duration::from_millis(300) {
            std::hint::spin_loop();
        }
        if let Ok(mut s) = sp.lock() {
            *s = Some((start, Instant::now()));
        }
        Ok(())
    };
    let spinner = if blocking {
        Task::blocking(NodeKind::Command, "spin", move |_| body())
    } else {
        Task::command("spin", move |_| async move { body() })
    };
    let params = Monitor {
        max_activations: Some(200),
        period: Some(Duration::from_millis(5)),
        ..Monitor::default()
    };
    let counted = Arc::new(AtomicU32::new(0));
    let c2 = counted.clone();
    let task = Task::goal("g", move |ctx| async move {
        let poll = ctx
            .spawn(Task::monitor("poll", params, move |_| {
                let st = st.clone();
                let c2 = c2.clone();
                async move {
                    c2.fetch_add(1, Ordering::SeqCst);
                    if let Ok(mut v) = st.lock() {
                        v.push(Instant::now());
                    }
                    Ok(())
                }
            }))
            .start()?;
        // Give the monitor a head start, then spin; stop the monitor once the spin ended.
        ctx.spawn(spinner)
            .disable_for(tcm::Facet::Handling, Duration::from_millis(20))
            .start()?;
        ctx.spawn(Task::command("stop", move |ctx| async move {
            ctx.terminate(poll)?;
            Ok(())
        }))
        .serial(tcm::NodeRef::Previous)
        .start()?;
        Ok(())
    });
    let report = rt
        .block_on(async { Runtime::new().run(task).await })
        .expect("the run");
    let (start, end) = spin
        .lock()
        .ok()
        .and_then(|s| *s)
        .expect("the spin ran and recorded its interval");
    let during = stamps
        .lock()
        .map(|v| v.iter().filter(|t| **t > start && **t < end).count())
        .unwrap_or(0);
    (u32::try_from(during).unwrap_or(u32::MAX), report.outcome)
}

#[test]
fn on_real_time_a_blocking_action_does_not_hold_back_a_monitor_beside_it() {
    let (during, outcome) = activations_during_a_spin(true);
    assert_eq!(outcome, RunOutcome::Completed);
    // About 60 are due in 300 ms; a loaded machine may miss some, never most.
    assert!(during >= 10, "only {during} activations during the spin");
    // The control: the same spin as a plain async action holds the one worker, and with it the
    // driver loop, so no activation happens while it runs.
    let (during, outcome) = activations_during_a_spin(false);
    assert_eq!(outcome, RunOutcome::Completed);
    assert!(during <= 1, "{during} activations during an async spin");
}

/// The nice value of the calling thread, from `/proc/thread-self/stat` (Linux).
#[cfg(target_os = "linux")]
fn thread_nice() -> Option<i32> {
    let stat = std::fs::read_to_string("/proc/thread-self/stat").ok()?;
    // Fields after the command name (in parentheses) start at the third, `state`; `nice` is the
    // nineteenth.
    let after = stat.rsplit_once(')')?.1;
    after.split_whitespace().nth(16)?.parse().ok()
}

#[cfg(target_os = "linux")]
#[tokio::test(start_paused = true)]
async fn blocking_nice_runs_bodies_at_a_lower_priority() {
    let task = |name: &'static str| {
        Task::blocking(NodeKind::Command, name, |_| {
            thread_nice()
                .ok_or_else(|| Failure::new("NoProc", "cannot read the thread's nice value"))
        })
    };
    let checked = Task::goal("g", move |ctx| async move {
        let nice: i32 = ctx.spawn(task("read")).wait_value().await?;
        if nice != 19 {
            return Err(Failure::new("Nice", format!("the body ran at nice {nice}")));
        }
        Ok(())
    });
    let (report, _) = run_checked(Runtime::new().blocking_nice(19), checked).await;
    assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
}
