//! Termination reaches the agents: terminating a remote goal terminates its subtree in the tree,
//! and each remote body of it is aborted on its agent, which runs the task's cleanup and confirms
//! before the node is terminated.

use crate::util::{Log, Net, Nodes, bounded, untimed};
use std::time::Duration;
use tcm::testing::{assert_order, run_checked};
use tcm::{RunOutcome, Runtime, Task};
use tcm_zenoh::{Child, RemoteCtx, RemoteFailure};

fn ms(n: u64) -> Duration {
    Duration::from_millis(n)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn terminating_a_remote_subtree_runs_each_cleanup_on_its_agent() {
    bounded(async {
        let net = Net::new("terminate").await;
        let log = Log::default();
        let (l1, l2, l3, l4) = (log.clone(), log.clone(), log.clone(), log.clone());
        let base = net
            .agent("base")
            .goal("patrol", move |ctx: RemoteCtx, (): ()| {
                let log = l1.clone();
                async move {
                    let scan = ctx.spawn(Child::here("scan", 3)).start().await?;
                    ctx.spawn(Child::local("beep", ())).start().await?;
                    log.push("patrol waits");
                    ctx.wait(scan).await?;
                    log.push("patrol went on");
                    Ok::<(), RemoteFailure>(())
                }
            })
            .on_terminate("patrol", move |(): ()| {
                let log = l2.clone();
                async move { log.push("patrol cleanup") }
            })
            .command("scan", move |_: RemoteCtx, n: u32| {
                let log = l3.clone();
                async move {
                    log.push(format!("scan {n}"));
                    tokio::time::sleep(Duration::from_secs(3600)).await;
                    Ok::<(), RemoteFailure>(())
                }
            })
            .on_terminate("scan", move |n: u32| {
                let log = l4.clone();
                async move {
                    tokio::time::sleep(ms(20)).await;
                    log.push(format!("scan {n} cleanup"));
                }
            });
        let base = net.join(base, "base").await;
        let beeps = Log::default();
        let b = beeps.clone();
        net.exec.register("beep", move |_| {
            let b = b.clone();
            Ok(Task::command("beep", move |_| async move {
                b.push("beep");
                // Terminated with its parent: dropped at once.
                tokio::time::sleep(Duration::from_secs(3600)).await;
                Ok(())
            }))
        });
        let exec = net.exec.clone();
        let nodes = Nodes::default();
        let noted = nodes.clone();
        let watch = log.clone();
        let main = Task::goal("main", move |ctx| async move {
            ctx.hold_children(false)?;
            let patrol = ctx
                .spawn(exec.remote("base", "patrol", ()).goal().task())
                .start()?;
            noted.note("patrol", patrol);
            watch.wait_for("scan 3", Duration::from_secs(10)).await;
            watch
                .wait_for("patrol waits", Duration::from_secs(10))
                .await;
            ctx.terminate(patrol)?;
            Ok(())
        });
        let (report, trace) = run_checked(Runtime::new(), main).await;
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        let story = untimed(&trace);
        assert_order(
            &story,
            &[
                "patrol handling active",
                "scan handling active",
                "patrol terminating",
                "scan terminating",
                "scan terminated",
                "patrol terminated",
            ],
        );
        assert_order(&story, &["beep handling active", "beep terminated"]);
        let entries = log.entries();
        for e in ["patrol cleanup", "scan 3 cleanup"] {
            assert!(entries.iter().any(|x| x == e), "{e} missing: {entries:?}");
        }
        assert!(
            !entries.iter().any(|x| x == "patrol went on"),
            "{entries:?}"
        );
        assert_eq!(beeps.entries(), ["beep"]);
        assert_eq!(base.stats().cancelled, 2, "{:?}", base.stats());
        assert_eq!(base.running(), 0);
        let stats = net.exec.stats();
        assert_eq!((stats.cancels, stats.cancelled), (2, 2), "{stats:?}");
        // The child the remote body spawned on its own agent ran there.
        let placed: Vec<(String, String)> = net
            .exec
            .placements()
            .iter()
            .map(|p| (p.agent.clone(), format!("{}", p.display)))
            .collect();
        assert_eq!(placed.len(), 2, "{placed:?}");
        assert!(placed.iter().all(|(a, _)| a == "base"));
        assert_eq!(
            net.exec.agent_of(nodes.get("patrol")).as_deref(),
            Some("base")
        );
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn closing_the_executive_aborts_its_bodies_on_the_agents_and_fails_its_remote_tasks() {
    bounded(async {
        let net = Net::new("close").await;
        let log = Log::default();
        let (l1, l2) = (log.clone(), log.clone());
        let agent = net
            .agent("arm")
            .command("spin", move |_: RemoteCtx, (): ()| {
                let log = l1.clone();
                async move {
                    log.push("spin");
                    tokio::time::sleep(Duration::from_secs(3600)).await;
                    Ok::<(), RemoteFailure>(())
                }
            })
            .on_terminate("spin", move |(): ()| {
                let log = l2.clone();
                async move { log.push("spin cleanup") }
            });
        let arm = net.join(agent, "arm").await;
        let exec = net.exec.clone();
        let watch = log.clone();
        let main = Task::goal("main", move |ctx| async move {
            let close = async {
                watch.wait_for("spin", Duration::from_secs(10)).await;
                exec.close().await;
            };
            let spin = ctx
                .spawn(exec.remote("arm", "spin", ()).task())
                .wait_outcome::<tcm_zenoh::Json>();
            let (ended, ()) = tokio::join!(spin, close);
            let failure = ended?.failure().cloned().expect("spin failed");
            assert_eq!(failure.exception, "RemoteError");
            assert_eq!(failure.message, "the executive was closed");
            // Nothing more can be placed.
            let later = ctx
                .spawn(exec.remote("arm", "spin", ()).task())
                .wait_outcome::<tcm_zenoh::Json>()
                .await?;
            assert_eq!(
                later.failure().map(|f| f.message.as_str()),
                Some("the executive was closed")
            );
            Ok(())
        });
        let (report, _) = run_checked(Runtime::new(), main).await;
        assert!(report.is_clean(), "{report}");
        log.wait_for("spin cleanup", Duration::from_secs(5)).await;
        assert_eq!(arm.stats().orphaned, 1);
        assert_eq!(arm.running(), 0);
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_remote_action_dropped_at_once_still_cancels_its_body() {
    bounded(async {
        let net = Net::new("drop").await;
        let log = Log::default();
        let (l1, l2) = (log.clone(), log.clone());
        let agent = net
            .agent("arm")
            .command("spin", move |_: RemoteCtx, (): ()| {
                let log = l1.clone();
                async move {
                    log.push("spin");
                    tokio::time::sleep(Duration::from_secs(3600)).await;
                    Ok::<(), RemoteFailure>(())
                }
            })
            .on_terminate("spin", move |(): ()| {
                let log = l2.clone();
                async move { log.push("spin cleanup") }
            });
        let arm = net.join(agent, "arm").await;
        let exec = net.exec.clone();
        let watch = log.clone();
        let main = Task::goal("main", move |ctx| async move {
            ctx.hold_children(false)?;
            // No grace period: the action is dropped as soon as its node is terminated.
            let spin = ctx
                .spawn(exec.remote("arm", "spin", ()).grace(Duration::ZERO).task())
                .start()?;
            watch.wait_for("spin", Duration::from_secs(10)).await;
            ctx.terminate(spin)?;
            Ok(())
        });
        let (report, trace) = run_checked(Runtime::new(), main).await;
        assert!(report.is_clean(), "{report}");
        assert_order(&untimed(&trace), &["spin terminating", "spin terminated"]);
        // The cancel left from the dropped action; the agent's confirmation is late.
        log.wait_for("spin cleanup", Duration::from_secs(5)).await;
        let start = std::time::Instant::now();
        while net.exec.stats().late < 1 {
            assert!(
                start.elapsed() < Duration::from_secs(5),
                "{:?}",
                net.exec.stats()
            );
            tokio::time::sleep(ms(5)).await;
        }
        let stats = net.exec.stats();
        // The confirmation is late; on a loaded machine a message the agent sent before it saw
        // the cancel may be too.
        assert_eq!((stats.cancels, stats.cancelled), (1, 0), "{stats:?}");
        assert!((1..=2).contains(&stats.late), "{stats:?}");
        assert_eq!(arm.stats().cancelled, 1);
    })
    .await;
}
