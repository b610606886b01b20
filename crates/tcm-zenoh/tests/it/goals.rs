//! Remote goals: a body on an agent expands the executive's tree, spawning children that run on
//! the executive, on another agent or on its own, under constraints, and waiting for them.

use crate::util::{Log, Net, bounded, untimed};
use serde_json::json;
use std::time::Duration;
use tcm::testing::{assert_order, run_checked};
use tcm::{Facet, RunOutcome, Runtime, Task};
use tcm_zenoh::{Child, ChildEnded, ChildRef, Json, RemoteCtx, RemoteFailure};

fn ms(n: u64) -> Duration {
    Duration::from_millis(n)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_remote_goal_spawns_local_and_remote_children_under_constraints() {
    bounded(async {
        let net = Net::new("goal").await;
        let log = Log::default();
        let (l1, l2, l3) = (log.clone(), log.clone(), log.clone());
        let arm = net
            .agent("arm")
            .goal("fetch", move |ctx: RemoteCtx, what: String| {
                let log = l1.clone();
                async move {
                    let door = ctx.spawn(Child::local("open_door", 1)).start().await?;
                    let grasp = ctx
                        .spawn(Child::on("hand", "grasp", &what))
                        .serial(ChildRef::Previous)
                        .start()
                        .await?;
                    ctx.spawn(Child::local("open_door", 2))
                        .sequential(Facet::Execution, grasp)
                        .start()
                        .await?;
                    log.push("fetch spawned");
                    // Its own agent, called for the value: the held children start meanwhile.
                    let weight = ctx.spawn(Child::here("weigh", &what)).call().await?;
                    let door_ended = ctx.wait(door).await?;
                    let grasp_ended = ctx.wait(grasp).await?;
                    assert!(door_ended.succeeded() && grasp_ended.succeeded());
                    log.push(format!("fetch weighed {weight}"));
                    Ok::<_, RemoteFailure>(json!({ "what": what, "weight": weight }))
                }
            })
            .command("weigh", move |_: RemoteCtx, what: String| {
                let log = l2.clone();
                async move {
                    log.push(format!("weigh {what}"));
                    Ok::<_, RemoteFailure>(what.len() * 100)
                }
            });
        let hand = net
            .agent("hand")
            .command("grasp", move |_: RemoteCtx, what: String| {
                let log = l3.clone();
                async move {
                    tokio::time::sleep(ms(20)).await;
                    log.push(format!("grasp {what}"));
                    Ok::<_, RemoteFailure>(())
                }
            });
        let _arm = net.join(arm, "arm").await;
        let _hand = net.join(hand, "hand").await;
        let doors = Log::default();
        let d = doors.clone();
        net.exec.register("open_door", move |args| {
            let d = d.clone();
            let n: u32 = serde_json::from_value(args)?;
            Ok(Task::command("open_door", move |_| async move {
                tokio::time::sleep(ms(10)).await;
                d.push(format!("door {n}"));
                Ok(())
            }))
        });
        let exec = net.exec.clone();
        let main = Task::goal("main", move |ctx| async move {
            let fetch = exec.remote("arm", "fetch", "mail").goal().task();
            let v: Json = ctx.spawn(fetch).wait_value().await?;
            assert_eq!(v, json!({"what": "mail", "weight": 400}));
            Ok(())
        });
        let (report, trace) = run_checked(Runtime::new(), main).await;
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        assert!(report.is_clean(), "{report}");
        let story = untimed(&trace);
        // The first door, then the grasp on the other agent, then the second door, which the
        // body does not wait for: the goal's execution completes after it.
        assert_order(
            &story,
            &[
                "fetch handling active",
                "open_door execution completed",
                "grasp handling active",
                "grasp execution completed",
                "open_door handling active",
                "fetch handling completed",
                "open_door execution completed",
                "fetch execution completed",
            ],
        );
        assert_order(
            &story,
            &[
                "weigh handling active",
                "weigh handling completed",
                "fetch handling completed",
            ],
        );
        assert_eq!(doors.entries(), ["door 1", "door 2"]);
        assert_eq!(
            log.entries(),
            [
                "fetch spawned",
                "weigh mail",
                "grasp mail",
                "fetch weighed 400"
            ]
        );
        let mut placed: Vec<(u64, String)> = net
            .exec
            .placements()
            .into_iter()
            .map(|p| (p.display, p.agent))
            .collect();
        placed.sort();
        let agents: Vec<&str> = placed.iter().map(|(_, a)| a.as_str()).collect();
        assert_eq!(
            agents,
            ["arm", "hand", "arm"],
            "fetch, grasp, weigh: {placed:?}"
        );
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_remote_body_sees_how_its_children_ended() {
    bounded(async {
        let defaults = tcm_zenoh::RemoteOptions {
            schedule_to_start: Some(ms(200)),
            ..Default::default()
        };
        let net = Net::with("ended", defaults, false).await;
        let arm = net
            .agent("arm")
            .goal("try", |ctx: RemoteCtx, (): ()| async move {
                let bad = ctx.spawn(Child::local("nope", ())).start().await;
                let unknown = bad.expect_err("no task nope is registered");
                assert!(unknown.is_a("RemoteError"), "{unknown}");
                let slow = ctx
                    .spawn(Child::local("slow", ()))
                    .terminate_in(ms(30))
                    .start()
                    .await?;
                let ended = ctx.wait(slow).await?;
                assert_eq!(ended, ChildEnded::Terminated);
                let other = ctx.spawn(Child::on("ghost", "x", ())).outcome();
                // Nobody offers it: the child fails with a schedule-to-start timeout.
                let ended = other.await?;
                let failure = ended.failure().expect("failed");
                assert_eq!(failure.exception, "RemoteTimeout");
                Ok::<_, RemoteFailure>("done")
            });
        let _arm = net.join(arm, "arm").await;
        net.exec.register("slow", |_| {
            Ok(Task::command("slow", |_| async {
                tokio::time::sleep(Duration::from_secs(3600)).await;
                Ok(())
            }))
        });
        let exec = net.exec.clone();
        let main = Task::goal("main", move |ctx| async move {
            let v: Json = ctx
                .spawn(exec.remote("arm", "try", ()).goal().task())
                .wait_value()
                .await?;
            assert_eq!(v, json!("done"));
            Ok(())
        });
        let (report, trace) = run_checked(Runtime::new(), main).await;
        assert!(report.is_clean(), "{report}");
        assert_order(
            &untimed(&trace),
            &[
                "slow terminating",
                "slow terminated",
                "x failed RemoteTimeout",
            ],
        );
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_remote_body_raises_external_events_and_terminates_its_children() {
    bounded(async {
        let net = Net::new("events").await;
        let arm = net
            .agent("arm")
            .goal("open", |ctx: RemoteCtx, (): ()| async move {
                let guard = ctx.spawn(Child::local("guard", ())).start().await?;
                ctx.raise_event("door_open").await?;
                ctx.terminate(guard).await?;
                let ended = ctx.wait(guard).await?;
                assert_eq!(ended, ChildEnded::Terminated);
                Ok::<_, RemoteFailure>(())
            });
        let _arm = net.join(arm, "arm").await;
        net.exec.register("guard", |_| {
            Ok(Task::command("guard", |_| async {
                tokio::time::sleep(Duration::from_secs(3600)).await;
                Ok(())
            }))
        });
        let exec = net.exec.clone();
        let main = Task::goal("main", move |ctx| async move {
            let door = ctx.external("door_open")?;
            ctx.spawn(Task::command("enter", |_| async { Ok(()) }))
                .with(tcm::Constraint::disable(
                    Facet::Handling,
                    tcm::When::External(door),
                ))
                .start()?;
            ctx.spawn(exec.remote("arm", "open", ()).goal().task())
                .start()?;
            Ok(())
        });
        let (report, trace) = run_checked(Runtime::new(), main).await;
        assert!(report.is_clean(), "{report}");
        assert_order(
            &untimed(&trace),
            &[
                "open handling active",
                "guard terminating",
                "guard terminated",
                "open handling completed",
            ],
        );
        assert_order(
            &untimed(&trace),
            &["open handling active", "enter handling active"],
        );
    })
    .await;
}
