//! Remote tasks on the executive's side: a node of the tree whose action is carried out by an
//! agent. The action places the task, sends the start, then hands each message of the agent to
//! the tree (a value or a typed failure ends it; a goal's calls spawn, wait for and terminate
//! children), enforces the timeouts, and turns the node's termination into a cancel that the agent
//! confirms once its cleanup ran (docs/distributed.md, "A remote task's life").

use crate::executive::{Executive, Incoming, Inner};
use crate::failure::{
    AgentLost, RemoteCancelled, RemoteError, RemoteFailure, RemoteTimeout, TimeoutKind,
};
use crate::wire::{
    self, Answer, ChildAt, ChildEnded, ChildRef, ChildSpec, Constraint, Json, Kind, Msg, Op,
    ToAgent, ToExec,
};
use serde::Serialize;
use std::sync::Arc;
use std::time::Duration;
use tcm::{Ctx, Exception, Failure, NodeId, NodeKind, NodeRef, Spawner, Task, WatchOutcome};
use tokio::sync::mpsc;
use tokio::task::JoinSet;
use tokio::time::Instant;

/// Where a remote task runs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum At {
    /// On this agent (it must be live and offer the task).
    Agent(String),
    /// On the first live agent, by name, that offers the task.
    Any,
}

impl At {
    /// On the agent named `name`.
    pub fn agent(name: impl Into<String>) -> At {
        At::Agent(name.into())
    }
}

impl From<&str> for At {
    fn from(name: &str) -> At {
        At::Agent(name.into())
    }
}

impl From<String> for At {
    fn from(name: String) -> At {
        At::Agent(name)
    }
}

/// The timeouts and grace period of a remote task. Each timeout that expires fails the node with
/// [`RemoteTimeout`] of its kind (and tells the agent to cancel the body).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RemoteOptions {
    /// From the node's start until an agent starts the body (no agent offers it, or the one that
    /// has it does not start it). Default 10 s; `None` waits for ever.
    pub schedule_to_start: Option<Duration>,
    /// From the body's start until it ends. Default: none.
    pub start_to_close: Option<Duration>,
    /// Between the body's start or heartbeat and its next heartbeat. Default: none.
    pub heartbeat: Option<Duration>,
    /// How long a terminated node waits for the agent to confirm its cancel (the node's grace
    /// period, [`tcm::Task::grace`]); `None`: the run's default grace period (1 s by default).
    pub grace: Option<Duration>,
}

impl Default for RemoteOptions {
    fn default() -> RemoteOptions {
        RemoteOptions {
            schedule_to_start: Some(Duration::from_secs(10)),
            start_to_close: None,
            heartbeat: None,
            grace: None,
        }
    }
}

/// A remote task being built ([`Executive::remote`]): a command unless [`Remote::goal`] says
/// otherwise; [`Remote::task`] (or `Task::from`) makes the node's task.
#[must_use = "a remote task does nothing until it is made a `Task` and spawned"]
pub struct Remote {
    exec: Arc<Inner>,
    at: At,
    name: String,
    args: Result<Json, String>,
    kind: Kind,
    options: RemoteOptions,
}

impl Executive {
    /// A remote task: the task `name` offered by an agent (`at`), run with `args` as a node of
    /// this process's tree. Its constraints, waits, termination and handlers are the tree's, as
    /// for any node; its value is the body's, as a [`serde_json::Value`], and its failure the
    /// body's typed failure, or [`AgentLost`], [`RemoteTimeout`], [`RemoteError`].
    pub fn remote(
        &self,
        at: impl Into<At>,
        name: impl Into<String>,
        args: impl Serialize,
    ) -> Remote {
        Remote {
            exec: self.inner.clone(),
            at: at.into(),
            name: name.into(),
            args: serde_json::to_value(args).map_err(|e| e.to_string()),
            kind: Kind::Command,
            options: self.inner.defaults.clone(),
        }
    }
}

