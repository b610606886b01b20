//! Suspending a remote subtree: as for any node (docs/semantics.md, "Suspension"), suspending a
//! remote goal suspends the children its body spawned in the tree, wherever they run, so what has
//! not started waits until it is unsuspended; what runs goes on (a body is not paused, here or on
//! an agent). The run then completes, through the checker.

use crate::util::{Log, Net, bounded, untimed};
use std::time::Duration;
use tcm::testing::{assert_order, run_checked};
use tcm::{RunOutcome, Runtime, Task};
use tcm_zenoh::{Child, ChildRef, RemoteCtx, RemoteFailure};

fn ms(n: u64) -> Duration {
    Duration::from_millis(n)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn suspending_a_remote_goal_holds_its_children_until_it_is_unsuspended() {
    bounded(async {
        let net = Net::new("suspend").await;
        let log = Log::default();
        let l = log.clone();
        let base = net
            .agent("base")
            .goal("patrol", |ctx: RemoteCtx, (): ()| async move {
                let mut legs = Vec::new();
                for i in 1..=3 {
                    let leg = ctx
                        .spawn(Child::here("leg", i))
                        .serial(ChildRef::Previous)
                        .start()
                        .await?;
                    legs.push(leg);
                }
                for leg in legs {
                    ctx.wait(leg).await?;
                }
                Ok::<_, RemoteFailure>(())
            })
            .command("leg", move |_: RemoteCtx, i: u32| {
                let log = l.clone();
                async move {
                    log.push(format!("leg {i} starts"));
                    tokio::time::sleep(ms(300)).await;
                    log.push(format!("leg {i} ends"));
                    Ok::<_, RemoteFailure>(())
                }
            });
        let _base = net.join(base, "base").await;
        let exec = net.exec.clone();
        let (l2, l3, seen) = (log.clone(), log.clone(), log.clone());
        // The operator suspends the patrol once its second leg has started, for 600 ms (a goal's
        // children start once its body returns or waits, so the operator is a command of its own).
        let main = Task::goal("main", move |ctx| async move {
            let patrol = ctx
                .spawn(exec.remote("base", "patrol", ()).goal().task())
                .start()?;
            ctx.spawn(Task::command("operator", move |ctx| async move {
                while !seen.entries().iter().any(|e| e == "leg 2 starts") {
                    tokio::time::sleep(ms(5)).await;
                }
                ctx.suspend(patrol)?;
                l2.push("suspended");
                tokio::time::sleep(ms(600)).await;
                l3.push("unsuspended");
                ctx.unsuspend(patrol)?;
                Ok(())
            }))
            .start()?;
            Ok(())
        });
        let (report, trace) = run_checked(Runtime::new(), main).await;
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        let entries = log.entries();
        // Leg 2 was running when the goal was suspended: it finished. Leg 3 waited for the
        // unsuspension, 600 ms later.
        let at = |what: &str| {
            entries
                .iter()
                .position(|e| e == what)
                .unwrap_or_else(|| panic!("no {what:?} in {entries:?}"))
        };
        assert!(at("leg 2 starts") < at("suspended"), "{entries:?}");
        assert!(at("unsuspended") < at("leg 3 starts"), "{entries:?}");
        assert!(at("leg 2 ends") < at("unsuspended"), "{entries:?}");
        let story = untimed(&trace);
        assert_order(
            &story,
            &[
                "patrol suspended",
                "leg suspended",
                "patrol unsuspended",
                "leg unsuspended",
                "patrol execution completed",
            ],
        );
    })
    .await;
}
