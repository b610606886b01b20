//! Steering a live run through the viewer (docs/viewer.md, "Steering a run"), over real HTTP and
//! WebSocket connections on loopback, with a real `Session` on the real clock, every trace through
//! the checker: a request without the run's token, with a wrong one, from a page of another
//! origin, or for a run without control is refused and changes nothing (the run is not paused,
//! its trace has no `control` record); a WebSocket upgrade from another origin is refused; with
//! the token, a program (no `Origin`) and a page of the viewer's own origin steer the run, each
//! request a `control` record naming the client, bad bodies and unknown nodes refused with what
//! is wrong; and a page that goes silent while the run is paused at a breakpoint has the run
//! released within about a second of the limit, once, and not before a page was heard at all.

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::{Duration, Instant};

use futures_util::StreamExt;
use tcm::testing::assert_checked;
use tcm::{Control, Recorder, Runtime, Session, Task, TraceEvent, TraceKind, WatchOutcome};
use tcm_view::Viewer;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio_tungstenite::tungstenite::Message;
use tokio_tungstenite::tungstenite::client::IntoClientRequest;

/// Longer than anything here should take: a test that does not end fails instead of hanging.
const LIMIT: Duration = Duration::from_secs(20);

/// A live run of `viewer` driven by a session: the session, its recorder and its run number.
fn start(viewer: &Viewer, name: &str) -> (Session, Recorder, usize) {
    let rec = Recorder::new();
    let live = viewer.live(name);
    let id = live.id();
    let session = Runtime::new()
        .with_sink(rec.clone())
        .with_sink(live)
        .start()
        .expect("inside a tokio runtime");
    (session, rec, id)
}

/// A command that runs until `gate` is notified.
fn held_open(gate: &Arc<tokio::sync::Notify>) -> Task {
    let gate = gate.clone();
    Task::command("hold", move |_| {
        let gate = gate.clone();
        async move {
            gate.notified().await;
            Ok(())
        }
    })
}

fn quick(name: &'static str) -> Task {
    Task::command(name, |_| async {
        tokio::time::sleep(Duration::from_millis(50)).await;
        Ok(())
    })
}

/// A response: status and body.
#[derive(Debug)]
struct Answer {
    status: u16,
    body: String,
}

impl Answer {
    fn json(&self) -> serde_json::Value {
        serde_json::from_str(&self.body).unwrap_or_else(|e| panic!("{e}: {}", self.body))
    }
}

/// `POST /api/runs/{run}/control` with `body` and `headers`, as a plain HTTP/1.1 client.
async fn post(addr: SocketAddr, run: usize, headers: &[(&str, &str)], body: &str) -> Answer {
    let mut req = format!(
        "POST /api/runs/{run}/control HTTP/1.1\r\nHost: {addr}\r\nContent-Type: application/json\r\n\
         Content-Length: {}\r\nConnection: close\r\n",
        body.len()
    );
    for (k, v) in headers {
        req.push_str(&format!("{k}: {v}\r\n"));
    }
    req.push_str("\r\n");
    req.push_str(body);
    let exchange = async {
        let mut s = tokio::net::TcpStream::connect(addr).await?;
        s.write_all(req.as_bytes()).await?;
        let mut out = Vec::new();
        s.read_to_end(&mut out).await?;
        Ok::<_, std::io::Error>(out)
    };
    let out = tokio::time::timeout(LIMIT, exchange)
        .await
        .expect("an answer in time")
        .expect("an HTTP exchange");
    let text = String::from_utf8_lossy(&out);
    let (head, body) = text.split_once("\r\n\r\n").expect("a head and a body");
    let status = head
        .split_whitespace()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .expect("a status");
    Answer {
        status,
        body: body.to_string(),
    }
}

fn controls(trace: &[TraceEvent]) -> Vec<(String, String)> {
    trace
        .iter()
        .filter_map(|e| match &e.kind {
            TraceKind::Control { what, by } => Some((what.clone(), by.clone())),
            _ => None,
        })
        .collect()
}

/// The display number of the node named `name` in `trace`.
fn number(trace: &[TraceEvent], name: &str) -> u64 {
    trace
        .iter()
        .find_map(|e| match &e.kind {
            TraceKind::Spawned { node, name: n, .. } if n == name => Some(*node),
            _ => None,
        })
        .unwrap_or_else(|| panic!("no node {name}"))
}

/// Reads the live socket until a message satisfies `want`.
async fn read_until(
    ws: &mut tokio_tungstenite::WebSocketStream<
        tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>,
    >,
    want: impl Fn(&serde_json::Value) -> bool,
) -> serde_json::Value {
    let read = async {
        loop {
            let msg = ws
                .next()
                .await
                .expect("the socket is open")
                .expect("a message");
            if let Message::Text(t) = msg {
                let v: serde_json::Value = serde_json::from_str(&t).expect("JSON");
                if want(&v) {
                    return v;
                }
            }
        }
    };
    tokio::time::timeout(LIMIT, read).await.expect("in time")
}

