//! The executive: the process that owns the one task tree. It joins a system, follows which agents
//! are live and what they offer (their liveliness tokens), receives the messages of its remote
//! tasks and hands each, once and in order, to the node's action (`executive/inbox.rs`,
//! `remote.rs`), and fails the remote tasks of an agent whose token is deleted with
//! [`AgentLost`](crate::AgentLost).

use crate::noise::{Ignored, Noise, Noted};
use crate::wire::{self, Json, Msg, ToAgent, ToExec};
use crate::{Error, RemoteOptions, Stats};
use std::collections::{BTreeMap, BTreeSet};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, RwLock};
use std::time::Duration;
use tcm::{Ctx, Failure, NodeId, Task};
use tokio::sync::{mpsc, watch};
use tokio::time::Instant;
use zenoh::pubsub::Publisher;
use zenoh::qos::CongestionControl;
use zenoh::sample::SampleKind;

mod inbox;

/// How many ended remote tasks the executive remembers, to tell a duplicate of their last message
/// from a late one.
const ENDED_KEPT: usize = 65_536;

/// At most one warning per remote task per interval about the messages it ignores, in the log and
/// the trace.
const REPEAT_INTERVAL: Duration = Duration::from_secs(1);

/// How many remote tasks the warnings follow one by one; past so many at once (forged messages
/// name any task), the others share one line in the log, and none in the trace.
const REPEAT_TASKS: usize = 256;

/// A task the executive can run for a remote body's `spawn` ([`Executive::register`]).
type Local = Arc<dyn Fn(Json) -> Result<Task, Failure> + Send + Sync>;

/// What the executive hands to a remote task's action.
#[derive(Debug)]
pub(crate) enum Incoming {
    Msg(ToExec),
    /// The agent's liveliness token was deleted.
    Lost,
    /// The executive was closed.
    Closed,
}

/// A remote task placed on an agent and not ended yet.
struct Pending {
    agent: String,
    last_seq: u64,
    // The agent's answers (`Attached`, numbered 0) still to come: to the question of a resumed
    // run, and to the one asked after a gap in the task's messages.
    questions: u32,
    // The agent was asked where the task stands after a gap (once per task).
    asked: bool,
    tx: mpsc::UnboundedSender<Incoming>,
    // The node's context, for warnings in the trace about its messages.
    ctx: Ctx,
}

/// Where a node ran: its display number and its agent.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Placement {
    /// The node.
    pub node: NodeId,
    /// Its display number in the run's trace.
    pub display: u64,
    /// The agent that ran its action.
    pub agent: String,
}

struct State {
    live: BTreeSet<String>,
    // Task → the agents whose offer token is live (an agent's offers go when its token does).
    offers: BTreeMap<String, BTreeSet<String>>,
    pending: BTreeMap<u64, Pending>,
    // Ended remote tasks: the sequence number of their last message, their agent and their
    // node's context (for a warning in the trace when a message of theirs comes again), oldest
    // ids first.
    ended: BTreeMap<u64, (u64, String, Ctx)>,
    placed: BTreeMap<NodeId, Placement>,
    // `Executive::close` was called.
    closed: bool,
    publishers: BTreeMap<String, Arc<Publisher<'static>>>,
    stats: Stats,
    // The ignored messages not reported yet, by remote task (`None`: the others, and the
    // messages that do not read), and the context of each task's node for the report.
    repeats: Noise<Option<u64>>,
    repeat_ctx: BTreeMap<u64, Ctx>,
}

impl Default for State {
    fn default() -> State {
        State {
            live: BTreeSet::new(),
            offers: BTreeMap::new(),
            pending: BTreeMap::new(),
            ended: BTreeMap::new(),
            placed: BTreeMap::new(),
            closed: false,
            publishers: BTreeMap::new(),
            stats: Stats::default(),
            repeats: Noise::new(None, REPEAT_TASKS, REPEAT_INTERVAL),
            repeat_ctx: BTreeMap::new(),
        }
    }
}

