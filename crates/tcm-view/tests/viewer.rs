//! The viewer's model and server on real runs (tcm on tokio's paused clock, every trace through
//! the checker): why a node waits and when it stops waiting, an exception's story, counts and
//! durations, the event filter, bad files named by line with what came before kept, a node's
//! details at the cursor (a monitor's activations and triggers, children, agent, log lines); state variables
//! (each one's changes and value at a cursor, a wait on a condition with the values that hold it,
//! what a skip, an invariant and a pause say at a cursor, skipped nodes counted apart); and the
//! server: the snapshot, each live record with the rows it changed over a WebSocket (the rows a
//! page builds from them being the snapshot's), and a page that falls behind being sent a fresh
//! snapshot instead of slowing the run.

mod common;

use common::secs;

use std::collections::BTreeMap;
use std::time::Duration;

use futures_util::StreamExt;
use tcm::testing::run_checked;
use tcm::{Facet, Runtime, Task, TraceSink};
use tcm_trace::{TraceEvent, TraceKind};
use tcm_view::{EventFilter, RunModel, Viewer, m_point};
use tokio_tungstenite::tungstenite::Message;

async fn mission() -> Vec<TraceEvent> {
    common::mission(false).await
}

fn model_of(trace: &[TraceEvent]) -> RunModel {
    let mut m = RunModel::new("mission");
    for ev in trace {
        m.apply(ev).expect("a checked trace applies");
    }
    m
}

fn number(m: &RunModel, name: &str) -> u64 {
    m.rows()
        .iter()
        .find(|r| r.name == name)
        .map(|r| r.number)
        .unwrap_or_else(|| panic!("no node {name}"))
}

#[tokio::test(start_paused = true)]
async fn a_serial_node_waits_on_the_previous_execution_until_it_completes() {
    let trace = mission().await;
    let m = model_of(&trace);
    let (drive, park) = (number(&m, "drive"), number(&m, "park"));
    let drive_done = m.rows()[drive as usize].marks
        [m_point(Facet::Execution, tcm::Point::Completed)]
    .expect("drive completed");
    assert_eq!(drive_done.t, 5_000_000_000);

    // At 3 s, park waits for drive's execution to complete, since it was spawned at 0.
    let v = m.node_view(park, m.seq_at(3_000_000_000)).expect("park");
    assert_eq!(v.states, ["disabled", "completed", "disabled"]);
    let execution: Vec<_> = v.waits.iter().filter(|w| w.facet == "execution").collect();
    assert_eq!(execution.len(), 1, "{:?}", v.waits);
    let event = execution[0].event.as_ref().expect("an event");
    assert_eq!(
        (event.node, event.facet, event.point),
        (drive, "execution", "completed")
    );
    assert_eq!(event.path, "mission/drive");
    assert!(
        execution[0].what.contains("drive {"),
        "{}",
        execution[0].what
    );
    assert_eq!(execution[0].since, 0);
    // Its handling waits for its own execution (the structural coupling of a command).
    assert!(
        v.waits
            .iter()
            .any(|w| w.facet == "handling" && w.what.contains("its own execution"))
    );

    // Once drive completed, nothing holds park's execution.
    let v = m.node_view(park, drive_done.seq).expect("park");
    assert!(
        !v.waits.iter().any(|w| w.facet == "execution"),
        "{:?}",
        v.waits
    );
    // At the end it ran for 1 s, and waits for nothing.
    let v = m.node_view(park, u64::MAX).expect("park");
    assert_eq!(v.ran_ns, Some(1_000_000_000));
    assert!(v.waits.is_empty(), "{:?}", v.waits);
    assert_eq!(v.life, "reclaimed");
}

