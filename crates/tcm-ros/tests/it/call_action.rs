//! The tree calls a ROS 2 action served by ros2-client's own action server: the goal's feedback
//! reaches the caller and its result is the task's value; terminating the node cancels the goal on
//! the server before the node ends; an aborted, server-canceled or rejected goal, and a missing
//! server, are typed exceptions that handlers in the tree take.

use crate::util::{
    FibFeedback, FibGoal, FibResult, FibServer, Log, Pair, Script, bounded, fib_type, fibonacci,
};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tcm::testing::{handler_choices, run_checked, story};
use tcm::{Handler, RunOutcome, Runtime, Task, WatchOutcome};
use tcm_ros::{ActionAborted, ActionCanceled, ActionClient, GoalRejected, RosTimeout, Waited};

type Fib = ActionClient<FibGoal, FibResult, FibFeedback>;

fn client(pair: &Pair, action: &str) -> Fib {
    Fib::new(&pair.client, action, &fib_type()).expect("action client")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_goal_passes_its_feedback_on_and_its_result_is_the_tasks_value() {
    bounded(async {
        let pair = Pair::new().await;
        let server = FibServer::start(
            &pair.server,
            "/fib_ok",
            Script::Succeed {
                step: Duration::from_millis(10),
            },
        );
        let fib = client(&pair, "/fib_ok");
        let seen = Arc::new(Mutex::new(Vec::new()));
        let s = seen.clone();
        let task = fib
            .goal(FibGoal { order: 6 })
            .on_feedback(move |f: FibFeedback| s.lock().expect("seen").push(f.sequence))
            .task();
        let value = Arc::new(Mutex::new(None));
        let v = value.clone();
        let main = Task::goal("main", move |ctx| async move {
            let r: FibResult = ctx.spawn(task).wait_value().await?;
            *v.lock().expect("value") = Some(r);
            Ok(())
        });
        let (report, trace) = run_checked(Runtime::new(), main).await;
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        assert!(report.is_clean(), "{report}");
        let result = value.lock().expect("value").take();
        assert_eq!(result.map(|r| r.sequence), Some(fibonacci(6)));
        // Every feedback message, in order, before the result (the first one is published as
        // the goal is accepted, and may overtake the acceptance).
        let expected: Vec<Vec<i32>> = (1..=6).map(|n| fibonacci(6)[..n].to_vec()).collect();
        assert_eq!(*seen.lock().expect("seen"), expected);
        assert!(
            server
                .log
                .entries()
                .contains(&"result Succeeded".to_string()),
            "{:?}",
            server.log.entries()
        );
        let lines = story(&trace);
        assert!(
            lines
                .iter()
                .any(|l| l.contains("fib_ok handling completed")),
            "{lines:#?}"
        );
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn terminating_the_node_cancels_the_goal_on_the_server_before_the_node_ends() {
    bounded(async {
        let pair = Pair::new().await;
        let server = FibServer::start(
            &pair.server,
            "/fib_endless",
            Script::Endless {
                step: Duration::from_millis(10),
            },
        );
        let fib = client(&pair, "/fib_endless");
        let seen = Arc::new(Mutex::new(0u32));
        let s = seen.clone();
        let task = fib
            .goal(FibGoal { order: 3 })
            .on_feedback(move |_| *s.lock().expect("seen") += 1)
            .task();
        let outcome = Arc::new(Mutex::new(None));
        let o = outcome.clone();
        let main = Task::goal("main", move |ctx| async move {
            let ended = ctx
                .spawn(task)
                .terminate_in(Duration::from_millis(400))
                .wait()
                .await?;
            *o.lock().expect("outcome") = Some(ended);
            Ok(())
        });
        let (report, trace) = run_checked(Runtime::new(), main).await;
        // What the server had done when the run ended: the cancel was answered, and the goal
        // ended canceled, before the node was terminated.
        let log = server.log.entries();
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        assert_eq!(
            *outcome.lock().expect("outcome"),
            Some(WatchOutcome::Terminated)
        );
        assert!(log.contains(&"cancel true".to_string()), "{log:?}");
        assert!(log.contains(&"result Canceled".to_string()), "{log:?}");
        assert!(
            *seen.lock().expect("seen") > 0,
            "feedback before the cancel"
        );
        let lines = story(&trace);
        assert!(
            lines
                .iter()
                .any(|l| l.contains("fib_endless") && l.contains("terminated")),
            "{lines:#?}"
        );
        // No feedback after the goal ended: the server stopped sending it.
        let after = log.iter().skip_while(|e| *e != "cancel true").skip(1);
        assert!(after.clone().all(|e| !e.starts_with("feedback")), "{log:?}");
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_aborted_goal_is_an_action_aborted_exception_taken_by_a_handler_in_the_tree() {
    bounded(async {
        let pair = Pair::new().await;
        let _server = FibServer::start(&pair.server, "/fib_abort", Script::Abort);
        let fib = client(&pair, "/fib_abort");
        let log = Log::default();
        let l = log.clone();
        let on_abort = Handler::on::<ActionAborted, _, _, _>("on_abort", move |ctx| {
            let l = l.clone();
            async move {
                let e = ctx.caught::<ActionAborted>().expect("an ActionAborted");
                l.push(format!("{} {}", e.action, e.result["sequence"]));
                Ok(())
            }
        });
        let task = fib.goal(FibGoal { order: 5 }).task();
        let main = Task::goal("main", move |ctx| async move {
            ctx.spawn(task).handler(on_abort).wait().await?;
            Ok(())
        });
        let (report, trace) = run_checked(Runtime::new(), main).await;
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        assert_eq!(handler_choices(&trace), ["on_abort<-ActionAborted"]);
        // The result sent with the abort travels with the exception.
        assert_eq!(log.entries(), ["/fib_abort [0,1]"]);
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_rejected_or_server_canceled_goal_is_taken_by_a_handler_of_their_ancestor() {
    bounded(async {
        let pair = Pair::new().await;
        let _rejecting = FibServer::start(&pair.server, "/fib_reject", Script::Reject);
        let _canceling = FibServer::start(&pair.server, "/fib_cancels", Script::CancelItself);
        let reject = client(&pair, "/fib_reject");
        let cancels = client(&pair, "/fib_cancels");
        let log = Log::default();
        let l = log.clone();
        let on_ros = Handler::new("on_ros", "RosError", move |ctx| {
            let l = l.clone();
            async move {
                if let Some(e) = ctx.caught::<GoalRejected>() {
                    l.push(format!("rejected {}", e.action));
                } else if let Some(e) = ctx.caught::<ActionCanceled>() {
                    l.push(format!("canceled {}", e.action));
                }
                Ok(())
            }
        });
        let first = reject.goal(FibGoal { order: 5 }).task();
        let second = cancels.goal(FibGoal { order: 5 }).task();
        let main = Task::goal("main", move |ctx| async move {
            ctx.spawn(first).wait().await?;
            ctx.spawn(second).wait().await?;
            Ok(())
        })
        .handler(on_ros);
        let (report, trace) = run_checked(Runtime::new(), main).await;
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        assert_eq!(
            handler_choices(&trace),
            ["on_ros<-GoalRejected", "on_ros<-ActionCanceled"]
        );
        assert_eq!(
            log.entries(),
            ["rejected /fib_reject", "canceled /fib_cancels"]
        );
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_goal_with_no_server_fails_with_a_timeout_never_a_silent_hang() {
    bounded(async {
        let pair = Pair::new().await;
        let fib = client(&pair, "/nobody_serves_this");
        let log = Log::default();
        let l = log.clone();
        let on_timeout = Handler::on::<RosTimeout, _, _, _>("on_timeout", move |ctx| {
            let l = l.clone();
            async move {
                let e = ctx.caught::<RosTimeout>().expect("a RosTimeout");
                assert_eq!(e.waited, Waited::GoalAnswer);
                l.push(e.to_string());
                Ok(())
            }
        });
        let task = fib
            .goal(FibGoal { order: 5 })
            .server_timeout(Duration::from_millis(300))
            .task();
        let main = Task::goal("main", move |ctx| async move {
            ctx.spawn(task).handler(on_timeout).wait().await?;
            Ok(())
        });
        let started = Instant::now();
        let (report, trace) = run_checked(Runtime::new(), main).await;
        assert!(
            started.elapsed() < Duration::from_secs(5),
            "{:?}",
            started.elapsed()
        );
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        assert_eq!(handler_choices(&trace), ["on_timeout<-RosTimeout"]);
        assert_eq!(
            log.entries(),
            ["/nobody_serves_this: waited 300 ms for an answer to the goal"]
        );
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_server_that_goes_away_during_the_goal_fails_it_with_a_timeout() {
    bounded(async {
        let pair = Pair::new().await;
        let server = FibServer::start(
            &pair.server,
            "/fib_goes",
            Script::Endless {
                step: Duration::from_millis(10),
            },
        );
        let fib = client(&pair, "/fib_goes");
        let (tx, mut rx) = tokio::sync::mpsc::unbounded_channel();
        let task = fib
            .goal(FibGoal { order: 3 })
            .server_timeout(Duration::from_millis(300))
            .on_feedback(move |_| {
                let _ = tx.send(());
            })
            .task();
        let log = Log::default();
        let l = log.clone();
        let on_timeout = Handler::on::<RosTimeout, _, _, _>("on_timeout", move |ctx| {
            let l = l.clone();
            async move {
                let e = ctx.caught::<RosTimeout>().expect("a RosTimeout");
                l.push(format!("{:?} {}", e.waited, e.after_ms));
                Ok(())
            }
        });
        let main = Task::goal("main", move |ctx| async move {
            ctx.spawn(task).handler(on_timeout).wait().await?;
            Ok(())
        });
        // The server goes once the goal runs (its first feedback came).
        let stop = tokio::spawn(async move {
            rx.recv().await.expect("feedback");
            drop(server);
            Instant::now()
        });
        let (report, trace) = run_checked(Runtime::new(), main).await;
        let gone = stop.await.expect("the server was dropped");
        assert!(
            gone.elapsed() < Duration::from_secs(5),
            "{:?}",
            gone.elapsed()
        );
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        assert_eq!(handler_choices(&trace), ["on_timeout<-RosTimeout"]);
        assert_eq!(log.entries(), ["Server 300"]);
    })
    .await;
}
