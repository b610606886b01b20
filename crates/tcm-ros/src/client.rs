//! Calling ROS 2 from the tree: an action's goal ([`ActionClient::goal`]) and a service's request
//! ([`ServiceClient::call`]) as `tcm` tasks, whose value is the result or the response and whose
//! failures are this crate's typed exceptions.
//!
//! ros2-client's zenoh action client is blocking and polled: its goal, result and cancel requests
//! wait on a channel (they run on threads of their own, `off_thread.rs`), and its feedback and
//! status arrive in queues shared by every goal of the client. One thread per client drains
//! them every few milliseconds and hands each feedback message to the goal it belongs to, keeping
//! for a while the messages of a goal whose acceptance was not yet seen (feedback can overtake
//! the answer to the goal). Its service client is asynchronous, and is used as it is.

use crate::failure::{ActionAborted, ActionCanceled, GoalRejected, RosError, RosTimeout, Waited};
use crate::off_thread;
use crate::{Error, parse_name};
use ros2_client::action_msgs::{CancelGoalResponseEnum, GoalStatusEnum};
use ros2_client::{ActionTypeName, GoalId, Node, ServiceError, ServiceTypeName};
use serde::Serialize;
use serde::de::DeserializeOwned;
use std::any::Any;
use std::collections::{BTreeMap, VecDeque};
use std::sync::{Arc, Mutex, MutexGuard, Weak};
use std::time::{Duration, Instant};
use tcm::{Ctx, Exception, Failure, Task};
use tokio::sync::mpsc;

/// How often the client's thread drains the feedback and status queues.
const POLL: Duration = Duration::from_millis(2);
/// How long to wait before asking a server that was not there again.
const RETRY: Duration = Duration::from_millis(50);
/// A request that found no server ends at once; one that took longer than this was answered late
/// or timed out in the backend, and is asked again without counting as a missing server.
const QUICK: Duration = Duration::from_secs(1);
/// How many feedback messages of goals not yet seen accepted are kept, and for how long.
const EARLY_MAX: usize = 256;
const EARLY_FOR: Duration = Duration::from_secs(10);
/// The default bound on waiting for a server (to answer a goal or a request; or to come back).
pub const DEFAULT_SERVER_TIMEOUT: Duration = Duration::from_secs(10);

/// A ROS 2 action client on a node, whose goals are `tcm` tasks ([`ActionClient::goal`]). `G`,
/// `R` and `F` are the action's goal, result and feedback messages. Clones share one client.
pub struct ActionClient<G, R, F> {
    shared: Arc<Shared<G, R, F>>,
}

impl<G, R, F> Clone for ActionClient<G, R, F> {
    fn clone(&self) -> Self {
        ActionClient {
            shared: self.shared.clone(),
        }
    }
}

struct Shared<G, R, F> {
    action: String,
    client: ros2_client::ActionClient<G, R, F>,
    routes: Mutex<Routes<F>>,
}