#[tokio::test(start_paused = true)]
async fn exceptions_counts_and_the_event_filter() {
    let trace = mission().await;
    let m = model_of(&trace);
    let honk = number(&m, "honk");
    let x = m.exceptions();
    assert_eq!(x.len(), 1);
    assert_eq!((x[0].node, x[0].exception.as_str()), (honk, "Jammed"));
    assert_eq!(x[0].path, "mission/honk");
    assert_eq!(x[0].at.t, 2_000_000_000);
    let steps: Vec<_> = x[0]
        .steps
        .iter()
        .map(|s| (s.what, s.detail.as_str()))
        .collect();
    assert_eq!(steps, [("chosen", "shrug")]);

    let stats = m.stats();
    let drive = stats.iter().find(|s| s.name == "drive").expect("drive");
    assert_eq!(
        (drive.count, drive.succeeded, drive.total_ns),
        (1, 1, 5_000_000_000)
    );
    let honk_stats = stats.iter().find(|s| s.name == "honk").expect("honk");
    assert_eq!((honk_stats.count, honk_stats.failed), (1, 1));
    // Longest total first.
    assert_eq!(stats[0].name, "drive");

    let only_park = EventFilter {
        name: Some("PARK".to_string()),
        ..EventFilter::default()
    };
    let (total, lines) = m.events(&only_park, 0, 1000);
    assert!(total > 3 && total == lines.len());
    assert!(
        lines
            .iter()
            .all(|l| l.contains(&format!("\"node\":{}", number(&m, "park")))
                || l.to_lowercase().contains("park"))
    );
    let window = EventFilter {
        from: Some(2_000_000_000),
        to: Some(2_000_000_000),
        ..EventFilter::default()
    };
    let (total, lines) = m.events(&window, 0, 2);
    assert_eq!(lines.len(), 2);
    assert!(
        total >= 3,
        "honk fails, is handled, and completes at 2 s: {total}"
    );
    assert!(lines.iter().all(|l| l.contains("\"t\":2000000000")));
}

/// `a` and `b` both use the base (capacity 1); `b` asks while `a` holds it.
#[tokio::test(start_paused = true)]
async fn a_node_waiting_for_a_resource_names_it_and_its_holder() {
    let task = Task::goal("mission", |ctx| async move {
        for name in ["a", "b"] {
            ctx.spawn(Task::command(name, |_| async {
                tokio::time::sleep(secs(2)).await;
                Ok(())
            }))
            .uses("base", 1)
            .start()?;
        }
        Ok(())
    });
    let trace = run_checked(Runtime::new().resource("base", 1), task)
        .await
        .1;
    let m = model_of(&trace);
    let (a, b) = (number(&m, "a"), number(&m, "b"));
    let v = m.node_view(b, m.seq_at(1_000_000_000)).expect("b");
    assert_eq!(v.states[0], "enabled");
    let start: Vec<_> = v.waits.iter().filter(|w| w.facet == "start").collect();
    assert_eq!(start.len(), 1, "{:?}", v.waits);
    assert!(
        start[0].what.contains("`base`: held by a {")
            && start[0].what.contains(&format!("{{{a}}}")),
        "{}",
        start[0].what
    );
    // Granted at 2 s: nothing holds it back any more.
    let v = m.node_view(b, m.seq_at(2_000_000_000)).expect("b");
    assert!(v.waits.is_empty(), "{:?}", v.waits);
}

/// A node placed on an agent (what `tcm-zenoh` records) carries the agent's name in the model,
/// the node's view and the snapshot the page loads.
#[tokio::test(start_paused = true)]
async fn a_node_placed_on_an_agent_shows_the_agent() {
    let task = Task::goal("mission", |ctx| async move {
        ctx.spawn(Task::command("grasp", |ctx| async move {
            ctx.placed("arm")?;
            tokio::time::sleep(secs(1)).await;
            Ok(())
        }))
        .start()?;
        ctx.spawn(Task::command("look", |_| async { Ok(()) }))
            .start()?;
        Ok(())
    });
    let trace = run_checked(Runtime::new(), task).await.1;
    let m = model_of(&trace);
    let (grasp, look) = (number(&m, "grasp"), number(&m, "look"));
    let row = |n: u64| m.rows().iter().find(|r| r.number == n).expect("a row");
    assert_eq!(row(grasp).agent.as_deref(), Some("arm"));
    assert_eq!(row(look).agent, None);
    let v = m.node_view(grasp, m.seq_at(1_000_000_000)).expect("grasp");
    assert_eq!(v.agent.as_deref(), Some("arm"));
    // Not before it was placed.
    let placed = trace
        .iter()
        .find(|e| matches!(e.kind, TraceKind::Placed { .. }))
        .expect("a placed record");
    let v = m.node_view(grasp, placed.seq - 1).expect("grasp");
    assert_eq!(v.agent, None);
    let snapshot: serde_json::Value =
        serde_json::from_str(&tcm_view::snapshot_json(0, &m)).expect("the snapshot is JSON");
    let nodes = snapshot["nodes"].as_array().expect("nodes");
    let entry = |n: u64| {
        nodes
            .iter()
            .find(|e| e[0] == n)
            .and_then(|e| e.as_array())
            .expect("an entry")
    };
    assert_eq!(entry(grasp).len(), 4 + tcm_view::MARKS + 1);
    assert_eq!(entry(grasp)[4 + tcm_view::MARKS], "arm");
    assert_eq!(entry(look).len(), 4 + tcm_view::MARKS);
}

