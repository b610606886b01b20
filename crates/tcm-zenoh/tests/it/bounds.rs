//! An agent's bounds (docs/distributed.md, "Bounds"): a start past the bodies it runs for one
//! executive, or in all, is refused; the executive's node fails at once with `RemoteRefused` (a
//! `RemoteError`) and a warning, instead of waiting for a body that will never run. A stranger's
//! flood of starts is held to the same bounds.

use crate::util::{JOIN, Log, Net, Stranger, bounded};
use serde_json::json;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tcm::testing::run_checked;
use tcm::{Ended, RunOutcome, Runtime, Task, TraceKind};
use tcm_zenoh::{AgentBuilder, Json, Limits, RemoteCtx, RemoteFailure, RemoteRefused};

/// Waits until `f()` holds, at most [`JOIN`].
async fn eventually(what: &str, f: impl Fn() -> bool) {
    let start = Instant::now();
    while !f() {
        assert!(start.elapsed() < JOIN, "not so within {JOIN:?}: {what}");
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
}

/// An agent `arm` offering `spin`, which logs `spin` and runs for an hour.
fn spinner(net: &Net, log: &Log, limits: Limits) -> AgentBuilder {
    let l = log.clone();
    net.agent("arm")
        .limits(limits)
        .command("spin", move |_: RemoteCtx, (): ()| {
            let log = l.clone();
            async move {
                log.push("spin");
                tokio::time::sleep(Duration::from_secs(3600)).await;
                Ok::<_, RemoteFailure>(())
            }
        })
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_start_past_the_agents_bound_fails_the_node_with_remote_refused() {
    bounded(async {
        let net = Net::new("bound-refused").await;
        let log = Log::default();
        let limits = Limits {
            bodies_per_executive: 2,
            ..Limits::default()
        };
        let arm = Arc::new(net.join(spinner(&net, &log, limits), "arm").await);
        let third: Arc<Mutex<Option<tcm::Failure>>> = Arc::default();
        let (exec, l, t) = (net.exec.clone(), log.clone(), third.clone());
        let main = Task::goal("main", move |ctx| async move {
            ctx.hold_children(false)?;
            let a = ctx.spawn(exec.remote("arm", "spin", ()).task()).start()?;
            let b = ctx.spawn(exec.remote("arm", "spin", ()).task()).start()?;
            let start = Instant::now();
            while l.entries().len() < 2 {
                assert!(start.elapsed() < JOIN, "two spins not started");
                tokio::time::sleep(Duration::from_millis(5)).await;
            }
            // The third is refused: a failure at once, not a wait for ever.
            let ended = ctx
                .spawn(exec.remote("arm", "spin", ()).task())
                .wait_outcome::<Json>()
                .await?;
            if let Ended::Failed(f) = ended {
                *t.lock().expect("third") = Some(f);
            }
            ctx.terminate(a)?;
            ctx.terminate(b)?;
            Ok(())
        });
        let (report, trace) = run_checked(Runtime::new(), main).await;
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        let f = third
            .lock()
            .expect("third")
            .clone()
            .expect("the third failed");
        assert!(f.is_a("RemoteError"), "{f:?}");
        let refused = f
            .data::<RemoteFailure>()
            .and_then(|r| r.data_as::<RemoteRefused>())
            .expect("a RemoteRefused");
        assert_eq!(
            (refused.agent.as_str(), refused.task.as_str()),
            ("arm", "spin")
        );
        assert!(refused.reason.contains("for this executive"), "{refused:?}");
        let warned: Vec<&String> = trace
            .iter()
            .filter_map(|ev| match &ev.kind {
                TraceKind::Warning { message, .. } => Some(message),
                _ => None,
            })
            .collect();
        assert!(
            warned.iter().any(|w| w.contains("refused by agent arm")),
            "{warned:?}"
        );
        assert_eq!(log.entries(), ["spin", "spin"]);
        let stats = arm.stats();
        assert_eq!(
            (stats.started, stats.over_limit, stats.cancelled),
            (2, 1, 2),
            "{stats:?}"
        );
        assert_eq!(arm.running(), 0);
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_strangers_flood_of_starts_is_held_to_the_agents_bounds() {
    bounded(async {
        let net = Net::new("bound-flood").await;
        let stranger = Stranger::new().await;
        let log = Log::default();
        let limits = Limits {
            bodies_per_executive: 3,
            bodies: 5,
            executives: 2,
        };
        let arm = net
            .join_beside(spinner(&net, &log, limits), "arm", &stranger)
            .await;
        // Ten starts from each of three executive ids nobody runs, whose tokens the stranger
        // declares (an agent starts tasks only for a live executive).
        let mut tokens = Vec::new();
        for exec in ["made-up-1", "made-up-2", "made-up-3"] {
            tokens.push(
                stranger
                    .session
                    .liveliness()
                    .declare_token(format!("tdl/{}/executives/{exec}", net.system))
                    .await
                    .expect("a token"),
            );
        }
        for exec in ["made-up-1", "made-up-2", "made-up-3"] {
            let key = format!("tdl/{}/to-agent/arm/{exec}", net.system);
            for task in 1..=10u64 {
                stranger
                    .forge(
                        key.clone(),
                        json!({"task": task, "seq": 1, "body": {"kind": "start", "node": 0,
                               "name": "spin", "task_kind": "command", "args": null}}),
                    )
                    .await;
            }
        }
        eventually("thirty starts seen", || {
            let s = arm.stats();
            s.started + s.over_limit == 30
        })
        .await;
        let stats = arm.stats();
        assert_eq!((stats.started, stats.over_limit), (5, 25), "{stats:?}");
        assert_eq!(arm.running(), 5);
    })
    .await;
}
