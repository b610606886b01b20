//! The web server: one page (HTML, CSS, JavaScript compiled into the binary) and a small JSON API
//! over the runs it holds, trace files read whole or runs fed live by a [`LiveSink`]. It runs on
//! its own thread and tokio runtime, so a program on virtual time, or one that blocks, never
//! slows it, and it never slows the program: a live run's records go to each page through a
//! bounded channel, and a page that falls behind is sent a fresh snapshot. Read-only, but for
//! a run given a control handle ([`Viewer::steer`]), which a page holding the run's token can
//! steer (`server/control.rs`).
//! The API and the page's messages are in `docs/viewer.md`: a live page gets a snapshot of the
//! fold's rows, then each record with the rows it changed as the fold has them after it
//! ([`record_json`]), so the page folds nothing itself.

mod control;

use std::net::{SocketAddr, TcpListener};
use std::sync::{Arc, Mutex, MutexGuard, RwLock};

use axum::Router;
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::{Path, Query, State};
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use serde::Deserialize;
use tcm_trace::TraceEvent;
use tokio::sync::{broadcast, oneshot};

use crate::model::{EventFilter, MARKS, Row, RunModel};

/// Records a page may fall behind by before it is sent a fresh snapshot instead.
const LAG: usize = 4096;

/// What can go wrong starting the viewer.
#[derive(Debug, thiserror::Error)]
pub enum ViewError {
    /// The address could not be bound.
    #[error("cannot listen on {addr}: {source}")]
    Bind {
        /// The address asked for.
        addr: SocketAddr,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The server's thread or runtime could not start.
    #[error("cannot start the viewer's server: {0}")]
    Start(#[source] std::io::Error),
    /// [`Viewer::steer`] was given a number that is no run of this viewer.
    #[error("the viewer has no run {0}")]
    NoRun(usize),
    /// The operating system gave no random bytes for a run's token.
    #[error("cannot make a token: the operating system gave no random bytes: {0}")]
    Random(String),
}

pub(crate) struct Run {
    model: Mutex<RunModel>,
    tx: broadcast::Sender<Arc<str>>,
    /// Its control, once a page may steer it (`control.rs`).
    steer: Mutex<Option<control::Steer>>,
}

impl Run {
    fn new(model: RunModel) -> Arc<Run> {
        let (tx, _) = broadcast::channel(LAG);
        Arc::new(Run {
            model: Mutex::new(model),
            tx,
            steer: Mutex::new(None),
        })
    }

    fn lock(&self) -> MutexGuard<'_, RunModel> {
        // A panic while the lock was held leaves a model that is still whole record by record.
        self.model.lock().unwrap_or_else(|e| e.into_inner())
    }
}

pub(crate) struct Shared {
    runs: RwLock<Vec<Arc<Run>>>,
    /// How long a steered run may go without a control request before it is released, in ms.
    release_after_ms: std::sync::atomic::AtomicU64,
}

impl Default for Shared {
    fn default() -> Shared {
        Shared {
            runs: RwLock::default(),
            release_after_ms: control::RELEASE_AFTER_MS.into(),
        }
    }
}

impl Shared {
    fn run(&self, id: usize) -> Option<Arc<Run>> {
        self.runs
            .read()
            .unwrap_or_else(|e| e.into_inner())
            .get(id)
            .cloned()
    }