#[tokio::test(start_paused = true)]
async fn a_nodes_log_lines_are_those_written_by_the_cursor() {
    let task = Task::command("grasp", |ctx| async move {
        ctx.log("opening")?;
        tokio::time::sleep(secs(1)).await;
        ctx.log("closed")?;
        Ok(())
    });
    let trace = run_checked(Runtime::new(), task).await.1;
    let m = model_of(&trace);
    let grasp = number(&m, "grasp");
    let logs = |seq: u64| m.node_view(grasp, seq).expect("grasp").logs;
    let first = trace
        .iter()
        .find(|e| matches!(e.kind, TraceKind::Log { .. }))
        .expect("a log record");
    assert_eq!(logs(first.seq - 1), []);
    assert_eq!(logs(first.seq), [("opening".to_string(), 0)]);
    let last = trace.last().expect("records").seq;
    assert_eq!(
        logs(last),
        [
            ("opening".to_string(), 0),
            ("closed".to_string(), 1_000_000_000)
        ]
    );
    // The Events tab lists them, and finds them by their text.
    let f = EventFilter {
        name: Some("CLOSED".to_string()),
        ..EventFilter::default()
    };
    let (total, lines) = m.events(&f, 0, 10);
    assert_eq!(total, 1);
    assert!(lines[0].contains("\"ev\":\"log\""), "{lines:?}");
}

/// A failure that a waiting parent took is told as taken by that parent, not as pending: the
/// parent that waited for its value fails with it; one that waited for how it ended goes on.
#[tokio::test(start_paused = true)]
async fn a_failure_a_waiting_parent_took_is_told_as_taken_by_it() {
    let m = model_of(&common::patrol().await);
    let (probe, fetch) = (number(&m, "probe"), number(&m, "fetch"));
    let steps = |m: &RunModel, n: u64| -> Vec<(&'static str, Option<u64>, String)> {
        let stories = m.stories();
        let story = stories.iter().find(|s| s.node == n).expect("a story");
        story
            .steps
            .iter()
            .map(|s| (s.what, s.node, s.detail.clone()))
            .collect()
    };
    assert_eq!(
        steps(&m, probe),
        [("taken", Some(fetch), "failed with it".to_string())]
    );
    // The fold's own story of it has no step: the viewer tells what the records imply.
    let fold = m
        .exceptions()
        .iter()
        .find(|s| s.node == probe)
        .expect("a story");
    assert!(fold.steps.is_empty());
    // `fetch`'s own failure is searched for from it: no handler, so unhandled.
    assert_eq!(steps(&m, fetch)[0].0, "unhandled");

    let task = Task::goal("mission", |ctx| async move {
        let ended = ctx
            .spawn(Task::command("probe", |_| async {
                Err::<u32, _>(tcm::Failure::new("Broken", "the probe broke"))
            }))
            .wait_outcome::<u32>()
            .await?;
        assert!(matches!(ended, tcm::Ended::Failed(_)));
        Ok(())
    });
    let m = model_of(&run_checked(Runtime::new(), task).await.1);
    let (probe, mission) = (number(&m, "probe"), number(&m, "mission"));
    assert_eq!(
        steps(&m, probe),
        [(
            "taken",
            Some(mission),
            "waited for it and did not fail with it".to_string()
        )]
    );
    assert_eq!(m.stories().len(), 1);
}

