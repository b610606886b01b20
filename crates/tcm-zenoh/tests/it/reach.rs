//! The first message to a peer waits until its inbox is known (docs/distributed.md, "Messages"):
//! zenoh drops a publication no known subscriber matches, and a peer's liveliness token can come
//! before its inbox's declaration. Each test plays one side with a bare zenoh session that
//! declares its inbox only after the other side has seen its token, and speaks the wire format by
//! hand.

use crate::util::{JOIN, Net, bounded, put};
use serde_json::{Value, json};
use std::time::Duration;
use tcm::testing::run_checked;
use tcm::{RunOutcome, Runtime, Task};
use tcm_zenoh::{Agent, Json, RemoteCtx, RemoteFailure};
use tokio::sync::mpsc;

/// How long the bare side waits before it declares its inbox.
const LATE: Duration = Duration::from_millis(500);

/// A bare subscriber of `key` whose samples (key, JSON) come through the returned channel.
async fn inbox(
    session: &zenoh::Session,
    key: String,
) -> (
    zenoh::pubsub::Subscriber<()>,
    mpsc::UnboundedReceiver<(String, Value)>,
) {
    let (tx, rx) = mpsc::unbounded_channel();
    let sub = session
        .declare_subscriber(key)
        .callback(move |s| {
            let v = serde_json::from_slice(&s.payload().to_bytes()).unwrap_or(Value::Null);
            let _ = tx.send((s.key_expr().as_str().to_string(), v));
        })
        .await
        .expect("a subscriber");
    (sub, rx)
}

async fn next(rx: &mut mpsc::UnboundedReceiver<(String, Value)>, what: &str) -> (String, Value) {
    tokio::time::timeout(JOIN, rx.recv())
        .await
        .unwrap_or_else(|_| panic!("no {what} within {JOIN:?}"))
        .expect("the subscriber is alive")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_start_waits_for_an_agent_whose_inbox_comes_after_its_token() {
    bounded(async {
        let net = Net::new("reach-exec").await;
        let sys = net.system.clone();
        let bare = zenoh::open(tcm_zenoh::config::loopback_connect(net.port).expect("config"))
            .await
            .expect("a session");
        let liveliness = bare.liveliness();
        let _offer = liveliness
            .declare_token(format!("tdl/{sys}/offers/work/late"))
            .await
            .expect("a token");
        let _agent = liveliness
            .declare_token(format!("tdl/{sys}/agents/late"))
            .await
            .expect("a token");
        net.exec
            .wait_for("late", Some("work"), JOIN)
            .await
            .expect("the executive sees the agent");
        let exec = net.exec.clone();
        let main = Task::goal("main", move |ctx| async move {
            let v: Json = ctx
                .spawn(
                    exec.remote("late", "work", 21)
                        .schedule_to_start(Some(Duration::from_secs(30)))
                        .task(),
                )
                .wait_value()
                .await?;
            assert_eq!(v, json!(42));
            Ok(())
        });
        let run = tokio::spawn(run_checked(Runtime::new(), main));
        // The executive has placed the task by now and would have sent its start.
        tokio::time::sleep(LATE).await;
        let (_sub, mut rx) = inbox(&bare, format!("tdl/{sys}/to-agent/late/*")).await;
        let (key, start) = next(&mut rx, "start").await;
        assert_eq!(start["seq"], 1, "{start}");
        assert_eq!(start["body"]["kind"], "start", "{start}");
        assert_eq!(start["body"]["name"], "work", "{start}");
        assert_eq!(start["body"]["args"], 21, "{start}");
        let exec_id = key.rsplit('/').next().expect("the executive's id");
        let done = json!({"task": start["task"], "seq": 1, "body": {"kind": "done", "result": {"Ok": 42}}});
        put(&bare, format!("tdl/{sys}/to-exec/{exec_id}/late"), done).await;
        let (report, _trace) = run.await.expect("the run");
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        assert!(report.unhandled.is_empty(), "{report}");
        let stats = net.exec.stats();
        assert_eq!(
            (stats.placed, stats.succeeded, stats.timeouts, stats.duplicates),
            (1, 1, 0, 0),
            "{stats:?}"
        );
        assert!(
            tokio::time::timeout(Duration::from_millis(100), rx.recv())
                .await
                .is_err(),
            "one start, nothing after it"
        );
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_done_waits_for_an_executive_whose_inbox_comes_after_its_token() {
    bounded(async {
        let sys = format!("reach-agent-{}", std::process::id());
        let port = tcm_zenoh::config::free_port().expect("a port");
        let bare = zenoh::open(tcm_zenoh::config::loopback_listen(port).expect("config"))
            .await
            .expect("a session");
        let _token = bare
            .liveliness()
            .declare_token(format!("tdl/{sys}/executives/bare"))
            .await
            .expect("a token");
        let agent = Agent::builder(sys.clone(), "a")
            .command("double", |_: RemoteCtx, x: i64| async move {
                Ok::<_, RemoteFailure>(x * 2)
            })
            .start(tcm_zenoh::config::loopback_connect(port).expect("config"))
            .await
            .expect("the agent starts");
        // The agent sees the executive's token at once; its inbox comes later.
        let start = json!({"task": 7, "seq": 1, "body": {
            "kind": "start", "node": 1, "name": "double", "task_kind": "command", "args": 21}});
        put(&bare, format!("tdl/{sys}/to-agent/a/bare"), start).await;
        tokio::time::sleep(LATE).await;
        let (_sub, mut rx) = inbox(&bare, format!("tdl/{sys}/to-exec/bare/a")).await;
        let (_, done) = next(&mut rx, "done").await;
        assert_eq!(
            done,
            json!({"task": 7, "seq": 1, "body": {"kind": "done", "result": {"Ok": 42}}})
        );
        let stats = agent.stats();
        assert_eq!((stats.duplicates, stats.late), (0, 0), "{stats:?}");
    })
    .await;
}
