//! Who may speak for a task (docs/distributed.md, "Who may speak"): the key of every message
//! names its sender, the executive accepts a task's messages only from the agent it placed the
//! task on, and an agent starts tasks only for an executive whose token is live.

use crate::util::{JOIN, Log, Net, Stranger, bounded};
use serde_json::json;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tcm::testing::run_checked;
use tcm::{RunOutcome, Runtime, Task, TraceKind};
use tcm_zenoh::{Json, RemoteCtx, RemoteFailure};

/// Waits until `f()` holds, at most [`JOIN`].
async fn eventually(what: &str, f: impl Fn() -> bool) {
    let start = Instant::now();
    while !f() {
        assert!(start.elapsed() < JOIN, "not so within {JOIN:?}: {what}");
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn another_agent_cannot_end_a_task_placed_on_arm() {
    bounded(async {
        let net = Net::new("identity-exec").await;
        let log = Log::default();
        let (gate, open) = tokio::sync::watch::channel(false);
        let l = log.clone();
        let agent = net.agent("arm").command("gated", move |_: RemoteCtx, (): ()| {
            let (log, mut open) = (l.clone(), open.clone());
            async move {
                log.push("gated");
                let _ = open.wait_for(|o| *o).await;
                Ok::<_, RemoteFailure>("real")
            }
        });
        let _arm = net.join(agent, "arm").await;
        let session = zenoh::open(tcm_zenoh::config::loopback_connect(net.port).expect("config"))
            .await
            .expect("the stranger's session");
        let stranger = Arc::new(Stranger { session, port: 0 });
        // The message numbered next (the agent sent `started`, number 1), as agent `ghost`.
        let key = format!("tdl/{}/to-exec/{}/ghost", net.system, net.exec.id());
        let value: Arc<Mutex<Option<Json>>> = Arc::default();
        let (exec, exec2, l, v) = (
            net.exec.clone(),
            net.exec.clone(),
            log.clone(),
            value.clone(),
        );
        let main = Task::goal("main", move |ctx| async move {
            ctx.hold_children(false)?;
            ctx.spawn(Task::goal("reader", move |ctx| async move {
                let got: Json = ctx
                    .spawn(exec.remote("arm", "gated", ()).task())
                    .wait_value()
                    .await?;
                *v.lock().expect("value") = Some(got);
                Ok(())
            }))
            .start()?;
            l.wait_for("gated", JOIN).await;
            stranger
                .forge(
                    key,
                    json!({"task": 1, "seq": 2, "body": {"kind": "done", "result": {"Ok": "forged"}}}),
                )
                .await;
            eventually("the forged done refused", || exec2.stats().strangers == 1).await;
            gate.send_replace(true);
            Ok(())
        });
        let (report, trace) = run_checked(Runtime::new(), main).await;
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        assert!(report.unhandled.is_empty() && report.failures == 0, "{report}");
        assert_eq!(*value.lock().expect("value"), Some(json!("real")));
        let warned: Vec<&String> = trace
            .iter()
            .filter_map(|ev| match &ev.kind {
                TraceKind::Warning { message, .. } => Some(message),
                _ => None,
            })
            .collect();
        assert!(
            warned
                .iter()
                .any(|w| w.contains("message from ghost (not the agent arm it runs on)")),
            "{warned:?}"
        );
        let stats = net.exec.stats();
        assert_eq!(
            (stats.strangers, stats.succeeded, stats.refused),
            (1, 1, 0),
            "{stats:?}"
        );
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_agent_starts_tasks_only_for_a_live_executive() {
    bounded(async {
        let net = Net::new("identity-agent").await;
        let stranger = Stranger::new().await;
        let log = Log::default();
        let l = log.clone();
        let agent = net
            .agent("arm")
            .command("work", move |_: RemoteCtx, x: i64| {
                let log = l.clone();
                async move {
                    log.push(format!("work {x}"));
                    Ok::<_, RemoteFailure>(x * 2)
                }
            });
        let arm = net.join_beside(agent, "arm", &stranger).await;
        // A start from an executive id no token stands for.
        stranger
            .forge(
                format!("tdl/{}/to-agent/arm/made-up", net.system),
                json!({"task": 1, "seq": 1, "body": {"kind": "start", "node": 0,
                       "name": "work", "task_kind": "command", "args": 666}}),
            )
            .await;
        eventually("the forged start refused", || arm.stats().strangers == 1).await;
        // The real executive's start runs.
        let exec = net.exec.clone();
        let main = Task::goal("main", move |ctx| async move {
            let v: Json = ctx
                .spawn(exec.remote("arm", "work", 21).task())
                .wait_value()
                .await?;
            assert_eq!(v, json!(42));
            Ok(())
        });
        let (report, _) = run_checked(Runtime::new(), main).await;
        assert!(report.is_clean(), "{report}");
        assert_eq!(log.entries(), ["work 21"]);
        let stats = arm.stats();
        assert_eq!(
            (stats.strangers, stats.started, stats.ended),
            (1, 1, 1),
            "{stats:?}"
        );
    })
    .await;
}
