//! Steering a live run from the page (docs/viewer.md, "Steering a run"): `POST
//! /api/runs/{id}/control` with a JSON body `{"op": …}` and the run's token in the header
//! `x-tdl-token`, each op one call of the run's [`tcm::Control`] naming who asked (`viewer
//! <peer address>`), so each is a `control` record of the trace.
//!
//! The rules, in the order they are checked:
//! - a request whose `Origin` is present and not the viewer's own (`http://<Host>`) is refused
//!   (403), as is every WebSocket upgrade of such a page (`server.rs`): a page of another site may
//!   neither steer nor watch a run;
//! - a run nobody gave a control handle ([`Viewer::steer`]) is refused (403);
//! - a request without the run's token (128 random bits from the OS, compared in constant time)
//!   is refused (403);
//! - a bad body is 400, a node that is not alive 404, a request the run refuses (a node not held,
//!   a run that ended) 409, each with what is wrong.
//!
//! Nothing is changed before all of that passed. Then, once a page was heard, a run left with
//! something set (paused, a breakpoint or approval rule set from the page, a node held) and no
//! request heard for [`Viewer::release_after`] (5 s unless told) is released: its breakpoints and
//! approval rules removed, its held nodes approved, the run resumed (`watchdog`), once per silence.

use std::net::SocketAddr;
use std::sync::atomic::Ordering;
use std::sync::{Arc, MutexGuard};
use std::time::{Duration, Instant};

use axum::body::Bytes;
use axum::extract::{ConnectInfo, Path, State};
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::Deserialize;
use tcm::{
    Approval, BreakAt, Breakpoint, Control, EngineError, Failure, Fault, FaultOutcome, Matcher,
    SteerId,
};

use super::{Run, Shared, ViewError, Viewer, json};

/// How long a steered run may go without a request from its page before it is released, by
/// default (ms).
pub(super) const RELEASE_AFTER_MS: u64 = 5_000;

/// How often the watchdog looks for silent pages.
const WATCH_EVERY: Duration = Duration::from_millis(500);

/// The header that carries a run's token.
const TOKEN_HEADER: &str = "x-tdl-token";

/// A run's control, once [`Viewer::steer`] gave it one.
pub(crate) struct Steer {
    control: Control,
    token: String,
    /// When the last request with the token came; `None` before the first.
    heard: Option<Instant>,
    /// Something was set from the page since the last release (a pause, a step, a breakpoint or
    /// an approval rule).
    set: bool,
    /// The run was released since the last request.
    released: bool,
}

impl Run {
    fn steering(&self) -> MutexGuard<'_, Option<Steer>> {
        // The state is whole after any panic: plain fields set one at a time.
        self.steer.lock().unwrap_or_else(|e| e.into_inner())
    }
}

