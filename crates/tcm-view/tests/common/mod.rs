//! The runs both viewer test binaries read, on tokio's paused clock, checked. `mission` runs
//! `drive` (5 s), then `park` (1 s, serial on `drive`), beside `honk` (2 s) which fails with
//! `Jammed`, handled by `shrug`; with `grasp`, also `grasp` (3 s), placed on the agent `arm`.
//! `patrol` has monitors: `watch` (3 activations, one a second, each a trigger) and `tick` (10,
//! two a second),
//! beside `drive` (6 s) and `fetch`, whose body waits for the value of `probe`, which fails with
//! `Broken` after 1 s: `fetch` takes the failure and fails with it.

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
