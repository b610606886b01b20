//! What a body running on an agent sees: [`RemoteCtx`]. A goal's body spawns children in the
//! executive's tree by name (a task registered on the executive, one offered by an agent, or one
//! of its own agent), with simple constraints, waits for them, terminates them, raises external
//! events; any body can heartbeat. Each of these is a call answered by the executive, which owns
//! the tree (docs/distributed.md, "What a remote body can do").

use crate::Error;
use crate::agent::AgentInner;
use crate::failure::{RemoteError, RemoteFailure};
use crate::wire::{
    Answer, ChildAt, ChildEnded, ChildRef, ChildSpec, Constraint, Json, Kind, Msg, Op, ToExec,
};
use serde::Serialize;
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tcm::Facet;
use tokio::sync::oneshot;

type Answering = oneshot::Sender<Result<Answer, RemoteFailure>>;

/// A remote task on the agent's side: where its messages go, their sequence, and the calls of its
/// body waiting for their answers.
pub(crate) struct Link {
    agent: Arc<AgentInner>,
    exec: String,
    task: u64,
    node: u64,
    // Held across the send, so messages leave in the order of their numbers.
    seq: tokio::sync::Mutex<u64>,
    calls: Mutex<BTreeMap<u64, Answering>>,
    next_call: AtomicU64,
}

impl Link {
    pub(crate) fn new(agent: Arc<AgentInner>, exec: String, task: u64, node: u64) -> Link {
        Link {
            agent,
            exec,
            task,
            node,
            seq: tokio::sync::Mutex::new(0),
            calls: Mutex::new(BTreeMap::new()),
            next_call: AtomicU64::new(1),
        }
    }

    /// Sends `body` to the executive; a failure is logged (the executive's side then times out, or
    /// sees the agent lost).
    pub(crate) async fn send(&self, body: ToExec) {
        if let Err(e) = self.try_send(body).await {
            tracing::warn!(target: "tcm_zenoh", agent = self.agent.name, task = self.task,
                "cannot reach the executive: {e}");
        }
    }

    /// Sends `body` from where no await is possible, if that can be done without waiting (the
    /// publisher is declared and no other send is under way); else gives it back.
    pub(crate) fn send_now(&self, body: ToExec) -> Option<ToExec> {
        use zenoh::Wait;
        let Some(publisher) = self.agent.cached_publisher(&self.exec) else {
            return Some(body);
        };
        let Ok(mut seq) = self.seq.try_lock() else {
            return Some(body);
        };
        *seq += 1;
        let bytes = Msg {
            task: self.task,
            seq: *seq,
            body,
        }
        .encode();
        let sent = if self.agent.duplicate {
            publisher
                .put(bytes.clone())
                .wait()
                .and_then(|()| publisher.put(bytes).wait())
        } else {
            publisher.put(bytes).wait()
        };
        if let Err(e) = sent {
            tracing::warn!(target: "tcm_zenoh", agent = self.agent.name, task = self.task,
                "cannot reach the executive: {e}");
        }
        None
    }

    async fn try_send(&self, body: ToExec) -> Result<(), Error> {
        let publisher = self.agent.outlet(&self.exec).await?;
        let mut seq = self.seq.lock().await;
        *seq += 1;
        let bytes = Msg {
            task: self.task,
            seq: *seq,
            body,
        }
        .encode();
        self.agent
            .put(&self.exec, publisher.as_deref(), bytes)
            .await
    }

    /// Sends the message `make` makes from the number of the last message sent, numbered 0
    /// (outside the sequence: the answer to a reattach, `agent/hold.rs`); the next message is
    /// numbered after that last one.
    pub(crate) async fn send_aside(&self, make: impl FnOnce(u64) -> ToExec) {
        let sent = async {
            let publisher = self.agent.outlet(&self.exec).await?;
            let seq = self.seq.lock().await;
            let bytes = Msg {
                task: self.task,
                seq: 0,
                body: make(*seq),
            }
            .encode();
            self.agent
                .put(&self.exec, publisher.as_deref(), bytes)
                .await
        };
        if let Err(e) = sent.await {
            tracing::warn!(target: "tcm_zenoh", agent = self.agent.name, task = self.task,
                "cannot reach the executive: {e}");
        }
    }

