//! A serving executive's runs started as ROS 2 action goals (`tcm_ros::run_task::run_task`),
//! driven by ros2-client's own action client: a goal runs a program's task in a run of its own,
//! its feedback gives the run's live nodes, its result the run's outcome; a goal naming no loaded
//! program is aborted; a canceled goal stops its run.

use std::sync::Arc;
use std::time::{Duration, Instant};

use crate::util::{Pair, bounded};
use ros2_client::action_msgs::GoalStatusEnum;
use tcm::{Recorder, Runtime};
use tcm_ros::ros2_client;
use tcm_ros::run_task::{RunTaskFeedback, RunTaskGoal, RunTaskResult, action_type, run_task};
use tdl_serve::{File, Reply, Request, Response, Server};

type RunTaskClient = ros2_client::ActionClient<RunTaskGoal, RunTaskResult, RunTaskFeedback>;

/// Ticks `n` times, 50 ms apart, then completes.
const TICKS: &str = "\
pub goal ticks(n: i64) {
    spawn tick(n);
}

monitor tick(n: i64) with period 50ms, maximum activate n {
}
";

fn send(client: &RunTaskClient, goal: RunTaskGoal) -> (ros2_client::GoalId, bool) {
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        match client.send_goal(goal.clone()) {
            Ok(answer) => return answer,
            Err(e) => {
                assert!(Instant::now() < deadline, "no server answered: {e}");
                std::thread::sleep(Duration::from_millis(50));
            }
        }
    }
}

/// The goal's status and result, its feedback collected meanwhile.
fn finish(
    client: &Arc<RunTaskClient>,
    goal: ros2_client::GoalId,
    seen: &mut Vec<RunTaskFeedback>,
) -> (i8, RunTaskResult) {
    let c = client.clone();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(c.get_result(goal));
    });
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        while let Some((g, f)) = client.take_feedback() {
            if g == goal {
                seen.push(f);
            }
        }
        match rx.recv_timeout(Duration::from_millis(5)) {
            Ok(answer) => return answer.expect("a result"),
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {
                assert!(Instant::now() < deadline, "no result");
            }
            Err(e) => panic!("no result: {e}"),
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_goal_runs_a_programs_task_and_returns_its_outcome_and_a_cancel_stops_the_run() {
    bounded(async {
        let pair = Pair::new().await;
        let dir = std::env::temp_dir().join(format!("tcm-ros-run-task-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let server = Server::new(tdl_interp::Registry::new(), None, &dir);
        let loaded = server.handle(
            Request::Load {
                name: "ticks".into(),
                files: vec![File {
                    name: "ticks.tdl".into(),
                    text: TICKS.into(),
                }],
                swap: Default::default(),
                verify: None,
            },
            "test",
        );
        assert!(matches!(loaded, Response::Ok(Reply::Loaded { .. })), "{loaded:?}");
        let offer = run_task(&pair.server, "/run_task", server.clone()).expect("the action");
        let rec = Recorder::new();
        let session = Runtime::new()
            .with_sink(rec.clone())
            .start()
            .expect("a session");
        let serving = session.spawn(offer).expect("the server starts");
        let name = ros2_client::Name::parse("/run_task").expect("name");
        let client: Arc<RunTaskClient> = Arc::new(
            pair.client
                .create_action_client(&name, &action_type())
                .expect("ros2-client's action client"),
        );
        let c = client.clone();
        tokio::task::spawn_blocking(move || {
            // Ten ticks: feedback while the run runs, then its outcome.
            let goal = RunTaskGoal {
                program: "ticks".into(),
                task: String::new(),
                args: "10".into(),
            };
            let (id, accepted) = send(&c, goal);
            assert!(accepted);
            let mut seen = Vec::new();
            let (status, result) = finish(&c, id, &mut seen);
            assert_eq!(status, GoalStatusEnum::Succeeded as i8, "{result:?}");
            assert!(result.outcome.starts_with("completed"), "{result:?}");
            assert!(result.run >= 1);
            assert!(
                seen.iter().any(|f| f.run == result.run && f.live_nodes >= 2),
                "feedback while it ran: {seen:?}"
            );
            let trace = std::fs::read_to_string(&result.trace).expect("its trace");
            assert_eq!(trace.matches("\"ev\":\"activated\"").count(), 10);
            // A program the executive does not hold: aborted.
            let (bad, accepted) = send(
                &c,
                RunTaskGoal {
                    program: "none".into(),
                    ..RunTaskGoal::default()
                },
            );
            assert!(accepted);
            let (status, _) = finish(&c, bad, &mut Vec::new());
            assert_eq!(status, GoalStatusEnum::Aborted as i8);
            // A long run, canceled once it runs: the run is stopped.
            let (long, accepted) = send(
                &c,
                RunTaskGoal {
                    program: "ticks".into(),
                    task: "ticks".into(),
                    args: "100000".into(),
                },
            );
            assert!(accepted);
            let mut seen = Vec::new();
            let deadline = Instant::now() + Duration::from_secs(20);
            while seen.is_empty() {
                assert!(Instant::now() < deadline, "no feedback");
                while let Some((g, f)) = c.take_feedback() {
                    if g == long {
                        seen.push(f);
                    }
                }
                std::thread::sleep(Duration::from_millis(5));
            }
            c.cancel_goal(long).expect("the cancel is answered");
            let (status, _) = finish(&c, long, &mut seen);
            assert_eq!(status, GoalStatusEnum::Canceled as i8);
            seen[0].run
        })
        .await
        .map(|long_run| {
            let deadline = Instant::now() + Duration::from_secs(20);
            loop {
                let s = server.status(Some(long_run));
                if s.first().is_some_and(|r| !r.running && r.outcome.as_deref().is_some_and(|o| o.starts_with("terminated"))) {
                    break;
                }
                assert!(Instant::now() < deadline, "the canceled goal's run was not stopped: {s:?}");
                std::thread::sleep(Duration::from_millis(20));
            }
        })
        .expect("the client's side");
        session.terminate(serving).expect("the server stops");
        session.finish().await.expect("the serving run ends");
        let trace = rec.events();
        tcm::testing::assert_checked(&trace);
        // The refused goal failed its node with the executive's reason.
        assert!(trace.iter().any(|e| matches!(&e.kind, tcm::TraceKind::Failed { exception, message, .. } if exception == "RunTaskRefused" && message.contains("no program `none`"))));
        let _ = std::fs::remove_dir_all(&dir);
    })
    .await;
}