/// The executive places the tasks a run puts `on` an agent (TDL's `spawn t(args) with on
/// "arm"`, [`tcm::Ctx::remote_task`]): give it to the run with `tcm::Runtime::placer`. The agent
/// name `*` is any live agent that offers the task.
impl tcm::Placer for Executive {
    fn place(
        &self,
        agent: &str,
        name: &str,
        kind: NodeKind,
        args: Json,
    ) -> Result<Task, tcm::Error> {
        let at = if agent == "*" {
            At::Any
        } else {
            At::agent(agent)
        };
        let remote = self.remote(at, name, args);
        Ok(match kind {
            NodeKind::Goal => remote.goal(),
            _ => remote,
        }
        .task())
    }
}

impl Remote {
    /// A goal: its body may spawn children through the executive.
    pub fn goal(mut self) -> Remote {
        self.kind = Kind::Goal;
        self
    }

    /// A command (the default).
    pub fn command(mut self) -> Remote {
        self.kind = Kind::Command;
        self
    }

    /// Sets the schedule-to-start timeout (`None`: wait for ever for an agent).
    pub fn schedule_to_start(mut self, d: Option<Duration>) -> Remote {
        self.options.schedule_to_start = d;
        self
    }

    /// Sets the start-to-close timeout.
    pub fn start_to_close(mut self, d: Duration) -> Remote {
        self.options.start_to_close = Some(d);
        self
    }

    /// Sets the heartbeat timeout: the body must heartbeat at least this often.
    pub fn heartbeat(mut self, d: Duration) -> Remote {
        self.options.heartbeat = Some(d);
        self
    }

    /// Sets the grace period the agent has to confirm a cancel.
    pub fn grace(mut self, d: Duration) -> Remote {
        self.options.grace = Some(d);
        self
    }

    /// Sets every option at once.
    pub fn options(mut self, options: RemoteOptions) -> Remote {
        self.options = options;
        self
    }

    /// The node's task: named after the remote task, retryable (a retry runs it again, as a new
    /// remote task), its arguments kept beside the node as a [`serde_json::Value`] (wiretaps read
    /// them; `Ctx::retry_with` a new value).
    pub fn task(self) -> Task {
        self.task_map(Result::<Json, String>::Ok)
    }
}

impl Remote {
    /// As [`Remote::task`], with the node's value read from the body's JSON as a `T`, so the
    /// tree waits for it as for a local task's value (`wait_value::<T>()`); a value that does not
    /// read as a `T` fails the node with [`RemoteError`].
    pub fn typed_task<T>(self) -> Task
    where
        T: serde::de::DeserializeOwned + Send + 'static,
    {
        self.task_map(|v| serde_json::from_value::<T>(v).map_err(|e| e.to_string()))
    }

    /// As [`Remote::task`], with the node's value made from the body's JSON by `read`, for a
    /// value type that is not `Deserialize`; an `Err` of `read` fails the node with
    /// [`RemoteError`].
    pub fn task_map<T, F>(self, read: F) -> Task
    where
        T: Send + 'static,
        F: Fn(Json) -> Result<T, String> + Send + Sync + 'static,
    {
        let kind = match self.kind {
            Kind::Command => NodeKind::Command,
            Kind::Goal => NodeKind::Goal,
        };
        let name = self.name.clone();
        let args = match self.args {
            Ok(a) => a,
            Err(e) => {
                let message = format!("arguments of remote task {name} do not serialise: {e}");
                return Task::new(kind, name, move |_| async move {
                    Err::<T, _>(RemoteError::failure(message))
                });
            }
        };
        let spec = Arc::new(Spec {
            exec: self.exec,
            at: self.at,
            name: self.name.clone(),
            kind: self.kind,
            options: self.options,
        });
        let grace = spec.options.grace;
        let read = Arc::new(read);
        let task = Task::retryable_with(kind, self.name, args, move |ctx, args| {
            let (spec, read) = (spec.clone(), read.clone());
            async move {
                let name = spec.name.clone();
                let value = run(spec, ctx, args).await?;
                read(value).map_err(|e| {
                    RemoteError::failure(format!(
                        "the value of remote task {name} does not read: {e}"
                    ))
                })
            }
        });
        match grace {
            Some(g) => task.grace(g),
            None => task,
        }
    }
}