    /// The executive answered call `call`.
    pub(crate) fn answer(&self, call: u64, result: Result<Answer, RemoteFailure>) {
        let tx = self
            .calls
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .remove(&call);
        if let Some(tx) = tx {
            let _ = tx.send(result);
        }
    }

    async fn call(&self, op: Op) -> Result<Answer, RemoteFailure> {
        let call = self.next_call.fetch_add(1, Ordering::Relaxed);
        let (tx, rx) = oneshot::channel();
        self.calls
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .insert(call, tx);
        self.try_send(ToExec::Call { call, op })
            .await
            .map_err(|e| RemoteError::remote(format!("cannot reach the executive: {e}")))?;
        rx.await
            .map_err(|_| RemoteError::remote("the executive did not answer"))?
    }
}

/// A child a remote body spawned, named in its constraints and waits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ChildId(u32);

impl From<ChildId> for ChildRef {
    fn from(c: ChildId) -> ChildRef {
        ChildRef::Child(c.0)
    }
}

/// A child for a remote body to spawn: a task by name, its arguments, and where it runs.
pub struct Child {
    spec: Result<ChildSpec, String>,
}

impl Child {
    fn new(at: ChildAt, name: &str, args: impl Serialize) -> Child {
        Child {
            spec: serde_json::to_value(args)
                .map(|args| ChildSpec {
                    name: name.to_string(),
                    args,
                    at,
                    task_kind: Kind::Command,
                })
                .map_err(|e| format!("arguments of {name} do not serialise: {e}")),
        }
    }

    /// The task `name` registered on the executive (`Executive::register`), run there.
    pub fn local(name: &str, args: impl Serialize) -> Child {
        Child::new(ChildAt::Local, name, args)
    }

    /// The task `name` offered by `agent`, run there (a command unless [`Child::goal`]).
    pub fn on(agent: &str, name: &str, args: impl Serialize) -> Child {
        Child::new(ChildAt::Agent(agent.to_string()), name, args)
    }

    /// The task `name`, on the first live agent by name that offers it.
    pub fn any(name: &str, args: impl Serialize) -> Child {
        Child::new(ChildAt::Any, name, args)
    }

    /// The task `name`, offered by the agent that runs this body.
    pub fn here(name: &str, args: impl Serialize) -> Child {
        Child::new(ChildAt::Same, name, args)
    }

    /// A remote goal rather than a command (no effect on a local task, whose kind is its own).
    pub fn goal(mut self) -> Child {
        if let Ok(s) = &mut self.spec {
            s.task_kind = Kind::Goal;
        }
        self
    }
}

/// What a body running on an agent sees. Cheap to clone.
#[derive(Clone)]
pub struct RemoteCtx {
    link: Arc<Link>,
    task: Arc<str>,
}

impl RemoteCtx {
    pub(crate) fn new(link: Arc<Link>, task: String) -> RemoteCtx {
        RemoteCtx {
            link,
            task: task.into(),
        }
    }

    /// The task's name.
    pub fn task(&self) -> &str {
        &self.task
    }

    /// The display number of the task's node in the executive's trace.
    pub fn node(&self) -> u64 {
        self.link.node
    }

    /// The id of the executive that started it.
    pub fn executive(&self) -> &str {
        &self.link.exec
    }

    /// Tells the executive the body is alive (resets the task's heartbeat timeout).
    pub async fn heartbeat(&self) {
        self.link.send(ToExec::Heartbeat).await;
    }

    /// Sets a state variable of the executive's run (docs/semantics.md, "State and conditions"):
    /// an input to its engine, recorded in its trace with the value, which the conditions that
    /// read it answer. A variable the run has not declared is declared with the value's type; a
    /// value of another type than the variable's is refused there, with a warning in its trace.
    pub async fn set_state(&self, var: &str, value: impl Into<tcm::StateValue>) {
        self.link
            .send(ToExec::SetState {
                var: var.to_string(),
                value: value.into(),
            })
            .await;
    }

