//! A TDL task offered as a ROS 2 action: [`ActionServer::serve`] is a goal of the tree whose
//! action answers the action's requests; each accepted ROS 2 goal runs a `tcm` task, built from
//! the goal, as a child of that node.
//!
//! ros2-client's zenoh action server is polled: the serving action drains its goal, cancel and
//! result queues every few milliseconds. A goal's child carries a termination constraint on an
//! external event of its own (`ros:<action>:cancel:<goal id>`), which a cancel request raises: the
//! cancellation is a TDL termination, visible in the trace, and the goal is reported canceled once
//! the child's subtree ended. The goal's status follows ROS 2's states (executing, canceling,
//! succeeded, canceled, aborted) on the action's status topic.

use crate::{Error, parse_name};
use ros2_client::action_msgs::{CancelGoalResponseEnum, GoalInfo, GoalStatus, GoalStatusEnum};
use ros2_client::builtin_interfaces::Time;
use ros2_client::{ActionTypeName, GoalId, Node, RmwRequestId};
use serde::Serialize;
use serde::de::DeserializeOwned;
use std::collections::{BTreeMap, VecDeque};
use std::sync::Arc;
use std::time::Duration;
use tcm::{Constraint, Ctx, Ended, Failure, Task, When};
use tokio::task::JoinSet;

/// How often the serving action drains the server's queues.
const POLL: Duration = Duration::from_millis(2);
/// How many ended goals are remembered (for late result requests and the status topic).
const ENDED_MAX: usize = 64;

/// A ROS 2 action server on a node whose goals run `tcm` tasks ([`ActionServer::serve`]). `G`,
/// `R` and `F` are the action's goal, result and feedback messages.
pub struct ActionServer<G, R, F> {
    shared: Arc<Shared<G, R, F>>,
    accept: Box<dyn FnMut(&G) -> bool + Send>,
}

struct Shared<G, R, F> {
    action: String,
    server: ros2_client::ActionServer<G, R, F>,
}

/// Publishes feedback for one goal, from the goal's task.
pub struct Feedback<F> {
    publish: Arc<dyn Fn(GoalId, F) -> Result<(), String> + Send + Sync>,
    goal: GoalId,
}

impl<F> Clone for Feedback<F> {
    fn clone(&self) -> Self {
        Feedback {
            publish: self.publish.clone(),
            goal: self.goal,
        }
    }
}

impl<F> Feedback<F> {
    /// Publishes `feedback` on the action's feedback topic for this goal.
    pub fn send(&self, feedback: F) -> Result<(), Error> {
        (self.publish)(self.goal, feedback).map_err(Error::Ros)
    }

    /// The goal's id, as ROS 2 tools print it (32 hexadecimal digits).
    pub fn goal(&self) -> String {
        format!("{:?}", self.goal)
    }
}

impl<G, R, F> ActionServer<G, R, F>
where
    G: DeserializeOwned + Send + Sync + 'static,
    R: Serialize + Clone + Default + Send + Sync + 'static,
    F: Serialize + Send + Sync + 'static,
{
    /// A server of the action `action` (a ROS 2 name such as `/fibonacci`) of type `action_type`
    /// on `node`. It accepts every goal unless told otherwise ([`ActionServer::accept`]).
    pub fn new(
        node: &Node,
        action: &str,
        action_type: &ActionTypeName,
    ) -> Result<ActionServer<G, R, F>, Error> {
        let name = parse_name(action)?;
        let server = node
            .create_action_server::<G, R, F>(&name, action_type)
            .map_err(|e| Error::Ros(format!("action server {action}: {e}")))?;
        Ok(ActionServer {
            shared: Arc::new(Shared {
                action: action.to_string(),
                server,
            }),
            accept: Box::new(|_| true),
        })
    }

    /// Accepts only the goals for which `accept` is true; the others are rejected.
    pub fn accept(mut self, accept: impl FnMut(&G) -> bool + Send + 'static) -> Self {
        self.accept = Box::new(accept);
        self
    }

    /// The server as a goal named `name`, which serves until its node is terminated. Each
    /// accepted goal runs the task `make` builds from it (with a handle to publish the goal's
    /// feedback) as a child of this node; the task's value, an `R`, is the goal's result. A task
    /// that succeeds ends the goal `SUCCEEDED`; one that fails, or ends with no `R`, `ABORTED`
    /// (with `R::default()`); one terminated after a cancel request `CANCELED`. When the serving
    /// node is terminated, its goals are terminated with it and reported canceled.
    pub fn serve<M>(self, name: impl Into<String>, make: M) -> Task
    where
        M: FnMut(G, Feedback<F>) -> Task + Send + 'static,
    {
        let name: String = name.into();
        Task::goal(name, move |ctx| serve(ctx, self, make))
    }
}

