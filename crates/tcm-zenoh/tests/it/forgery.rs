//! A stranger on the network (a bare zenoh session linked with the agent or the executive, which
//! knows the keys and forges messages by hand) cannot drive a remote node where its executive did
//! not: a `cancel` the executive never sent is not a success but a `RemoteCancelled` failure, and
//! a message numbered past the next one expected (a sequence poisoned with 2^64-1, a gap) is
//! refused on both sides and changes nothing but a question to the agent where the task stands
//! (docs/distributed.md, "Exactly once"). The agent
//! binary logs what it ignores, one line per executive and interval.

use crate::util::{JOIN, Log, Net, Stranger, bounded};
use serde_json::json;
use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::sync::{Arc, Mutex, mpsc};
use std::time::{Duration, Instant};
use tcm::testing::{handler_choices, run_checked};
use tcm::{Handler, RunOutcome, Runtime, Task, TraceKind};
use tcm_zenoh::{AgentBuilder, Json, RemoteCancelled, RemoteCtx, RemoteFailure};

/// Waits until `f()` holds, at most [`JOIN`].
async fn eventually(what: &str, f: impl Fn() -> bool) {
    let start = Instant::now();
    while !f() {
        assert!(start.elapsed() < JOIN, "not so within {JOIN:?}: {what}");
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
}

/// The trace's warnings.
fn warnings(trace: &[tcm::TraceEvent]) -> Vec<String> {
    trace
        .iter()
        .filter_map(|ev| match &ev.kind {
            TraceKind::Warning { message, .. } => Some(message.clone()),
            _ => None,
        })
        .collect()
}

/// An agent `arm` offering `spin`, which runs for an hour and logs `spin`, with a cleanup that
/// logs `spin cleanup`.
fn spinner(net: &Net, log: &Log) -> AgentBuilder {
    let (l1, l2) = (log.clone(), log.clone());
    net.agent("arm")
        .command("spin", move |_: RemoteCtx, (): ()| {
            let log = l1.clone();
            async move {
                log.push("spin");
                tokio::time::sleep(Duration::from_secs(3600)).await;
                Ok::<_, RemoteFailure>(())
            }
        })
        .on_terminate("spin", move |(): ()| {
            let log = l2.clone();
            async move { log.push("spin cleanup") }
        })
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_cancel_the_executive_never_sent_fails_the_node_with_remote_cancelled() {
    bounded(async {
        let net = Net::new("forge-cancel").await;
        let stranger = Arc::new(Stranger::new().await);
        let log = Log::default();
        let _arm = net.join_beside(spinner(&net, &log), "arm", &stranger).await;
        let caught: Arc<Mutex<Option<RemoteCancelled>>> = Arc::default();
        let c = caught.clone();
        let on_cancelled = Handler::on::<RemoteCancelled, _, _, _>("on_cancelled", move |ctx| {
            let c = c.clone();
            async move {
                *c.lock().expect("caught") = tcm_zenoh::caught::<RemoteCancelled>(&ctx);
                Ok(())
            }
        });
        let exec = net.exec.clone();
        let key = format!("tdl/{}/to-agent/arm/{}", net.system, net.exec.id());
        let l = log.clone();
        let main = Task::goal("main", move |ctx| async move {
            ctx.hold_children(false)?;
            let spin = ctx
                .spawn(exec.remote("arm", "spin", ()).task())
                .handler(on_cancelled)
                .start()?;
            l.wait_for("spin", JOIN).await;
            // The executive's start was message 1 of task 1: the forged cancel is the next one,
            // so the agent, which cannot tell, applies it.
            stranger
                .forge(
                    key,
                    json!({"task": 1, "seq": 2, "body": {"kind": "cancel"}}),
                )
                .await;
            ctx.wait(spin).await?;
            Ok(())
        });
        let (report, trace) = run_checked(Runtime::new(), main).await;
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        assert!(report.unhandled.is_empty(), "{report}");
        // Not `Succeeded(null)`: a typed failure, which a handler of it (or of RemoteError) takes.
        assert_eq!(handler_choices(&trace), ["on_cancelled<-RemoteCancelled"]);
        assert_eq!(
            *caught.lock().expect("caught"),
            Some(RemoteCancelled {
                agent: "arm".into(),
                task: "spin".into()
            })
        );
        assert_eq!(log.entries(), ["spin", "spin cleanup"]);
        let warned = warnings(&trace);
        assert!(
            warned.iter().any(|w| w.contains("no cancel was sent")),
            "{warned:?}"
        );
        let stats = net.exec.stats();
        assert_eq!(
            (
                stats.cancels,
                stats.cancelled,
                stats.succeeded,
                stats.failed
            ),
            (0, 0, 0, 1),
            "{stats:?}"
        );
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_poisoned_sequence_number_cannot_make_the_executive_ignore_the_real_done() {
    bounded(async {
        let net = Net::new("forge-seq-exec").await;
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
        let arm = Arc::new(net.join(agent, "arm").await);
        // The stranger reaches the executive's inbox as any agent does.
        let stranger = zenoh::open(tcm_zenoh::config::loopback_connect(net.port).expect("config"))
            .await
            .expect("the stranger's session");
        let stranger = Arc::new(Stranger {
            session: stranger,
            port: 0,
        });
        // The stranger says it is `arm`, the agent the task runs on (the key names the sender).
        let key = format!("tdl/{}/to-exec/{}/arm", net.system, net.exec.id());
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
            // A `started` numbered 2^64-1 would make the real messages duplicates, and the node
            // would wait for ever; a `done` past a gap would end it with a forged value.
            stranger
                .forge(
                    key.clone(),
                    json!({"task": 1, "seq": u64::MAX, "body": {"kind": "started"}}),
                )
                .await;
            stranger
                .forge(
                    key,
                    json!({"task": 1, "seq": 5, "body": {"kind": "done", "result": {"Ok": "forged"}}}),
                )
                .await;
            eventually("two messages refused", || exec2.stats().refused == 2).await;
            // The gap made the executive ask the agent where the task stands, once; the answer
            // (still running) changes nothing.
            eventually("the agent asked", || arm.stats().reattached == 1).await;
            assert_eq!(arm.running(), 1, "the body still runs");
            gate.send_replace(true);
            Ok(())
        });
        let (report, trace) = run_checked(Runtime::new(), main).await;
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        assert!(
            report.unhandled.is_empty() && report.panics.is_empty() && report.failures == 0,
            "{report}"
        );
        assert_eq!(*value.lock().expect("value"), Some(json!("real")));
        // The first refusal is a warning of its own; the second, about the same task within a
        // second, is counted for one record when the second ends, after this short run.
        let warned = warnings(&trace);
        assert_eq!(
            warned
                .iter()
                .filter(|w| w.contains("out-of-order message"))
                .count(),
            1,
            "{warned:?}"
        );
        let stats = net.exec.stats();
        assert_eq!(
            (stats.refused, stats.succeeded, stats.duplicates),
            (2, 1, 0),
            "{stats:?}"
        );
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_poisoned_sequence_number_cannot_make_the_agent_ignore_the_executives_cancel() {
    bounded(async {
        let net = Net::new("forge-seq-agent").await;
        let stranger = Arc::new(Stranger::new().await);
        let log = Log::default();
        let arm = Arc::new(
            net.join_beside(spinner(&net, &log), "arm", &stranger)
                .await,
        );
        let key = format!("tdl/{}/to-agent/arm/{}", net.system, net.exec.id());
        let (exec, a, l) = (net.exec.clone(), arm.clone(), log.clone());
        let main = Task::goal("main", move |ctx| async move {
            ctx.hold_children(false)?;
            let spin = ctx
                .spawn(exec.remote("arm", "spin", ()).task())
                .start()?;
            l.wait_for("spin", JOIN).await;
            // A reply numbered 2^64-1 would make the executive's cancel (number 2) a duplicate;
            // a start not numbered 1 would do the same to a task to come.
            stranger
                .forge(
                    key.clone(),
                    json!({"task": 1, "seq": u64::MAX,
                           "body": {"kind": "reply", "call": 1, "result": {"Ok": {"answer": "done"}}}}),
                )
                .await;
            stranger
                .forge(
                    key,
                    json!({"task": 2, "seq": u64::MAX, "body": {"kind": "start", "node": 0,
                           "name": "spin", "task_kind": "command", "args": null}}),
                )
                .await;
            eventually("two messages refused", || a.stats().refused == 2).await;
            ctx.terminate(spin)?;
            Ok(())
        });
        let (report, _) = run_checked(Runtime::new(), main).await;
        assert!(report.is_clean(), "{report}");
        assert_eq!(log.entries(), ["spin", "spin cleanup"]);
        let stats = arm.stats();
        assert_eq!(
            (stats.started, stats.cancelled, stats.refused, stats.duplicates),
            (1, 1, 2, 0),
            "{stats:?}"
        );
        // The executive's cancel was applied and confirmed within the grace period.
        let stats = net.exec.stats();
        assert_eq!((stats.cancels, stats.cancelled), (1, 1), "{stats:?}");
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_agent_binary_logs_what_it_ignores_in_one_line_per_executive_and_interval() {
    bounded(async {
        let net = Net::new("forge-log").await;
        let stranger = Stranger::new().await;
        let mut child = Command::new(env!("CARGO_BIN_EXE_tcm-zenoh-agent"))
            .args([
                net.system.as_str(),
                "loud",
                &net.port.to_string(),
                &stranger.port.to_string(),
            ])
            .env_remove("RUST_LOG")
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("the agent process starts");
        let err = child.stderr.take().expect("its stderr");
        let (tx, lines) = mpsc::channel::<String>();
        std::thread::spawn(move || {
            for line in BufReader::new(err).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        net.exec
            .wait_for("loud", None, JOIN)
            .await
            .expect("the executive sees the agent");
        // Fifty messages about a task the agent never had, from a forged executive.
        let key = format!("tdl/{}/to-agent/loud/forged", net.system);
        for seq in 1..=50u64 {
            stranger
                .forge(
                    key.clone(),
                    json!({"task": 999, "seq": seq, "body": {"kind": "cancel"}}),
                )
                .await;
        }
        let mut seen = Vec::new();
        let start = Instant::now();
        // The first is logged at once; the others are held for the line at the interval's end
        // (10 s), which this test does not wait for.
        while start.elapsed() < Duration::from_millis(1500) {
            while let Ok(line) = lines.try_recv() {
                seen.push(line);
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        let _ = child.kill();
        let _ = child.wait();
        let ours: Vec<&String> = seen.iter().filter(|l| l.contains("tcm_zenoh")).collect();
        assert_eq!(ours.len(), 1, "{seen:#?}");
        assert!(
            ours[0].contains("WARN") && ours[0].contains("late cancel 1 of ended task 999"),
            "{ours:?}"
        );
        assert!(
            ours[0].contains("loud") && ours[0].contains("forged"),
            "{ours:?}"
        );
    })
    .await;
}