impl From<Remote> for Task {
    fn from(r: Remote) -> Task {
        r.task()
    }
}

/// What every run of one remote task shares.
struct Spec {
    exec: Arc<Inner>,
    at: At,
    name: String,
    kind: Kind,
    options: RemoteOptions,
}

/// The remote task as the executive sees it once placed: where it runs and the sequence of the
/// messages sent to it. Dropped before it ended (the node's action was dropped), it cancels the
/// body on the agent.
struct Link {
    exec: Arc<Inner>,
    task: u64,
    agent: String,
    seq: u64,
    ended: bool,
    cancelled: bool,
}

impl Link {
    fn next(&mut self, body: ToAgent) -> Msg<ToAgent> {
        self.seq += 1;
        Msg {
            task: self.task,
            seq: self.seq,
            body,
        }
    }

    async fn send(&mut self, body: ToAgent) -> Result<(), Failure> {
        let msg = self.next(body);
        self.exec
            .send(&self.agent, &msg)
            .await
            .map_err(|e| RemoteError::failure(format!("cannot reach agent {}: {e}", self.agent)))
    }

    /// Tells the agent to cancel the body, once.
    async fn cancel(&mut self) {
        if !self.cancelled && !self.ended {
            self.cancelled = true;
            if let Err(e) = self.send(ToAgent::Cancel).await {
                tracing::warn!(target: "tcm_zenoh", task = self.task, "cancel not sent: {e}");
            }
        }
    }

    /// The task ended on this side: later messages are late.
    fn end(&mut self) {
        if !self.ended {
            self.ended = true;
            self.exec.forget(self.task);
        }
    }
}

impl Drop for Link {
    fn drop(&mut self) {
        if !self.ended {
            if !self.cancelled {
                let msg = self.next(ToAgent::Cancel);
                self.exec.send_later(&self.agent, msg);
                self.exec.count(|s| s.cancels += 1);
            }
            self.exec.forget(self.task);
        }
    }
}

async fn sleep_until(at: Option<Instant>) {
    match at {
        Some(at) => tokio::time::sleep_until(at).await,
        None => std::future::pending().await,
    }
}

fn timeout(
    kind: TimeoutKind,
    spec: &Spec,
    agent: Option<&str>,
    after: Option<Duration>,
) -> Failure {
    spec.exec.count(|s| s.timeouts += 1);
    RemoteTimeout {
        kind,
        task: spec.name.clone(),
        agent: agent.map(str::to_string),
        after_ms: after.map_or(0, |d| d.as_millis() as u64),
    }
    .raise()
}

