//! Agents: processes that join a system and offer tasks by name. An agent holds a liveliness token
//! for itself and one per offered task, runs a body for each `Start` it receives (once, however
//! often the message comes), reports its end, and on a `Cancel` aborts the body, runs the task's
//! cleanup and confirms. When an executive's token goes, the bodies it started are aborted and
//! cleaned up too: nobody is left to want them; unless the agent holds them for a while
//! ([`AgentBuilder::hold`], `agent/hold.rs`), so that the executive, resumed from its journal,
//! re-attaches to them.

use crate::Error;
use crate::body::{Link, RemoteCtx};
use crate::failure::{RemoteError, RemoteFailure, RemoteRefused};
use crate::noise::{Ignored, Noise, Noted};
use crate::sequence::{Known, Verdict, start_verdict, verdict};
use crate::wire::{self, Json, Kind, Msg, ToAgent, ToExec};
use serde::Serialize;
use serde::de::DeserializeOwned;
use std::collections::{BTreeMap, BTreeSet};
use std::future::Future;
use std::pin::Pin;
use std::sync::{Arc, Mutex, MutexGuard};
use std::task::{Context, Poll, Waker};
use tokio::task::AbortHandle;
use tokio::time::Instant;
use zenoh::pubsub::Publisher;
use zenoh::qos::CongestionControl;
use zenoh::sample::SampleKind;

mod builder;
mod hold;

pub use builder::AgentBuilder;

/// How many ended tasks an agent remembers, to tell a duplicate message from a late one.
const ENDED_KEPT: usize = 65_536;

type BoxFuture<T> = Pin<Box<dyn Future<Output = T> + Send>>;
type BodyFn = Arc<dyn Fn(RemoteCtx, Json) -> BoxFuture<Result<Json, RemoteFailure>> + Send + Sync>;
type CleanupFn = Arc<dyn Fn(Json) -> BoxFuture<()> + Send + Sync>;

/// A task an agent offers.
#[derive(Clone)]
struct Offer {
    kind: Kind,
    body: BodyFn,
    cleanup: Option<CleanupFn>,
}

/// The counters of an agent.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AgentStats {
    /// Bodies started.
    pub started: u64,
    /// Bodies that ended by themselves (value or failure).
    pub ended: u64,
    /// Bodies aborted by a cancel.
    pub cancelled: u64,
    /// Bodies aborted because their executive's token went (and, with [`AgentBuilder::hold`],
    /// no executive re-attached to them in time).
    pub orphaned: u64,
    /// Tasks an executive resumed from its journal re-attached to: running, or ended with their
    /// end kept.
    pub reattached: u64,
    /// Messages received twice, ignored.
    pub duplicates: u64,
    /// Messages of a running task numbered past the next one expected (a gap, a forged sequence
    /// number), and starts not numbered 1: refused.
    pub refused: u64,
    /// Messages about a task that ended, or that this agent never had, ignored.
    pub late: u64,
    /// Messages that could not be read, ignored.
    pub malformed: u64,
    /// Starts refused because a bound was reached ([`Limits`]): the node fails with
    /// [`RemoteRefused`](crate::RemoteRefused).
    pub over_limit: u64,
    /// Starts refused because the executive the key names is not live (no token of it is known):
    /// not answered.
    pub strangers: u64,
}

/// The bounds of an agent (docs/distributed.md, "Bounds"). A start past one is refused: the body
/// does not run, and the executive's node fails at once with
/// [`RemoteRefused`](crate::RemoteRefused), a `RemoteError`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// Bodies running at once for one executive. Default 256.
    pub bodies_per_executive: usize,
    /// Bodies running at once in all. Default 1024.
    pub bodies: usize,
    /// Executives a publisher is kept for at once (one per live executive, released when its
    /// token goes); messages to any other go out without one. Default 16.
    pub executives: usize,
}

impl Default for Limits {
    fn default() -> Limits {
        Limits {
            bodies_per_executive: 256,
            bodies: 1024,
            executives: 16,
        }
    }
}