/// The text of a message ignored (`what`, of a `whose` task).
fn ignored_text(msg: &Msg<ToExec>, what: &str, whose: &str) -> String {
    format!(
        "{what} {} of {whose} {} ignored ({})",
        msg.seq,
        msg.task,
        msg.body.name()
    )
}

impl State {
    fn end(&mut self, task: u64, seq: u64) {
        if let Some(p) = self.pending.remove(&task) {
            self.ended.insert(task, (seq, p.agent, p.ctx));
        }
        while self.ended.len() > ENDED_KEPT {
            self.ended.pop_first();
        }
    }
}

pub(crate) struct Inner {
    pub(crate) session: zenoh::Session,
    // Where the reports of repeated warnings are written from.
    rt: tokio::runtime::Handle,
    pub(crate) system: String,
    pub(crate) id: String,
    state: Mutex<State>,
    // Bumped whenever an agent or an offer comes or goes; placement waits on it.
    changed: watch::Sender<u64>,
    next_task: AtomicU64,
    pub(crate) defaults: RemoteOptions,
    locals: RwLock<BTreeMap<String, Local>>,
    // Messages sent from where no await is possible (a dropped action's cancel).
    outbox: mpsc::UnboundedSender<(String, Msg<ToAgent>)>,
    // Fault injection for tests: send every message twice.
    pub(crate) duplicate: bool,
    // The executive's declarations, until it is closed.
    keep: Mutex<Option<Keep>>,
}

/// The process that owns the task tree and runs some of its nodes' actions on agents. Cheap to
/// clone. Remote tasks are made with [`Executive::remote`]; they are nodes of any `tcm` run of
/// this process, and keep the executive open while they exist.
#[derive(Clone)]
pub struct Executive {
    pub(crate) inner: Arc<Inner>,
}

struct Keep {
    _token: zenoh::liveliness::LivelinessToken,
    _inbox: zenoh::pubsub::Subscriber<()>,
    _agents: zenoh::pubsub::Subscriber<()>,
}

impl Executive {
    /// Joins `system` with a zenoh session opened from `config` (see [`crate::config`]), with the
    /// default options of remote tasks.
    pub async fn open(system: &str, config: zenoh::Config) -> Result<Executive, Error> {
        Executive::open_with(system, config, RemoteOptions::default()).await
    }

    /// As [`Executive::open`], with `defaults` for every remote task that sets no options of its
    /// own (and for the children remote bodies spawn on agents).
    pub async fn open_with(
        system: &str,
        config: zenoh::Config,
        defaults: RemoteOptions,
    ) -> Result<Executive, Error> {
        let session = zenoh::open(config).await.map_err(Error::zenoh)?;
        Executive::join(system, None, session, defaults, false).await
    }

    /// As [`Executive::open_with`], under the id `id` instead of its zenoh session's: an
    /// executive that may be resumed from its journal (docs/distributed.md, "An executive that
    /// comes back") opens under an id of its own, and its resumed run under the same, so that
    /// agents holding its bodies let it re-attach to them. Two live executives of a system must
    /// not share an id. `id` must be a valid name (ASCII letters, digits, `_`, `-`, `.`). Its
    /// remote tasks are numbered from the wall clock's microseconds, so that a new run under the
    /// id never reuses a number an agent remembers from an earlier one.
    pub async fn open_as(
        system: &str,
        id: &str,
        config: zenoh::Config,
        defaults: RemoteOptions,
    ) -> Result<Executive, Error> {
        if !wire::valid_name(id) {
            return Err(Error::BadName(id.into()));
        }
        let session = zenoh::open(config).await.map_err(Error::zenoh)?;
        let exec = Executive::join(system, Some(id.into()), session, defaults, false).await?;
        // Agents remember the tasks of an id across its runs: this run's are numbered from the
        // wall clock's microseconds, after those of any earlier run under the id (which placed
        // fewer than one task per microsecond).
        let base = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(1, |d| u64::try_from(d.as_micros()).unwrap_or(u64::MAX / 2));
        exec.inner.next_task.fetch_max(base, Ordering::Relaxed);
        Ok(exec)
    }

