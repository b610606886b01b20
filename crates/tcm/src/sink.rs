//! Trace sinks: where the records of a run go. A run may have several.
//!
//! Whatever the sinks, every `warning` record of a run (an unhandled failure's "No exception
//! handler found …" among them) is logged through `tracing` at `WARN` level, target `tcm`, so a
//! failure is never silent, and every `log` record (a body's `log` line) at `INFO`;
//! [`TracingSink`] logs the whole tree.

use std::collections::BTreeMap;
use std::io::Write;
use std::sync::{Arc, Mutex};
use tcm_trace::TraceEvent;
use tcm_trace::{TextLog, TextLogOptions, TraceKind};

/// Receives every trace record of a run, in order.
pub trait TraceSink: Send {
    /// One record.
    fn record(&mut self, ev: &TraceEvent);
    /// The run ended; write out anything buffered.
    fn flush(&mut self) {}
    /// Whether this sink logs warnings and log lines through `tracing` itself, so the runtime
    /// need not (default: no).
    fn logs_warnings(&self) -> bool {
        false
    }
}

/// A boxed sink is a sink: a program that chooses its sinks at run time (a file or not, a text
/// log or not) keeps them as `Box<dyn TraceSink>` and gives them to [`crate::Runtime::with_sink`]
/// as they are.
impl<T: TraceSink + ?Sized> TraceSink for Box<T> {
    fn record(&mut self, ev: &TraceEvent) {
        (**self).record(ev);
    }

    fn flush(&mut self) {
        (**self).flush();
    }

    fn logs_warnings(&self) -> bool {
        (**self).logs_warnings()
    }
}

/// Logs a `warning` record (at `WARN`) or a `log` record (at `INFO`) through `tracing`; other
/// records are ignored.
pub(crate) fn log_notable(ev: &TraceEvent) {
    match &ev.kind {
        TraceKind::Warning {
            node: Some(node),
            message,
        } => tracing::warn!(target: "tcm", node = *node, t_ns = ev.t, "{message}"),
        TraceKind::Warning {
            node: None,
            message,
        } => {
            tracing::warn!(target: "tcm", t_ns = ev.t, "{message}");
        }
        TraceKind::Log { node, message } => {
            tracing::info!(target: "tcm", node = *node, t_ns = ev.t, "{message}");
        }
        _ => {}
    }
}

/// Writes JSON lines (`docs/trace-format.md`), each record written through to `W` as it comes
/// (one `write` and one `flush` per record), so a process killed at any moment (even by
/// `SIGKILL`) leaves a file whose every complete line is a record, losing at most the record
/// being written. To buffer, pass a `BufWriter`: its `flush` still runs for every record.
pub struct JsonLines<W: Write + Send>(pub W);

impl<W: Write + Send> TraceSink for JsonLines<W> {
    fn record(&mut self, ev: &TraceEvent) {
        // One line, one write: a line is never split between two writes.
        let mut line = tcm_trace::to_line(ev);
        line.push('\n');
        // A failing writer must not stop the robot: the record is dropped.
        let _ = self.0.write_all(line.as_bytes());
        let _ = self.0.flush();
    }
    fn flush(&mut self) {
        let _ = self.0.flush();
    }
}

/// Writes TCM's text log (docs/semantics.md, "TCM-compatible output").
pub struct TextLogSink<W: Write + Send> {
    log: TextLog,
    out: W,
}

impl<W: Write + Send> TextLogSink<W> {
    /// A text log with TCM's default options.
    pub fn new(out: W) -> TextLogSink<W> {
        TextLogSink::with_options(out, TextLogOptions::default())
    }

    /// A text log with the given options.
    pub fn with_options(out: W, options: TextLogOptions) -> TextLogSink<W> {
        TextLogSink {
            log: TextLog::new(options),
            out,
        }
    }
}

impl<W: Write + Send> TraceSink for TextLogSink<W> {
    fn record(&mut self, ev: &TraceEvent) {
        let _ = self.log.write(ev, &mut self.out);
    }
    fn flush(&mut self) {
        let _ = self.out.flush();
    }
}

/// Keeps every record in memory, for tests and tools. Cloning shares the buffer.
#[derive(Clone, Default)]
pub struct Recorder(Arc<Mutex<Vec<TraceEvent>>>);

impl Recorder {
    /// An empty recorder.
    pub fn new() -> Recorder {
        Recorder::default()
    }

    /// A copy of the records so far.
    pub fn events(&self) -> Vec<TraceEvent> {
        self.0.lock().map(|v| v.clone()).unwrap_or_default()
    }
}

