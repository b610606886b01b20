//! Failures are loud: the report lists every unhandled failure and counts failures and warnings,
//! warnings go through `tracing` even without a trace sink, and `TracingSink` shows the whole
//! tree to a `tracing` subscriber.

use std::sync::{Arc, Mutex};
use tcm::{Exception, Handler, RunOutcome, Runtime, Task, TracingSink};
use tracing::field::{Field, Visit};
use tracing::span::{Attributes, Id, Record};
use tracing::{Event, Level, Metadata, Subscriber};

#[derive(Debug, thiserror::Error)]
#[error("every route to room {room} is blocked")]
struct NoPath {
    room: u32,
}

impl Exception for NoPath {}

/// One `tracing` event as seen by the subscriber: level, target, and its fields as text.
#[derive(Clone, Debug)]
struct Seen {
    level: Level,
    target: String,
    fields: Vec<(String, String)>,
}

impl Seen {
    fn field(&self, name: &str) -> Option<&str> {
        self.fields
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_str())
    }
}

/// A subscriber that keeps every event.
#[derive(Clone, Default)]
struct Collect(Arc<Mutex<Vec<Seen>>>);

impl Collect {
    fn seen(&self) -> Vec<Seen> {
        self.0.lock().map(|v| v.clone()).unwrap_or_default()
    }
}

struct Fields<'a>(&'a mut Vec<(String, String)>);

impl Visit for Fields<'_> {
    fn record_debug(&mut self, field: &Field, value: &dyn std::fmt::Debug) {
        self.0
            .push((field.name().to_string(), format!("{value:?}")));
    }
    fn record_str(&mut self, field: &Field, value: &str) {
        self.0.push((field.name().to_string(), value.to_string()));
    }
}

