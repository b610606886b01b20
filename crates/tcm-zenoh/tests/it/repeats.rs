//! Repeated warnings about one remote task are aggregated in the executive's trace
//! (docs/distributed.md, "Trace"): the first message ignored about a task is a `warning` record of
//! its own, what follows within a second is counted and written as one record when the second
//! ends. A flood of copies of an ended task's `done` adds a bounded number of records.

use crate::util::{JOIN, Net, Stranger, bounded};
use serde_json::json;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tcm::testing::run_checked;
use tcm::{RunOutcome, Runtime, Task, TraceKind};
use tcm_zenoh::{RemoteCtx, RemoteFailure};

/// How many copies the stranger sends.
const COPIES: u64 = 2_000;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn copies_of_an_ended_tasks_done_add_a_bounded_number_of_records() {
    bounded(async {
        let net = Net::new("repeats").await;
        let agent = net
            .agent("arm")
            .command("echo", |_: RemoteCtx, v: u32| async move {
                Ok::<_, RemoteFailure>(v)
            });
        let _arm = net.join(agent, "arm").await;
        let session = zenoh::open(tcm_zenoh::config::loopback_connect(net.port).expect("config"))
            .await
            .expect("the stranger's session");
        let stranger = Arc::new(Stranger { session, port: 0 });
        // As `arm`, the agent the task ran on (the key names the sender).
        let key = format!("tdl/{}/to-exec/{}/arm", net.system, net.exec.id());
        let exec = net.exec.clone();
        let main = Task::goal("main", move |ctx| async move {
            let v: serde_json::Value = ctx
                .spawn(exec.remote("arm", "echo", 7).task())
                .wait_value()
                .await?;
            assert_eq!(v, json!(7));
            // Task 1 ended with its `done`, number 1: copies of it are duplicates.
            let flood = Instant::now();
            let copy =
                json!({"task": 1, "seq": 1, "body": {"kind": "done", "result": {"Ok": 666}}});
            // The first through the helper, which waits until the inbox is known; the others
            // through one publisher.
            stranger.forge(key.clone(), copy.clone()).await;
            let publisher = stranger
                .session
                .declare_publisher(key)
                // Blocking, so that no copy is dropped on a full queue.
                .congestion_control(zenoh::qos::CongestionControl::Block)
                .await
                .expect("a publisher");
            let bytes = serde_json::to_vec(&copy).expect("JSON");
            for _ in 1..COPIES {
                publisher.put(bytes.clone()).await.expect("a put");
            }
            let start = Instant::now();
            while exec.stats().duplicates < COPIES {
                assert!(
                    start.elapsed() < JOIN,
                    "copies not all seen: {:?}",
                    exec.stats()
                );
                tokio::time::sleep(Duration::from_millis(5)).await;
            }
            let took = flood.elapsed();
            // The count of the last second is written when it ends.
            tokio::time::sleep(Duration::from_millis(1500)).await;
            Ok(took)
        });
        let (report, trace) = run_checked(Runtime::new(), main).await;
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        let warned: Vec<&String> = trace
            .iter()
            .filter_map(|ev| match &ev.kind {
                TraceKind::Warning { message, .. } => Some(message),
                _ => None,
            })
            .collect();
        // The first copy is a record of its own; the others are counted, one record per second.
        assert!(
            warned[0].contains("duplicate message 1 of ended remote task 1 ignored"),
            "{warned:?}"
        );
        let counted: u64 = warned[1..]
            .iter()
            .map(|w| {
                w.split(' ')
                    .next()
                    .and_then(|n| n.parse::<u64>().ok())
                    .unwrap_or_else(|| panic!("not a count: {w}"))
            })
            .sum();
        assert_eq!(1 + counted, COPIES, "{warned:?}");
        assert!(
            warned.len() <= 2 + 10,
            "{} records for {COPIES} copies: {warned:?}",
            warned.len()
        );
        assert!(
            warned[1..]
                .iter()
                .all(|w| w.contains("duplicate message(s) of remote task 1 ignored in the last")),
            "{warned:?}"
        );
        assert_eq!(net.exec.stats().duplicates, COPIES);
    })
    .await;
}