impl Viewer {
    /// Lets pages steer live run `run` (a [`LiveSink`](super::LiveSink)'s id) through `control`;
    /// returns the run's token, which a page must send with each control request (see
    /// [`Viewer::control_url`]). A new call replaces the handle and the token.
    pub fn steer(&self, run: usize, control: Control) -> Result<String, ViewError> {
        let Some(r) = self.shared.run(run) else {
            return Err(ViewError::NoRun(run));
        };
        let token = token()?;
        *r.steering() = Some(Steer {
            control,
            token: token.clone(),
            heard: None,
            set: false,
            released: false,
        });
        r.lock().control = true;
        // Pages open on the run start again from a snapshot, which says it can be steered.
        let _ = r.tx.send(Arc::from(r#"{"type":"resync"}"#));
        Ok(token)
    }

    /// The address of a page that steers run `run`, its token in it
    /// (`http://127.0.0.1:PORT/?run=ID&token=TOKEN`); `None` for a run without control.
    pub fn control_url(&self, run: usize) -> Option<String> {
        let r = self.shared.run(run)?;
        let steer = r.steering();
        let token = &steer.as_ref()?.token;
        Some(format!("http://{}/?run={run}&token={token}", self.addr))
    }

    /// How long a steered run may go without a control request (a page's heartbeat among them)
    /// while something is set before it is released (5 s unless told; for tests).
    pub fn release_after(&self, after: Duration) {
        let ms = u64::try_from(after.as_millis()).unwrap_or(u64::MAX);
        self.shared.release_after_ms.store(ms, Ordering::Relaxed);
    }
}

/// 128 random bits from the operating system, in hex.
fn token() -> Result<String, ViewError> {
    let mut bytes = [0u8; 16];
    getrandom::fill(&mut bytes).map_err(|e| ViewError::Random(e.to_string()))?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

/// Whether two strings are equal, in a time that does not depend on where they differ.
fn same(a: &str, b: &str) -> bool {
    a.len() == b.len() && a.bytes().zip(b.bytes()).fold(0u8, |d, (x, y)| d | (x ^ y)) == 0
}

/// Whether the request comes from a page of another origin than the viewer's own: its `Origin`
/// is present and is not `http://` and its `Host`. Programs (no `Origin`) are not pages.
pub(super) fn foreign_origin(headers: &HeaderMap) -> bool {
    let Some(origin) = headers.get(header::ORIGIN) else {
        return false;
    };
    let host = headers.get(header::HOST).and_then(|h| h.to_str().ok());
    match (origin.to_str().ok(), host) {
        (Some(origin), Some(host)) => !origin.eq_ignore_ascii_case(&format!("http://{host}")),
        _ => true,
    }
}

pub(super) fn forbidden(why: &str) -> Response {
    (StatusCode::FORBIDDEN, why.to_string()).into_response()
}

fn refused(status: StatusCode, why: String) -> Response {
    (status, why).into_response()
}

/// `POST /api/runs/{id}/control`.
pub(super) async fn control(
    State(shared): State<Arc<Shared>>,
    Path(id): Path<usize>,
    ConnectInfo(peer): ConnectInfo<SocketAddr>,
    headers: HeaderMap,
    body: Bytes,
) -> Response {
    let Some(run) = shared.run(id) else {
        return super::no_run(id);
    };
    if foreign_origin(&headers) {
        return forbidden("a page of another origin may not steer a run");
    }
    let control = {
        let mut steer = run.steering();
        let Some(s) = steer.as_mut() else {
            return forbidden("control is off for this run");
        };
        let given = headers.get(TOKEN_HEADER).and_then(|t| t.to_str().ok());
        if !given.is_some_and(|t| same(t, &s.token)) {
            return forbidden("a control request needs the run's token (header x-tdl-token)");
        }
        s.heard = Some(Instant::now());
        s.released = false;
        s.control.clone()
    };
    let op = match parse(&body) {
        Ok(op) => op,
        Err(why) => return refused(StatusCode::BAD_REQUEST, why),
    };
    let by = format!("viewer {peer}");
    let sets = op.sets();
    match act(&control, op, &by) {
        Ok(done) => {
            if sets {
                if let Some(s) = run.steering().as_mut() {
                    s.set = true;
                }
            }
            let paused = control.is_paused().unwrap_or(false);
            let mut answer = serde_json::json!({"ok": true, "paused": paused});
            if let Some(id) = done.id {
                answer["id"] = id.0.into();
            }
            if let Some(changed) = done.changed {
                answer["changed"] = changed.into();
            }
            json(answer.to_string())
        }
        Err(Refusal(status, why)) => refused(status, why),
    }
}

/// Which nodes a request is about.
#[derive(Debug)]
enum Target {
    Task(String),
    Path(String),
    Node(u64),
    Exception(String),
}

/// A control request, checked.
#[derive(Debug)]
enum Op {
    Pause,
    Resume,
    Step,
    StepToStart,
    Heartbeat,
    Break(BreakAt, Target),
    Remove(u32),
    Inject(Target, u32, FaultOutcome),
    Approval(Target, Option<Duration>),
    Approve(u64),
    Refuse(u64, String),
    Raise(String, Option<serde_json::Value>),
    Terminate(u64),
    Suspend(u64),
    Unsuspend(u64),
}

impl Op {
    /// Whether the op leaves something set that a silent page must not leave behind.
    fn sets(&self) -> bool {
        matches!(
            self,
            Op::Pause | Op::Step | Op::StepToStart | Op::Break(..) | Op::Approval(..)
        )
    }
}

/// The fields a request may carry besides `op` (each op takes some of them).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Request {
    at: Option<String>,
    task: Option<String>,
    path: Option<String>,
    node: Option<u64>,
    exception: Option<String>,
    id: Option<u32>,
    times: Option<u32>,
    message: Option<String>,
    never: Option<bool>,
    timeout_ms: Option<u64>,
    reason: Option<String>,
    event: Option<String>,
    data: Option<serde_json::Value>,
    value: Option<serde_json::Value>,
}

/// Each op and the fields it takes besides `op`.
const OPS: &[(&str, &[&str])] = &[
    ("pause", &[]),
    ("resume", &[]),
    ("step", &[]),
    ("step_to_start", &[]),
    ("heartbeat", &[]),
    ("break", &["at", "task", "path", "node", "exception"]),
    ("remove", &["id"]),
    (
        "inject",
        &[
            "task",
            "path",
            "node",
            "times",
            "exception",
            "message",
            "never",
            "value",
            "data",
        ],
    ),
    ("approval", &["task", "path", "node", "timeout_ms"]),
    ("approve", &["node"]),
    ("refuse", &["node", "reason"]),
    ("raise", &["event", "data"]),
    ("terminate", &["node"]),
    ("suspend", &["node"]),
    ("unsuspend", &["node"]),
];

/// Reads and checks a request's body; the error says what is wrong with it.
fn parse(body: &[u8]) -> Result<Op, String> {
    let value: serde_json::Value =
        serde_json::from_slice(body).map_err(|e| format!("the body is not JSON: {e}"))?;
    let serde_json::Value::Object(fields) = &value else {
        return Err(r#"the body must be a JSON object: {"op": …}"#.to_string());
    };
    let Some(op) = fields.get("op").and_then(serde_json::Value::as_str) else {
        return Err("the body has no `op` (a string)".to_string());
    };
    let names: Vec<&str> = OPS.iter().map(|(name, _)| *name).collect();
    let Some((_, takes)) = OPS.iter().find(|(name, _)| *name == op) else {
        return Err(format!("unknown op `{op}`: one of {}", names.join(", ")));
    };
    if let Some(extra) = fields
        .keys()
        .find(|k| *k != "op" && !takes.contains(&k.as_str()))
    {
        let takes = if takes.is_empty() {
            "nothing else".to_string()
        } else {
            takes.join(", ")
        };
        return Err(format!("`{op}` takes no `{extra}` (it takes {takes})"));
    }
    let mut rest = fields.clone();
    rest.remove("op");
    let r: Request = serde_json::from_value(serde_json::Value::Object(rest))
        .map_err(|e| format!("{op}: {e}"))?;
    let node = |r: &Request| {
        r.node
            .ok_or_else(|| format!("`{op}` needs `node`, a number"))
    };
    Ok(match op {
        "pause" => Op::Pause,
        "resume" => Op::Resume,
        "step" => Op::Step,
        "step_to_start" => Op::StepToStart,
        "heartbeat" => Op::Heartbeat,
        "break" => {
            let at = match r.at.as_deref() {
                Some("start") => BreakAt::Start,
                Some("end") => BreakAt::End,
                Some("raised") => BreakAt::Raised,
                Some("handler") => BreakAt::Handler,
                Some(other) => {
                    return Err(format!(
                        "`at` is `{other}`: one of start, end, raised, handler"
                    ));
                }
                None => return Err("`break` needs `at`: start, end, raised or handler".into()),
            };
            Op::Break(at, target(&r, op, true)?)
        }
        "remove" => Op::Remove(r.id.ok_or("`remove` needs `id`, a rule's number")?),
        "inject" => {
            let times = r.times.unwrap_or(1);
            if times == 0 {
                return Err("`times` is 0: a fault for no node".into());
            }
            let outcome = match (&r.exception, r.never) {
                _ if r.value.is_some() && (r.exception.is_some() || r.never == Some(true)) => {
                    return Err("give one of `exception`, `value` and `never: true`".into());
                }
                (None, None | Some(false)) if r.value.is_some() => {
                    let value = r.value.clone().unwrap_or_default();
                    FaultOutcome::Succeed(Some(tcm::json_value(value)))
                }
                (Some(e), None | Some(false)) if !e.is_empty() => {
                    let message = r.message.clone().unwrap_or_else(|| "injected".into());
                    let mut failure = Failure::new(e.clone(), message);
                    failure.data = r.data.clone().map(|d| Arc::new(d) as _);
                    FaultOutcome::Fail(failure)
                }
                (None, Some(true)) => FaultOutcome::Never,
                (Some(_), Some(true)) => {
                    return Err("give `exception` or `never: true`, not both".into());
                }
                (Some(_), _) => return Err("`exception` is empty".into()),
                (None, _) => {
                    return Err(
                        "`inject` needs `exception` (and `message`), `value` or `never: true`"
                            .into(),
                    );
                }
            };
            Op::Inject(target(&r, op, false)?, times, outcome)
        }
        "approval" => Op::Approval(
            target(&r, op, false)?,
            r.timeout_ms.map(Duration::from_millis),
        ),
        "approve" => Op::Approve(node(&r)?),
        "refuse" => Op::Refuse(
            node(&r)?,
            r.reason
                .filter(|s| !s.is_empty())
                .unwrap_or_else(|| "refused from the viewer".into()),
        ),
        "raise" => match r.event {
            Some(e) if !e.is_empty() => Op::Raise(e, r.data),
            _ => return Err("`raise` needs `event`, the external event's name".into()),
        },
        "terminate" => Op::Terminate(node(&r)?),
        "suspend" => Op::Suspend(node(&r)?),
        "unsuspend" => Op::Unsuspend(node(&r)?),
        _ => return Err(format!("unknown op `{op}`")),
    })
}

/// The one target among `task`, `path`, `node` (and `exception` for a breakpoint).
fn target(r: &Request, op: &str, exceptions: bool) -> Result<Target, String> {
    let mut given = Vec::new();
    if let Some(t) = &r.task {
        given.push(("task", Target::Task(t.clone()), t.is_empty()));
    }
    if let Some(p) = &r.path {
        given.push(("path", Target::Path(p.clone()), p.is_empty()));
    }
    if let Some(n) = r.node {
        given.push(("node", Target::Node(n), false));
    }
    if exceptions {
        if let Some(e) = &r.exception {
            given.push(("exception", Target::Exception(e.clone()), e.is_empty()));
        }
    }
    let names = if exceptions {
        "`task`, `path`, `node` or `exception`"
    } else {
        "`task`, `path` or `node`"
    };
    if given.len() > 1 {
        return Err(format!("`{op}` takes one of {names}, not several"));
    }
    match given.pop() {
        None => Err(format!("`{op}` needs one of {names}")),
        Some((name, _, true)) => Err(format!("`{name}` is empty")),
        Some((_, t, false)) => Ok(t),
    }
}

/// What a request did: the rule it made, whether it changed anything.
#[derive(Default)]
struct Done {
    id: Option<SteerId>,
    changed: Option<bool>,
}

/// A request the run refused, with its status and why.
struct Refusal(StatusCode, String);

impl From<tcm::Error> for Refusal {
    fn from(e: tcm::Error) -> Refusal {
        match e {
            tcm::Error::RunEnded => Refusal(StatusCode::CONFLICT, "the run ended".into()),
            e => Refusal(StatusCode::CONFLICT, e.to_string()),
        }
    }
}

/// The live node numbered `n` (the trace's display number).
fn node(control: &Control, n: u64) -> Result<tcm::NodeId, Refusal> {
    control.node_by_number(n)?.ok_or_else(|| {
        Refusal(
            StatusCode::NOT_FOUND,
            format!("no live node {n} in this run"),
        )
    })
}

fn matcher(control: &Control, target: Target) -> Result<Matcher, Refusal> {
    Ok(match target {
        Target::Task(t) => Matcher::Task(t.into()),
        Target::Path(p) => Matcher::Path(p),
        Target::Node(n) => Matcher::Node(node(control, n)?),
        Target::Exception(e) => Matcher::Exception(e.into()),
    })
}

/// Carries out `op` as `by` asked.
fn act(control: &Control, op: Op, by: &str) -> Result<Done, Refusal> {
    let changed = |c: bool| Done {
        id: None,
        changed: Some(c),
    };
    let made = |id: SteerId| Done {
        id: Some(id),
        changed: None,
    };
    let held = |e: tcm::Error, n: u64| match e {
        tcm::Error::Engine(EngineError::NotHeld(_)) => Refusal(
            StatusCode::CONFLICT,
            format!("node {n} is not held for approval"),
        ),
        e => e.into(),
    };
    Ok(match op {
        Op::Heartbeat => {
            // The run must still be there for the page to go on steering it.
            control.is_paused()?;
            Done::default()
        }
        Op::Pause => changed(control.pause(by)?),
        Op::Resume => changed(control.resume(by)?),
        Op::Step => changed(control.step(by)?),
        Op::StepToStart => changed(control.step_to_start(by)?),
        Op::Break(at, target) => {
            let on = matcher(control, target)?;
            made(control.add_breakpoint(Breakpoint { at, on }, by)?)
        }
        Op::Remove(id) => changed(control.remove(SteerId(id), by)?),
        Op::Inject(target, times, outcome) => {
            let on = matcher(control, target)?;
            made(control.inject(Fault { on, times, outcome }, by)?)
        }
        Op::Approval(target, timeout) => {
            let on = matcher(control, target)?;
            made(control.require_approval(Approval { on, timeout }, by)?)
        }
        Op::Approve(n) => {
            let id = node(control, n)?;
            control.approve(id, by).map_err(|e| held(e, n))?;
            Done::default()
        }
        Op::Refuse(n, reason) => {
            let id = node(control, n)?;
            control.refuse(id, by, &reason).map_err(|e| held(e, n))?;
            Done::default()
        }
        Op::Raise(event, None) => {
            control.note_input(&format!("raise {event}"), by)?;
            control.raise(&event)?;
            Done::default()
        }
        Op::Raise(event, Some(data)) => {
            control.note_input(&format!("raise {event} with {data}"), by)?;
            control.raise_with(&event, data)?;
            Done::default()
        }
        Op::Terminate(n) => {
            let id = node(control, n)?;
            control.terminate_as(id, by)?;
            Done::default()
        }
        Op::Suspend(n) => {
            let id = node(control, n)?;
            control.suspend(id, by)?;
            Done::default()
        }
        Op::Unsuspend(n) => {
            let id = node(control, n)?;
            control.unsuspend(id, by)?;
            Done::default()
        }
    })
}

/// Releases each steered run whose page went silent (see the module's documentation); runs on
/// the viewer's runtime as long as the server does.
pub(super) async fn watchdog(shared: Arc<Shared>) {
    let mut tick = tokio::time::interval(WATCH_EVERY);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    // The viewer's one endless loop besides the server's: it ends with the runtime.
    loop {
        tick.tick().await;
        let after = Duration::from_millis(shared.release_after_ms.load(Ordering::Relaxed));
        let runs = shared
            .runs
            .read()
            .unwrap_or_else(|e| e.into_inner())
            .clone();
        for run in runs {
            release_if_silent(&run, after);
        }
    }
}

fn release_if_silent(run: &Run, after: Duration) {
    let (control, set) = {
        let steer = run.steering();
        let Some(s) = steer.as_ref() else {
            return;
        };
        match s.heard {
            Some(heard) if !s.released && heard.elapsed() >= after => {}
            _ => return,
        }
        (s.control.clone(), s.set)
    };
    let waits =
        control.is_paused().unwrap_or(false) || control.held().is_ok_and(|held| !held.is_empty());
    if !(set || waits) {
        return;
    }
    let why = format!(
        "viewer: no controlling page heard for {} s",
        after.as_secs_f64()
    );
    // A run that ended needs no release.
    let _ = control.release(&why);
    if let Some(s) = run.steering().as_mut() {
        s.released = true;
        s.set = false;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn headers(pairs: &[(&'static str, &'static str)]) -> HeaderMap {
        let mut h = HeaderMap::new();
        for (k, v) in pairs {
            h.insert(*k, v.parse().expect("a header value"));
        }
        h
    }

    #[test]
    fn only_a_page_of_the_viewers_own_origin_or_none_passes() {
        let own = headers(&[
            ("host", "127.0.0.1:7878"),
            ("origin", "http://127.0.0.1:7878"),
        ]);
        assert!(!foreign_origin(&own));
        assert!(!foreign_origin(&headers(&[("host", "127.0.0.1:7878")])));
        for origin in [
            "http://evil.example",
            "http://127.0.0.1:7879",
            "https://127.0.0.1:7878",
            "null",
        ] {
            let h = headers(&[("host", "127.0.0.1:7878"), ("origin", origin)]);
            assert!(foreign_origin(&h), "{origin}");
        }
        assert!(foreign_origin(&headers(&[(
            "origin",
            "http://127.0.0.1:7878"
        )])));
    }

    #[test]
    fn a_bad_body_says_what_is_wrong() {
        let err = |body: &str| parse(body.as_bytes()).expect_err(body);
        assert!(err("{").contains("not JSON"));
        assert!(err("[]").contains("JSON object"));
        assert!(err(r#"{"op":"fly"}"#).contains("unknown op `fly`"));
        assert!(err(r#"{"op":"pause","node":3}"#).contains("`pause` takes no `node`"));
        assert!(err(r#"{"op":"break","task":"a"}"#).contains("needs `at`"));
        assert!(err(r#"{"op":"break","at":"soon","task":"a"}"#).contains("`at` is `soon`"));
        assert!(err(r#"{"op":"break","at":"start"}"#).contains("needs one of"));
        assert!(err(r#"{"op":"break","at":"start","task":"a","node":1}"#).contains("not several"));
        assert!(err(r#"{"op":"inject","task":"a"}"#).contains("needs `exception`"));
        assert!(
            err(r#"{"op":"inject","task":"a","exception":"E","never":true}"#).contains("not both")
        );
        assert!(err(r#"{"op":"inject","task":"a","never":true,"times":0}"#).contains("times"));
        assert!(err(r#"{"op":"approve"}"#).contains("needs `node`"));
        assert!(err(r#"{"op":"approve","node":"x"}"#).contains("invalid type"));
        assert!(err(r#"{"op":"raise"}"#).contains("needs `event`"));
        assert!(matches!(
            parse(br#"{"op":"inject","path":"**/guarded*","exception":"Blocked"}"#),
            Ok(Op::Inject(Target::Path(_), 1, FaultOutcome::Fail(_)))
        ));
        assert!(matches!(
            parse(br#"{"op":"break","at":"raised","exception":"Blocked"}"#),
            Ok(Op::Break(BreakAt::Raised, Target::Exception(_)))
        ));
    }

    #[test]
    fn tokens_are_fresh_and_compared_whole() {
        let (a, b) = (token().expect("a token"), token().expect("a token"));
        assert_eq!(a.len(), 32);
        assert_ne!(a, b);
        assert!(same(&a, &a.clone()));
        assert!(!same(&a, &b));
        assert!(!same(&a, &a[..31]));
    }
}