/// A running agent. Dropping it (or [`Agent::close`]) withdraws it: its tokens go, executives
/// fail the tasks it ran with `AgentLost`, and its bodies are aborted.
pub struct Agent {
    inner: Arc<AgentInner>,
    _inbox: zenoh::pubsub::Subscriber<()>,
    _execs: zenoh::pubsub::Subscriber<()>,
    _tokens: Vec<zenoh::liveliness::LivelinessToken>,
}

impl Agent {
    /// An agent named `name` of `system`, offering nothing yet.
    pub fn builder(system: impl Into<String>, name: impl Into<String>) -> AgentBuilder {
        AgentBuilder {
            system: system.into(),
            name: name.into(),
            offers: BTreeMap::new(),
            duplicate: false,
            limits: Limits::default(),
            hold: std::time::Duration::ZERO,
        }
    }

    /// The agent's name.
    pub fn name(&self) -> &str {
        &self.inner.name
    }

    /// The agent's zenoh session, for a program's own traffic.
    pub fn session(&self) -> &zenoh::Session {
        &self.inner.session
    }

    /// The agent's counters.
    pub fn stats(&self) -> AgentStats {
        self.inner.lock().stats
    }

    /// How many bodies run now.
    pub fn running(&self) -> usize {
        self.inner.lock().running.len()
    }

    /// Withdraws the agent and closes its session (see [`Agent`]'s drop).
    pub async fn close(self) {
        let session = self.inner.session.clone();
        drop(self);
        if let Err(e) = session.close().await {
            tracing::warn!(target: "tcm_zenoh", "closing the agent's session: {e}");
        }
    }
}

impl Drop for Agent {
    /// Withdraws the agent: its tokens and subscriptions go (executives fail the tasks it ran
    /// with `AgentLost`), and its bodies are aborted, without cleanup: nobody waits for their
    /// confirmation any more.
    fn drop(&mut self) {
        let bodies: Vec<AbortHandle> = {
            let mut s = self.inner.lock();
            std::mem::take(&mut s.running)
                .into_values()
                .filter_map(|r| r.body)
                .collect()
        };
        for b in bodies {
            b.abort();
        }
    }
}

/// How long a start from an executive whose token was not seen waits for it.
const PARK_WAIT: std::time::Duration = std::time::Duration::from_secs(2);

/// How many such starts wait at once; the others are refused at once.
const PARKED: usize = 64;

/// A start waiting for its executive's token.
struct Parked {
    task: u64,
    seq: u64,
    node: u64,
    name: String,
    kind: Kind,
    args: Json,
}

/// A body that runs.
struct Running {
    last_seq: u64,
    body: Option<AbortHandle>,
    link: Arc<Link>,
    offer: Offer,
    args: Json,
    // Its executive's token went: aborted unless it re-attaches in time (`hold.rs`).
    orphaned: bool,
}

#[derive(Default)]
struct AgentState {
    // By executive and task id.
    running: BTreeMap<(String, u64), Running>,
    ended: BTreeMap<(String, u64), u64>,
    ended_order: std::collections::VecDeque<(String, u64)>,
    // The executives whose token is live.
    live: BTreeSet<String>,
    // Starts from executives whose token was not seen yet, by executive.
    parked: BTreeMap<String, Vec<Parked>>,
    // One per live executive, at most `Limits::executives`.
    publishers: BTreeMap<String, Arc<Publisher<'static>>>,
    stats: AgentStats,
    // The ignored messages not logged yet, by executive.
    noise: Noise,
    // With a hold: the ends of bodies that ended, for an executive that re-attaches (`hold.rs`).
    outcomes: hold::Outcomes,
    // How often each executive's token went: a hold ends only the absence it began with.
    absences: BTreeMap<String, u64>,
}

impl AgentState {
    fn end(&mut self, key: (String, u64), last_seq: u64) {
        self.running.remove(&key);
        if self.ended.insert(key.clone(), last_seq).is_none() {
            self.ended_order.push_back(key);
        }
        while self.ended_order.len() > ENDED_KEPT {
            if let Some(old) = self.ended_order.pop_front() {
                self.ended.remove(&old);
            }
        }
    }