    /// Starts building the spawn of `child` under this body's node.
    pub fn spawn(&self, child: Child) -> RemoteSpawn<'_> {
        RemoteSpawn {
            ctx: self,
            child,
            constraints: Vec::new(),
        }
    }

    /// Waits until `child`'s execution completes, and tells how it ended (its value is not kept:
    /// use [`RemoteSpawn::call`] for it). While the body waits, the children it spawned start.
    pub async fn wait(&self, child: ChildId) -> Result<ChildEnded, RemoteFailure> {
        match self.link.call(Op::Wait { child: child.0 }).await? {
            Answer::Ended { ended } => Ok(ended),
            other => Err(unexpected(&other)),
        }
    }

    /// Terminates `child` and its subtree.
    pub async fn terminate(&self, child: ChildId) -> Result<(), RemoteFailure> {
        self.link
            .call(Op::Terminate { child: child.0 })
            .await
            .map(|_| ())
    }

    /// Raises the named external event of the executive's run.
    pub async fn raise_event(&self, event: &str) -> Result<(), RemoteFailure> {
        self.link
            .call(Op::Raise {
                event: event.to_string(),
            })
            .await
            .map(|_| ())
    }
}

fn unexpected(a: &Answer) -> RemoteFailure {
    RemoteError::remote(format!("unexpected answer from the executive: {a:?}"))
}

/// A spawn being built by a remote body: add constraints, then [`RemoteSpawn::start`] it or
/// [`RemoteSpawn::call`] it.
#[must_use = "a spawn does nothing until `start` or `call` is awaited"]
pub struct RemoteSpawn<'a> {
    ctx: &'a RemoteCtx,
    child: Child,
    constraints: Vec<Constraint>,
}

impl RemoteSpawn<'_> {
    /// `serial <of>`: the child's expansion and execution wait until `of`'s execution completed.
    pub fn serial(mut self, of: impl Into<ChildRef>) -> Self {
        self.constraints.push(Constraint::Serial(of.into()));
        self
    }

    /// `sequential <facet> <of>`.
    pub fn sequential(mut self, facet: Facet, of: impl Into<ChildRef>) -> Self {
        self.constraints
            .push(Constraint::Sequential(facet, of.into()));
        self
    }

    /// `terminate in <d>`.
    pub fn terminate_in(mut self, d: Duration) -> Self {
        self.constraints
            .push(Constraint::TerminateInMs(d.as_millis() as u64));
        self
    }

    /// `disable <facet> for <d>`.
    pub fn disable_for(mut self, facet: Facet, d: Duration) -> Self {
        self.constraints
            .push(Constraint::DisableForMs(facet, d.as_millis() as u64));
        self
    }

    /// Spawns the child; returns at once with its id (TDL's non-blocking `spawn`). As for any
    /// body, the child starts when this body waits or ends.
    pub async fn start(self) -> Result<ChildId, RemoteFailure> {
        let child = self.child.spec.map_err(RemoteError::remote)?;
        let op = Op::Spawn {
            child,
            constraints: self.constraints,
        };
        match self.ctx.link.call(op).await? {
            Answer::Spawned { child } => Ok(ChildId(child)),
            other => Err(unexpected(&other)),
        }
    }

    /// Spawns the child and waits for how it ended, with its value (TDL's `let v = spawn … with
    /// wait`: the child's failure that no handler on it takes is returned, not searched for
    /// above it).
    pub async fn outcome(self) -> Result<ChildEnded, RemoteFailure> {
        let child = self.child.spec.map_err(RemoteError::remote)?;
        let op = Op::Call {
            child,
            constraints: self.constraints,
        };
        match self.ctx.link.call(op).await? {
            Answer::Ended { ended } => Ok(ended),
            other => Err(unexpected(&other)),
        }
    }

    /// As [`RemoteSpawn::outcome`], as a function call: the child's value, or its failure (a
    /// terminated child is a `RemoteError`), so `?` passes the child's exception on.
    pub async fn call(self) -> Result<Json, RemoteFailure> {
        match self.outcome().await? {
            ChildEnded::Succeeded { value } => Ok(value),
            ChildEnded::Failed { failure, .. } => Err(failure),
            ChildEnded::Terminated => Err(RemoteError::remote("the child was terminated")),
        }
    }
}