/// Where a goal is.
enum State<R> {
    Executing,
    Canceling,
    Ended(GoalStatusEnum, R),
}

struct Entry<R> {
    state: State<R>,
    stamp: Time,
    event: String,
}

/// The serving action.
async fn serve<G, R, F, M>(
    ctx: Ctx,
    server: ActionServer<G, R, F>,
    mut make: M,
) -> Result<(), Failure>
where
    G: DeserializeOwned + Send + Sync + 'static,
    R: Serialize + Clone + Default + Send + Sync + 'static,
    F: Serialize + Send + Sync + 'static,
    M: FnMut(G, Feedback<F>) -> Task + Send + 'static,
{
    // The goals' children start at once: the server never ends nor waits on the engine itself.
    ctx.hold_children(false)?;
    let cancelled = ctx.cancelled();
    tokio::pin!(cancelled);
    let ActionServer { shared, mut accept } = server;
    let s = shared.clone();
    let publish: Arc<dyn Fn(GoalId, F) -> Result<(), String> + Send + Sync> =
        Arc::new(move |goal, feedback| {
            s.server
                .publish_feedback(goal, feedback)
                .map_err(|e| format!("{}: feedback: {e}", s.action))
        });
    let mut goals: BTreeMap<GoalId, Entry<R>> = BTreeMap::new();
    let mut ended: VecDeque<GoalId> = VecDeque::new();
    let mut waiting: Vec<(RmwRequestId, GoalId)> = Vec::new();
    let mut running: JoinSet<(GoalId, Result<Ended<R>, tcm::Error>)> = JoinSet::new();
    let mut stopping = false;
    loop {
        let mut changed = false;
        tokio::select! {
            // The serving node's termination first: its goals, terminated with it, are canceled
            // ones, even when their ends are ready at the same poll.
            biased;
            () = &mut cancelled, if !stopping => {
                stopping = true;
                for entry in goals.values_mut() {
                    if matches!(entry.state, State::Executing) {
                        entry.state = State::Canceling;
                        changed = true;
                    }
                }
            }
            Some(joined) = running.join_next() => {
                if let Ok((goal, end)) = joined {
                    end_goal(&shared.action, &mut goals, &mut ended, goal, end);
                    changed = true;
                }
            }
            () = tokio::time::sleep(POLL) => {
                while let Some((request, goal, message)) = shared.server.try_receive_goal() {
                    let ok = !stopping && !goals.contains_key(&goal) && accept(&message);
                    if let Err(e) = shared.server.respond_goal(request, ok) {
                        tracing::warn!(target: "tcm_ros", action = %shared.action, "respond_goal: {e}");
                    }
                    if !ok {
                        continue;
                    }
                    let event = format!("ros:{}:cancel:{goal:?}", shared.action);
                    let feedback = Feedback { publish: publish.clone(), goal };
                    let task = make(message, feedback);
                    let external = ctx.external(&event)?;
                    let c = ctx.clone();
                    running.spawn(async move {
                        let end = c
                            .spawn(task)
                            .with(Constraint::terminate(When::External(external)))
                            .wait_outcome::<R>()
                            .await;
                        (goal, end)
                    });
                    goals.insert(goal, Entry { state: State::Executing, stamp: Time::now(), event });
                    changed = true;
                }
                while let Some((request, goal)) = shared.server.try_receive_cancel() {
                    let (code, canceling) = cancel(&ctx, &mut goals, goal)?;
                    changed |= !canceling.is_empty();
                    if let Err(e) = shared.server.respond_cancel(request, code, canceling) {
                        tracing::warn!(target: "tcm_ros", action = %shared.action, "respond_cancel: {e}");
                    }
                }
                while let Some((request, goal)) = shared.server.try_receive_result_request() {
                    waiting.push((request, goal));
                }
            }
        }
        answer_results(&shared, &goals, &mut waiting);
        if changed {
            let list = goals
                .iter()
                .map(|(goal, entry)| GoalStatus {
                    goal_info: GoalInfo {
                        goal_id: *goal,
                        stamp: entry.stamp,
                    },
                    status: match &entry.state {
                        State::Executing => GoalStatusEnum::Executing,
                        State::Canceling => GoalStatusEnum::Canceling,
                        State::Ended(status, _) => *status,
                    },
                })
                .collect();
            if let Err(e) = shared.server.publish_status(list) {
                tracing::warn!(target: "tcm_ros", action = %shared.action, "status: {e}");
            }
        }
        if stopping && running.is_empty() {
            // Result requests that came meanwhile are answered before the server goes.
            while let Some(request) = shared.server.try_receive_result_request() {
                waiting.push(request);
            }
            answer_results(&shared, &goals, &mut waiting);
            return Ok(());
        }
    }
}