    /// Before a run resumes from `journal`: the remote tasks this executive places from now on
    /// are numbered after every task the journal's run placed (its placement records), so that
    /// none is taken by an agent for one it had.
    pub fn resume_from(&self, journal: &tcm_journal::Journal) {
        let last = journal
            .entries
            .iter()
            .filter_map(|e| match &e.input {
                tcm_journal::Input::Recorded { value, .. } => crate::remote::placed_task(value),
                _ => None,
            })
            .max();
        if let Some(last) = last {
            self.inner.next_task.fetch_max(last + 1, Ordering::Relaxed);
        }
    }

    /// Opens an executive listening on a free port of 127.0.0.1 (peer mode, multicast scouting
    /// off); returns it and the port agents connect to.
    pub async fn open_loopback(system: &str) -> Result<(Executive, u16), Error> {
        Executive::open_loopback_with(system, RemoteOptions::default(), false).await
    }

    /// As [`Executive::open_loopback`], with default options; `duplicate` sends every message
    /// twice (fault injection: agents must ignore the copies).
    pub async fn open_loopback_with(
        system: &str,
        defaults: RemoteOptions,
        duplicate: bool,
    ) -> Result<(Executive, u16), Error> {
        let mut last = None;
        // The port was free when chosen; another process may have taken it since.
        for _ in 0..5 {
            let port = crate::config::free_port()?;
            match zenoh::open(crate::config::loopback_listen(port)?).await {
                Ok(session) => {
                    let exec =
                        Executive::join(system, None, session, defaults.clone(), duplicate).await?;
                    return Ok((exec, port));
                }
                Err(e) => last = Some(Error::zenoh(e)),
            }
        }
        Err(last.unwrap_or_else(|| Error::Zenoh("cannot open a session".into())))
    }

    async fn join(
        system: &str,
        id: Option<String>,
        session: zenoh::Session,
        defaults: RemoteOptions,
        duplicate: bool,
    ) -> Result<Executive, Error> {
        if !wire::valid_name(system) {
            return Err(Error::BadName(system.into()));
        }
        let id = id.unwrap_or_else(|| session.zid().to_string());
        let rt = tokio::runtime::Handle::try_current()
            .map_err(|_| Error::Zenoh("an executive must open inside a tokio runtime".into()))?;
        let (outbox, mut outgoing) = mpsc::unbounded_channel::<(String, Msg<ToAgent>)>();
        let inner = Arc::new(Inner {
            keep: Mutex::new(None),
            session: session.clone(),
            rt,
            system: system.into(),
            id: id.clone(),
            state: Mutex::new(State::default()),
            changed: watch::Sender::new(0),
            next_task: AtomicU64::new(1),
            defaults,
            locals: RwLock::new(BTreeMap::new()),
            outbox,
            duplicate,
        });
        let weak = Arc::downgrade(&inner);
        let inbox = session
            .declare_subscriber(wire::executive_inboxes(system, &id))
            .callback(move |sample| {
                if let Some(inner) = weak.upgrade() {
                    // The key's last chunk names the agent that sent it.
                    let key = sample.key_expr().as_str();
                    let from = key.rsplit('/').next().unwrap_or_default();
                    inner.receive(from, &sample.payload().to_bytes());
                }
            })
            .await
            .map_err(Error::zenoh)?;
        let weak = Arc::downgrade(&inner);
        let prefix = format!("tdl/{system}/");
        let agents = session
            .liveliness()
            .declare_subscriber(format!("tdl/{system}/**"))
            .history(true)
            .callback(move |sample| {
                if let Some(inner) = weak.upgrade() {
                    let key = sample.key_expr().as_str();
                    let rest = key.strip_prefix(&prefix).unwrap_or(key);
                    inner.liveliness(rest, sample.kind() == SampleKind::Put);
                }
            })
            .await
            .map_err(Error::zenoh)?;
        let token = session
            .liveliness()
            .declare_token(wire::executive_token(system, &id))
            .await
            .map_err(Error::zenoh)?;
        let weak = Arc::downgrade(&inner);
        tokio::spawn(async move {
            while let Some((agent, msg)) = outgoing.recv().await {
                let Some(inner) = weak.upgrade() else { break };
                if let Err(e) = inner.send(&agent, &msg).await {
                    tracing::warn!(target: "tcm_zenoh", agent, task = msg.task, "cannot send: {e}");
                }
            }
        });
        *inner.keep.lock().unwrap_or_else(|p| p.into_inner()) = Some(Keep {
            _token: token,
            _inbox: inbox,
            _agents: agents,
        });
        Ok(Executive { inner })
    }