/// A node's details are those at the cursor, not at the end of the run: a monitor's activations,
/// triggers and children, a node's agent.
#[tokio::test(start_paused = true)]
async fn a_nodes_details_are_those_at_the_cursor() {
    let trace = common::patrol().await;
    let m = model_of(&trace);
    let watch = number(&m, "watch");
    let seq_of = |what: &dyn Fn(&TraceKind) -> bool, nth: usize| {
        trace
            .iter()
            .filter(|e| what(&e.kind))
            .nth(nth)
            .map(|e| e.seq)
            .expect("such a record")
    };
    let activated =
        |k: &TraceKind| matches!(k, TraceKind::Activated { monitor, .. } if *monitor == watch);
    let triggered =
        |k: &TraceKind| matches!(k, TraceKind::Triggered { monitor, .. } if *monitor == watch);
    let details = |seq: u64| {
        let v = m.node_view(watch, seq).expect("watch");
        (v.activations, v.triggers_count, v.children.len())
    };
    let first = seq_of(&activated, 0);
    assert_eq!(details(first - 2), (0, 0, 0), "before its first activation");
    // Its first activation is spawned just before the record saying so.
    assert_eq!(details(first - 1), (0, 0, 1));
    assert_eq!(details(first), (1, 0, 1));
    assert_eq!(details(seq_of(&triggered, 0)), (1, 1, 1));
    assert_eq!(details(seq_of(&activated, 1)), (2, 1, 2));
    // At the end, the fold's row (the last activation came as the monitor completed, whose
    // trigger may count no more).
    let row = m.node(watch).expect("watch");
    assert!(row.triggers >= 2);
    assert_eq!(details(u64::MAX), (3, row.triggers, 3));
}

/// An activation's row names its monitor after the agent's place (`null` when it runs here), so
/// the page can fold a monitor's activations into one row; another node's row has no such entry.
#[tokio::test(start_paused = true)]
async fn an_activations_row_names_its_monitor() {
    let m = model_of(&common::patrol().await);
    let rows = snapshot_rows(&m);
    let tick = number(&m, "tick");
    let acts: Vec<_> = rows
        .values()
        .filter(|r| r[3] == "ACT-tick")
        .map(|r| r.as_array().expect("a row"))
        .collect();
    assert_eq!(acts.len(), 10);
    for r in acts {
        assert_eq!(r.len(), 4 + tcm_view::MARKS + 2, "{r:?}");
        assert_eq!(r[4 + tcm_view::MARKS], serde_json::Value::Null);
        assert_eq!(r[5 + tcm_view::MARKS], tick);
    }
    let drive = &rows[&number(&m, "drive")];
    assert_eq!(drive.as_array().expect("a row").len(), 4 + tcm_view::MARKS);
    assert_eq!(
        rows[&tick].as_array().expect("a row").len(),
        4 + tcm_view::MARKS
    );
}

#[test]
fn a_bad_line_is_named_with_its_file_and_line_and_what_came_before_is_kept() {
    let good = [
        r#"{"seq":0,"t":0,"ev":"run_started","version":4,"run":0}"#,
        r#"{"seq":1,"t":0,"ev":"spawned","node":1,"parent":0,"kind":"command","name":"beep"}"#,
    ];
    let text = format!(
        "{}\n{}\n{{\"seq\":2,\"t\":0,\"ev\":\"spaw",
        good[0], good[1]
    );
    let m = RunModel::read("cut.jsonl", "cut.jsonl", text.as_bytes());
    let p = m.problem.as_ref().expect("a problem");
    assert_eq!((p.source.as_str(), p.line), ("cut.jsonl", 3));
    assert!(p.to_string().starts_with("cut.jsonl:3: "), "{p}");
    assert_eq!(m.len(), 2);
    assert_eq!(m.rows()[1].name, "beep");

    let newer = r#"{"seq":0,"t":0,"ev":"run_started","version":99,"run":0}"#;
    let m = RunModel::read("new.jsonl", "new.jsonl", newer.as_bytes());
    let p = m.problem.as_ref().expect("a problem");
    assert_eq!(p.line, 1);
    assert!(p.message.contains("99"), "{p}");

    let m = RunModel::read("empty.jsonl", "empty.jsonl", &b"\n\n"[..]);
    assert!(
        m.problem
            .as_ref()
            .expect("a problem")
            .message
            .contains("no trace record")
    );

    let foreign = "{\"hello\": 1}\n";
    let m = RunModel::read("x.json", "x.json", foreign.as_bytes());
    assert_eq!(m.problem.as_ref().expect("a problem").line, 1);

    let skipped = format!(
        "{}\n{}",
        good[0], r#"{"seq":5,"t":0,"ev":"external","name":"go"}"#
    );
    let m = RunModel::read("gap.jsonl", "gap.jsonl", skipped.as_bytes());
    let p = m.problem.as_ref().expect("a problem");
    assert_eq!(p.line, 2);
    assert!(p.message.contains("record number 5"), "{p}");
}