    /// How many bodies run for executive `exec`.
    fn running_for(&self, exec: &str) -> usize {
        let exec = exec.to_string();
        self.running
            .range((exec.clone(), 0)..=(exec, u64::MAX))
            .count()
    }

    /// Why a start from `exec` is refused, if a bound is reached.
    fn over_limit(&self, exec: &str, limits: &Limits) -> Option<String> {
        if self.running.len() >= limits.bodies {
            return Some(format!(
                "{} bodies run already, the agent's bound",
                self.running.len()
            ));
        }
        let mine = self.running_for(exec);
        (mine >= limits.bodies_per_executive)
            .then(|| format!("{mine} bodies run already for this executive, the agent's bound"))
    }
}

pub(crate) struct AgentInner {
    session: zenoh::Session,
    system: String,
    pub(crate) name: String,
    offers: BTreeMap<String, Offer>,
    rt: tokio::runtime::Handle,
    pub(crate) duplicate: bool,
    limits: Limits,
    // How long the bodies of an executive whose token went keep running (`hold.rs`).
    hold: std::time::Duration,
    state: Mutex<AgentState>,
}

impl AgentInner {
    fn lock(&self) -> MutexGuard<'_, AgentState> {
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// The publisher to executive `exec`'s inbox, if it was declared.
    pub(crate) fn cached_publisher(&self, exec: &str) -> Option<Arc<Publisher<'static>>> {
        self.lock().publishers.get(exec).cloned()
    }

    /// The publisher to executive `exec`'s inbox, declared and matched (see [`crate::matched`])
    /// before it is kept; `None` for an executive whose token is not live, or past
    /// [`Limits::executives`] (its messages go out with [`AgentInner::put_once`]).
    pub(crate) async fn outlet(
        &self,
        exec: &str,
    ) -> Result<Option<Arc<Publisher<'static>>>, Error> {
        {
            let s = self.lock();
            if let Some(p) = s.publishers.get(exec) {
                return Ok(Some(p.clone()));
            }
            if !s.live.contains(exec) || s.publishers.len() >= self.limits.executives {
                return Ok(None);
            }
        }
        let p = self
            .session
            .declare_publisher(wire::executive_inbox(&self.system, exec, &self.name))
            .congestion_control(CongestionControl::Block)
            .await
            .map_err(Error::zenoh)?;
        if !crate::matched(&p).await? {
            tracing::warn!(target: "tcm_zenoh", agent = self.name, "no subscriber of {exec}'s inbox is known: sending anyway");
        }
        let p = Arc::new(p);
        let mut s = self.lock();
        // Gone meanwhile: not kept.
        if !s.live.contains(exec) {
            return Ok(Some(p));
        }
        Ok(Some(
            s.publishers.entry(exec.to_string()).or_insert(p).clone(),
        ))
    }

    /// Sends `bytes` to executive `exec`'s inbox, through `publisher` or, without one, as a put
    /// of the session that keeps nothing (twice with fault injection on).
    pub(crate) async fn put(
        &self,
        exec: &str,
        publisher: Option<&Publisher<'static>>,
        bytes: Vec<u8>,
    ) -> Result<(), Error> {
        let copies = if self.duplicate { 2 } else { 1 };
        for _ in 0..copies {
            match publisher {
                Some(p) => p.put(bytes.clone()).await.map_err(Error::zenoh)?,
                None => self.put_once(exec, bytes.clone()).await?,
            }
        }
        Ok(())
    }

    /// Sends `bytes` to executive `exec`'s inbox without a publisher.
    async fn put_once(&self, exec: &str, bytes: Vec<u8>) -> Result<(), Error> {
        self.session
            .put(wire::executive_inbox(&self.system, exec, &self.name), bytes)
            .congestion_control(CongestionControl::Block)
            .await
            .map_err(Error::zenoh)
    }

    /// A message from executive `exec` arrived: applied once, in order (numbered one more than
    /// the last of its task: a start is number 1); duplicates, messages out of order and messages
    /// of ended tasks are counted, logged (see [`crate::noise`]) and dropped.
    fn receive(self: &Arc<Self>, exec: &str, bytes: &[u8]) {
        let msg: Msg<ToAgent> = match wire::decode_to_agent(bytes) {
            Ok(m) => m,
            Err(e) => {
                self.lock().stats.malformed += 1;
                self.ignored(exec, Ignored::Malformed, || {
                    format!("malformed message ignored: {e}")
                });
                return;
            }
        };
        let kind = msg.body.name();
        match msg.body {
            // Outside the task's sequence (`hold.rs`).
            ToAgent::Reattach => self.reattach(exec.to_string(), msg.task),
            ToAgent::Start {
                node,
                name,
                task_kind,
                args,
            } => self.start(
                exec.to_string(),
                msg.task,
                msg.seq,
                node,
                name,
                task_kind,
                args,
            ),
            body => {
                let key = (exec.to_string(), msg.task);
                let mut s = self.lock();
                let known = match (s.running.get(&key), s.ended.get(&key)) {
                    (Some(r), _) => Known::Running(r.last_seq),
                    (None, Some(last)) => Known::Ended(*last),
                    (None, None) => Known::Unknown,
                };
                let ended = if matches!(known, Known::Running(_)) {
                    ""
                } else {
                    "ended "
                };
                // Zenoh delivers one publisher's messages in order: anything but the next number
                // (a gap, a forged 2^64-1 that would make the executive's cancel a duplicate) is
                // refused and changes nothing.
                let (what, text) = match verdict(known, msg.seq) {
                    Verdict::Apply => (None, String::new()),
                    Verdict::Duplicate => {
                        s.stats.duplicates += 1;
                        (Some(Ignored::Duplicate), "duplicate".to_string())
                    }
                    Verdict::Late => {
                        s.stats.late += 1;
                        (Some(Ignored::Late), "late".to_string())
                    }
                    Verdict::OutOfOrder { expected } => {
                        s.stats.refused += 1;
                        (Some(Ignored::Refused), format!("(expected {expected})"))
                    }
                };
                if let Some(what) = what {
                    drop(s);
                    self.ignored(exec, what, || match what {
                        Ignored::Refused => format!(
                            "out-of-order {kind} {} of task {} refused {text}",
                            msg.seq, msg.task
                        ),
                        _ => format!(
                            "{text} {kind} {} of {ended}task {} ignored",
                            msg.seq, msg.task
                        ),
                    });
                    return;
                }
                let Some(r) = s.running.get_mut(&key) else {
                    return;
                };
                r.last_seq = msg.seq;
                match body {
                    ToAgent::Cancel => {
                        let seq = r.last_seq;
                        let body = r.body.take();
                        let link = r.link.clone();
                        let cleanup = r.offer.cleanup.clone();
                        let args = r.args.clone();
                        s.end(key, seq);
                        s.stats.cancelled += 1;
                        drop(s);
                        if let Some(b) = body {
                            b.abort();
                        }
                        self.rt.spawn(async move {
                            if let Some(c) = cleanup {
                                c(args).await;
                            }
                            link.send(ToExec::Cancelled).await;
                        });
                    }
                    ToAgent::Reply { call, result } => r.link.answer(call, result),
                    ToAgent::Start { .. } | ToAgent::Reattach => {}
                }
            }
        }
    }

    /// A message from `exec` was ignored: logged at once if it is the first from there in a
    /// while (`detail` says what it was), else counted for the line at the end of the interval.
    fn ignored(self: &Arc<Self>, exec: &str, what: Ignored, detail: impl FnOnce() -> String) {
        let (noted, peer) = {
            let mut s = self.lock();
            let exec = exec.to_string();
            let peer = s.noise.counted_as(&exec).clone();
            (s.noise.note(&exec, what, Instant::now()), peer)
        };
        let Noted::Log(at) = noted else { return };
        tracing::warn!(target: "tcm_zenoh", agent = self.name, executive = exec, "{}", detail());
        let weak = Arc::downgrade(self);
        self.rt.spawn(async move {
            let mut at = at;
            loop {
                tokio::time::sleep_until(at).await;
                let Some(me) = weak.upgrade() else { break };
                let flushed = me.lock().noise.flush(&peer, Instant::now());
                let Some((held, over, next)) = flushed else {
                    break;
                };
                let line = crate::noise::line(&held, &peer, over);
                tracing::warn!(target: "tcm_zenoh", agent = me.name, "{line}");
                at = next;
            }
        });
    }

    #[allow(clippy::too_many_arguments)]
    fn start(
        self: &Arc<Self>,
        exec: String,
        task: u64,
        seq: u64,
        node: u64,
        name: String,
        kind: Kind,
        args: Json,
    ) {
        let key = (exec.clone(), task);
        let mut s = self.lock();
        let known = match (s.running.get(&key), s.ended.get(&key)) {
            (Some(r), _) => Known::Running(r.last_seq),
            (None, Some(last)) => Known::Ended(*last),
            (None, None) => Known::Unknown,
        };
        let verdict = start_verdict(known, seq);
        if verdict == Verdict::Duplicate {
            s.stats.duplicates += 1;
            drop(s);
            self.ignored(&exec, Ignored::Duplicate, || {
                format!("duplicate start {seq} of task {task} ignored")
            });
            return;
        }
        // Only a live executive of the system starts tasks. A start from an id whose token was
        // not seen waits a little for it (the token's notice and the start can come by different
        // paths), at most `PARKED` starts at once; then it is refused, and not answered (nobody
        // would read the answer).
        if !s.live.contains(&exec) {
            if s.parked.values().map(Vec::len).sum::<usize>() < PARKED {
                let first = !s.parked.contains_key(&exec);
                s.parked.entry(exec.clone()).or_default().push(Parked {
                    task,
                    seq,
                    node,
                    name,
                    kind,
                    args,
                });
                drop(s);
                if first {
                    let weak = Arc::downgrade(self);
                    self.rt.spawn(async move {
                        tokio::time::sleep(PARK_WAIT).await;
                        if let Some(me) = weak.upgrade() {
                            me.unpark(&exec);
                        }
                    });
                }
                return;
            }
            s.stats.strangers += 1;
            drop(s);
            self.ignored(&exec, Ignored::Stranger, || {
                format!("start {seq} of task {task} refused: no executive {exec} is live")
            });
            return;
        }
        // A task's first message is its start, number 1: a start numbered otherwise (a forged
        // 2^64-1 would make every later message of the task a duplicate) is refused, and the
        // task stays unknown.
        if verdict != Verdict::Apply {
            s.stats.refused += 1;
            drop(s);
            self.ignored(&exec, Ignored::Refused, || {
                format!("start {seq} of task {task} refused (a start is number 1)")
            });
            return;
        }
        let link = Arc::new(Link::new(self.clone(), exec, task, node));
        let offer = match self.offers.get(&name) {
            Some(o) if o.kind == kind => o.clone(),
            other => {
                let message = match other {
                    Some(_) => format!("agent {} offers {name} as another kind of task", self.name),
                    None => format!("agent {} does not offer {name}", self.name),
                };
                s.end(key, seq);
                drop(s);
                self.rt.spawn(async move {
                    link.send(ToExec::Done {
                        result: Err(RemoteError::remote(message)),
                    })
                    .await;
                });
                return;
            }
        };
        if let Some(reason) = s.over_limit(&key.0, &self.limits) {
            let exec = key.0.clone();
            s.end(key, seq);
            s.stats.over_limit += 1;
            drop(s);
            self.ignored(&exec, Ignored::OverLimit, || {
                format!("start of {name} (task {task}) refused: {reason}")
            });
            let failure = RemoteFailure::raise(RemoteRefused {
                agent: self.name.clone(),
                task: name,
                reason,
            });
            self.rt.spawn(async move {
                link.send(ToExec::Done {
                    result: Err(failure),
                })
                .await;
            });
            return;
        }
        s.stats.started += 1;
        s.running.insert(
            key.clone(),
            Running {
                last_seq: seq,
                body: None,
                link: link.clone(),
                offer: offer.clone(),
                args: args.clone(),
                orphaned: false,
            },
        );
        drop(s);
        // The body's first poll runs here, on the thread that received the start, in the agent's
        // runtime: a body that ends at once (a no-op, a query of a cached value) then costs no
        // hop to another thread, and its `Done` says both that it started and that it ended. A
        // body must not block before its first await, as on any async executor.
        let ctx = RemoteCtx::new(link.clone(), name);
        let (fut, first) = {
            let _rt = self.rt.enter();
            let mut fut = (offer.body)(ctx, args);
            let first = fut.as_mut().poll(&mut Context::from_waker(Waker::noop()));
            (fut, first)
        };
        match first {
            Poll::Ready(result) => {
                if self.finish(&key, &result) {
                    if let Some(body) = link.send_now(ToExec::Done { result }) {
                        self.rt.spawn(async move { link.send(body).await });
                    }
                }
            }
            Poll::Pending => {
                let me = self.clone();
                let key2 = key.clone();
                let body_link = link.clone();
                let mut s = self.lock();
                let Some(r) = s.running.get_mut(&key) else {
                    // Cancelled meanwhile: the body is dropped here.
                    return;
                };
                // Spawned under the lock, so a cancel that comes next finds the body to abort.
                // Tokio polls it again at once, with a waker that works.
                let handle = self.rt.spawn(async move {
                    body_link.send(ToExec::Started).await;
                    let result = fut.await;
                    if me.finish(&key2, &result) {
                        body_link.send(ToExec::Done { result }).await;
                    }
                });
                r.body = Some(handle.abort_handle());
            }
        }
    }

    /// Starts the starts of `exec` parked until its token came: applied if it came, else refused.
    fn unpark(self: &Arc<Self>, exec: &str) {
        let (parked, live) = {
            let mut s = self.lock();
            (
                s.parked.remove(exec).unwrap_or_default(),
                s.live.contains(exec),
            )
        };
        for p in parked {
            if live {
                self.start(
                    exec.to_string(),
                    p.task,
                    p.seq,
                    p.node,
                    p.name,
                    p.kind,
                    p.args,
                );
            } else {
                self.lock().stats.strangers += 1;
                self.ignored(exec, Ignored::Stranger, || {
                    format!(
                        "start {} of task {} refused: no executive {exec} is live",
                        p.seq, p.task
                    )
                });
            }
        }
    }

    /// The body of `key` ended by itself with `result`: it is no longer running, so a cancel that
    /// comes now is late (with a hold, its end is kept for an executive that re-attaches). False
    /// if it was not running any more (cancelled meanwhile).
    fn finish(&self, key: &(String, u64), result: &Result<Json, RemoteFailure>) -> bool {
        let mut s = self.lock();
        let Some(r) = s.running.get(key) else {
            return false;
        };
        let seq = r.last_seq;
        if !self.hold.is_zero() {
            let link = r.link.clone();
            s.outcomes.keep(key.clone(), seq, link, result.clone());
        }
        s.end(key.clone(), seq);
        s.stats.ended += 1;
        true
    }

    /// Executive `exec`'s token went: its bodies are aborted and cleaned up, at once or, with a
    /// hold, when it ends (`hold.rs`).
    fn executive_gone(self: &Arc<Self>, exec: &str) {
        {
            let mut s = self.lock();
            s.live.remove(exec);
            s.publishers.remove(exec);
        }
        if !self.hold.is_zero() {
            self.hold_for(exec);
            return;
        }
        self.abandon(exec, |_| true);
    }

    /// Aborts and cleans up the bodies of `exec` that `which` picks; `exec` is no longer live.
    fn abandon(self: &Arc<Self>, exec: &str, which: impl Fn(&Running) -> bool) {
        let mut s = self.lock();
        let keys: Vec<(String, u64)> = s
            .running
            .iter()
            .filter(|(k, r)| k.0 == exec && which(r))
            .map(|(k, _)| k)
            .cloned()
            .collect();
        for key in keys {
            if let Some(r) = s.running.remove(&key) {
                s.stats.orphaned += 1;
                if let Some(b) = r.body {
                    b.abort();
                }
                if let Some(c) = r.offer.cleanup.clone() {
                    let args = r.args.clone();
                    self.rt.spawn(async move { c(args).await });
                }
                s.end(key, r.last_seq);
            }
        }
    }
}
