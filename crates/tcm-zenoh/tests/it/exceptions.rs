//! Exceptions across processes: a typed exception raised in a remote body is handled by the
//! executive's handler of its type or an ancestor, which may retry the remote task; and a failure
//! in the tree reaches a remote body typed.

use crate::util::{Log, Net, bounded};
use serde::{Deserialize, Serialize};
use std::sync::Arc;
use std::sync::atomic::{AtomicU32, Ordering};
use tcm::testing::{handler_choices, run_checked};
use tcm::{Exception, Handler, RunOutcome, Runtime, Task};
use tcm_zenoh::{Child, RemoteCtx, RemoteFailure};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, thiserror::Error)]
#[error("no grasp at {x}")]
struct NoGrasp {
    x: i32,
}

impl Exception for NoGrasp {
    fn ancestry() -> &'static [&'static str] {
        &["ArmFailure"]
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, thiserror::Error)]
#[error("{kg} kg is too heavy")]
struct TooHeavy {
    kg: u32,
}

impl Exception for TooHeavy {
    fn ancestry() -> &'static [&'static str] {
        &["Overload"]
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, thiserror::Error)]
#[error("dropped {what}: {why}")]
struct Dropped {
    what: String,
    why: String,
}

impl Exception for Dropped {}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_remote_exception_is_handled_by_a_local_handler_of_its_ancestor_which_retries() {
    bounded(async {
        let net = Net::new("raise").await;
        let attempts = Arc::new(AtomicU32::new(0));
        let a = attempts.clone();
        let arm = net
            .agent("arm")
            .command("grasp", move |_: RemoteCtx, x: i32| {
                let a = a.clone();
                async move {
                    if a.fetch_add(1, Ordering::SeqCst) == 0 {
                        return Err(RemoteFailure::raise(NoGrasp { x }));
                    }
                    Ok(x + 1)
                }
            });
        let _arm = net.join(arm, "arm").await;
        let log = Log::default();
        let l = log.clone();
        let recover = Handler::new("recover", "ArmFailure", move |ctx| {
            let l = l.clone();
            async move {
                let e = tcm_zenoh::caught::<NoGrasp>(&ctx).expect("a NoGrasp, read from JSON");
                let failure = ctx.failure().expect("in a handler");
                l.push(format!(
                    "caught {} ({e:?}): {}",
                    failure.exception, failure.message
                ));
                let retry = ctx.retry()?;
                ctx.wait(retry).await?;
                Ok(())
            }
        });
        let exec = net.exec.clone();
        let main = Task::goal("main", move |ctx| async move {
            let v: tcm_zenoh::Json = ctx
                .spawn(exec.remote("arm", "grasp", 41).task())
                .handler(recover)
                .wait_value()
                .await?;
            assert_eq!(v, serde_json::json!(42), "the retry's value is the task's");
            Ok(())
        });
        let (report, trace) = run_checked(Runtime::new(), main).await;
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        assert!(report.is_clean(), "{report}");
        assert_eq!(handler_choices(&trace), ["recover<-NoGrasp"]);
        assert_eq!(
            log.entries(),
            ["caught NoGrasp (NoGrasp { x: 41 }): no grasp at 41"]
        );
        assert_eq!(attempts.load(Ordering::SeqCst), 2);
        // The retry is a remote task of its own, on the same agent.
        let placed = net.exec.placements();
        assert_eq!(placed.len(), 2);
        assert!(placed.iter().all(|p| p.agent == "arm"));
        let stats = net.exec.stats();
        assert_eq!((stats.failed, stats.succeeded), (1, 1), "{stats:?}");
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_local_failure_reaches_a_remote_body_typed_and_its_own_comes_back() {
    bounded(async {
        let net = Net::new("reverse").await;
        let arm = net
            .agent("arm")
            .goal("carry", |ctx: RemoteCtx, what: String| async move {
                match ctx.spawn(Child::local("lift", 50)).call().await {
                    Err(f) if f.is_a("Overload") => Err(RemoteFailure::raise(Dropped {
                        what,
                        why: f.to_string(),
                    })),
                    Err(f) => Err(f),
                    Ok(_) => Ok(()),
                }
            });
        let _arm = net.join(arm, "arm").await;
        net.exec.register("lift", |args| {
            let kg: u32 = serde_json::from_value(args)?;
            Ok(Task::command("lift", move |_| async move {
                Err::<(), _>(TooHeavy { kg }.raise())
            }))
        });
        let log = Log::default();
        let l = log.clone();
        let on_dropped = Handler::on::<Dropped, _, _, _>("on_dropped", move |ctx| {
            let l = l.clone();
            async move {
                let d = tcm_zenoh::caught::<Dropped>(&ctx).expect("a Dropped");
                l.push(format!("{d:?}"));
                Ok(())
            }
        });
        let exec = net.exec.clone();
        let main = Task::goal("main", move |ctx| async move {
            ctx.spawn(exec.remote("arm", "carry", "box").goal().task())
                .handler(on_dropped)
                .start()?;
            Ok(())
        });
        let (report, trace) = run_checked(Runtime::new(), main).await;
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        // The child's failure was the remote body's to look at: not unhandled.
        assert!(report.unhandled.is_empty(), "{report}");
        assert_eq!(handler_choices(&trace), ["on_dropped<-Dropped"]);
        assert_eq!(
            log.entries(),
            [r#"Dropped { what: "box", why: "TooHeavy: 50 kg is too heavy" }"#]
        );
    })
    .await;
}
