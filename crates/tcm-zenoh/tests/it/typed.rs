//! Typed values of remote tasks: `Remote::typed_task` and `Remote::task_map` give the node a value
//! of a Rust type, read from the body's JSON, so a tree waits for it as for a local task's; a
//! value that does not read fails the node with `RemoteError`.

use crate::util::{Net, bounded};
use serde::{Deserialize, Serialize};
use tcm::testing::run_checked;
use tcm::{Runtime, Task};
use tcm_zenoh::{RemoteCtx, RemoteFailure};

#[derive(Debug, PartialEq, Serialize, Deserialize)]
struct Pose {
    x: f64,
    y: f64,
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_remote_value_is_read_as_a_rust_type_or_fails_with_remote_error() {
    bounded(async {
        let net = Net::new("typed").await;
        let _base = net
            .join(
                net.agent("base")
                    .command("pose", |_: RemoteCtx, (): ()| async {
                        Ok::<_, RemoteFailure>(serde_json::json!({"x": 1.5, "y": -2.0}))
                    }),
                "base",
            )
            .await;
        let exec = net.exec.clone();
        let main = Task::goal("main", move |ctx| async move {
            let pose: Pose = ctx
                .spawn(exec.remote("base", "pose", ()).typed_task::<Pose>())
                .wait_value()
                .await?;
            assert_eq!(pose, Pose { x: 1.5, y: -2.0 });
            let sum: f64 = ctx
                .spawn(exec.remote("base", "pose", ()).task_map(|v| {
                    Ok(v["x"].as_f64().unwrap_or(0.0) + v["y"].as_f64().unwrap_or(0.0))
                }))
                .wait_value()
                .await?;
            assert_eq!(sum, -0.5);
            let bad = ctx
                .spawn(exec.remote("base", "pose", ()).typed_task::<String>())
                .wait_outcome::<String>()
                .await?;
            let f = bad
                .failure()
                .cloned()
                .expect("a value that does not read fails");
            assert_eq!(f.exception, "RemoteError");
            assert!(f.message.contains("does not read"), "{}", f.message);
            Ok(())
        });
        let (report, _) = run_checked(Runtime::new(), main).await;
        assert!(report.is_clean(), "{report}");
    })
    .await;
}