/// A snapshot's or a live message's rows, by node number.
fn rows_of(rows: &serde_json::Value) -> BTreeMap<u64, serde_json::Value> {
    rows.as_array()
        .expect("rows")
        .iter()
        .map(|r| (r[0].as_u64().expect("a node number"), r.clone()))
        .collect()
}

fn snapshot_rows(m: &RunModel) -> BTreeMap<u64, serde_json::Value> {
    let snapshot: serde_json::Value =
        serde_json::from_str(&tcm_view::snapshot_json(0, m)).expect("the snapshot is JSON");
    rows_of(&snapshot["nodes"])
}

/// After each record of a run, its live message carries the record and the rows it changed, as
/// the snapshot then has them, and every row of the snapshot that the record changed.
#[tokio::test(start_paused = true)]
async fn each_live_message_carries_the_record_and_the_rows_it_changed() {
    live_messages_carry_the_rows(&mission().await);
    live_messages_carry_the_rows(&common::patrol().await);
}

fn live_messages_carry_the_rows(trace: &[TraceEvent]) {
    let mut m = RunModel::new("mission");
    let mut before = snapshot_rows(&m);
    let mut built = before.clone();
    let mut carried = 0;
    for ev in trace {
        m.apply(ev).expect("a checked trace applies");
        let msg: serde_json::Value =
            serde_json::from_str(&tcm_view::record_json(&m)).expect("the message is JSON");
        assert_eq!(msg["type"], "record");
        let line: serde_json::Value = serde_json::from_str(&tcm_trace::to_line(ev)).expect("JSON");
        assert_eq!(msg["record"], line);
        let after = snapshot_rows(&m);
        let rows = rows_of(&msg["rows"]);
        for (n, row) in &rows {
            assert_eq!(Some(row), after.get(n), "record {}: row {n}", ev.seq);
        }
        for (n, row) in &after {
            if before.get(n) != Some(row) {
                assert!(rows.contains_key(n), "record {}: row {n} not sent", ev.seq);
            }
        }
        carried += rows.len();
        built.extend(rows);
        before = after;
    }
    // The rows built from the messages alone are the snapshot's at the end.
    assert_eq!(built, before);
    assert!(carried >= trace.len() / 2, "{carried} rows in all");
}

async fn next_json(
    ws: &mut tokio_tungstenite::WebSocketStream<
        tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>,
    >,
) -> serde_json::Value {
    loop {
        let msg = tokio::time::timeout(Duration::from_secs(10), ws.next())
            .await
            .expect("a message within 10 s")
            .expect("the socket is open")
            .expect("a message");
        if let Message::Text(t) = msg {
            return serde_json::from_str(&t).expect("JSON");
        }
    }
}