fn not_paused(control: &Control) {
    assert!(!control.is_paused().expect("the run is on"), "paused");
}

#[tokio::test(flavor = "current_thread")]
async fn only_the_token_and_the_viewers_own_origin_steer_a_run() {
    let viewer = Viewer::serve(([127, 0, 0, 1], 0).into()).expect("serve on loopback");
    // Nothing is released while this test runs, however slow the machine.
    viewer.release_after(Duration::from_secs(600));
    let addr = viewer.addr();
    let (session, rec, id) = start(&viewer, "steered");
    let plain = viewer.live("without control").id();
    let control = session.control();
    let token = viewer.steer(id, control.clone()).expect("a run to steer");
    assert_eq!(token.len(), 32);
    assert_eq!(
        viewer.control_url(id),
        Some(format!("http://{addr}/?run={id}&token={token}"))
    );
    assert_eq!(viewer.control_url(plain), None);
    let gate = Arc::new(tokio::sync::Notify::new());
    session.spawn(held_open(&gate)).expect("spawn");
    tokio::time::sleep(Duration::from_millis(100)).await;

    let pause = r#"{"op":"pause"}"#;
    let own = format!("http://{addr}");
    let refused = [
        (vec![], "token"),
        (
            vec![("x-tdl-token", "0123456789abcdef0123456789abcdef")],
            "token",
        ),
        (vec![("x-tdl-token", &token[..31])], "token"),
        (
            vec![
                ("x-tdl-token", token.as_str()),
                ("Origin", "http://evil.example"),
            ],
            "another origin",
        ),
        (
            vec![
                ("x-tdl-token", token.as_str()),
                ("Origin", "http://127.0.0.1:1"),
            ],
            "another origin",
        ),
        (
            vec![("x-tdl-token", token.as_str()), ("Origin", "null")],
            "another origin",
        ),
    ];
    for (headers, why) in &refused {
        let a = post(addr, id, headers, pause).await;
        assert_eq!(a.status, 403, "{headers:?}: {a:?}");
        assert!(a.body.contains(why), "{headers:?}: {a:?}");
    }
    let a = post(addr, plain, &[("x-tdl-token", &token)], pause).await;
    assert_eq!(
        (a.status, a.body.as_str()),
        (403, "control is off for this run")
    );
    // A refused request is not heard: a bad body without the token is refused for the token.
    let a = post(addr, id, &[], "{").await;
    assert_eq!(a.status, 403, "{a:?}");

    // A page of another site may not even watch.
    let live = format!("ws://{addr}/api/runs/{id}/live");
    let mut foreign = live.as_str().into_client_request().expect("a request");
    foreign
        .headers_mut()
        .insert("origin", "http://evil.example".parse().expect("a header"));
    match tokio_tungstenite::connect_async(foreign).await {
        Err(tokio_tungstenite::tungstenite::Error::Http(r)) => assert_eq!(r.status(), 403),
        other => panic!("a foreign page's WebSocket: {:?}", other.map(|_| ())),
    }
    // The viewer's own page may, and learns the run can be steered.
    let mut request = live.as_str().into_client_request().expect("a request");
    request
        .headers_mut()
        .insert("origin", own.parse().expect("a header"));
    let (mut ws, _) = tokio_tungstenite::connect_async(request)
        .await
        .expect("the viewer's own page watches");
    let snapshot = read_until(&mut ws, |m| m["type"] == "snapshot").await;
    assert_eq!(
        (&snapshot["control"], &snapshot["paused"], &snapshot["held"]),
        (
            &true.into(),
            &serde_json::Value::Null,
            &serde_json::json!([])
        )
    );

    // Nothing changed so far.
    tokio::time::sleep(Duration::from_millis(200)).await;
    not_paused(&control);
    assert_eq!(controls(&rec.events()), []);

    // With the token: a program (no Origin) pauses, the page's own origin sets a breakpoint.
    let a = post(addr, id, &[("x-tdl-token", &token)], pause).await;
    assert_eq!(a.status, 200, "{a:?}");
    assert_eq!(
        a.json(),
        serde_json::json!({"ok": true, "paused": true, "changed": true})
    );
    assert!(control.is_paused().expect("the run is on"));
    let paused = read_until(&mut ws, |m| m["type"] == "record" && !m["paused"].is_null()).await;
    assert!(
        paused["paused"]
            .as_str()
            .is_some_and(|why| why.starts_with("asked by viewer 127.0.0.1:")),
        "{paused}"
    );
    let with_origin = [("x-tdl-token", token.as_str()), ("Origin", own.as_str())];
    let a = post(
        addr,
        id,
        &with_origin,
        r#"{"op":"break","at":"start","task":"later"}"#,
    )
    .await;
    assert_eq!((a.status, a.json()["id"].as_u64()), (200, Some(1)), "{a:?}");

    // Bad bodies, unknown nodes and refusals say what is wrong.
    let hold = number(&rec.events(), "hold");
    let cases = [
        (r#"{"op":"fly"}"#, 400, "unknown op `fly`"),
        (r#"{"op":"break","at":"start"}"#, 400, "needs one of"),
        (r#"{"op":"pause","task":"x"}"#, 400, "takes no `task`"),
        (r#"{"op":"approve","node":999}"#, 404, "no live node 999"),
        (r#"{"op":"remove","id":7}"#, 200, r#""changed":false"#),
    ];
    for (body, status, says) in cases {
        let a = post(addr, id, &with_origin, body).await;
        assert_eq!(a.status, status, "{body}: {a:?}");
        assert!(a.body.contains(says), "{body}: {a:?}");
    }
    let approve = format!(r#"{{"op":"approve","node":{hold}}}"#);
    let a = post(addr, id, &with_origin, &approve).await;
    assert_eq!(a.status, 409, "{a:?}");
    assert!(a.body.contains("not held"), "{a:?}");

    let a = post(addr, id, &with_origin, r#"{"op":"resume"}"#).await;
    assert_eq!(a.json()["paused"], false, "{a:?}");
    not_paused(&control);
    let raise = r#"{"op":"raise","event":"bump","data":{"side":"left"}}"#;
    let a = post(addr, id, &with_origin, raise).await;
    assert_eq!(a.status, 200, "{a:?}");

    gate.notify_one();
    session.finish().await.expect("finish");
    let trace = rec.events();
    assert_checked(&trace);
    let done = controls(&trace);
    let whats: Vec<&str> = done.iter().map(|(w, _)| w.as_str()).collect();
    assert_eq!(
        whats,
        [
            "pause",
            "breakpoint before the start of task later (#1)",
            "continue",
            r#"raise bump with {"side":"left"}"#
        ]
    );
    assert!(
        done.iter()
            .all(|(_, by)| by.starts_with("viewer 127.0.0.1:")),
        "{done:?}"
    );
    viewer.stop();
}

#[tokio::test(flavor = "current_thread")]
async fn a_run_whose_page_went_silent_is_released_once() {
    let viewer = Viewer::serve(([127, 0, 0, 1], 0).into()).expect("serve on loopback");
    viewer.release_after(Duration::from_millis(500));
    let addr = viewer.addr();
    let (session, rec, id) = start(&viewer, "steered");
    let control = session.control();
    let token = viewer.steer(id, control.clone()).expect("a run to steer");
    let auth = [("x-tdl-token", token.as_str())];

    // Paused by the program itself, with no page heard yet: nothing to release.
    control.pause("the program").expect("pause");
    tokio::time::sleep(Duration::from_millis(1200)).await;
    assert!(
        control.is_paused().expect("the run is on"),
        "released before any page"
    );

    // A page sets a breakpoint on `work`, which waits for the run's pause, and keeps beating.
    let a = post(
        addr,
        id,
        &auth,
        r#"{"op":"break","at":"start","task":"work"}"#,
    )
    .await;
    assert_eq!(a.status, 200, "{a:?}");
    let work = session.spawn(quick("work")).expect("spawn");
    for _ in 0..6 {
        tokio::time::sleep(Duration::from_millis(200)).await;
        let a = post(addr, id, &auth, r#"{"op":"heartbeat"}"#).await;
        assert_eq!(a.json(), serde_json::json!({"ok": true, "paused": true}));
    }
    assert!(
        control.is_paused().expect("the run is on"),
        "released while heard"
    );

    // Silence: released within about a second, the breakpoint gone with the pause.
    let silent = Instant::now();
    while control.is_paused().expect("the run is on") {
        assert!(silent.elapsed() < Duration::from_secs(5), "never released");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let after = silent.elapsed();
    assert!(
        after >= Duration::from_millis(450) && after < Duration::from_secs(3),
        "released after {after:?}"
    );
    let ended = tokio::time::timeout(LIMIT, control.wait(work)).await;
    assert!(matches!(ended, Ok(Ok(WatchOutcome::Reached))), "{ended:?}");
    // Once per silence.
    tokio::time::sleep(Duration::from_millis(1200)).await;
    session.finish().await.expect("finish");
    let trace = rec.events();
    assert_checked(&trace);
    let by = "viewer: no controlling page heard for 0.5 s";
    let released: Vec<_> = controls(&trace)
        .into_iter()
        .filter(|(_, b)| b == by)
        .map(|(what, _)| what)
        .collect();
    assert_eq!(released, ["release breakpoints and holds", "continue"]);
    let pauses = trace
        .iter()
        .filter(|e| matches!(e.kind, TraceKind::Paused { .. }))
        .count();
    assert_eq!(
        pauses, 1,
        "the breakpoint was released before `work` started"
    );
    viewer.stop();
}
