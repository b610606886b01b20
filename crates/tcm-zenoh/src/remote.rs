//! Remote tasks on the executive's side: a node of the tree whose action is carried out by an
//! agent. The action (`remote/life.rs`) places the task, sends the start, then hands each message
//! of the agent to the tree (a value or a typed failure ends it; a goal's calls spawn, wait for
//! and terminate children, [`Body`]), enforces the timeouts, and turns the node's termination into
//! a cancel that the agent confirms once its cleanup ran (docs/distributed.md, "A remote task's
//! life").

use crate::executive::{Executive, Inner};
use crate::failure::{RemoteError, RemoteFailure};
use crate::wire::{Answer, ChildAt, ChildEnded, ChildRef, ChildSpec, Constraint, Json, Kind, Op};
use serde::Serialize;
use std::sync::Arc;
use std::time::Duration;
use tcm::{Ctx, NodeId, NodeKind, NodeRef, Spawner, Task, WatchOutcome};
use tokio::task::JoinSet;

mod life;

pub(crate) use life::placed_task;
use life::{reattach, run};

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
    /// A resumed run's replay hands the waiting parent the same `T`, read from the journal
    /// ([`Task::journaled`]).
    pub fn typed_task<T>(self) -> Task
    where
        T: Serialize + serde::de::DeserializeOwned + Send + 'static,
    {
        self.task_map(|v| serde_json::from_value::<T>(v).map_err(|e| e.to_string()))
            .journaled::<T>()
    }

    /// As [`Remote::task_map`], with `write` making the value JSON again, for a run's journal: a
    /// resumed run's replay hands the waiting parent the same `T` ([`Task::journaled_with`]).
    pub fn task_map_journaled<T, F, W>(self, read: F, write: W) -> Task
    where
        T: Send + 'static,
        F: Fn(Json) -> Result<T, String> + Send + Sync + 'static,
        W: Fn(&T) -> Json + Send + Sync + 'static,
    {
        let read = Arc::new(read);
        let decode = read.clone();
        self.task_map(move |v| read(v)).journaled_with(
            move |v| v.downcast_ref::<T>().map(&write),
            move |j| decode(j).ok().map(|t| Box::new(t) as tcm::Value),
        )
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
        let again = (spec.clone(), read.clone(), args.clone());
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
        // A command that was running when the run crashed finds its body on the agent again
        // (docs/distributed.md, "An executive that comes back").
        let task = match kind {
            NodeKind::Command => task.reattach(move |ctx, recorded| {
                let (spec, read, args) = (again.0.clone(), again.1.clone(), again.2.clone());
                async move {
                    let name = spec.name.clone();
                    let value = reattach(spec, ctx, args, recorded).await?;
                    read(value).map_err(|e| {
                        RemoteError::failure(format!(
                            "the value of remote task {name} does not read: {e}"
                        ))
                    })
                }
            }),
            _ => task,
        };
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
