//! The run both viewer test binaries read: `mission` runs `drive` (5 s), then `park` (1 s, serial
//! on `drive`), beside `honk` (2 s) which fails with `Jammed`, handled by `shrug`; with
//! `grasp`, also `grasp` (3 s), placed on the agent `arm`. On tokio's paused clock, checked.

use std::time::Duration;

use tcm::testing::run_checked;
use tcm::{Facet, Failure, Handler, NodeKind, NodeRef, Runtime, Task};
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
