//! Exactly once: every message carries its task's id and a sequence number, and a receiver applies
//! each once. With every message sent twice (the agent's and the executive's fault injection),
//! each body runs once, each call is carried out once, each completion counts once, and the
//! copies are counted as duplicates.

use crate::util::{Log, Net, bounded, untimed};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};
use tcm::testing::{assert_order, run_checked};
use tcm::{NodeRef, RunOutcome, Runtime, Task, TraceKind};
use tcm_zenoh::{Child, Json, RemoteCtx, RemoteFailure, RemoteOptions};

/// Waits until `f()` holds, at most 5 s.
async fn eventually(what: &str, f: impl Fn() -> bool) {
    let start = Instant::now();
    while !f() {
        assert!(start.elapsed() < Duration::from_secs(5), "not so: {what}");
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn duplicated_completions_and_calls_from_an_agent_are_applied_once() {
    bounded(async {
        let net = Net::new("dup").await;
        let count = Arc::new(AtomicU64::new(0));
        let c = count.clone();
        let agent = net
            .agent("twice")
            .duplicate_messages(true)
            .command("count", move |_: RemoteCtx, (): ()| {
                let c = c.clone();
                async move { Ok::<_, RemoteFailure>(c.fetch_add(1, Ordering::SeqCst) + 1) }
            })
            .goal("expand", |ctx: RemoteCtx, (): ()| async move {
                let a = ctx.spawn(Child::local("note", "a")).start().await?;
                ctx.spawn(Child::local("note", "b")).start().await?;
                ctx.wait(a).await?;
                Ok::<_, RemoteFailure>(())
            });
        let twice = net.join(agent, "twice").await;
        let notes = Log::default();
        let n = notes.clone();
        net.exec.register("note", move |args| {
            let n = n.clone();
            let what: String = serde_json::from_value(args)?;
            Ok(Task::command("note", move |_| async move {
                n.push(what);
                Ok(())
            }))
        });
        let exec = net.exec.clone();
        let main = Task::goal("main", move |ctx| async move {
            for _ in 0..3 {
                ctx.spawn(exec.remote("twice", "count", ()).task())
                    .serial(NodeRef::Previous)
                    .start()?;
            }
            let v: Json = ctx
                .spawn(exec.remote("twice", "expand", ()).goal().task())
                .wait_value()
                .await?;
            assert_eq!(v, Json::Null);
            Ok(())
        });
        let (report, trace) = run_checked(Runtime::new(), main).await;
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        assert!(
            report.unhandled.is_empty() && report.panics.is_empty(),
            "{report}"
        );
        assert_eq!(count.load(Ordering::SeqCst), 3, "each body ran once");
        // The trace says where each remote node ran, and each copy that came before the run
        // ended is a warning on its node (the last completion's copy may come after).
        let placed: Vec<(u64, &str)> = trace
            .iter()
            .filter_map(|ev| match &ev.kind {
                TraceKind::Placed { node, agent } => Some((*node, agent.as_str())),
                _ => None,
            })
            .collect();
        assert_eq!(placed.iter().map(|p| p.1).collect::<Vec<_>>(), ["twice"; 4]);
        let warnings: Vec<(Option<u64>, &str)> = trace
            .iter()
            .filter_map(|ev| match &ev.kind {
                TraceKind::Warning { node, message } => Some((*node, message.as_str())),
                _ => None,
            })
            .collect();
        assert_eq!(warnings.len() as u64, report.warnings);
        assert!((1..=8).contains(&warnings.len()), "{warnings:?}");
        // On the remote node while it is in the tree, on the run once it has been reclaimed.
        for (node, message) in &warnings {
            assert!(message.contains("duplicate message"), "{message}");
            assert!(
                node.is_none_or(|n| placed.iter().any(|p| p.0 == n)),
                "{message}"
            );
        }
        let mut noted = notes.entries();
        noted.sort();
        assert_eq!(noted, ["a", "b"], "each spawn was carried out once");
        let story = untimed(&trace);
        assert_eq!(
            story
                .iter()
                .filter(|l| *l == "count handling completed")
                .count(),
            3
        );
        assert_order(
            &story,
            &[
                "expand handling active",
                "note handling active",
                "expand handling completed",
            ],
        );
        // Three completions, and for the goal: three calls, its start and its completion; each
        // sent twice.
        eventually("8 duplicates", || net.exec.stats().duplicates == 8).await;
        let stats = net.exec.stats();
        assert_eq!((stats.succeeded, stats.late), (4, 0), "{stats:?}");
        assert_eq!(twice.stats().started, 4);
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn duplicated_starts_and_cancels_from_the_executive_are_applied_once() {
    bounded(async {
        let net = Net::with("dupexec", RemoteOptions::default(), true).await;
        let count = Arc::new(AtomicU64::new(0));
        let c = count.clone();
        let log = Log::default();
        let (l1, l2) = (log.clone(), log.clone());
        let agent = net
            .agent("once")
            .command("count", move |_: RemoteCtx, (): ()| {
                let c = c.clone();
                async move { Ok::<_, RemoteFailure>(c.fetch_add(1, Ordering::SeqCst) + 1) }
            })
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
            });
        let once = net.join(agent, "once").await;
        let exec = net.exec.clone();
        let main = Task::goal("main", move |ctx| async move {
            ctx.spawn(exec.remote("once", "count", ()).task()).start()?;
            ctx.spawn(exec.remote("once", "count", ()).task()).start()?;
            ctx.spawn(exec.remote("once", "spin", ()).task())
                .terminate_in(Duration::from_millis(200))
                .start()?;
            Ok(())
        });
        let (report, _) = run_checked(Runtime::new(), main).await;
        assert!(report.is_clean(), "{report}");
        assert_eq!(count.load(Ordering::SeqCst), 2);
        assert_eq!(log.entries(), ["spin", "spin cleanup"]);
        // Three starts and a cancel, each sent twice.
        eventually("4 duplicates", || once.stats().duplicates == 4).await;
        let stats = once.stats();
        assert_eq!(
            (stats.started, stats.cancelled, stats.late),
            (3, 1, 0),
            "{stats:?}"
        );
    })
    .await;
}