    fn add(&self, model: RunModel) -> (usize, Arc<Run>) {
        let run = Run::new(model);
        let mut runs = self.runs.write().unwrap_or_else(|e| e.into_inner());
        runs.push(run.clone());
        (runs.len() - 1, run)
    }
}

/// A running viewer. Dropping it stops the server.
pub struct Viewer {
    shared: Arc<Shared>,
    addr: SocketAddr,
    stop: Option<oneshot::Sender<()>>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Viewer {
    /// Serves the viewer on `addr` (port 0: any free port) from a thread of its own.
    pub fn serve(addr: SocketAddr) -> Result<Viewer, ViewError> {
        let listener =
            TcpListener::bind(addr).map_err(|source| ViewError::Bind { addr, source })?;
        let bound = listener.local_addr().map_err(ViewError::Start)?;
        listener.set_nonblocking(true).map_err(ViewError::Start)?;
        let shared = Arc::new(Shared::default());
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .map_err(ViewError::Start)?;
        let (stop, stopped) = oneshot::channel::<()>();
        let app = router(shared.clone());
        let watched = shared.clone();
        let thread = std::thread::Builder::new()
            .name("tcm-view".to_string())
            .spawn(move || {
                runtime.block_on(async move {
                    let Ok(listener) = tokio::net::TcpListener::from_std(listener) else {
                        return;
                    };
                    tokio::spawn(control::watchdog(watched));
                    // The peer's address names who asked for each control request.
                    let app = app.into_make_service_with_connect_info::<SocketAddr>();
                    let _ = axum::serve(listener, app)
                        .with_graceful_shutdown(async move {
                            let _ = stopped.await;
                        })
                        .await;
                });
            })
            .map_err(ViewError::Start)?;
        Ok(Viewer {
            shared,
            addr: bound,
            stop: Some(stop),
            thread: Some(thread),
        })
    }

    /// The address the server listens on.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// The page's address.
    pub fn url(&self) -> String {
        format!("http://{}/", self.addr)
    }

    /// The page's address opening run `run` (its number in the selector, as [`Viewer::add`]
    /// gives it) with the time cursor on its record `seq`: `http://ADDR/?run=RUN&at=SEQ`
    /// (docs/viewer.md, "Opening it").
    pub fn url_at(&self, run: usize, seq: u64) -> String {
        format!("http://{}/?run={run}&at={seq}", self.addr)
    }

    /// Shows a run read whole (a trace file); returns its number in the selector.
    pub fn add(&self, model: RunModel) -> usize {
        self.shared.add(model).0
    }

    /// A run fed as it goes: give the sink to the runtime (`tcm::Runtime::sink`), and every page
    /// shows its records as they come.
    pub fn live(&self, name: impl Into<String>) -> LiveSink {
        let (id, run) = self.shared.add(RunModel::new(name));
        LiveSink { id, run }
    }

    /// Stops the server and waits for its thread.
    pub fn stop(mut self) {
        self.shutdown();
    }

    /// Serves until the process ends.
    pub fn wait(mut self) {
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }

    fn shutdown(&mut self) {
        if let Some(stop) = self.stop.take() {
            let _ = stop.send(());
        }
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

impl Drop for Viewer {
    fn drop(&mut self) {
        self.shutdown();
    }
}

/// Where the viewer listens unless told otherwise.
pub const DEFAULT_ADDR: SocketAddr =
    SocketAddr::new(std::net::IpAddr::V4(std::net::Ipv4Addr::LOCALHOST), 7878);

impl Viewer {
    /// Serves on `listen` if given, else on [`DEFAULT_ADDR`], or on any free loopback port when
    /// that one is taken (a second viewer on the same machine).
    pub fn start(listen: Option<SocketAddr>) -> Result<Viewer, ViewError> {
        match listen {
            Some(addr) => Viewer::serve(addr),
            None => Viewer::serve(DEFAULT_ADDR)
                .or_else(|_| Viewer::serve(SocketAddr::new(DEFAULT_ADDR.ip(), 0))),
        }
    }
}

/// The warning to print before serving on `addr` when other machines may reach it.
pub fn exposure_warning(addr: &SocketAddr) -> Option<String> {
    (!addr.ip().is_loopback()).then(|| {
        format!(
            "warning: the viewer listens on {addr}, which other machines may reach; it has \
             no authentication to watch a run, and a steered run's token goes over plain HTTP"
        )
    })
}

/// A trace sink feeding a live run of a [`Viewer`]. Recording never waits for a page: it appends
/// to the run's model under a short lock and offers the record to a bounded channel.
pub struct LiveSink {
    id: usize,
    run: Arc<Run>,
}

impl LiveSink {
    /// The run's number in the selector (`/api/runs/<id>`).
    pub fn id(&self) -> usize {
        self.id
    }
}

impl tcm::TraceSink for LiveSink {
    fn record(&mut self, ev: &TraceEvent) {
        let line = tcm_trace::to_line(ev).into_boxed_str();
        let mut model = self.run.lock();
        if model.problem.is_some() {
            return;
        }
        match model.apply_line(ev, line) {
            Ok(()) => {
                let message: Arc<str> = Arc::from(record_json(&model));
                drop(model);
                // No page listening is not an error.
                let _ = self.run.tx.send(message);
            }
            Err(message) => {
                let name = model.name.clone();
                model.problem = Some(crate::model::Problem {
                    source: name,
                    line: 0,
                    message: format!("record {}: {message}", ev.seq),
                });
                drop(model);
                let _ = self.run.tx.send(Arc::from(r#"{"type":"resync"}"#));
            }
        }
    }

    fn flush(&mut self) {
        let mut model = self.run.lock();
        if !model.finished {
            model.finished = true;
            drop(model);
            let _ = self.run.tx.send(Arc::from(r#"{"type":"finished"}"#));
        }
    }
}

static INDEX_HTML: &str = include_str!("../page/index.html");
static APP_JS: &str = include_str!("../page/app.js");
static STYLE_CSS: &str = include_str!("../page/style.css");
static STEER_JS: &str = include_str!("../page/steer.js");

fn router(shared: Arc<Shared>) -> Router {
    Router::new()
        .route(
            "/",
            get(|| async { page("text/html; charset=utf-8", INDEX_HTML) }),
        )
        .route(
            "/app.js",
            get(|| async { page("text/javascript; charset=utf-8", APP_JS) }),
        )
        .route(
            "/style.css",
            get(|| async { page("text/css; charset=utf-8", STYLE_CSS) }),
        )
        .route(
            "/steer.js",
            get(|| async { page("text/javascript; charset=utf-8", STEER_JS) }),
        )
        .route("/api/runs", get(runs))
        .route("/api/runs/{id}/snapshot", get(snapshot))
        .route("/api/runs/{id}/live", get(live))
        .route("/api/runs/{id}/node/{n}", get(node))
        .route("/api/runs/{id}/exceptions", get(exceptions))
        .route("/api/runs/{id}/stats", get(stats))
        .route("/api/runs/{id}/events", get(events))
        .route("/api/runs/{id}/trace.jsonl", get(trace))
        .route("/api/runs/{id}/control", post(control::control))
        .with_state(shared)
}

fn page(mime: &'static str, body: &'static str) -> Response {
    ([(header::CONTENT_TYPE, mime)], body).into_response()
}

fn json(body: String) -> Response {
    ([(header::CONTENT_TYPE, "application/json")], body).into_response()
}

fn not_found(what: String) -> Response {
    (StatusCode::NOT_FOUND, what).into_response()
}

fn no_run(id: usize) -> Response {
    not_found(format!("no run {id}"))
}

async fn runs(State(shared): State<Arc<Shared>>) -> Response {
    let runs = shared
        .runs
        .read()
        .unwrap_or_else(|e| e.into_inner())
        .clone();
    let list: Vec<serde_json::Value> = runs
        .iter()
        .enumerate()
        .map(|(id, run)| {
            let m = run.lock();
            serde_json::json!({
                "id": id,
                "name": m.name,
                "records": m.len(),
                "finished": m.finished,
                "problem": m.problem.as_ref().map(ToString::to_string),
            })
        })
        .collect();
    json(serde_json::Value::Array(list).to_string())
}

/// The snapshot message (`docs/viewer.md`, "Snapshot").
pub fn snapshot_json(id: usize, m: &RunModel) -> String {
    use std::fmt::Write as _;
    let mut out = String::with_capacity(64 + 80 * m.rows().len());
    let problem = m.problem.as_ref().map(ToString::to_string);
    let _ = write!(
        out,
        r#"{{"type":"snapshot","run":{id},"name":{},"version":{},"records":{},"last_t":{},"finished":{},"problem":{},"marks":{MARKS},"times":["#,
        serde_json::Value::from(m.name.as_str()),
        m.version.map_or("null".to_string(), |v| v.to_string()),
        m.len(),
        m.last_t(),
        m.finished,
        serde_json::Value::from(problem),
    );
    for (i, (s, t)) in m.times().iter().enumerate() {
        if i > 0 {
            out.push(',');
        }
        let _ = write!(out, "{s},{t}");
    }
    out.push_str(r#"],"states":["#);
    for (i, lane) in m.state_lanes().iter().enumerate() {
        if i > 0 {
            out.push(',');
        }
        let changes: Vec<serde_json::Value> = lane
            .changes
            .iter()
            .flat_map(|(mark, v)| [mark.seq.into(), serde_json::to_value(v).unwrap_or_default()])
            .collect();
        out.push_str(
            &serde_json::json!({"name": lane.name, "ty": lane.ty, "changes": changes}).to_string(),
        );
    }
    out.push_str(r#"],"nodes":["#);
    write_rows(&mut out, m.rows());
    out.push(']');
    write_steering(&mut out, m);
    out.push('}');
    out
}

/// The run's steering state as the fold has it, for the snapshot and each live record: whether
/// a page may steer it, why it is paused (`null` if it is not), the nodes held for approval.
fn write_steering(out: &mut String, m: &RunModel) {
    use std::fmt::Write as _;
    let replay = m.replay();
    let paused = serde_json::Value::from(replay.paused());
    let held: Vec<String> = replay.held().map(|n| n.to_string()).collect();
    let _ = write!(
        out,
        r#","control":{},"paused":{paused},"held":[{}]"#,
        m.control,
        held.join(",")
    );
}

/// The live message of the last record applied to `m` (`docs/viewer.md`, "Live messages"): the
/// record as its trace line, and the rows it changed, as the fold has them after it
/// ([`tcm_trace::Replay::changed_rows`]), in the snapshot's format; and the state variable it
/// declared or changed, if it did, with its value after it.
pub fn record_json(m: &RunModel) -> String {
    let record = m.len().checked_sub(1).and_then(|seq| m.line(seq));
    let changed = m.changed_rows();
    let mut out = String::with_capacity(64 + record.map_or(0, str::len) + 80 * changed.len());
    out.push_str(r#"{"type":"record","record":"#);
    out.push_str(record.unwrap_or("null"));
    out.push_str(r#","rows":["#);
    write_rows(
        &mut out,
        changed.iter().filter_map(|&n| m.rows().get(n as usize)),
    );
    out.push(']');
    if let Some(lane) = m.state_changed() {
        let value = lane.changes.last().map(|(_, v)| v);
        let state = serde_json::json!({"name": lane.name, "ty": lane.ty, "value": value});
        out.push_str(r#","state":"#);
        out.push_str(&state.to_string());
    }
    write_steering(&mut out, m);
    out.push('}');
    out
}

/// Rows as the snapshot writes them, separated by commas: `[number, parent, kind, name, m0 …
/// m15]`, then the agent for a node placed on one (`null` for none, when a monitor follows), then
/// for an activation its monitor's number. A number no record allocated is left out.
fn write_rows<'a>(out: &mut String, rows: impl IntoIterator<Item = &'a Row>) {
    use std::fmt::Write as _;
    let mut first = true;
    for r in rows {
        if r.number != 0 && r.parent.is_none() {
            continue;
        }
        if !first {
            out.push(',');
        }
        first = false;
        let kind = r.kind.map_or("reserved", crate::model::kind_str);
        let _ = write!(
            out,
            "[{},{},\"{}\",{}",
            r.number,
            r.parent.map_or(-1, |p| p as i64),
            kind,
            serde_json::Value::from(r.name.as_str())
        );
        for m in 0..MARKS {
            match r.marks[m] {
                Some(mark) => {
                    let _ = write!(out, ",{}", mark.seq);
                }
                None => out.push_str(",-1"),
            }
        }
        match (&r.agent, r.activation_of) {
            (Some(agent), _) => {
                let _ = write!(out, ",{}", serde_json::Value::from(agent.as_str()));
            }
            (None, Some(_)) => out.push_str(",null"),
            (None, None) => {}
        }
        if let Some(monitor) = r.activation_of {
            let _ = write!(out, ",{monitor}");
        }
        out.push(']');
    }
}

async fn snapshot(State(shared): State<Arc<Shared>>, Path(id): Path<usize>) -> Response {
    match shared.run(id) {
        Some(run) => json(snapshot_json(id, &run.lock())),
        None => no_run(id),
    }
}

async fn live(
    ws: WebSocketUpgrade,
    State(shared): State<Arc<Shared>>,
    Path(id): Path<usize>,
    headers: HeaderMap,
) -> Response {
    // A page of another site may not read a run (a browser lets any page open a WebSocket).
    if control::foreign_origin(&headers) {
        return control::forbidden("a page of another origin may not watch a run");
    }
    match shared.run(id) {
        Some(run) => ws.on_upgrade(move |socket| live_socket(socket, id, run)),
        None => no_run(id),
    }
}

async fn live_socket(mut socket: WebSocket, id: usize, run: Arc<Run>) {
    loop {
        // Subscribing under the model's lock: no record falls between the snapshot and the
        // first record's message.
        let (snapshot, mut rx) = {
            let model = run.lock();
            (snapshot_json(id, &model), run.tx.subscribe())
        };
        if socket.send(Message::Text(snapshot.into())).await.is_err() {
            return;
        }
        loop {
            tokio::select! {
                msg = rx.recv() => match msg {
                    Ok(line) if &*line == r#"{"type":"resync"}"# => break,
                    Ok(line) => {
                        if socket.send(Message::Text((&*line).into())).await.is_err() {
                            return;
                        }
                    }
                    // Fell behind: start again from a snapshot.
                    Err(broadcast::error::RecvError::Lagged(_)) => break,
                    Err(broadcast::error::RecvError::Closed) => return,
                },
                incoming = socket.recv() => match incoming {
                    None | Some(Err(_)) | Some(Ok(Message::Close(_))) => return,
                    Some(Ok(_)) => {}
                },
            }
        }
    }
}

#[derive(Deserialize)]
struct At {
    at: Option<u64>,
}

async fn node(
    State(shared): State<Arc<Shared>>,
    Path((id, n)): Path<(usize, u64)>,
    Query(q): Query<At>,
) -> Response {
    let Some(run) = shared.run(id) else {
        return no_run(id);
    };
    let model = run.lock();
    let at = q.at.unwrap_or(u64::MAX);
    match model.node_view(n, at) {
        Some(v) => json(serde_json::to_string(&v).unwrap_or_default()),
        None => not_found(format!("no node {n} in run {id}")),
    }
}

async fn exceptions(State(shared): State<Arc<Shared>>, Path(id): Path<usize>) -> Response {
    match shared.run(id) {
        Some(run) => json(serde_json::to_string(&run.lock().stories()).unwrap_or_default()),
        None => no_run(id),
    }
}

async fn stats(State(shared): State<Arc<Shared>>, Path(id): Path<usize>) -> Response {
    match shared.run(id) {
        Some(run) => json(serde_json::to_string(&run.lock().stats()).unwrap_or_default()),
        None => no_run(id),
    }
}

/// Query strings carry numbers as text, which `serde(flatten)` cannot read: the fields are listed.
#[derive(Deserialize)]
struct EventQuery {
    name: Option<String>,
    from: Option<u64>,
    to: Option<u64>,
    node: Option<u64>,
    offset: Option<usize>,
    limit: Option<usize>,
}

async fn events(
    State(shared): State<Arc<Shared>>,
    Path(id): Path<usize>,
    Query(q): Query<EventQuery>,
) -> Response {
    let Some(run) = shared.run(id) else {
        return no_run(id);
    };
    let model = run.lock();
    let offset = q.offset.unwrap_or(0);
    let limit = q.limit.unwrap_or(200).min(5000);
    let filter = EventFilter {
        name: q.name.filter(|n| !n.is_empty()),
        from: q.from,
        to: q.to,
        node: q.node,
    };
    let (total, lines) = model.events(&filter, offset, limit);
    let mut out = format!(r#"{{"total":{total},"offset":{offset},"records":["#);
    for (i, l) in lines.iter().enumerate() {
        if i > 0 {
            out.push(',');
        }
        out.push_str(l);
    }
    out.push_str("]}");
    json(out)
}

async fn trace(State(shared): State<Arc<Shared>>, Path(id): Path<usize>) -> Response {
    let Some(run) = shared.run(id) else {
        return no_run(id);
    };
    let model = run.lock();
    let mut out = String::new();
    for seq in 0..model.len() {
        if let Some(l) = model.line(seq) {
            out.push_str(l);
            out.push('\n');
        }
    }
    ([(header::CONTENT_TYPE, "application/x-ndjson")], out).into_response()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_an_address_beyond_loopback_is_warned_about() {
        let warn = |a: &str| exposure_warning(&a.parse().expect("an address"));
        assert_eq!(warn("127.0.0.1:7878"), None);
        assert_eq!(warn("[::1]:7878"), None);
        let w = warn("0.0.0.0:7878").expect("a warning");
        assert!(
            w.contains("0.0.0.0:7878") && w.contains("no authentication"),
            "{w}"
        );
        assert!(warn("192.168.1.5:80").is_some());
    }
}