    /// Leaves the system: the executive's token goes (agents abort the bodies it started and run
    /// their cleanups), its session closes, and every remote task still placed or waiting for an
    /// agent fails with [`RemoteError`](crate::RemoteError).
    pub async fn close(&self) {
        let keep = self
            .inner
            .keep
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .take();
        {
            let mut s = self.inner.lock();
            s.closed = true;
            let pending: Vec<u64> = s.pending.keys().copied().collect();
            for id in pending {
                if let Some(p) = s.pending.get(&id) {
                    let _ = p.tx.send(Incoming::Closed);
                    let last = p.last_seq;
                    s.end(id, last);
                }
            }
        }
        self.inner.changed.send_modify(|n| *n += 1);
        drop(keep);
        if let Err(e) = self.inner.session.close().await {
            tracing::warn!(target: "tcm_zenoh", "closing the executive's session: {e}");
        }
    }

    /// Runs `fut` on the tokio runtime the executive was opened in, and waits for it. Zenoh's
    /// calls need a multi-thread runtime; a tree driven on a current-thread one (a journaled run,
    /// docs/semantics.md, "Durable runs") reaches zenoh through this, as remote tasks do. From a
    /// multi-thread runtime, `fut` runs where it is.
    pub async fn on_runtime<F>(&self, fut: F) -> Result<F::Output, Error>
    where
        F: std::future::Future + Send + 'static,
        F::Output: Send + 'static,
    {
        if !on_current_thread() {
            return Ok(fut.await);
        }
        self.inner.rt.spawn(fut).await.map_err(Error::zenoh)
    }

    /// The system's name.
    pub fn system(&self) -> &str {
        &self.inner.system
    }

    /// This executive's id: its zenoh session's, unique per run of the process.
    pub fn id(&self) -> &str {
        &self.inner.id
    }

    /// The zenoh session, for a program's own traffic.
    pub fn session(&self) -> &zenoh::Session {
        &self.inner.session
    }

    /// Registers a task of this process that remote bodies may spawn by name (`Child::local`):
    /// `make` builds it from the arguments the body gave, or fails (the body's spawn then fails
    /// with that failure). A task called for its value (`call`) gives it to the body when its
    /// action returns a [`serde_json::Value`].
    pub fn register(
        &self,
        name: impl Into<String>,
        make: impl Fn(Json) -> Result<Task, Failure> + Send + Sync + 'static,
    ) {
        if let Ok(mut locals) = self.inner.locals.write() {
            locals.insert(name.into(), Arc::new(make));
        }
    }

    /// The agent that ran (or runs) `node`'s action, if it is a remote task that was placed.
    pub fn agent_of(&self, node: NodeId) -> Option<String> {
        self.inner.lock().placed.get(&node).map(|p| p.agent.clone())
    }

    /// Every remote task placed so far, by node.
    pub fn placements(&self) -> Vec<Placement> {
        self.inner.lock().placed.values().cloned().collect()
    }

