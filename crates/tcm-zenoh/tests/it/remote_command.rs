//! Remote commands: nodes of the executive's tree whose actions run on an agent, under the tree's
//! constraints (serial, sequential, terminate at), with their values coming back and their agent
//! recorded.

use crate::util::{Log, Net, Nodes, bounded, untimed};
use serde_json::json;
use std::time::Duration;
use tcm::testing::{assert_order, run_checked};
use tcm::{Event, Facet, NodeRef, Point, RunOutcome, Runtime, Task};
use tcm_zenoh::{At, Json, RemoteCtx, RemoteFailure};

fn ms(n: u64) -> Duration {
    Duration::from_millis(n)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_remote_command_runs_under_serial_sequential_and_terminate_at_constraints() {
    bounded(async {
        let net = Net::new("constraints").await;
        let log = Log::default();
        let (l1, l2, l3) = (log.clone(), log.clone(), log.clone());
        let _arm = net
            .join(
                net.agent("arm")
                    .command("move", move |_: RemoteCtx, x: i64| {
                        let log = l1.clone();
                        async move {
                            log.push(format!("move {x}"));
                            tokio::time::sleep(ms(30)).await;
                            Ok::<_, RemoteFailure>(x * 2)
                        }
                    })
                    .command("spin", move |_: RemoteCtx, (): ()| {
                        let log = l2.clone();
                        async move {
                            log.push("spin");
                            loop {
                                tokio::time::sleep(ms(10)).await;
                            }
                            #[allow(unreachable_code)]
                            Ok::<(), RemoteFailure>(())
                        }
                    })
                    .on_terminate("spin", move |(): ()| {
                        let log = l3.clone();
                        async move { log.push("spin cleanup") }
                    }),
                "arm",
            )
            .await;
        let exec = net.exec.clone();
        let nodes = Nodes::default();
        let noted = nodes.clone();
        let plan = Task::goal("plan", move |ctx| async move {
            let prep = ctx
                .spawn(Task::command("prepare", |_| async {
                    tokio::time::sleep(ms(20)).await;
                    Ok(())
                }))
                .start()?;
            let mv = ctx
                .spawn(exec.remote("arm", "move", 21).task())
                .serial(NodeRef::Previous)
                .start()?;
            let speak = ctx
                .spawn(Task::command("speak", |_| async {
                    tokio::time::sleep(ms(20)).await;
                    Ok(())
                }))
                .sequential(Facet::Execution, mv)
                .start()?;
            let spin = ctx
                .spawn(exec.remote(At::agent("arm"), "spin", ()).task())
                .terminate_at(Event::new(speak, Point::Completed))
                .start()?;
            noted.note("prepare", prep);
            noted.note("move", mv);
            noted.note("spin", spin);
            Ok(())
        });
        let (report, trace) = run_checked(Runtime::new(), plan).await;
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        assert!(report.is_clean(), "{report}");
        let story = untimed(&trace);
        assert_order(
            &story,
            &[
                "prepare execution completed",
                "move handling active",
                "move execution completed",
                "speak handling active",
                "speak execution completed",
                "spin terminating",
                "spin terminated",
            ],
        );
        // The remote bodies ran, and the terminated one was cleaned up before its node ended.
        assert_eq!(log.entries(), ["spin", "move 21", "spin cleanup"]);
        assert_eq!(net.exec.agent_of(nodes.get("move")).as_deref(), Some("arm"));
        assert_eq!(net.exec.agent_of(nodes.get("spin")).as_deref(), Some("arm"));
        assert_eq!(net.exec.agent_of(nodes.get("prepare")), None);
        let stats = net.exec.stats();
        assert_eq!(
            (
                stats.placed,
                stats.succeeded,
                stats.cancels,
                stats.cancelled
            ),
            (2, 1, 1, 1),
            "{stats:?}"
        );
        assert_eq!((stats.duplicates, stats.late), (0, 0), "{stats:?}");
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn any_agent_is_the_first_by_name_that_offers_the_task_and_its_value_comes_back() {
    bounded(async {
        let net = Net::new("any").await;
        let double = |name: &'static str| {
            move |_: RemoteCtx, x: i64| async move {
                Ok::<_, RemoteFailure>(json!({ "by": name, "value": x * 2 }))
            }
        };
        let _b = net
            .join(net.agent("b").command("double", double("b")), "b")
            .await;
        let _a = net
            .join(net.agent("a").command("double", double("a")), "a")
            .await;
        let _c = net
            .join(net.agent("c").command("other", double("c")), "c")
            .await;
        net.exec
            .wait_for("a", Some("double"), crate::util::JOIN)
            .await
            .expect("offer seen");
        assert_eq!(net.exec.offering("double"), ["a", "b"]);
        let exec = net.exec.clone();
        let nodes = Nodes::default();
        let noted = nodes.clone();
        let main = Task::goal("main", move |ctx| async move {
            let node = ctx
                .spawn(exec.remote(At::Any, "double", 21).task())
                .start()?;
            noted.note("double", node);
            let v: Json = ctx
                .spawn(exec.remote(At::Any, "double", 5).task())
                .wait_value()
                .await?;
            assert_eq!(v, json!({"by": "a", "value": 10}));
            Ok(())
        });
        let (report, _) = run_checked(Runtime::new(), main).await;
        assert!(report.is_clean(), "{report}");
        assert_eq!(net.exec.agent_of(nodes.get("double")).as_deref(), Some("a"));
        assert_eq!(net.exec.placements().len(), 2);
    })
    .await;
}
