//! A task of the tree offered as a ROS 2 action, called by ros2-client's own action client: each
//! goal runs a task built from it as a child of the serving node, its feedback reaches the client,
//! its value is the result; a cancel request terminates the child and the goal ends canceled; a
//! failing task aborts the goal; a goal the server does not accept is rejected.

use crate::util::{FibFeedback, FibGoal, FibResult, Pair, bounded, fib_type, fibonacci};
use ros2_client::GoalId;
use ros2_client::action_msgs::{CancelGoalResponseEnum, GoalStatusEnum};
use serde::{Deserialize, Serialize};
use std::sync::Arc;
use std::time::{Duration, Instant};
use tcm::testing::{assert_checked, assert_no_panics, story};
use tcm::{Exception, Recorder, RunOutcome, Runtime, Task};
use tcm_ros::{Feedback, ros2_client};

type RosFib = ros2_client::ActionClient<FibGoal, FibResult, FibFeedback>;

#[derive(Clone, Debug, Serialize, Deserialize, thiserror::Error)]
#[error("order {order} is too long")]
struct TooLong {
    order: i32,
}

impl Exception for TooLong {}

/// The task a goal runs: one feedback message per number, `step` apart (a second for order 30,
/// long enough to be canceled), the sequence as its value; an order over 100 fails.
fn fib_task(goal: FibGoal, feedback: Feedback<FibFeedback>) -> Task {
    Task::command("fibonacci", move |ctx| async move {
        if goal.order > 100 {
            return Err(TooLong { order: goal.order }.raise());
        }
        let step = Duration::from_millis(if goal.order == 30 { 1000 } else { 10 });
        let seq = fibonacci(goal.order);
        for n in 1..=seq.len() {
            feedback.send(FibFeedback {
                sequence: seq[..n].to_vec(),
            })?;
            ctx.sleep(step).await;
        }
        Ok(FibResult { sequence: seq })
    })
}