/// The action of a remote task's node.
async fn run(spec: Arc<Spec>, ctx: Ctx, args: Json) -> Result<Json, Failure> {
    // Looking at the signal now gives the action its grace period: a terminated node waits for
    // the agent's confirmation.
    let cancelled = ctx.cancelled();
    tokio::pin!(cancelled);
    let exec = spec.exec.clone();
    let opts = &spec.options;
    let node = ctx.node();
    let display = ctx.info(node).ok().flatten().map_or(0, |i| i.display);
    let task = exec.next_task();
    let (tx, mut rx) = mpsc::unbounded_channel();
    let scheduled = Instant::now();
    let sts = opts.schedule_to_start.map(|d| scheduled + d);
    let named = match &spec.at {
        At::Agent(a) => Some(a.as_str()),
        At::Any => None,
    };
    if !wire::valid_name(&spec.name) || !named.is_none_or(wire::valid_name) {
        return Err(RemoteError::failure(format!(
            "bad task or agent name in {}{}: use ASCII letters, digits, `_`, `-` and `.`",
            spec.name,
            named.map(|a| format!(" on {a}")).unwrap_or_default()
        )));
    }
    let agent = tokio::select! {
        a = exec.place(named, &spec.name, task, &ctx, display, tx) => match a {
            Some(a) => a,
            None => return Err(RemoteError::failure("the executive was closed")),
        },
        () = sleep_until(sts) => {
            return Err(timeout(TimeoutKind::ScheduleToStart, &spec, named, opts.schedule_to_start));
        }
        () = &mut cancelled => return Ok(Json::Null),
    };
    // The trace says where the action runs (a `placed` record) before anything comes back.
    ctx.placed(&agent)
        .map_err(|e| RemoteError::failure(e.to_string()))?;
    let mut link = Link {
        exec: exec.clone(),
        task,
        agent: agent.clone(),
        seq: 0,
        ended: false,
        cancelled: false,
    };
    // The start waits until the agent's inbox is known here: sent before, it would be lost.
    tokio::select! {
        r = exec.reach(&agent) => r.map_err(|e| RemoteError::failure(e.to_string()))?,
        () = sleep_until(sts) => {
            link.end();
            return Err(timeout(TimeoutKind::ScheduleToStart, &spec, Some(&agent), opts.schedule_to_start));
        }
        () = &mut cancelled => {
            link.end();
            return Ok(Json::Null);
        }
    }
    link.send(ToAgent::Start {
        node: display,
        name: spec.name.clone(),
        task_kind: spec.kind,
        args,
    })
    .await?;
    let mut body = Body {
        ctx: ctx.clone(),
        exec: exec.clone(),
        agent: agent.clone(),
        children: Vec::new(),
        calls: JoinSet::new(),
    };
    let mut started = false;
    let mut stc: Option<Instant> = None;
    let mut hb: Option<Instant> = None;
    loop {
        tokio::select! {
            biased;
            msg = rx.recv() => {
                let Some(msg) = msg else {
                    link.end();
                    return Err(RemoteError::failure("the executive closed"));
                };
                match msg {
                    Incoming::Closed => {
                        link.ended = true;
                        return Err(RemoteError::failure("the executive was closed"));
                    }
                    Incoming::Lost => {
                        link.ended = true;
                        if link.cancelled {
                            return Ok(Json::Null);
                        }
                        exec.count(|s| s.agent_lost += 1);
                        return Err(AgentLost { agent, task: spec.name.clone() }.raise());
                    }
                    Incoming::Msg(ToExec::Started) => {
                        started = true;
                        let now = Instant::now();
                        stc = opts.start_to_close.map(|d| now + d);
                        hb = opts.heartbeat.map(|d| now + d);
                    }
                    Incoming::Msg(ToExec::Heartbeat) => {
                        hb = opts.heartbeat.map(|d| Instant::now() + d);
                    }
                    Incoming::Msg(ToExec::SetState { var, value }) => {
                        if let Err(e) = ctx.set_state_named(&var, value) {
                            let text = format!(
                                "agent {agent} set state variable `{var}` for remote task {task}: {e}"
                            );
                            tracing::warn!("{text}");
                            let _ = ctx.warn(text);
                        }
                    }
                    Incoming::Msg(ToExec::Done { result }) => {
                        link.ended = true;
                        if link.cancelled {
                            return Ok(Json::Null);
                        }
                        return match result {
                            Ok(v) => {
                                exec.count(|s| s.succeeded += 1);
                                Ok(v)
                            }
                            Err(f) => {
                                exec.count(|s| s.failed += 1);
                                if f.exception == "RemoteRefused" {
                                    // A bound of the agent was reached: said in the log and
                                    // the trace, as a start nobody ran.
                                    let text = format!(
                                        "remote task {task} ({}) refused by agent {agent}: {}",
                                        spec.name, f.message
                                    );
                                    tracing::warn!(target: "tcm_zenoh", task, agent, "{text}");
                                    let _ = ctx.warn(text);
                                }
                                Err(f.into_failure())
                            }
                        };
                    }
                    Incoming::Msg(ToExec::Cancelled) => {
                        link.ended = true;
                        if link.cancelled {
                            exec.count(|s| s.cancelled += 1);
                            return Ok(Json::Null);
                        }
                        // A cancel this executive never sent aborted the body (a forged one, or
                        // an agent that cancels on its own): the node has no value to succeed
                        // with.
                        let text = format!(
                            "remote task {task} ({}) on agent {agent} was cancelled, but no cancel \
                             was sent to it: the node fails with RemoteCancelled",
                            spec.name
                        );
                        tracing::warn!(target: "tcm_zenoh", task, agent, "{text}");
                        let _ = ctx.warn(text);
                        exec.count(|s| s.failed += 1);
                        return Err(RemoteCancelled { agent, task: spec.name.clone() }.raise());
                    }
                    Incoming::Msg(ToExec::Call { call, op }) => {
                        if let Some(result) = body.call(call, op) {
                            link.send(ToAgent::Reply { call, result }).await?;
                        }
                    }
                }
            }
            Some(done) = body.calls.join_next(), if !body.calls.is_empty() => {
                if let Ok((call, result)) = done {
                    link.send(ToAgent::Reply { call, result }).await?;
                }
            }
            () = sleep_until(sts), if !started && !link.cancelled => {
                link.cancel().await;
                link.end();
                return Err(timeout(TimeoutKind::ScheduleToStart, &spec, Some(&agent), opts.schedule_to_start));
            }
            () = sleep_until(stc), if started && !link.cancelled => {
                link.cancel().await;
                link.end();
                return Err(timeout(TimeoutKind::StartToClose, &spec, Some(&agent), opts.start_to_close));
            }
            () = sleep_until(hb), if started && !link.cancelled => {
                link.cancel().await;
                link.end();
                return Err(timeout(TimeoutKind::Heartbeat, &spec, Some(&agent), opts.heartbeat));
            }
            () = &mut cancelled, if !link.cancelled => {
                exec.count(|s| s.cancels += 1);
                link.cancel().await;
            }
        }
    }
}