/// Answers the result requests of ended (or unknown) goals.
fn answer_results<G, R, F>(
    shared: &Shared<G, R, F>,
    goals: &BTreeMap<GoalId, Entry<R>>,
    waiting: &mut Vec<(RmwRequestId, GoalId)>,
) where
    G: DeserializeOwned,
    R: Serialize + Clone + Default,
    F: Serialize,
{
    waiting.retain(|(request, goal)| {
        let (status, result) = match goals.get(goal) {
            Some(Entry {
                state: State::Ended(status, result),
                ..
            }) => (*status as i8, result.clone()),
            Some(_) => return true,
            None => (GoalStatusEnum::Unknown as i8, R::default()),
        };
        if let Err(e) = shared.server.respond_result(*request, status, result) {
            tracing::warn!(target: "tcm_ros", action = %shared.action, "respond_result: {e}");
        }
        false
    });
}

/// Records a goal's end: its status and result, from how its task ended.
fn end_goal<R: Default>(
    action: &str,
    goals: &mut BTreeMap<GoalId, Entry<R>>,
    ended: &mut VecDeque<GoalId>,
    goal: GoalId,
    end: Result<Ended<R>, tcm::Error>,
) {
    let Some(entry) = goals.get_mut(&goal) else {
        return;
    };
    let canceling = matches!(entry.state, State::Canceling);
    entry.state = match end {
        Ok(Ended::Succeeded(result)) => State::Ended(GoalStatusEnum::Succeeded, result),
        Ok(Ended::Terminated) if canceling => State::Ended(GoalStatusEnum::Canceled, R::default()),
        Ok(Ended::Terminated) => State::Ended(GoalStatusEnum::Aborted, R::default()),
        // Its `skip if` condition held: it has no value, as a task that ends without an `R`.
        Ok(Ended::Skipped) => {
            tracing::info!(target: "tcm_ros", action, goal = ?goal, "the goal's task was skipped");
            State::Ended(GoalStatusEnum::Aborted, R::default())
        }
        Ok(Ended::Failed(f)) => {
            tracing::info!(target: "tcm_ros", action, goal = ?goal, "the goal's task failed: {f}");
            State::Ended(GoalStatusEnum::Aborted, R::default())
        }
        Err(e) => {
            tracing::warn!(target: "tcm_ros", action, goal = ?goal, "the goal's task: {e}");
            State::Ended(GoalStatusEnum::Aborted, R::default())
        }
    };
    ended.push_back(goal);
    while ended.len() > ENDED_MAX {
        if let Some(old) = ended.pop_front() {
            goals.remove(&old);
        }
    }
}

/// A cancel request: terminates the goal's child (every running goal's for the zero id) by
/// raising its cancel event. Returns the answer's code and the goals now canceling.
fn cancel<R>(
    ctx: &Ctx,
    goals: &mut BTreeMap<GoalId, Entry<R>>,
    goal: GoalId,
) -> Result<(CancelGoalResponseEnum, Vec<GoalInfo>), Failure> {
    let all = goal == GoalId::ZERO;
    let mut canceling = Vec::new();
    let mut terminal = false;
    for (id, entry) in goals.iter_mut() {
        if !all && *id != goal {
            continue;
        }
        match entry.state {
            State::Executing => {
                ctx.raise(&entry.event)?;
                entry.state = State::Canceling;
                canceling.push(GoalInfo {
                    goal_id: *id,
                    stamp: entry.stamp,
                });
            }
            State::Canceling => canceling.push(GoalInfo {
                goal_id: *id,
                stamp: entry.stamp,
            }),
            State::Ended(..) => terminal = true,
        }
    }
    let code = if !canceling.is_empty() {
        CancelGoalResponseEnum::None
    } else if terminal {
        CancelGoalResponseEnum::GoalTerminated
    } else {
        CancelGoalResponseEnum::UnknownGoal
    };
    Ok((code, canceling))
}