    /// The live agents, by name.
    pub fn agents(&self) -> Vec<String> {
        self.inner.lock().live.iter().cloned().collect()
    }

    /// The live agents that offer `task`, by name.
    pub fn offering(&self, task: &str) -> Vec<String> {
        let s = self.inner.lock();
        s.offers
            .get(task)
            .map(|a| a.intersection(&s.live).cloned().collect())
            .unwrap_or_default()
    }

    /// Every task the live agents offer, with the live agents offering it, by name.
    pub fn offers(&self) -> std::collections::BTreeMap<String, Vec<String>> {
        let s = self.inner.lock();
        s.offers
            .iter()
            .map(|(task, agents)| {
                (
                    task.clone(),
                    agents.intersection(&s.live).cloned().collect::<Vec<_>>(),
                )
            })
            .filter(|(_, agents)| !agents.is_empty())
            .collect()
    }

    /// The executive's counters.
    pub fn stats(&self) -> Stats {
        self.inner.lock().stats
    }

    /// Waits until `agent` is live and offers `task` (with `task` `None`: until it is live), at
    /// most `timeout`.
    pub async fn wait_for(
        &self,
        agent: &str,
        task: Option<&str>,
        timeout: Duration,
    ) -> Result<(), Error> {
        let mut rx = self.inner.changed.subscribe();
        let ready = || {
            let s = self.inner.lock();
            s.live.contains(agent)
                && task.is_none_or(|t| s.offers.get(t).is_some_and(|a| a.contains(agent)))
        };
        let wait = async {
            while !ready() {
                if rx.changed().await.is_err() {
                    break;
                }
            }
        };
        tokio::time::timeout(timeout, wait)
            .await
            .map_err(|_| Error::Timeout(format!("agent {agent} not live after {timeout:?}")))
    }

    /// Waits until `agent` is no longer live, at most `timeout`.
    pub async fn wait_gone(&self, agent: &str, timeout: Duration) -> Result<(), Error> {
        let mut rx = self.inner.changed.subscribe();
        let wait = async {
            while self.inner.lock().live.contains(agent) {
                if rx.changed().await.is_err() {
                    break;
                }
            }
        };
        tokio::time::timeout(timeout, wait)
            .await
            .map_err(|_| Error::Timeout(format!("agent {agent} still live after {timeout:?}")))
    }
}

