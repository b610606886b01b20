//! Trace sinks: where the records of a run go. A run may have several.

use std::io::Write;
use std::sync::{Arc, Mutex};
use tcm_trace::TraceEvent;
use tcm_trace::{TextLog, TextLogOptions};

/// Receives every trace record of a run, in order.
pub trait TraceSink: Send {
    /// One record.
    fn record(&mut self, ev: &TraceEvent);
    /// The run ended; write out anything buffered.
    fn flush(&mut self) {}
}

/// Writes JSON lines (`docs/trace-format.md`).
pub struct JsonLines<W: Write + Send>(pub W);

impl<W: Write + Send> TraceSink for JsonLines<W> {
    fn record(&mut self, ev: &TraceEvent) {
        // A failing writer must not stop the robot: the record is dropped.
        let _ = tcm_trace::jsonl::write_line(ev, &mut self.0);
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