#[test]
fn a_live_page_gets_a_snapshot_then_records_and_a_fresh_snapshot_when_it_falls_behind() {
    let trace = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .start_paused(true)
        .build()
        .expect("runtime")
        .block_on(mission());
    let viewer = Viewer::serve(([127, 0, 0, 1], 0).into()).expect("serve on loopback");
    assert!(viewer.url().starts_with("http://127.0.0.1:"));
    let mut sink = viewer.live("mission");
    let half = trace.len() / 2;
    for ev in &trace[..half] {
        sink.record(ev);
    }
    let url = format!("ws://{}/api/runs/{}/live", viewer.addr(), sink.id());
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .expect("runtime");
    rt.block_on(async {
        let (mut ws, _) = tokio_tungstenite::connect_async(url.as_str())
            .await
            .expect("connect");
        // Opened mid-run: a snapshot of what is there…
        let snap = next_json(&mut ws).await;
        assert_eq!(snap["type"], "snapshot");
        assert_eq!(snap["records"], half as u64);
        assert_eq!(snap["finished"], false);
        assert_eq!(
            rows_of(&snap["nodes"]),
            snapshot_rows(&model_of(&trace[..half]))
        );
        // …then each record, as the trace schema writes it, with the rows it changed: the rows
        // the page builds are those of the snapshot after them.
        let mut rows = rows_of(&snap["nodes"]);
        for ev in &trace[half..half + 3] {
            sink.record(ev);
        }
        for (i, ev) in trace[half..half + 3].iter().enumerate() {
            let got = next_json(&mut ws).await;
            assert_eq!(got["type"], "record");
            assert_eq!(
                got["record"],
                serde_json::from_str::<serde_json::Value>(&tcm_trace::to_line(ev)).expect("JSON")
            );
            let changed = rows_of(&got["rows"]);
            let fold = snapshot_rows(&model_of(&trace[..half + i + 1]));
            for (n, row) in &changed {
                assert_eq!(Some(row), fold.get(n), "record {}: row {n}", ev.seq);
            }
            rows.extend(changed);
            assert_eq!(rows, fold, "the rows after record {}", ev.seq);
        }
        // A page that does not read while the run goes on never holds the run up: it falls
        // behind and is sent a fresh snapshot with everything, then the records after it.
        let start = trace.len();
        let mut seq = start as u64;
        let t = trace.last().map_or(0, |e| e.t);
        for ev in &trace[half + 3..] {
            sink.record(ev);
        }
        // 20 MB: more than the socket buffers on both sides hold.
        let name = "tick".repeat(250);
        let mut all = trace.clone();
        for _ in 0..20_000 {
            let tick = TraceEvent {
                seq,
                t,
                kind: tcm_trace::TraceKind::External { name: name.clone() },
            };
            sink.record(&tick);
            all.push(tick);
            seq += 1;
        }
        sink.flush();
        // Read on: a fresh snapshot comes, and from it on, every record in order to the end; the
        // rows built from it are the fold's at the end.
        let (mut last, mut finished, mut snapshots) = (0u64, false, 0);
        while !(snapshots > 0 && last == seq && finished) {
            let m = next_json(&mut ws).await;
            if m["type"] == "snapshot" {
                snapshots += 1;
                last = m["records"].as_u64().expect("records");
                finished = m["finished"] == true;
                rows = rows_of(&m["nodes"]);
            } else if m["type"] == "finished" {
                finished = true;
            } else if snapshots > 0 {
                assert_eq!(m["type"], "record");
                assert_eq!(
                    m["record"]["seq"], last,
                    "records after the snapshot come in order"
                );
                rows.extend(rows_of(&m["rows"]));
                last += 1;
            }
        }
        assert!(seq > start as u64);
        assert_eq!(rows, snapshot_rows(&model_of(&all)));
    });
    viewer.stop();
}

/// The last record at or before `s` seconds.
fn at_secs(m: &RunModel, s: f64) -> u64 {
    m.seq_at((s * 1e9) as u64)
}

#[tokio::test(start_paused = true)]
async fn each_state_variable_has_its_changes_and_a_value_at_any_cursor() {
    let trace = common::powered().await;
    let m = model_of(&trace);
    let lanes: Vec<(&str, &str)> = m
        .state_lanes()
        .iter()
        .map(|l| (l.name.as_str(), l.ty))
        .collect();
    assert_eq!(
        lanes,
        [
            ("battery_ok", "bool"),
            ("fault", "bool"),
            ("charge", "float"),
            ("position", "float"),
            ("docked", "bool"),
        ]
    );
    let lane = |name: &str| {
        m.state_lanes()
            .iter()
            .find(|l| l.name == name)
            .unwrap_or_else(|| panic!("no lane {name}"))
    };
    // Declared, then each change; `fault` set to the value it had is a set, not a change.
    let changes = |name: &str| -> Vec<(u64, String)> {
        lane(name)
            .changes
            .iter()
            .map(|(mk, v)| (mk.t / 1_000_000_000, v.to_string()))
            .collect()
    };
    assert_eq!(
        changes("battery_ok"),
        [(0, "true".into()), (2, "false".into()), (5, "true".into())]
    );
    assert_eq!(
        changes("charge"),
        [(0, "100.0".into()), (2, "20.0".into()), (5, "90.0".into())]
    );
    assert_eq!(changes("fault"), [(0, "false".to_string())]);
    assert_eq!(lane("fault").sets, 2);
    assert_eq!(changes("position"), [(0, "unknown".to_string())]);

    // At 3 s and at 6 s, with since when.
    let value = |name: &str, s: f64| {
        let (v, since) = m.state_at(name, at_secs(&m, s)).expect("declared");
        (v.to_string(), since.t / 1_000_000_000)
    };
    assert_eq!(value("battery_ok", 3.0), ("false".into(), 2));
    assert_eq!(value("battery_ok", 6.0), ("true".into(), 5));
    assert_eq!(value("charge", 3.0), ("20.0".into(), 2));
    assert_eq!(value("position", 6.0), ("unknown".into(), 0));
    // Before its declaration, a variable has no value.
    assert!(m.state_at("battery_ok", 0).is_none());
}

