//! A remote task's life on the executive's side (docs/distributed.md, "A remote task's life"):
//! the node's action places the task, records where (`Ctx::record_durable`, so that a run resumed
//! from its journal finds it), sends the start, then follows the agent's messages until the body
//! ends ([`follow`]). A command that was running when the run crashed is re-attached
//! ([`reattach`]): the resumed executive, under the same id, asks the agent for the task, which
//! still runs it (or kept its end), and follows it from there (docs/distributed.md, "An executive
//! that comes back").

use super::{Body, Spec};
use crate::executive::{Incoming, Inner};
use crate::failure::{AgentLost, RemoteCancelled, RemoteError, RemoteTimeout, TimeoutKind};
use crate::wire::{self, Json, Kind, Msg, ToAgent, ToExec};
use std::future::Future;
use std::pin::Pin;
use std::sync::Arc;
use std::time::Duration;
use tcm::{Ctx, Exception, Failure};
use tokio::sync::mpsc;
use tokio::task::JoinSet;
use tokio::time::Instant;

/// Where a remote task was placed, as its node records it in the run's journal.
#[derive(serde::Serialize, serde::Deserialize)]
struct Placed {
    exec: String,
    task: u64,
    agent: String,
}

/// The task number of a placement record (a value a node recorded), if it is one.
pub(crate) fn placed_task(recorded: &Json) -> Option<u64> {
    let placed: Placed = serde_json::from_value(recorded.get("remote")?.clone()).ok()?;
    Some(placed.task)
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

/// The signal that the node is being terminated, looked at once by the action.
type Cancelled<'a> = Pin<&'a mut (dyn Future<Output = ()> + Send)>;

/// The action of a remote task's node.
pub(super) async fn run(spec: Arc<Spec>, ctx: Ctx, args: Json) -> Result<Json, Failure> {
    // Looking at the signal now gives the action its grace period: a terminated node waits for
    // the agent's confirmation.
    let cancelled = ctx.cancelled();
    tokio::pin!(cancelled);
    let exec = spec.exec.clone();
    let opts = &spec.options;
    let node = ctx.node();
    let display = ctx.info(node).ok().flatten().map_or(0, |i| i.display);
    if spec.kind == Kind::Goal && ctx.replaying() {
        // Its children came from the agent's calls, which a replay does not have.
        return Err(RemoteError::failure(format!(
            "remote goal {} cannot be replayed from a journal yet: its children came from its \
             agent",
            spec.name
        )));
    }
    let task = exec.next_task();
    let (tx, rx) = mpsc::unbounded_channel();
    let scheduled = Instant::now();
    let sts = opts.schedule_to_start.map(|d| scheduled + d);
    let named = match &spec.at {
        super::At::Agent(a) => Some(a.as_str()),
        super::At::Any => None,
    };
    if !wire::valid_name(&spec.name) || !named.is_none_or(wire::valid_name) {
        return Err(RemoteError::failure(format!(
            "bad task or agent name in {}{}: use ASCII letters, digits, `_`, `-` and `.`",
            spec.name,
            named.map(|a| format!(" on {a}")).unwrap_or_default()
        )));
    }
    let agent = tokio::select! {
        a = exec.place(named, &spec.name, task, &ctx, display, tx, false) => match a {
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
    // Where it runs is on disk before the start leaves, with a journal: a run resumed after a
    // crash re-attaches to the body by it.
    let placed = Placed {
        exec: exec.id.clone(),
        task,
        agent: agent.clone(),
    };
    if let Err(f) = ctx.record_durable(serde_json::json!({ "remote": placed })) {
        link.end();
        return Err(f);
    }
    link.send(ToAgent::Start {
        node: display,
        name: spec.name.clone(),
        task_kind: spec.kind,
        args,
    })
    .await?;
    follow(&spec, &ctx, link, rx, cancelled, sts, None).await
}

/// The action a resumed run gives a remote command that was running at the crash, from what its
/// node recorded: placed, it is re-attached on its agent; not placed, it was never started, and
/// starts now.
pub(super) async fn reattach(
    spec: Arc<Spec>,
    ctx: Ctx,
    args: Json,
    recorded: Vec<Json>,
) -> Result<Json, Failure> {
    let placed = recorded.iter().rev().find_map(|v| {
        v.get("remote")
            .and_then(|p| serde_json::from_value::<Placed>(p.clone()).ok())
    });
    let Some(placed) = placed else {
        return run(spec, ctx, args).await;
    };
    let exec = spec.exec.clone();
    let lost = |why: String| {
        let text = format!(
            "remote task {} ({}) on agent {} cannot be re-attached: {why}",
            placed.task, spec.name, placed.agent
        );
        tracing::warn!(target: "tcm_zenoh", task = placed.task, "{text}");
        let _ = ctx.warn(text);
        spec.exec.count(|s| s.agent_lost += 1);
        AgentLost {
            agent: placed.agent.clone(),
            task: spec.name.clone(),
        }
        .raise()
    };
    if placed.exec != exec.id {
        return Err(lost(format!(
            "it was placed by executive {}, and this one is {} (open the resumed executive with \
             `Executive::open_as` under the same id)",
            placed.exec, exec.id
        )));
    }
    exec.reattached(placed.task);
    let cancelled = ctx.cancelled();
    tokio::pin!(cancelled);
    let opts = &spec.options;
    let display = ctx.info(ctx.node()).ok().flatten().map_or(0, |i| i.display);
    let (tx, rx) = mpsc::unbounded_channel();
    // The agent's answer must come within the schedule-to-start timeout.
    let sts = opts.schedule_to_start.map(|d| Instant::now() + d);
    let agent = Some(placed.agent.as_str());
    let placing = exec.place(agent, &spec.name, placed.task, &ctx, display, tx, true);
    tokio::select! {
        a = placing => if a.is_none() {
            return Err(RemoteError::failure("the executive was closed"));
        },
        () = sleep_until(sts) => {
            return Err(lost(format!("agent {} is not live", placed.agent)));
        }
        () = &mut cancelled => return Ok(Json::Null),
    }
    ctx.placed(&placed.agent)
        .map_err(|e| RemoteError::failure(e.to_string()))?;
    let link = Link {
        exec: exec.clone(),
        task: placed.task,
        agent: placed.agent.clone(),
        seq: 0,
        ended: false,
        cancelled: false,
    };
    exec.reach(&placed.agent)
        .await
        .map_err(|e| RemoteError::failure(e.to_string()))?;
    let ask = Msg {
        task: placed.task,
        seq: 0,
        body: ToAgent::Reattach,
    };
    exec.send(&placed.agent, &ask)
        .await
        .map_err(|e| RemoteError::failure(format!("cannot reach agent {}: {e}", placed.agent)))?;
    // Sent if the agent never had the task: the crash came between the placement's record and
    // the start.
    let start = ToAgent::Start {
        node: display,
        name: spec.name.clone(),
        task_kind: spec.kind,
        args,
    };
    follow(&spec, &ctx, link, rx, cancelled, sts, Some(start)).await
}

/// Follows a placed remote task until it ends: its messages, its timeouts, and the node's
/// termination turned into a cancel.
async fn follow(
    spec: &Spec,
    ctx: &Ctx,
    mut link: Link,
    mut rx: mpsc::UnboundedReceiver<Incoming>,
    mut cancelled: Cancelled<'_>,
    sts: Option<Instant>,
    mut unstarted: Option<ToAgent>,
) -> Result<Json, Failure> {
    let exec = spec.exec.clone();
    let opts = &spec.options;
    let (task, agent) = (link.task, link.agent.clone());
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
                let done = match msg {
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
                        None
                    }
                    Incoming::Msg(ToExec::Attached { received, done, .. }) => {
                        // The next message to the agent is numbered after the last it applied.
                        link.seq = received;
                        started = true;
                        let now = Instant::now();
                        stc = opts.start_to_close.map(|d| now + d);
                        hb = opts.heartbeat.map(|d| now + d);
                        done
                    }
                    Incoming::Msg(ToExec::Unattached { started: false, .. }) if unstarted.is_some() => {
                        if let Some(start) = unstarted.take() {
                            link.send(start).await?;
                        }
                        None
                    }
                    Incoming::Msg(ToExec::Unattached { reason, .. }) => {
                        link.ended = true;
                        if link.cancelled {
                            return Ok(Json::Null);
                        }
                        let text = format!("remote task {task} ({}) cannot be re-attached: {reason}", spec.name);
                        tracing::warn!(target: "tcm_zenoh", task, agent, "{text}");
                        let _ = ctx.warn(text);
                        exec.count(|s| s.agent_lost += 1);
                        return Err(AgentLost { agent, task: spec.name.clone() }.raise());
                    }
                    Incoming::Msg(ToExec::Heartbeat) => {
                        hb = opts.heartbeat.map(|d| Instant::now() + d);
                        None
                    }
                    Incoming::Msg(ToExec::SetState { var, value }) => {
                        if let Err(e) = ctx.set_state_named(&var, value) {
                            let text = format!(
                                "agent {agent} set state variable `{var}` for remote task {task}: {e}"
                            );
                            tracing::warn!("{text}");
                            let _ = ctx.warn(text);
                        }
                        None
                    }
                    Incoming::Msg(ToExec::Done { result }) => Some(result),
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
                        None
                    }
                };
                let Some(result) = done else { continue };
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
                            // A bound of the agent was reached: said in the log and the trace,
                            // as a start nobody ran.
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
            Some(done) = body.calls.join_next(), if !body.calls.is_empty() => {
                if let Ok((call, result)) = done {
                    link.send(ToAgent::Reply { call, result }).await?;
                }
            }
            () = sleep_until(sts), if !started && !link.cancelled => {
                link.cancel().await;
                link.end();
                return Err(timeout(TimeoutKind::ScheduleToStart, spec, Some(&agent), opts.schedule_to_start));
            }
            () = sleep_until(stc), if started && !link.cancelled => {
                link.cancel().await;
                link.end();
                return Err(timeout(TimeoutKind::StartToClose, spec, Some(&agent), opts.start_to_close));
            }
            () = sleep_until(hb), if started && !link.cancelled => {
                link.cancel().await;
                link.end();
                return Err(timeout(TimeoutKind::Heartbeat, spec, Some(&agent), opts.heartbeat));
            }
            () = &mut cancelled, if !link.cancelled => {
                exec.count(|s| s.cancels += 1);
                link.cancel().await;
            }
        }
    }
}
