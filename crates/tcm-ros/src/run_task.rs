//! A serving executive's runs as a ROS 2 action (docs/distributed.md, "A serving executive"):
//! [`run_task`] is a goal of a tree that serves the action `run_task` ([`ActionServer`]): a goal
//! names a program the executive holds, one of its tasks and the task's arguments (JSON text);
//! the task starts in a run of its own ([`tdl_serve::Server`]), the goal's feedback gives the
//! run's number and live node count every [`FEEDBACK_EVERY`], and its result the run's outcome
//! and trace file. A goal canceled stops its run (its top-level task terminated, its cleanup
//! run); a request the executive refuses aborts the goal (the failure, with the reason, is in the
//! serving tree's trace).

use std::time::Duration;

use ros2_client::{ActionTypeName, Message, Node};
use serde::{Deserialize, Serialize};
use tcm::{Failure, Task};
use tdl_serve::{Reply, Request, Response, Server};

use crate::{ActionServer, Error, Feedback};

/// How often a running goal's feedback is published.
pub const FEEDBACK_EVERY: Duration = Duration::from_millis(100);

/// A `run_task` goal.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RunTaskGoal {
    /// The program, as loaded into the executive.
    pub program: String,
    /// The task (empty: the program's default task).
    pub task: String,
    /// The task's arguments as JSON text (empty: none), as `tdl start --args` takes them.
    pub args: String,
}
impl Message for RunTaskGoal {}

/// A `run_task` goal's feedback.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RunTaskFeedback {
    /// The run's number.
    pub run: u64,
    /// Its live nodes now.
    pub live_nodes: u64,
}
impl Message for RunTaskFeedback {}

/// A `run_task` goal's result.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RunTaskResult {
    /// The run's number (0 when it never started).
    pub run: u64,
    /// How it ended (the report's first line), or why it never started.
    pub outcome: String,
    /// Its trace file.
    pub trace: String,
}
impl Message for RunTaskResult {}

/// The action's type (`tdl_msgs/action/RunTask`).
pub fn action_type() -> ActionTypeName {
    ActionTypeName::new("tdl_msgs", "RunTask")
}

/// The goal serving the action `action` (a ROS 2 name, such as `/run_task`) on `node` with
/// `server`'s programs: run it in a tree of its own (`Runtime::run`) for as long as the action is
/// to be offered. Requests are made to the executive as the client `ros2`.
pub fn run_task(node: &Node, action: &str, server: Server) -> Result<Task, Error> {
    let actions = ActionServer::<RunTaskGoal, RunTaskResult, RunTaskFeedback>::new(
        node,
        action,
        &action_type(),
    )?;
    Ok(actions.serve("run_task", move |goal, feedback| {
        let server = server.clone();
        Task::command("run_task", move |ctx| run_goal(ctx, server, goal, feedback))
    }))
}

/// One goal: starts the run, publishes its feedback until it ends, stops it when canceled.
async fn run_goal(
    ctx: tcm::Ctx,
    server: Server,
    goal: RunTaskGoal,
    feedback: Feedback<RunTaskFeedback>,
) -> Result<RunTaskResult, Failure> {
    let args = if goal.args.trim().is_empty() {
        serde_json::Value::Null
    } else {
        serde_json::from_str(&goal.args).map_err(|e| {
            Failure::new("RunTaskRefused", format!("the arguments are not JSON: {e}"))
        })?
    };
    let start = Request::Start {
        program: goal.program.clone(),
        task: (!goal.task.is_empty()).then(|| goal.task.clone()),
        args,
    };
    let (run, trace) = match server.handle(start, "ros2") {
        Response::Ok(Reply::Started { run, trace }) => (run, trace),
        Response::Ok(other) => {
            return Err(Failure::new("RunTaskRefused", format!("{other:?}")));
        }
        Response::Refused(why) => return Err(Failure::new("RunTaskRefused", why)),
    };
    let cancelled = ctx.cancelled();
    tokio::pin!(cancelled);
    loop {
        let info = server.status(Some(run)).into_iter().next();
        match info {
            Some(i) if !i.running && i.outcome.is_some() => {
                return Ok(RunTaskResult {
                    run,
                    outcome: i.outcome.unwrap_or_default(),
                    trace,
                });
            }
            Some(i) => {
                let _ = feedback.send(RunTaskFeedback {
                    run,
                    live_nodes: i.live_nodes,
                });
            }
            None => return Err(Failure::new("RunTaskRefused", format!("run {run} is gone"))),
        }
        tokio::select! {
            () = &mut cancelled => {
                let _ = server.handle(Request::Stop { run }, "ros2");
                return Err(Failure::new("RunTaskCanceled", format!("run {run} was stopped")));
            }
            () = tokio::time::sleep(FEEDBACK_EVERY) => {}
        }
    }
}