impl TraceSink for Recorder {
    fn record(&mut self, ev: &TraceEvent) {
        if let Ok(mut v) = self.0.lock() {
            v.push(ev.clone());
        }
    }
}

/// Turns trace records into `tracing` events, so a robot's existing subscriber sees the task
/// tree (docs/semantics.md, "Logging through tracing"). Every event has target `tcm`, the record's
/// virtual time in `t_ns` and, when it concerns a node, the node's number (`node`) and instance
/// name (`name`):
///
/// - `WARN`: warnings, among them each unhandled failure ("No exception handler found …",
///   with the failure's `exception` and its data as text in `failure`);
/// - `INFO`: the lines bodies log (`log`), failures (`failed`, handled or not), terminations
///   and handler choices;
/// - `DEBUG`: spawns and facet transitions;
/// - `TRACE`: every other record.
///
/// With this sink the runtime does not log warnings a second time.
///
/// ```
/// # #[tokio::main(flavor = "current_thread", start_paused = true)]
/// # async fn main() -> Result<(), tcm::Error> {
/// use tcm::{Runtime, Task, TracingSink};
/// let report = Runtime::new()
///     .with_sink(TracingSink::new())
///     .run(Task::command("beep", |_| async { Ok(()) }))
///     .await?;
/// assert!(report.is_clean());
/// # Ok(())
/// # }
/// ```
#[derive(Debug, Default)]
pub struct TracingSink {
    // Instance names of the live nodes, by number.
    names: BTreeMap<u64, String>,
    // The last failure of each live node: (exception, message).
    failed: BTreeMap<u64, (String, String)>,
}

impl TracingSink {
    /// A sink logging to the current `tracing` subscriber.
    pub fn new() -> TracingSink {
        TracingSink::default()
    }

    fn name(&self, node: u64) -> &str {
        self.names.get(&node).map_or("", String::as_str)
    }
}

impl TraceSink for TracingSink {
    fn record(&mut self, ev: &TraceEvent) {
        let t_ns = ev.t;
        match &ev.kind {
            TraceKind::Spawned {
                node,
                parent,
                kind,
                name,
                ..
            } => {
                self.names.insert(*node, name.clone());
                tracing::debug!(target: "tcm", t_ns, node = *node, name = name.as_str(), parent = *parent, kind = ?kind, "spawned");
            }
            TraceKind::Reserved { node, name, .. } => {
                self.names.insert(*node, name.clone());
                tracing::trace!(target: "tcm", t_ns, node = *node, name = name.as_str(), "reserved");
            }
            TraceKind::Transition {
                node,
                facet,
                from,
                to,
            } => {
                tracing::debug!(target: "tcm", t_ns, node = *node, name = self.name(*node), facet = %facet, from = %from, to = %to, "{facet} {to}");
            }
            TraceKind::Failed {
                node,
                exception,
                message,
            } => {
                self.failed
                    .insert(*node, (exception.clone(), message.clone()));
                tracing::info!(target: "tcm", t_ns, node = *node, name = self.name(*node), exception = exception.as_str(), "failed: {message}");
            }
            TraceKind::Warning {
                node: Some(node),
                message,
            } => {
                let (exception, failure) = self
                    .failed
                    .get(node)
                    .map_or(("", ""), |(e, m)| (e.as_str(), m.as_str()));
                tracing::warn!(target: "tcm", t_ns, node = *node, name = self.name(*node), exception, failure, "{message}");
            }
            TraceKind::Warning {
                node: None,
                message,
            } => {
                tracing::warn!(target: "tcm", t_ns, "{message}");
            }
            TraceKind::Log { node, message } => {
                tracing::info!(target: "tcm", t_ns, node = *node, name = self.name(*node), "{message}");
            }
            TraceKind::Terminated { node } => {
                tracing::info!(target: "tcm", t_ns, node = *node, name = self.name(*node), "terminated");
            }
            TraceKind::HandlerChosen {
                node,
                failing,
                exception,
                handler,
                ..
            } => {
                tracing::info!(target: "tcm", t_ns, node = *node, failing = *failing, name = self.name(*failing), exception = exception.as_str(), handler = handler.as_str(), "handler chosen");
            }
            TraceKind::Reclaimed { node } => {
                tracing::trace!(target: "tcm", t_ns, node = *node, name = self.name(*node), "reclaimed");
                self.names.remove(node);
                self.failed.remove(node);
            }
            _ => {
                tracing::trace!(target: "tcm", t_ns, record = %tcm_trace::to_line(ev), "record");
            }
        }
    }

    fn logs_warnings(&self) -> bool {
        true
    }
}