#[tokio::test(start_paused = true)]
async fn a_node_waiting_on_a_condition_says_which_with_the_values_that_hold_it() {
    let trace = common::powered().await;
    let m = model_of(&trace);
    let drive = number(&m, "drive");

    // At 4 s, its handling waits for the condition, held by `battery_ok`, false since 2 s.
    let v = m.node_view(drive, at_secs(&m, 4.0)).expect("drive");
    let waits: Vec<_> = v.waits.iter().filter(|w| w.condition.is_some()).collect();
    assert_eq!(waits.len(), 1, "{:?}", v.waits);
    let w = waits[0];
    assert_eq!(w.facet, "handling");
    assert_eq!(w.condition.as_deref(), Some("battery_ok && !fault"));
    assert_eq!(
        w.what,
        "waits for `battery_ok && !fault` (false): battery_ok = false since 2.000 s, \
         fault = false since 0.000 s"
    );
    assert_eq!(w.since, 3_000_000_000);
    let forms: Vec<(&str, &str, &str, &str)> = v
        .conditions
        .iter()
        .map(|c| {
            (
                c.form.as_str(),
                c.condition.as_str(),
                c.value.as_str(),
                c.state.as_str(),
            )
        })
        .collect();
    assert_eq!(
        forms,
        [
            (
                "disable handling until",
                "battery_ok && !fault",
                "false",
                "has not held yet: the facet waits for it"
            ),
            (
                "invariant",
                "charge > 10.0",
                "true",
                "watched once it starts"
            ),
        ]
    );

    // At 5.5 s, it runs: nothing holds it, the condition held at 5 s, the invariant holds.
    let v = m.node_view(drive, at_secs(&m, 5.5)).expect("drive");
    assert!(v.waits.is_empty(), "{:?}", v.waits);
    assert_eq!(v.states[0], "active");
    let states: Vec<&str> = v.conditions.iter().map(|c| c.state.as_str()).collect();
    assert_eq!(states, ["held at 5.000 s: met for good", "watched: holds"]);
    let reads: Vec<String> = v.conditions[1].reads.iter().map(|r| r.text()).collect();
    assert_eq!(reads, ["charge = 90.0 since 5.000 s"]);
    // After its end, the invariant is no longer watched.
    let v = m.node_view(drive, u64::MAX).expect("drive");
    assert_eq!(
        v.conditions[1].state,
        "watched until its execution completed at 6.000 s"
    );
}