/// The executive's side of a remote goal's body: its children, and its calls in progress.
struct Body {
    ctx: Ctx,
    exec: Arc<Inner>,
    agent: String,
    children: Vec<NodeId>,
    calls: JoinSet<(u64, Result<Answer, RemoteFailure>)>,
}

impl Body {
    /// Carries out a call of the body: at once (its answer), or as a wait whose answer comes from
    /// `calls` (`None`).
    fn call(&mut self, call: u64, op: Op) -> Option<Result<Answer, RemoteFailure>> {
        match op {
            Op::Spawn { child, constraints } => Some(self.spawn(child, &constraints)),
            Op::Call { child, constraints } => {
                let task = match self.task(child) {
                    Ok(t) => t,
                    Err(f) => return Some(Err(f)),
                };
                let refs = match self.refs(&constraints) {
                    Ok(r) => r,
                    Err(f) => return Some(Err(f)),
                };
                let ctx = self.ctx.clone();
                self.calls.spawn(async move {
                    let spawner = constrain(ctx.spawn(task), &constraints, &refs);
                    let ended = match spawner.wait_outcome::<Json>().await {
                        Ok(tcm::Ended::Succeeded(value)) => ChildEnded::Succeeded { value },
                        Ok(tcm::Ended::Failed(f)) => ChildEnded::Failed {
                            failure: RemoteFailure::from_failure(&f),
                            handled: false,
                        },
                        // A skipped child did not run: as a terminated one, it has no value.
                        Ok(tcm::Ended::Terminated | tcm::Ended::Skipped) => ChildEnded::Terminated,
                        // It succeeded with a value that is no JSON.
                        Err(tcm::Error::NoValue(_)) => ChildEnded::Succeeded { value: Json::Null },
                        Err(e) => return (call, Err(RemoteError::remote(e.to_string()))),
                    };
                    (call, Ok(Answer::Ended { ended }))
                });
                None
            }
            Op::Wait { child } => {
                let node = match self.child(child) {
                    Ok(n) => n,
                    Err(f) => return Some(Err(f)),
                };
                let ctx = self.ctx.clone();
                self.calls.spawn(async move {
                    let ended = match ctx.wait(node).await {
                        // A plain wait returns for a skipped child as for one that succeeded.
                        Ok(
                            WatchOutcome::Reached
                            | WatchOutcome::Recovered { .. }
                            | WatchOutcome::Skipped,
                        ) => ChildEnded::Succeeded { value: Json::Null },
                        Ok(WatchOutcome::Failed(f)) => ChildEnded::Failed {
                            failure: RemoteFailure::from_failure(&f),
                            handled: false,
                        },
                        Ok(WatchOutcome::Handled(f)) => ChildEnded::Failed {
                            failure: RemoteFailure::from_failure(&f),
                            handled: true,
                        },
                        Ok(WatchOutcome::Terminated | WatchOutcome::Dead) => ChildEnded::Terminated,
                        Err(e) => return (call, Err(RemoteError::remote(e.to_string()))),
                    };
                    (call, Ok(Answer::Ended { ended }))
                });
                None
            }
            Op::Terminate { child } => Some(
                self.child(child)
                    .and_then(|n| {
                        self.ctx
                            .terminate(n)
                            .map_err(|e| RemoteError::remote(e.to_string()))
                    })
                    .map(|()| Answer::Done),
            ),
            Op::Raise { event } => Some(
                self.ctx
                    .raise(&event)
                    .map(|()| Answer::Done)
                    .map_err(|e| RemoteError::remote(e.to_string())),
            ),
        }
    }

