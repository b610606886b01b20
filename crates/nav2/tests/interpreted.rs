//! The navigation loaded at run time from `src/navigate.tdl` (the file the build compiles), the
//! servers registered in Rust, runs as the compiled navigation runs: the same trace, record for
//! record, and the same log, with and without faults, and with a new goal preempting a recovery.

use std::time::Duration;

use nav2::servers::{Costmap, Entry, Nav, NavError};
use tdl::patterns::{InTurn, Recovered};
use tdl::{Ctx, Ended, Recorder, Runtime, Task, TraceEvent};
use tdl_interp::{Host, IntoValue, Program, Registry, Value, host_err, ok};

/// A recovery's name as the servers take it.
fn recovery_name(name: &str) -> &'static str {
    match name {
        "spin" => "spin",
        "wait" => "wait",
        "back_up" => "back_up",
        "clear_local" => "clear_local",
        _ => "clear_global",
    }
}

/// How a round of recoveries ended, as the program matches it.
fn recovered(r: Recovered) -> Value {
    match r {
        Recovered::By(i) => Value::variant("Recovered", "By", vec![i.into_value()]),
        Recovered::Failed(f) => Value::variant("Recovered", "Failed", vec![f.into_value()]),
        Recovered::Preempted => Value::variant("Recovered", "Preempted", Vec::new()),
        Recovered::Terminated => Value::variant("Recovered", "Terminated", Vec::new()),
    }
}

/// The servers, as the program calls them.
fn registry() -> Registry {
    let mut r = Registry::new();
    r.host_type("Nav")
        .host_type("InTurn")
        .host_type("Path")
        .host_type("NavError")
        .host_type("Costmap")
        .async_method("Nav", "compute_path", |n: Host<Nav>| async move {
            match n.0.compute_path().await {
                Ok(path) => ok(Host(path)),
                Err(e) => host_err(e),
            }
        })
        .async_method("Nav", "follow_path", |n: Host<Nav>| async move {
            match n.0.follow_path().await {
                Ok(()) => ok(()),
                Err(e) => host_err(e),
            }
        })
        .async_method("Nav", "recovery", |n: Host<Nav>, name: String| async move {
            n.0.recovery(recovery_name(&name)).await
        })
        .method(
            "Nav",
            "publish",
            |n: Host<Nav>, p: Host<nav2::servers::Path>| {
                n.0.publish(p.0);
            },
        )
        .method("Nav", "finished", |n: Host<Nav>, o: Ended<()>| {
            n.0.finished(&o)
        })
        .method("NavError", "recovery_helps", |e: Host<NavError>| {
            e.0.recovery_helps()
        })
        .method("Costmap", "name", |c: Host<Costmap>| c.0.name())
        .method("InTurn", "reset", |t: Host<InTurn>| t.0.reset())
        .async_method(
            "InTurn",
            "recover",
            |t: Host<InTurn>, ctx: Ctx| async move { t.0.recover(&ctx).await.map(recovered) },
        )
        .constant("Costmap::Local", Host(Costmap::Local))
        .constant("Costmap::Global", Host(Costmap::Global));
    r
}

fn program() -> Program {
    let file = format!("{}/src/navigate.tdl", env!("CARGO_MANIFEST_DIR"));
    match Program::load(&[file], &registry()) {
        Ok(p) => p,
        Err(e) => panic!("{e}"),
    }
}

/// The recoveries in turn, built from the loaded program's tasks.
fn recoveries(program: &Program, nav: &Nav) -> InTurn {
    let (program, n) = (program.clone(), nav.clone());
    nav.recoveries_with(move |i| {
        let name = ["clearing_actions", "spin", "wait_a_while", "back_up"][i.min(3)];
        match program.task(name, vec![Host(n.clone()).into_value()]) {
            Ok(t) => t,
            Err(e) => Task::command("missing_recovery", move |_| async move {
                Err::<(), _>(tdl::Failure::new("Interpreter", e.to_string()))
            }),
        }
    })
}