#[tokio::test(start_paused = true)]
async fn skip_and_pause_say_what_their_condition_was_at_the_cursor() {
    let trace = common::powered().await;
    let m = model_of(&trace);
    let (dock, patrol) = (number(&m, "dock"), number(&m, "patrol"));

    let v = m.node_view(dock, u64::MAX).expect("dock");
    assert_eq!(v.conditions.len(), 1);
    let skip = &v.conditions[0];
    assert_eq!(
        (
            skip.form.as_str(),
            skip.condition.as_str(),
            skip.value.as_str()
        ),
        ("skip if", "!is_known(position)", "true")
    );
    assert_eq!(skip.state, "held when its turn came: skipped at 0.000 s");

    // At 3 s, `patrol` is enabled and paused by its own `pause while docked`.
    let v = m.node_view(patrol, at_secs(&m, 3.0)).expect("patrol");
    let paused = "it is paused by `pause while docked`: docked = true since 0.000 s";
    assert_eq!(v.paused.as_deref(), Some(paused));
    let start: Vec<&str> = v
        .waits
        .iter()
        .filter(|w| w.facet == "start")
        .map(|w| w.what.as_str())
        .collect();
    assert_eq!(start, [paused]);
    assert_eq!(
        (
            v.conditions[0].form.as_str(),
            v.conditions[0].value.as_str()
        ),
        ("pause while", "true")
    );
    assert_eq!(
        v.conditions[0].state,
        "holds: its subtree is paused (nothing new starts in it)"
    );
    // From 7 s, it is not.
    let v = m.node_view(patrol, at_secs(&m, 7.2)).expect("patrol");
    assert_eq!(v.paused, None);
    assert_eq!(v.conditions[0].state, "does not hold: not paused");
    assert!(!v.waits.iter().any(|w| w.facet == "start"), "{:?}", v.waits);
    // At 8.5 s, `sweep2`'s turn came while its ancestor's pause held again (from 7.5 s).
    let sweep2 = number(&m, "sweep2");
    let v = m.node_view(sweep2, at_secs(&m, 8.5)).expect("sweep2");
    let paused = format!(
        "its ancestor patrol {{{patrol}}} is paused by `pause while docked`: docked = true since 7.500 s"
    );
    assert_eq!(v.paused.as_deref(), Some(paused.as_str()));
    let start: Vec<&str> = v
        .waits
        .iter()
        .filter(|w| w.facet == "start")
        .map(|w| w.what.as_str())
        .collect();
    assert_eq!(start, [paused.as_str()]);
    let ran = v.history.iter().any(|(what, _)| what == "handling active");
    assert!(!ran, "{:?}", v.history);
    let v = m.node_view(sweep2, u64::MAX).expect("sweep2");
    let active = v.history.iter().find(|(what, _)| what == "handling active");
    assert_eq!(active.map(|a| a.1), Some(9_000_000_000));
    assert_eq!(v.paused, None);
}

#[tokio::test(start_paused = true)]
async fn counts_tell_skipped_nodes_apart_from_those_that_succeeded() {
    let trace = common::powered().await;
    let m = model_of(&trace);
    let stats = m.stats();
    let of = |name: &str| {
        let s = stats.iter().find(|s| s.name == name).expect("a task");
        (s.count, s.succeeded, s.skipped, s.ran)
    };
    assert_eq!(of("dock"), (1, 0, 1, 0));
    assert_eq!(of("drive"), (1, 1, 0, 1));
}

#[tokio::test(start_paused = true)]
async fn the_snapshot_and_live_messages_carry_the_state_variables() {
    let trace = common::powered().await;
    let mut m = RunModel::new("powered");
    let mut changed = Vec::new();
    for ev in &trace {
        m.apply(ev).expect("a checked trace applies");
        let msg: serde_json::Value =
            serde_json::from_str(&tcm_view::record_json(&m)).expect("JSON");
        if let Some(state) = msg.get("state") {
            changed.push((ev.t / 1_000_000_000, state.to_string()));
        }
    }
    let battery: Vec<_> = changed
        .iter()
        .filter(|(_, s)| s.contains("battery_ok"))
        .collect();
    assert_eq!(
        battery,
        [
            &(
                0,
                r#"{"name":"battery_ok","ty":"bool","value":true}"#.to_string()
            ),
            &(
                2,
                r#"{"name":"battery_ok","ty":"bool","value":false}"#.to_string()
            ),
            &(
                5,
                r#"{"name":"battery_ok","ty":"bool","value":true}"#.to_string()
            ),
        ]
    );
    // `fault`'s set to the value it had sends nothing.
    assert_eq!(
        changed.iter().filter(|(_, s)| s.contains("fault")).count(),
        1
    );
    let snap: serde_json::Value =
        serde_json::from_str(&tcm_view::snapshot_json(0, &m)).expect("JSON");
    let charge = &snap["states"][2];
    assert_eq!(charge["name"], "charge");
    assert_eq!(charge["ty"], "float");
    let values: Vec<f64> = charge["changes"]
        .as_array()
        .expect("changes")
        .chunks(2)
        .map(|p| p[1].as_f64().expect("a number"))
        .collect();
    assert_eq!(values, [100.0, 20.0, 90.0]);
}