impl Subscriber for Collect {
    fn enabled(&self, _: &Metadata<'_>) -> bool {
        true
    }
    fn new_span(&self, _: &Attributes<'_>) -> Id {
        Id::from_u64(1)
    }
    fn record(&self, _: &Id, _: &Record<'_>) {}
    fn record_follows_from(&self, _: &Id, _: &Id) {}
    fn event(&self, event: &Event<'_>) {
        let mut fields = Vec::new();
        event.record(&mut Fields(&mut fields));
        let seen = Seen {
            level: *event.metadata().level(),
            target: event.metadata().target().to_string(),
            fields,
        };
        if let Ok(mut v) = self.0.lock() {
            v.push(seen);
        }
    }
    fn enter(&self, _: &Id) {}
    fn exit(&self, _: &Id) {}
}

/// A mission whose `plan` fails with `NoPath` and no handler takes it; `drive` still runs.
fn mission() -> Task {
    Task::goal("deliver", |ctx| async move {
        ctx.spawn(Task::command("plan", |_| async {
            Err::<(), _>(NoPath { room: 7 }.raise())
        }))
        .start()?;
        ctx.spawn(Task::command("drive", |_| async { Ok(()) }))
            .start()?;
        Ok(())
    })
}

#[tokio::test(start_paused = true)]
async fn an_unhandled_failure_is_in_the_report_and_logged_without_a_sink() {
    let collect = Collect::default();
    let _guard = tracing::subscriber::set_default(collect.clone());
    let report = Runtime::new().run(mission()).await.expect("run");
    // TCM's default: the run goes on and completes, but says what went wrong.
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(report.unhandled.len(), 1, "{report}");
    let u = &report.unhandled[0];
    assert_eq!(u.path, "deliver/plan");
    assert_eq!(u.failure.exception, "NoPath");
    assert_eq!(u.failure.message, "every route to room 7 is blocked");
    assert_eq!((report.failures, report.warnings), (1, 1));
    assert!(!report.is_clean());
    let text = report.to_string();
    assert!(
        text.contains("unhandled exception NoPath in deliver/plan")
            && text.contains("1 unhandled failure(s), 1 failure(s), 1 warning(s)"),
        "{text}"
    );
    let warnings: Vec<Seen> = collect
        .seen()
        .into_iter()
        .filter(|s| s.level == Level::WARN)
        .collect();
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert_eq!(warnings[0].target, "tcm");
    assert_eq!(
        warnings[0].field("message"),
        Some("No exception handler found for exception type \"NoPath\"")
    );
}

#[tokio::test(start_paused = true)]
async fn a_handled_failure_is_counted_but_not_unhandled() {
    let task = mission().handler(Handler::on::<NoPath, _, _, _>("replan", |_| async {
        Ok(())
    }));
    let report = Runtime::new().run(task).await.expect("run");
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert!(report.unhandled.is_empty(), "{report}");
    assert_eq!((report.failures, report.warnings), (1, 0));
    assert!(report.is_clean());
}

#[tokio::test(start_paused = true)]
async fn the_tracing_sink_shows_the_tree_to_a_subscriber() {
    let collect = Collect::default();
    let _guard = tracing::subscriber::set_default(collect.clone());
    let report = Runtime::new()
        .with_sink(TracingSink::new())
        .run(mission())
        .await
        .expect("run");
    assert_eq!(report.unhandled.len(), 1);
    let seen = collect.seen();
    assert!(seen.iter().all(|s| s.target == "tcm"), "{seen:?}");
    // Transitions at debug, with the node's name.
    let transition = seen.iter().find(|s| {
        s.level == Level::DEBUG
            && s.field("name") == Some("drive")
            && s.field("facet") == Some("handling")
            && s.field("to") == Some("completed")
    });
    assert!(transition.is_some(), "{seen:?}");
    // The failure at info, and the unhandled failure once, at warn, with its exception and data.
    let failed = seen
        .iter()
        .filter(|s| s.level == Level::INFO && s.field("exception") == Some("NoPath"));
    assert_eq!(failed.count(), 1, "{seen:?}");
    let warnings: Vec<&Seen> = seen.iter().filter(|s| s.level == Level::WARN).collect();
    assert_eq!(warnings.len(), 1, "logged once, by the sink: {warnings:?}");
    let w = warnings[0];
    assert_eq!(w.field("name"), Some("plan"));
    assert_eq!(w.field("exception"), Some("NoPath"));
    assert_eq!(
        w.field("message"),
        Some("No exception handler found for exception type \"NoPath\"")
    );
    assert_eq!(w.field("failure"), Some("every route to room 7 is blocked"));
}

/// A writer standing for a file: what reached it survives a `SIGKILL`, what a `BufWriter` still
/// holds does not.
#[derive(Clone, Default)]
struct Disk(Arc<Mutex<Vec<u8>>>);

impl std::io::Write for Disk {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        if let Ok(mut d) = self.0.lock() {
            d.extend_from_slice(buf);
        }
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

#[test]
fn json_lines_writes_each_record_through_even_behind_a_buffer() {
    use tcm::{JsonLines, TraceEvent, TraceKind, TraceSink};
    let disk = Disk::default();
    let mut sink = JsonLines(std::io::BufWriter::new(disk.clone()));
    for seq in 0..3 {
        let ev = TraceEvent {
            seq,
            t: seq * 1_000,
            kind: TraceKind::External {
                name: format!("door_{seq}"),
            },
        };
        sink.record(&ev);
        // No `flush` of the sink: the process may die now.
        let text = disk
            .0
            .lock()
            .map(|d| String::from_utf8_lossy(&d).into_owned())
            .unwrap_or_default();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len() as u64, seq + 1, "{text}");
        assert!(text.ends_with('\n'), "{text}");
        assert_eq!(tcm_trace_line(lines[seq as usize]), Some(ev));
    }
}

fn tcm_trace_line(line: &str) -> Option<tcm::TraceEvent> {
    serde_json::from_str(line).ok()
}
