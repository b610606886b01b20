//! The runs both viewer test binaries read, on tokio's paused clock, checked. `mission` runs
//! `drive` (5 s), then `park` (1 s, serial on `drive`), beside `honk` (2 s) which fails with
//! `Jammed`, handled by `shrug`; with `grasp`, also `grasp` (3 s), placed on the agent `arm`.
//! `patrol` has monitors: `watch` (3 activations, one a second, each a trigger) and `tick` (10,
//! two a second),
//! beside `drive` (6 s) and `fetch`, whose body waits for the value of `probe`, which fails with
//! `Broken` after 1 s: `fetch` takes the failure and fails with it. `powered` has state variables
//! and triggers on conditions (see its documentation).

use std::time::Duration;

use tcm::testing::run_checked;
use tcm::{Facet, Failure, Handler, Monitor, NodeKind, NodeRef, Runtime, Task};
use tcm_trace::TraceEvent;

pub(crate) fn secs(s: u64) -> Duration {
    Duration::from_secs(s)
}

/// The mission's trace; `grasp` adds the placed command.
pub(crate) async fn mission(grasp: bool) -> Vec<TraceEvent> {
    let task = Task::goal("mission", move |ctx| async move {
        ctx.spawn(Task::command("drive", |_| async {
            tokio::time::sleep(secs(5)).await;
            Ok(())
        }))
        .start()?;
        ctx.spawn(Task::command("park", |_| async {
            tokio::time::sleep(secs(1)).await;
            Ok(())
        }))
        .sequential(Facet::Execution, NodeRef::Previous)
        .start()?;
        ctx.spawn(
            Task::retryable(NodeKind::Command, "honk", |_| async {
                tokio::time::sleep(secs(2)).await;
                Err::<(), _>(Failure::new("Jammed", "the horn is stuck"))
            })
            .handler(Handler::new("shrug", "Jammed", |_| async { Ok(()) })),
        )
        .start()?;
        if grasp {
            ctx.spawn(Task::command("grasp", |ctx| async move {
                ctx.placed("arm")?;
                tokio::time::sleep(secs(3)).await;
                Ok(())
            }))
            .start()?;
        }
        Ok(())
    });
    run_checked(Runtime::new(), task).await.1
}

/// The patrol's trace (see the module's documentation).
pub(crate) async fn patrol() -> Vec<TraceEvent> {
    let every = |period: Duration, times: u32| Monitor {
        max_activations: Some(times),
        period: Some(period),
        ..Monitor::default()
    };
    let task = Task::goal("patrol", move |ctx| async move {
        ctx.spawn(Task::monitor(
            "watch",
            every(secs(1), 3),
            |ctx| async move {
                ctx.trigger()?;
                Ok::<(), Failure>(())
            },
        ))
        .start()?;
        ctx.spawn(Task::monitor(
            "tick",
            every(Duration::from_millis(500), 10),
            |_| async { Ok::<(), Failure>(()) },
        ))
        .start()?;
        ctx.spawn(Task::command("drive", |_| async {
            tokio::time::sleep(secs(6)).await;
            Ok(())
        }))
        .start()?;
        ctx.spawn(Task::goal("fetch", |ctx| async move {
            let found: u32 = ctx
                .spawn(Task::command("probe", |_| async {
                    tokio::time::sleep(secs(1)).await;
                    Err::<u32, _>(Failure::new("Broken", "the probe broke"))
                }))
                .wait_value()
                .await?;
            let _ = found;
            Ok(())
        }))
        .start()?;
        Ok(())
    });
    run_checked(Runtime::new(), task).await.1
}

/// The state mission's trace: state variables `battery_ok` (true), `fault` (false), `charge`
/// (100.0), `docked` (true) and `position` (unknown). `drain` sets `battery_ok` false and `charge`
/// to 20.0 at 2 s, `battery_ok` true again and `charge` to 90.0 at 5 s (and `fault` false, which
/// it was: a set that is no change), `docked` false at 7 s, true at 7.5 s, false at 9 s. `dock` is skipped (`skip if
/// !is_known(position)`); `drive` (1 s) is spawned at 3 s, after `settle`, with `disable handling
/// until battery_ok && !fault` and `invariant charge > 10.0`, so it waits from 3 s to 5 s;
/// `patrol` is paused while `docked`, so it starts at 7 s; its `sweep` runs to 8 s, and `sweep2`,
/// serial on `sweep`, is paused by `patrol`'s pause from 8 s to 9 s and runs to 10 s.
pub(crate) async fn powered() -> Vec<TraceEvent> {
    use tcm::{BinOp, Constraint, Expr, StateType, StateValue, StateVar, When};
    let battery_ok = || StateVar::new("battery_ok", StateType::Bool, true);
    let fault = || StateVar::new("fault", StateType::Bool, false);
    let charge = || StateVar::new("charge", StateType::Float, 100.0);
    let docked = || StateVar::new("docked", StateType::Bool, true);
    let position = || StateVar::new("position", StateType::Float, StateValue::Unknown);
    let task = Task::goal("mission", move |ctx| async move {
        let ready = ctx.condition(
            &[battery_ok(), fault()],
            Expr::and(Expr::var("battery_ok"), Expr::not(Expr::var("fault"))),
        )?;
        let charged = ctx.condition(
            &[charge()],
            Expr::bin(BinOp::Gt, Expr::var("charge"), Expr::lit(10.0)),
        )?;
        let lost = ctx.condition(&[position()], Expr::not(Expr::known(Expr::var("position"))))?;
        let at_dock = ctx.condition(&[docked()], Expr::var("docked"))?;
        ctx.spawn(Task::command("drain", move |ctx| async move {
            tokio::time::sleep(secs(2)).await;
            ctx.set_state(&battery_ok(), false)?;
            ctx.set_state(&charge(), 20.0)?;
            tokio::time::sleep(secs(3)).await;
            ctx.set_state(&battery_ok(), true)?;
            ctx.set_state(&charge(), 90.0)?;
            ctx.set_state(&fault(), false)?;
            tokio::time::sleep(secs(2)).await;
            ctx.set_state(&docked(), false)?;
            tokio::time::sleep(Duration::from_millis(500)).await;
            ctx.set_state(&docked(), true)?;
            tokio::time::sleep(Duration::from_millis(1500)).await;
            ctx.set_state(&docked(), false)?;
            Ok(())
        }))
        .start()?;
        ctx.spawn(Task::command("dock", |_| async { Ok(()) }))
            .with(Constraint::skip_if(lost))
            .start()?;
        ctx.spawn(Task::goal("patrol", |ctx| async move {
            for name in ["sweep", "sweep2"] {
                ctx.spawn(Task::command(name, |_| async {
                    tokio::time::sleep(secs(1)).await;
                    Ok(())
                }))
                .sequential(Facet::Execution, NodeRef::Previous)
                .start()?;
            }
            Ok(())
        }))
        .with(Constraint::pause_while(at_dock))
        .start()?;
        ctx.spawn(Task::command("settle", |_| async {
            tokio::time::sleep(secs(3)).await;
            Ok(())
        }))
        .wait()
        .await?;
        ctx.spawn(Task::command("drive", |_| async {
            tokio::time::sleep(secs(1)).await;
            Ok(())
        }))
        .with(Constraint::disable(Facet::Handling, When::Condition(ready)))
        .with(Constraint::invariant(charged))
        .start()?;
        Ok(())
    });
    run_checked(Runtime::new(), task).await.1
}