    fn spawn(
        &mut self,
        child: ChildSpec,
        constraints: &[Constraint],
    ) -> Result<Answer, RemoteFailure> {
        let task = self.task(child)?;
        let refs = self.refs(constraints)?;
        let node = constrain(self.ctx.spawn(task), constraints, &refs)
            .start()
            .map_err(|e| RemoteError::remote(e.to_string()))?;
        self.children.push(node);
        Ok(Answer::Spawned {
            child: (self.children.len() - 1) as u32,
        })
    }

    /// The task a child names.
    fn task(&self, child: ChildSpec) -> Result<Task, RemoteFailure> {
        let at = match child.at {
            ChildAt::Local => {
                let make = self.exec.local(&child.name).ok_or_else(|| {
                    RemoteError::remote(format!(
                        "no task {} is registered on the executive",
                        child.name
                    ))
                })?;
                return make(child.args).map_err(|f| RemoteFailure::from_failure(&f));
            }
            ChildAt::Agent(a) => At::Agent(a),
            ChildAt::Any => At::Any,
            ChildAt::Same => At::Agent(self.agent.clone()),
        };
        let remote = Remote {
            exec: self.exec.clone(),
            at,
            name: child.name,
            args: Ok(child.args),
            kind: child.task_kind,
            options: self.exec.defaults.clone(),
        };
        Ok(remote.task())
    }

    fn child(&self, i: u32) -> Result<NodeId, RemoteFailure> {
        self.children
            .get(i as usize)
            .copied()
            .ok_or_else(|| RemoteError::remote(format!("no child {i}")))
    }

    /// The nodes the constraints name, in order (`Previous` stays as it is).
    fn refs(&self, constraints: &[Constraint]) -> Result<Vec<NodeRef>, RemoteFailure> {
        let mut refs = Vec::new();
        for c in constraints {
            if let Constraint::Serial(r) | Constraint::Sequential(_, r) = c {
                refs.push(match r {
                    ChildRef::Previous => NodeRef::Previous,
                    ChildRef::Child(i) => NodeRef::Node(self.child(*i)?),
                });
            }
        }
        Ok(refs)
    }
}

/// Applies a remote body's constraints to a spawn; `refs` are the nodes they name, in order.
fn constrain<'a>(mut s: Spawner<'a>, constraints: &[Constraint], refs: &[NodeRef]) -> Spawner<'a> {
    let mut refs = refs.iter().copied();
    for c in constraints {
        s = match c {
            Constraint::Serial(_) => s.serial(refs.next().unwrap_or(NodeRef::Previous)),
            Constraint::Sequential(f, _) => {
                s.sequential(*f, refs.next().unwrap_or(NodeRef::Previous))
            }
            Constraint::TerminateInMs(ms) => s.terminate_in(Duration::from_millis(*ms)),
            Constraint::DisableForMs(f, ms) => s.disable_for(*f, Duration::from_millis(*ms)),
        };
    }
    s
}