/// Where feedback goes: the running goals' channels, and messages of goals not yet seen.
struct Routes<F> {
    goals: BTreeMap<GoalId, mpsc::UnboundedSender<F>>,
    early: VecDeque<(GoalId, F, Instant)>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

impl<G, R, F> ActionClient<G, R, F>
where
    G: Serialize + Clone + Send + Sync + 'static,
    R: DeserializeOwned + Serialize + Send + 'static,
    F: DeserializeOwned + Send + 'static,
{
    /// A client of the action `action` (a ROS 2 name such as `/navigate`) of type `action_type`
    /// (`ActionTypeName::new("nav2_msgs", "NavigateToPose")`) on `node`.
    pub fn new(
        node: &Node,
        action: &str,
        action_type: &ActionTypeName,
    ) -> Result<ActionClient<G, R, F>, Error> {
        let name = parse_name(action)?;
        let client = node
            .create_action_client::<G, R, F>(&name, action_type)
            .map_err(|e| Error::Ros(format!("action client {action}: {e}")))?;
        let shared = Arc::new(Shared {
            action: action.to_string(),
            client,
            routes: Mutex::new(Routes {
                goals: BTreeMap::new(),
                early: VecDeque::new(),
            }),
        });
        let weak = Arc::downgrade(&shared);
        std::thread::Builder::new()
            .name(format!("tcm-ros {action}"))
            .spawn(move || poll(weak))
            .map_err(|e| Error::Ros(format!("cannot start the feedback thread: {e}")))?;
        Ok(ActionClient { shared })
    }

    /// The action's name.
    pub fn action(&self) -> &str {
        &self.shared.action
    }

    /// A goal of this action, to make a task of ([`Goal::task`]).
    pub fn goal(&self, goal: G) -> Goal<G, R, F> {
        let name = self
            .shared
            .action
            .rsplit('/')
            .next()
            .filter(|n| !n.is_empty())
            .unwrap_or("action")
            .to_string();
        Goal {
            shared: self.shared.clone(),
            goal,
            name,
            feedback: None,
            server_timeout: DEFAULT_SERVER_TIMEOUT,
        }
    }
}

/// The client's thread: drains the queues until the client is dropped.
fn poll<G, R, F>(weak: Weak<Shared<G, R, F>>)
where
    G: Serialize,
    R: DeserializeOwned,
    F: DeserializeOwned,
{
    loop {
        match weak.upgrade() {
            Some(shared) => shared.pump(),
            None => return,
        }
        std::thread::sleep(POLL);
    }
}

impl<G, R, F> Shared<G, R, F>
where
    G: Serialize,
    R: DeserializeOwned,
    F: DeserializeOwned,
{
    /// Hands every queued feedback message to its goal, and empties the status queue (nobody
    /// reads it, and a full queue would stall the session).
    fn pump(&self) {
        let mut routes = lock(&self.routes);
        while let Some((goal, feedback)) = self.client.take_feedback() {
            match routes.goals.get(&goal) {
                Some(tx) => {
                    let _ = tx.send(feedback);
                }
                None => {
                    if routes.early.len() == EARLY_MAX {
                        routes.early.pop_front();
                    }
                    routes.early.push_back((goal, feedback, Instant::now()));
                }
            }
        }
        while self.client.take_status().is_some() {}
        while routes
            .early
            .front()
            .is_some_and(|(_, _, at)| at.elapsed() > EARLY_FOR)
        {
            routes.early.pop_front();
        }
    }

    /// Routes `goal`'s feedback to a new channel, with what arrived before.
    fn route(&self, goal: GoalId) -> mpsc::UnboundedReceiver<F> {
        let (tx, rx) = mpsc::unbounded_channel();
        let mut routes = lock(&self.routes);
        let early = std::mem::take(&mut routes.early);
        for (g, f, at) in early {
            if g == goal {
                let _ = tx.send(f);
            } else {
                routes.early.push_back((g, f, at));
            }
        }
        routes.goals.insert(goal, tx);
        rx
    }

    fn unroute(&self, goal: GoalId) {
        lock(&self.routes).goals.remove(&goal);
    }
}

/// A goal of an action, made into a task by [`Goal::task`].
pub struct Goal<G, R, F> {
    shared: Arc<Shared<G, R, F>>,
    goal: G,
    name: String,
    feedback: Option<Box<dyn FnMut(F) + Send>>,
    server_timeout: Duration,
}

impl<G, R, F> Goal<G, R, F>
where
    G: Serialize + Clone + Send + Sync + 'static,
    R: DeserializeOwned + Serialize + Send + 'static,
    F: DeserializeOwned + Send + 'static,
{
    /// Calls `f` with each feedback message of the goal, in order, from the task's action (so
    /// never after the task ended). To pass it to another task, send it into a channel.
    pub fn on_feedback(mut self, f: impl FnMut(F) + Send + 'static) -> Self {
        self.feedback = Some(Box::new(f));
        self
    }

    /// How long to wait for a server: to answer the goal (from the task's start), or to come back
    /// when the requests for the result find none. Default [`DEFAULT_SERVER_TIMEOUT`]. Expired,
    /// the task fails with [`RosTimeout`].
    pub fn server_timeout(mut self, timeout: Duration) -> Self {
        self.server_timeout = timeout;
        self
    }

    /// The task's name (default: the last part of the action's name).
    pub fn named(mut self, name: impl Into<String>) -> Self {
        self.name = name.into();
        self
    }

    /// The goal as a command: its action sends the goal (asking again while no server answers,
    /// at most the server timeout), passes the feedback on, and returns the result when the goal
    /// succeeds; it fails with [`GoalRejected`], [`ActionAborted`], [`ActionCanceled`] or
    /// [`RosTimeout`]. When the node is terminated, it asks the server to cancel the goal, waits
    /// for the server's answer and then for the goal's end, within the node's grace period.
    pub fn task(self) -> Task {
        let name = self.name.clone();
        Task::command(name, move |ctx| run(ctx, self))
    }

    /// The goal as [`Goal::task`] makes it, its end passed through `then` before it is the
    /// node's (`interp.rs` makes the result a value of an interpreted program).
    pub(crate) fn task_then<T, E>(self, then: E) -> Task
    where
        T: Any + Send,
        E: FnOnce(Result<R, Failure>) -> Result<T, Failure> + Send + 'static,
    {
        let name = self.name.clone();
        Task::command(name, move |ctx| async move { then(run(ctx, self).await) })
    }
}

/// The action of a goal's task.
async fn run<G, R, F>(ctx: Ctx, mut g: Goal<G, R, F>) -> Result<R, Failure>
where
    G: Serialize + Clone + Send + Sync + 'static,
    R: DeserializeOwned + Serialize + Send + 'static,
    F: DeserializeOwned + Send + 'static,
{
    let cancelled = ctx.cancelled();
    tokio::pin!(cancelled);
    let shared = g.shared.clone();
    let action = shared.action.clone();
    let started = Instant::now();
    let goal = loop {
        let s = shared.clone();
        let goal = g.goal.clone();
        let send = off_thread::run("tcm-ros send_goal", move || s.client.send_goal(goal));
        tokio::pin!(send);
        let answer = tokio::select! {
            answer = &mut send => answer?,
            () = &mut cancelled => {
                // A goal may be on its way: wait for the answer (within the grace period) and
                // cancel the goal if it was accepted.
                if let Ok(Ok((goal, true))) = send.await {
                    cancel(&shared, goal).await;
                }
                return Err(RosError::failure("terminated"));
            }
        };
        match answer {
            Ok((goal, true)) => break goal,
            Ok((_, false)) => return Err(GoalRejected { action }.raise()),
            Err(ServiceError::NoReply) => {
                if started.elapsed() >= g.server_timeout {
                    return Err(timeout(&action, Waited::GoalAnswer, g.server_timeout));
                }
                tokio::select! {
                    () = tokio::time::sleep(RETRY) => {}
                    () = &mut cancelled => return Err(RosError::failure("terminated")),
                }
            }
            Err(e) => return Err(RosError::failure(format!("{action}: send_goal: {e}"))),
        }
    };
    let mut feedback = shared.route(goal);
    let _unroute = Unroute {
        shared: shared.clone(),
        goal,
    };
    let result = result(shared.clone(), goal, g.server_timeout);
    tokio::pin!(result);
    let mut cancel_sent = false;
    loop {
        tokio::select! {
            Some(f) = feedback.recv() => {
                if let Some(cb) = g.feedback.as_mut() {
                    cb(f);
                }
            }
            ended = &mut result => {
                let (status, value) = ended?;
                // Feedback sent before the result may still be queued: pass it on first.
                shared.pump();
                while let Ok(f) = feedback.try_recv() {
                    if let Some(cb) = g.feedback.as_mut() {
                        cb(f);
                    }
                }
                return outcome(&action, goal, status, value);
            }
            () = &mut cancelled, if !cancel_sent => {
                cancel_sent = true;
                cancel(&shared, goal).await;
                // Then the goal's end, which the server reports once it stopped; the grace
                // period bounds the wait.
            }
        }
    }
}

/// Removes a goal's feedback route when its action ends or is dropped.
struct Unroute<G, R, F>
where
    G: Serialize,
    R: DeserializeOwned,
    F: DeserializeOwned,
{
    shared: Arc<Shared<G, R, F>>,
    goal: GoalId,
}

impl<G, R, F> Drop for Unroute<G, R, F>
where
    G: Serialize,
    R: DeserializeOwned,
    F: DeserializeOwned,
{
    fn drop(&mut self) {
        self.shared.unroute(self.goal);
    }
}

/// Asks for the goal's result until a server gives it: a request that found no server is asked
/// again after a pause, for at most `server_timeout` in a row; one that the backend timed out
/// (a long goal) at once.
async fn result<G, R, F>(
    shared: Arc<Shared<G, R, F>>,
    goal: GoalId,
    server_timeout: Duration,
) -> Result<(i8, R), Failure>
where
    G: Serialize + Send + Sync + 'static,
    R: DeserializeOwned + Send + 'static,
    F: DeserializeOwned + Send + 'static,
{
    let mut missing_since: Option<Instant> = None;
    loop {
        let asked = Instant::now();
        let s = shared.clone();
        match off_thread::run("tcm-ros get_result", move || s.client.get_result(goal)).await? {
            Ok(ended) => return Ok(ended),
            Err(ServiceError::NoReply) if asked.elapsed() < QUICK => {
                let since = *missing_since.get_or_insert(asked);
                if since.elapsed() >= server_timeout {
                    return Err(timeout(&shared.action, Waited::Server, server_timeout));
                }
                tokio::time::sleep(RETRY).await;
            }
            Err(ServiceError::NoReply) => missing_since = None,
            Err(e) => {
                return Err(RosError::failure(format!(
                    "{}: get_result: {e}",
                    shared.action
                )));
            }
        }
    }
}

/// Asks the server to cancel `goal` and waits for its answer.
async fn cancel<G, R, F>(shared: &Arc<Shared<G, R, F>>, goal: GoalId)
where
    G: Serialize + Send + Sync + 'static,
    R: DeserializeOwned + Send + 'static,
    F: DeserializeOwned + Send + 'static,
{
    let s = shared.clone();
    let answer = off_thread::run("tcm-ros cancel_goal", move || s.client.cancel_goal(goal)).await;
    match answer {
        Ok(Ok(r)) if r.return_code == CancelGoalResponseEnum::None => {
            tracing::debug!(target: "tcm_ros", action = %shared.action, goal = ?goal, "the server accepted the cancellation");
        }
        Ok(Ok(r)) => {
            tracing::warn!(target: "tcm_ros", action = %shared.action, goal = ?goal, code = ?r.return_code, "the server did not cancel the goal");
        }
        Ok(Err(e)) => {
            tracing::warn!(target: "tcm_ros", action = %shared.action, goal = ?goal, "cancel_goal: {e}");
        }
        Err(f) => tracing::warn!(target: "tcm_ros", action = %shared.action, "cancel_goal: {f}"),
    }
}

/// A goal's end as the task's: its value, or a typed failure. Status codes are ROS 2's
/// (`action_msgs/msg/GoalStatus`: 4 succeeded, 5 canceled, 6 aborted).
fn outcome<R: Serialize>(action: &str, goal: GoalId, status: i8, value: R) -> Result<R, Failure> {
    let goal = format!("{goal:?}");
    let json = || serde_json::to_value(&value).unwrap_or(serde_json::Value::Null);
    if status == GoalStatusEnum::Succeeded as i8 {
        Ok(value)
    } else if status == GoalStatusEnum::Aborted as i8 {
        Err(ActionAborted {
            action: action.to_string(),
            goal,
            result: json(),
        }
        .raise())
    } else if status == GoalStatusEnum::Canceled as i8 {
        Err(ActionCanceled {
            action: action.to_string(),
            goal,
            result: json(),
        }
        .raise())
    } else {
        Err(RosError::failure(format!(
            "{action}: goal {goal} ended with status {status}, which is not terminal"
        )))
    }
}

fn timeout(name: &str, waited: Waited, after: Duration) -> Failure {
    RosTimeout {
        name: name.to_string(),
        waited,
        after_ms: u64::try_from(after.as_millis()).unwrap_or(u64::MAX),
    }
    .raise()
}

/// A ROS 2 service client on a node, whose requests are `tcm` tasks ([`ServiceClient::call`]).
/// Clones share one client.
pub struct ServiceClient<Q, A> {
    shared: Arc<ServiceShared<Q, A>>,
}

impl<Q, A> Clone for ServiceClient<Q, A> {
    fn clone(&self) -> Self {
        ServiceClient {
            shared: self.shared.clone(),
        }
    }
}

struct ServiceShared<Q, A> {
    service: String,
    client: ros2_client::Client<Q, A>,
}

impl<Q, A> ServiceClient<Q, A>
where
    Q: Serialize + Clone + Send + Sync + 'static,
    A: DeserializeOwned + Send + 'static,
{
    /// A client of the service `service` (a ROS 2 name such as `/add_two_ints`) of type
    /// `service_type` on `node`.
    pub fn new(
        node: &Node,
        service: &str,
        service_type: &ServiceTypeName,
    ) -> Result<ServiceClient<Q, A>, Error> {
        let name = parse_name(service)?;
        let client = node
            .create_client::<Q, A>(&name, service_type)
            .map_err(|e| Error::Ros(format!("service client {service}: {e}")))?;
        Ok(ServiceClient {
            shared: Arc::new(ServiceShared {
                service: service.to_string(),
                client,
            }),
        })
    }

    /// The service's name.
    pub fn service(&self) -> &str {
        &self.shared.service
    }

    /// A request to this service, to make a task of ([`Call::task`]).
    pub fn call(&self, request: Q) -> Call<Q, A> {
        let name = self
            .shared
            .service
            .rsplit('/')
            .next()
            .filter(|n| !n.is_empty())
            .unwrap_or("service")
            .to_string();
        Call {
            shared: self.shared.clone(),
            request,
            name,
            timeout: DEFAULT_SERVER_TIMEOUT,
        }
    }
}

/// A request to a service, made into a task by [`Call::task`].
pub struct Call<Q, A> {
    shared: Arc<ServiceShared<Q, A>>,
    request: Q,
    name: String,
    timeout: Duration,
}

impl<Q, A> Call<Q, A>
where
    Q: Serialize + Clone + Send + Sync + 'static,
    A: DeserializeOwned + Send + 'static,
{
    /// How long to wait for the response, from the task's start (asking again while no server
    /// is there). Default [`DEFAULT_SERVER_TIMEOUT`]. Expired, the task fails with [`RosTimeout`].
    pub fn timeout(mut self, timeout: Duration) -> Self {
        self.timeout = timeout;
        self
    }

    /// The task's name (default: the last part of the service's name).
    pub fn named(mut self, name: impl Into<String>) -> Self {
        self.name = name.into();
        self
    }

    /// The request as a command whose value is the response. A terminated node drops the
    /// request (a ROS 2 service call cannot be canceled).
    pub fn task(self) -> Task {
        let name = self.name.clone();
        Task::command(name, move |_ctx| self.run())
    }

    /// The request as [`Call::task`] makes it, its end passed through `then` before it is the
    /// node's (`interp.rs` makes the response a value of an interpreted program).
    pub(crate) fn task_then<T, E>(self, then: E) -> Task
    where
        T: Any + Send,
        E: FnOnce(Result<A, Failure>) -> Result<T, Failure> + Send + 'static,
    {
        let name = self.name.clone();
        Task::command(name, move |_ctx| async move { then(self.run().await) })
    }

    async fn run(self) -> Result<A, Failure> {
        let service = &self.shared.service;
        let deadline = tokio::time::Instant::now() + self.timeout;
        loop {
            let call = self.shared.client.async_call(self.request.clone());
            match tokio::time::timeout_at(deadline, call).await {
                Err(_) => return Err(timeout(service, Waited::Response, self.timeout)),
                Ok(Ok(response)) => return Ok(response),
                Ok(Err(ServiceError::NoReply)) => {
                    if tokio::time::Instant::now() + RETRY >= deadline {
                        tokio::time::sleep_until(deadline).await;
                        return Err(timeout(service, Waited::Response, self.timeout));
                    }
                    tokio::time::sleep(RETRY).await;
                }
                Ok(Err(e)) => return Err(RosError::failure(format!("{service}: {e}"))),
            }
        }
    }
}
