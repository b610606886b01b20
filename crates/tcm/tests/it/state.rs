//! State variables and conditions through the runtime (docs/semantics.md, "State and
//! conditions"): a body sets a variable, a handle sets one from another task, a step waits on a
//! condition, an invariant fails a node with a typed exception that a handler takes, a body reads
//! a variable typed. On virtual time, every trace checked.

use crate::util::{only, run_checked, story};
use std::time::Duration;
use tcm::{
    Constraint, Expr, Facet, Handler, InvariantFailed, RunOutcome, Runtime, StateType, StateValue,
    StateVar, Task, When,
};

fn healthy() -> StateVar {
    StateVar::new("healthy", StateType::Bool, true)
}

fn battery() -> StateVar {
    StateVar::new("battery", StateType::Float, 100.0)
}

fn sleeper(name: &'static str, secs: u64) -> Task {
    Task::command(name, move |_| async move {
        tokio::time::sleep(Duration::from_secs(secs)).await;
        Ok(())
    })
}

#[tokio::test(start_paused = true)]
async fn a_step_waits_for_a_condition_set_from_a_body_and_from_a_handle() {
    let rt = Runtime::new().state(battery());
    let events = rt.events();
    // Another task of the program: the battery is charged to 90 at 5 s.
    tokio::spawn(async move {
        tokio::time::sleep(Duration::from_secs(5)).await;
        events.set_state("battery", 90).expect("set");
    });
    let mission = Task::goal("mission", |ctx| async move {
        // The battery drops at 1 s; `charged` waits for it to pass 80 again.
        ctx.spawn(Task::command("drain", |ctx| async move {
            tokio::time::sleep(Duration::from_secs(1)).await;
            ctx.set_state(&battery(), 20.5)?;
            Ok(())
        }))
        .start()?;
        ctx.spawn(sleeper("settle", 2)).wait().await?;
        let charged = ctx.condition(
            &[battery()],
            Expr::bin(tcm::BinOp::Gt, Expr::var("battery"), Expr::lit(80)),
        )?;
        ctx.spawn(sleeper("drive", 1))
            .with(Constraint::disable(
                Facet::Handling,
                When::Condition(charged),
            ))
            .start()?;
        Ok(())
    });
    let (report, trace) = run_checked(rt, mission).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(
        only(&story(&trace), &["set battery", "drive handling active"]),
        [
            "1 set battery = 20.5",
            "5 set battery = 90.0",
            "5 drive handling active"
        ]
    );
}

#[tokio::test(start_paused = true)]
async fn an_invariant_failure_is_a_typed_exception_a_handler_takes() {
    let caught = std::sync::Arc::new(std::sync::Mutex::new(None::<String>));
    let seen = caught.clone();
    let mission = Task::goal("mission", move |ctx| {
        let seen = seen.clone();
        async move {
            let ok = ctx.condition(&[healthy()], Expr::var("healthy"))?;
            ctx.spawn(Task::command("fault", |ctx| async move {
                tokio::time::sleep(Duration::from_secs(3)).await;
                ctx.set_state(&healthy(), false)?;
                Ok(())
            }))
            .start()?;
            let recover = Handler::new("recover", "InvariantFailed", move |ctx| {
                let seen = seen.clone();
                async move {
                    let f = ctx.failure().expect("a handler has its failure");
                    let data = f.data::<InvariantFailed>().map(|d| d.condition.clone());
                    *seen.lock().expect("lock") = data;
                    Ok(())
                }
            });
            ctx.spawn(sleeper("drive", 10))
                .with(Constraint::invariant(ok))
                .handler(recover)
                .start()?;
            Ok(())
        }
    });
    let (_, trace) = run_checked(Runtime::new(), mission).await;
    assert_eq!(
        only(
            &story(&trace),
            &["set healthy", "drive failed", "recover handling active"]
        ),
        [
            "3 set healthy = false",
            "3 drive failed InvariantFailed",
            "3 recover handling active"
        ]
    );
    assert_eq!(caught.lock().expect("lock").as_deref(), Some("healthy"));
}

#[tokio::test(start_paused = true)]
async fn a_body_reads_a_variable_typed_and_unknown_reads_as_none() {
    let mission = Task::goal("mission", |ctx| async move {
        let position = StateVar::new("position", StateType::Float, StateValue::Unknown);
        assert_eq!(ctx.read_state::<f64>(&position)?, None);
        ctx.set_state(&position, 3)?;
        assert_eq!(ctx.read_state::<f64>(&position)?, Some(3.0));
        assert_eq!(ctx.read_state::<bool>(&healthy())?, Some(true));
        assert_eq!(ctx.state("position")?, Some(StateValue::Float(3.0)));
        // A value of another type is an error that fails the body.
        let err = ctx.set_state(&position, "north").expect_err("a string");
        assert!(
            err.to_string().contains("expected a value of type `float`"),
            "{err}"
        );
        Ok(())
    });
    let (report, _) = run_checked(Runtime::new(), mission).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
}

#[tokio::test(start_paused = true)]
async fn a_skipped_child_ends_skipped_and_has_no_value() {
    let mission = Task::goal("mission", |ctx| async move {
        let position = StateVar::new("position", StateType::Float, StateValue::Unknown);
        let unknown = ctx.condition(&[position], Expr::not(Expr::known(Expr::var("position"))))?;
        let range = || Task::command("range", |_| async { Ok(12.5_f64) });
        let ended = ctx
            .spawn(range())
            .with(Constraint::skip_if(unknown))
            .wait_outcome::<f64>()
            .await?;
        assert!(ended.skipped(), "{:?}", ended.value());
        let err = ctx
            .spawn(range())
            .with(Constraint::skip_if(unknown))
            .wait_value::<f64>()
            .await
            .expect_err("no value");
        assert!(matches!(err, tcm::Error::ChildSkipped), "{err}");
        // A plain wait returns, as for a child that succeeded.
        ctx.spawn(range())
            .with(Constraint::skip_if(unknown))
            .wait()
            .await?;
        Ok(())
    });
    let (report, trace) = run_checked(Runtime::new(), mission).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(only(&story(&trace), &["skipped"]).len(), 3);
}

#[tokio::test(start_paused = true)]
async fn a_handle_that_outlives_its_run_is_told_the_run_ended() {
    let rt = Runtime::new();
    let events = rt.events();
    let (report, _) = run_checked(rt, sleeper("short", 1)).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert!(matches!(
        events.set_state("battery", 10.0),
        Err(tcm::Error::RunEnded)
    ));
    assert!(matches!(events.raise("go"), Err(tcm::Error::RunEnded)));
}