/// Sends `goal` with ros2-client's action client, asking again until a server answers: the goal's
/// id and whether it was accepted.
fn send(client: &RosFib, goal: FibGoal) -> (GoalId, bool) {
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

/// Waits for `goal`'s feedback until `until` says it has enough, at most 20 s.
fn feedback_until(
    client: &RosFib,
    goal: GoalId,
    seen: &mut Vec<Vec<i32>>,
    until: impl Fn(&[Vec<i32>]) -> bool,
) {
    let deadline = Instant::now() + Duration::from_secs(20);
    while !until(seen) {
        assert!(Instant::now() < deadline, "feedback so far: {seen:?}");
        while let Some((g, f)) = client.take_feedback() {
            if g == goal {
                seen.push(f.sequence);
            }
        }
        std::thread::sleep(Duration::from_millis(1));
    }
}

/// The goal's result (status and value), its feedback collected meanwhile.
fn finish(client: &Arc<RosFib>, goal: GoalId, seen: &mut Vec<Vec<i32>>) -> (i8, FibResult) {
    let c = client.clone();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(c.get_result(goal));
    });
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        while let Some((g, f)) = client.take_feedback() {
            if g == goal {
                seen.push(f.sequence);
            }
        }
        match rx.recv_timeout(Duration::from_millis(1)) {
            Ok(answer) => {
                std::thread::sleep(Duration::from_millis(20));
                while let Some((g, f)) = client.take_feedback() {
                    if g == goal {
                        seen.push(f.sequence);
                    }
                }
                return answer.expect("a result");
            }
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {
                assert!(Instant::now() < deadline, "no result");
            }
            Err(e) => panic!("no result: {e}"),
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_task_offered_as_an_action_serves_ros2_clients_goals() {
    bounded(async {
        let pair = Pair::new().await;
        let offer = tcm_ros::ActionServer::<FibGoal, FibResult, FibFeedback>::new(
            &pair.server,
            "/offered",
            &fib_type(),
        )
        .expect("action server")
        .accept(|g: &FibGoal| g.order >= 0)
        .serve("offer_fibonacci", fib_task);
        let rec = Recorder::new();
        let session = Runtime::new()
            .with_sink(rec.clone())
            .start()
            .expect("a session");
        let serving = session.spawn(offer).expect("the server starts");
        let name = ros2_client::Name::parse("/offered").expect("name");
        let client: Arc<RosFib> = Arc::new(
            pair.client
                .create_action_client(&name, &fib_type())
                .expect("ros2-client's action client"),
        );
        let c = client.clone();
        let statuses = tokio::task::spawn_blocking(move || {
            // A goal that succeeds: its feedback, then its result.
            let (ok, accepted) = send(&c, FibGoal { order: 6 });
            assert!(accepted);
            let mut seen = Vec::new();
            let (status, result) = finish(&c, ok, &mut seen);
            assert_eq!(status, GoalStatusEnum::Succeeded as i8);
            assert_eq!(result.sequence, fibonacci(6));
            let expected: Vec<Vec<i32>> = (1..=6).map(|n| fibonacci(6)[..n].to_vec()).collect();
            assert_eq!(seen, expected);

            // A goal the server does not accept.
            let (_, accepted) = send(&c, FibGoal { order: -1 });
            assert!(!accepted, "a negative order is rejected");

            // A goal canceled by the client once it runs.
            let (long, accepted) = send(&c, FibGoal { order: 30 });
            assert!(accepted);
            let mut seen = Vec::new();
            feedback_until(&c, long, &mut seen, |s| !s.is_empty());
            let answer = c.cancel_goal(long).expect("the cancel is answered");
            assert_eq!(answer.return_code, CancelGoalResponseEnum::None);
            assert!(answer.goals_canceling.iter().any(|g| g.goal_id == long));
            let (status, _) = finish(&c, long, &mut seen);
            assert_eq!(status, GoalStatusEnum::Canceled as i8);
            let again = c.cancel_goal(long).expect("a second cancel is answered");
            assert_eq!(again.return_code, CancelGoalResponseEnum::GoalTerminated);

            // A goal whose task fails.
            let (bad, accepted) = send(&c, FibGoal { order: 200 });
            assert!(accepted);
            let (status, result) = finish(&c, bad, &mut Vec::new());
            assert_eq!(status, GoalStatusEnum::Aborted as i8);
            assert_eq!(result, FibResult::default());

            // The status topic said how each goal ended.
            let mut last = None;
            let deadline = Instant::now() + Duration::from_secs(5);
            while Instant::now() < deadline {
                while let Some(s) = c.take_status() {
                    last = Some(s);
                }
                if last.as_ref().is_some_and(|s| s.status_list.len() == 3) {
                    break;
                }
                std::thread::sleep(Duration::from_millis(5));
            }
            let last = last.expect("status messages");
            [ok, long, bad].map(|g| {
                last.status_list
                    .iter()
                    .find(|s| s.goal_info.goal_id == g)
                    .map(|s| s.status)
            })
        })
        .await
        .expect("the ROS 2 client's steps");
        assert_eq!(
            statuses,
            [
                Some(GoalStatusEnum::Succeeded),
                Some(GoalStatusEnum::Canceled),
                Some(GoalStatusEnum::Aborted)
            ]
        );
        // A goal running when the serving node is terminated ends canceled, and a result
        // request waiting for it is answered.
        let c = client.clone();
        let (running, result) = tokio::task::spawn_blocking(move || {
            let (goal, accepted) = send(&c, FibGoal { order: 30 });
            assert!(accepted);
            feedback_until(&c, goal, &mut Vec::new(), |s| !s.is_empty());
            let (tx, rx) = std::sync::mpsc::channel();
            std::thread::spawn(move || {
                let _ = tx.send(c.get_result(goal));
            });
            // Time for the request to reach the server (well under a millisecond on loopback):
            // one sent after the server went would find nobody.
            std::thread::sleep(Duration::from_millis(200));
            (goal, rx)
        })
        .await
        .expect("a fourth goal runs");
        session.terminate(serving).expect("terminate the server");
        let (status, _) = tokio::task::spawn_blocking(move || {
            result
                .recv_timeout(Duration::from_secs(20))
                .expect("the result request is answered")
                .expect("a result")
        })
        .await
        .expect("the fourth goal's result");
        assert_eq!(status, GoalStatusEnum::Canceled as i8, "goal {running:?}");
        let report = session.finish().await.expect("the run ends");
        let trace = rec.events();
        assert_no_panics(&report, &trace);
        assert_checked(&trace);
        assert_eq!(report.outcome, RunOutcome::Terminated, "{report}");
        let lines = story(&trace);
        // Four goals ran as children of the serving node; the canceled one was terminated by
        // its cancel event, the last one with the serving node.
        let of_goals = |what: &str| {
            lines
                .iter()
                .filter(|l| {
                    l.split_once(' ')
                        .is_some_and(|(_, r)| r == format!("fibonacci {what}"))
                })
                .count()
        };
        assert_eq!(of_goals("handling active"), 4, "{lines:#?}");
        assert_eq!(of_goals("terminated"), 2, "{lines:#?}");
        assert_eq!(of_goals("failed TooLong"), 1, "{lines:#?}");
    })
    .await;
}
