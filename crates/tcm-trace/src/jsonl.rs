//! The JSON-lines codec of the trace: one [`TraceEvent`] per line, schema in `docs/trace-format.md`.
//!
//! Writers call [`write_line`] (or [`to_line`]) per record; readers call [`read_jsonl`] for a whole
//! trace or iterate a [`JsonlReader`] to stream a long one. A trace file is user input, so every
//! reading error names the line and says what is wrong.

use crate::event::{OLDEST_READABLE_VERSION, TRACE_FORMAT_VERSION, TraceEvent, TraceKind};
use std::io::{self, BufRead, Write};

#[cfg(test)]
mod tests;

/// Why a trace could not be read.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReadError {
    /// The underlying reader failed.
    #[error("line {line}: cannot read the trace: {source}")]
    Io {
        /// Line number, from 1.
        line: usize,
        /// The I/O error.
        #[source]
        source: io::Error,
    },
    /// The line is not a trace record of this schema.
    #[error("line {line}: not a trace record: {source}")]
    Json {
        /// Line number, from 1.
        line: usize,
        /// What serde_json found wrong (its column counts within the line).
        #[source]
        source: serde_json::Error,
    },
    /// The trace was written with a schema this reader does not know (newer, or too old).
    #[error(
        "line {line}: the trace has format version {found}, but this reader reads versions {oldest} to {supported}"
    )]
    Version {
        /// Line number, from 1.
        line: usize,
        /// Version found in the `run_started` record.
        found: u32,
        /// The newest version this crate reads (the one it writes).
        supported: u32,
        /// The oldest version this crate still reads.
        oldest: u32,
    },
}

/// Renders one record as a JSON line, without the newline.
pub fn to_line(ev: &TraceEvent) -> String {
    // Serialising the trace types cannot fail: every map key is a string and no custom `Serialize`
    // impl can return an error. Keep a visible fallback rather than a panic all the same.
    serde_json::to_string(ev).unwrap_or_else(|e| {
        format!(
            r#"{{"seq":{},"t":{},"ev":"warning","node":null,"message":"unserialisable record: {}"}}"#,
            ev.seq,
            ev.t,
            e.to_string().replace(['"', '\\'], "'")
        )
    })
}

/// Writes one record as a JSON line, with its newline.
pub fn write_line(ev: &TraceEvent, w: &mut impl Write) -> io::Result<()> {
    let mut line = to_line(ev);
    line.push('\n');
    w.write_all(line.as_bytes())
}

/// Parses one line (without its newline). `line_no` is only used in the error.
pub fn parse_line(line: &str, line_no: usize) -> Result<TraceEvent, ReadError> {
    let ev: TraceEvent = serde_json::from_str(line).map_err(|source| ReadError::Json {
        line: line_no,
        source,
    })?;
    if let TraceKind::RunStarted { version, .. } = ev.kind {
        if !(OLDEST_READABLE_VERSION..=TRACE_FORMAT_VERSION).contains(&version) {
            return Err(ReadError::Version {
                line: line_no,
                found: version,
                supported: TRACE_FORMAT_VERSION,
                oldest: OLDEST_READABLE_VERSION,
            });
        }
    }
    Ok(ev)
}

/// Streams records from a JSON-lines trace. Blank lines are skipped.
#[derive(Debug)]
pub struct JsonlReader<R> {
    inner: R,
    line_no: usize,
    buf: String,
    failed: bool,
}

impl<R: BufRead> JsonlReader<R> {
    /// Reads from `inner`.
    pub fn new(inner: R) -> JsonlReader<R> {
        JsonlReader {
            inner,
            line_no: 0,
            buf: String::new(),
            failed: false,
        }
    }
}

impl<R: BufRead> Iterator for JsonlReader<R> {
    type Item = Result<TraceEvent, ReadError>;

    fn next(&mut self) -> Option<Self::Item> {
        // After an I/O error the reader's position is unknown: stop rather than report garbage.
        if self.failed {
            return None;
        }
        loop {
            self.buf.clear();
            self.line_no += 1;
            match self.inner.read_line(&mut self.buf) {
                Ok(0) => return None,
                Ok(_) => {}
                Err(source) => {
                    self.failed = true;
                    return Some(Err(ReadError::Io {
                        line: self.line_no,
                        source,
                    }));
                }
            }
            let line = self.buf.trim();
            if !line.is_empty() {
                return Some(parse_line(line, self.line_no));
            }
        }
    }
}

/// Reads a whole JSON-lines trace; stops at the first bad line.
pub fn read_jsonl(r: impl BufRead) -> Result<Vec<TraceEvent>, ReadError> {
    JsonlReader::new(r).collect()
}