/// Runs a navigation on a fresh `Nav` made by `setup`, with a new goal sent once `preempt_on`
/// is logged (if given); its trace and log.
async fn navigate(
    setup: &dyn Fn() -> Nav,
    preempt_on: Option<&'static str>,
    task: &dyn Fn(&Nav) -> Task,
) -> (Vec<TraceEvent>, Vec<Entry>) {
    let nav = setup();
    let rt = Runtime::new();
    let events = rt.events();
    let goals = nav.clone();
    let sender = preempt_on.map(|what| {
        tdl::tokio::spawn(async move {
            // At most ten minutes of the run's time: a run that never gets there ends the wait.
            for _ in 0..12_000 {
                tdl::tokio::time::sleep(Duration::from_millis(50)).await;
                if goals.log().iter().any(|e| e.what == what) {
                    break;
                }
            }
            tdl::tokio::time::sleep(Duration::from_millis(500)).await;
            let _ = goals.new_goal(-2.0, |n| events.raise(n));
        })
    });
    let rec = Recorder::new();
    let run = rt.with_sink(rec.clone()).run(task(&nav)).await;
    assert!(run.is_ok(), "the run ends");
    if let Some(s) = sender {
        let _ = s.await;
    }
    let trace = rec.events();
    tdl::testing::assert_checked(&trace);
    (trace, nav.log())
}

/// The navigation of `setup`, compiled and interpreted: the same trace and the same log.
async fn alike(setup: &dyn Fn() -> Nav, preempt_on: Option<&'static str>) {
    let compiled = navigate(setup, preempt_on, &|nav| {
        nav2::navigate_to_pose(nav.clone(), nav.recoveries())
    })
    .await;
    let program = program();
    let interpreted = navigate(setup, preempt_on, &|nav| {
        let args = vec![
            Host(nav.clone()).into_value(),
            Host(recoveries(&program, nav)).into_value(),
        ];
        match program.task("navigate_to_pose", args) {
            Ok(t) => t,
            Err(e) => panic!("{e}"),
        }
    })
    .await;
    tdl::testing::assert_same_trace(&compiled.0, &interpreted.0, "compiled, then interpreted");
    let what = |log: &[Entry]| {
        log.iter()
            .map(|e| (e.at, e.what.clone()))
            .collect::<Vec<_>>()
    };
    assert_eq!(what(&compiled.1), what(&interpreted.1));
}

#[tokio::test(start_paused = true)]
async fn a_clean_navigation_runs_interpreted_as_compiled() {
    alike(&|| Nav::new(5.0), None).await;
}

#[tokio::test(start_paused = true)]
async fn bounded_retries_and_recoveries_in_turn_run_interpreted_as_compiled() {
    alike(
        &|| {
            let nav = Nav::new(5.0);
            nav.fail_controller([NavError::FailedToMakeProgress; 40]);
            nav
        },
        None,
    )
    .await;
}

#[tokio::test(start_paused = true)]
async fn failures_recovery_cannot_help_run_interpreted_as_compiled() {
    alike(
        &|| {
            let nav = Nav::new(5.0);
            nav.fail_planner([NavError::GoalOutsideMap]);
            nav
        },
        None,
    )
    .await;
    alike(
        &|| {
            let nav = Nav::new(5.0);
            nav.fail_planner([NavError::NoValidPath, NavError::NoValidPath]);
            nav.fail_controller([NavError::FailedToMakeProgress, NavError::InvalidPath]);
            nav
        },
        None,
    )
    .await;
}

#[tokio::test(start_paused = true)]
async fn a_preempted_recovery_runs_interpreted_as_compiled() {
    alike(
        &|| {
            let nav = Nav::new(5.0);
            nav.fail_controller([NavError::FailedToMakeProgress; 6]);
            nav
        },
        Some("recovery wait"),
    )
    .await;
}