impl Inner {
    fn lock(&self) -> MutexGuard<'_, State> {
        // A panic under this lock leaves consistent maps (each update is one insert or remove).
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }

    pub(crate) fn next_task(&self) -> u64 {
        self.next_task.fetch_add(1, Ordering::Relaxed)
    }

    pub(crate) fn local(&self, name: &str) -> Option<Local> {
        self.locals.read().ok()?.get(name).cloned()
    }

    /// A message was ignored: about remote task `task` (`None`: one that does not read), whose
    /// node's context is `ctx` while its run lasts. Reported at once (in the log, and in the
    /// trace as a warning on the node) if it is the first about the task in a while (`detail`
    /// says what it was), else counted for one report when the interval ends.
    fn ignored(
        self: &Arc<Self>,
        task: Option<u64>,
        what: Ignored,
        ctx: Option<Ctx>,
        detail: impl FnOnce() -> String,
    ) {
        let (noted, key) = {
            let mut s = self.lock();
            let key = *s.repeats.counted_as(&task);
            let noted = s.repeats.note(&key, what, Instant::now());
            if let (Noted::Log(_), Some(t), Some(c)) = (&noted, key, &ctx) {
                s.repeat_ctx.insert(t, c.clone());
            }
            (noted, key)
        };
        let Noted::Log(at) = noted else { return };
        let text = detail();
        tracing::warn!(target: "tcm_zenoh", task, "{text}");
        if let (Some(_), Some(ctx)) = (key, ctx) {
            let _ = ctx.warn(text);
        }
        let weak = Arc::downgrade(self);
        self.rt.spawn(async move {
            let mut at = at;
            loop {
                tokio::time::sleep_until(at).await;
                let Some(me) = weak.upgrade() else { break };
                let (flushed, ctx) = {
                    let mut s = me.lock();
                    let flushed = s.repeats.flush(&key, Instant::now());
                    let ctx = key.and_then(|t| match flushed {
                        Some(_) => s.repeat_ctx.get(&t).cloned(),
                        None => s.repeat_ctx.remove(&t),
                    });
                    (flushed, ctx)
                };
                let Some((held, over, next)) = flushed else {
                    break;
                };
                let text = match key {
                    Some(t) => format!(
                        "{held} message(s) of remote task {t} ignored in the last {} ms",
                        over.as_millis()
                    ),
                    None => format!(
                        "{held} message(s) of other remote tasks ignored in the last {} ms",
                        over.as_millis()
                    ),
                };
                tracing::warn!(target: "tcm_zenoh", task = key, "{text}");
                if let Some(ctx) = ctx {
                    let _ = ctx.warn(text);
                }
                at = next;
            }
        });
    }

    /// A liveliness token came (`put`) or went, its key without the system's prefix.
    fn liveliness(&self, key: &str, put: bool) {
        let mut parts = key.split('/');
        let mut s = self.lock();
        match (parts.next(), parts.next(), parts.next()) {
            (Some("agents"), Some(agent), None) => {
                if put {
                    s.live.insert(agent.to_string());
                } else {
                    s.live.remove(agent);
                    s.publishers.remove(agent);
                    let lost: Vec<u64> = s
                        .pending
                        .iter()
                        .filter(|(_, p)| p.agent == agent)
                        .map(|(id, _)| *id)
                        .collect();
                    if !lost.is_empty() {
                        tracing::warn!(target: "tcm_zenoh", agent,
                            "agent {agent}'s token was deleted: {} remote task(s) placed there fail with AgentLost", lost.len());
                    }
                    for id in lost {
                        if let Some(p) = s.pending.get(&id) {
                            let _ = p.tx.send(Incoming::Lost);
                            let last = p.last_seq;
                            s.end(id, last);
                        }
                    }
                }
            }
            (Some("offers"), Some(task), Some(agent)) => {
                let agents = s.offers.entry(task.to_string()).or_default();
                if put {
                    agents.insert(agent.to_string());
                } else {
                    agents.remove(agent);
                }
            }
            _ => return,
        }
        drop(s);
        self.changed.send_modify(|n| *n += 1);
    }

    /// Places remote task `task` (of node `node`, numbered `display`) on a live agent that
    /// offers `name`: `agent`, or the first by name when `None`. Waits until there is one; the
    /// task is then pending there, its messages going to `tx`. `None` once the executive closed.
    #[allow(clippy::too_many_arguments)]
    pub(crate) async fn place(
        &self,
        agent: Option<&str>,
        name: &str,
        task: u64,
        ctx: &Ctx,
        display: u64,
        tx: mpsc::UnboundedSender<Incoming>,
        reattaching: bool,
    ) -> Option<String> {
        let node = ctx.node();
        let mut rx = self.changed.subscribe();
        loop {
            {
                let mut s = self.lock();
                if s.closed {
                    return None;
                }
                let chosen = s.offers.get(name).and_then(|offering| match agent {
                    Some(a) => (offering.contains(a) && s.live.contains(a)).then(|| a.to_string()),
                    None => offering.iter().find(|a| s.live.contains(*a)).cloned(),
                });
                if let Some(chosen) = chosen {
                    s.pending.insert(
                        task,
                        Pending {
                            agent: chosen.clone(),
                            last_seq: 0,
                            questions: u32::from(reattaching),
                            asked: false,
                            tx,
                            ctx: ctx.clone(),
                        },
                    );
                    s.placed.insert(
                        node,
                        Placement {
                            node,
                            display,
                            agent: chosen.clone(),
                        },
                    );
                    s.stats.placed += 1;
                    return Some(chosen);
                }
            }
            if rx.changed().await.is_err() {
                return None;
            }
        }
    }

    /// The remote task ended on this side (a timeout, a dropped action): later messages are late.
    pub(crate) fn forget(&self, task: u64) {
        let mut s = self.lock();
        if let Some(p) = s.pending.get(&task) {
            let last = p.last_seq;
            s.end(task, last);
        }
    }

    pub(crate) fn count(&self, f: impl FnOnce(&mut Stats)) {
        f(&mut self.lock().stats);
    }

    /// A task of the resumed run's journal, numbered `task`, is this executive's again: the ones
    /// it places from now on are numbered after it.
    pub(crate) fn reattached(&self, task: u64) {
        self.next_task
            .fetch_max(task.saturating_add(1), Ordering::Relaxed);
    }

    /// Sends `msg` to `agent`'s inbox, reliably (zenoh blocks rather than drop it when congested);
    /// from a current-thread runtime (a journaled run's tree), on the executive's own runtime,
    /// as zenoh needs.
    pub(crate) async fn send(
        self: &Arc<Self>,
        agent: &str,
        msg: &Msg<ToAgent>,
    ) -> Result<(), Error> {
        if !on_current_thread() {
            return self.send_here(agent, msg).await;
        }
        let (me, agent, msg) = (self.clone(), agent.to_string(), msg.clone());
        self.rt
            .spawn(async move { me.send_here(&agent, &msg).await })
            .await
            .map_err(Error::zenoh)?
    }

    async fn send_here(&self, agent: &str, msg: &Msg<ToAgent>) -> Result<(), Error> {
        let publisher = self.publisher(agent).await?;
        let bytes = msg.encode();
        if self.duplicate {
            publisher.put(bytes.clone()).await.map_err(Error::zenoh)?;
        }
        publisher.put(bytes).await.map_err(Error::zenoh)
    }

    /// Waits until `agent`'s inbox is reachable: its publisher declared and a subscriber of it
    /// known, or given up after a while (the sends then go out anyway).
    pub(crate) async fn reach(self: &Arc<Self>, agent: &str) -> Result<(), Error> {
        if !on_current_thread() {
            return self.publisher(agent).await.map(drop);
        }
        let (me, agent) = (self.clone(), agent.to_string());
        self.rt
            .spawn(async move { me.publisher(&agent).await.map(drop) })
            .await
            .map_err(Error::zenoh)?
    }

    /// Queues `msg` for `agent`, from where no await is possible.
    pub(crate) fn send_later(&self, agent: &str, msg: Msg<ToAgent>) {
        let _ = self.outbox.send((agent.to_string(), msg));
    }

    async fn publisher(&self, agent: &str) -> Result<Arc<Publisher<'static>>, Error> {
        if let Some(p) = self.lock().publishers.get(agent) {
            return Ok(p.clone());
        }
        let p = self
            .session
            .declare_publisher(wire::agent_inbox(&self.system, agent, &self.id))
            .congestion_control(CongestionControl::Block)
            .await
            .map_err(Error::zenoh)?;
        if !crate::matched(&p).await? {
            tracing::warn!(target: "tcm_zenoh", agent, "no subscriber of the agent's inbox is known: sending anyway");
        }
        let p = Arc::new(p);
        let mut s = self.lock();
        Ok(s.publishers.entry(agent.to_string()).or_insert(p).clone())
    }
}

/// Whether this is a current-thread tokio runtime's thread, where zenoh's calls cannot run.
fn on_current_thread() -> bool {
    tokio::runtime::Handle::try_current()
        .is_ok_and(|h| h.runtime_flavor() == tokio::runtime::RuntimeFlavor::CurrentThread)
}
