//! A durable run's journal (docs/semantics.md, "Durable runs"): every input the engine of a run
//! receives (an action's end with its value or typed failure, an external event with its data, a
//! state variable set, an operation from outside), with the time the engine was given, so that a
//! run can be rebuilt by replaying them through the same program.
//!
//! The file is text, one record a line: the record's CRC-32 in eight hex digits, a space, and the
//! record as JSON. The first record is the [`Header`]: the journal's format version and the
//! identity of the program that wrote it (an interpreted program's source hash, or the version a
//! compiled binary declares). Each other record is an [`Entry`].
//!
//! - [`Writer`] appends entries with a chosen [`Durability`]: every record synced to the disk
//!   before `append` returns; group commit (synced at most every N milliseconds by a thread of
//!   the writer's, and when it is closed); or group commit and everything synced before the run
//!   acts outside the process (its caller asks, [`Writer::commit_before_acting`]). A failed
//!   write or sync is an error, and the writer refuses every append after it: a run never goes
//!   on unjournaled (its caller fails the run).
//! - [`read`] reads a journal back for a program: a last record cut short (a crash mid-write) is
//!   dropped with a warning; a record whose checksum does not match stops the reading with its
//!   line and byte offset; a journal of another program or of a newer format is refused.

mod read;
mod write;

pub use read::{Journal, read};
pub use write::{Durability, Store, Writer};

use serde::{Deserialize, Serialize};

/// The format version this crate writes, and the newest it reads.
pub const JOURNAL_FORMAT_VERSION: u32 = 2;

/// The journal's first record.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Header {
    /// The format version ([`JOURNAL_FORMAT_VERSION`] when written).
    pub journal: u32,
    /// The identity of the program whose run it journals.
    pub program: String,
    /// What the run started, as its writer describes it (`tdl run`: the task and its arguments),
    /// for a replay or a resumption to start the same.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start: Option<serde_json::Value>,
}

impl Header {
    /// The header of a journal of `program`, in this crate's format.
    pub fn new(program: &str) -> Header {
        Header {
            journal: JOURNAL_FORMAT_VERSION,
            program: program.to_string(),
            start: None,
        }
    }

    /// With what the run started.
    pub fn starting(mut self, start: serde_json::Value) -> Header {
        self.start = Some(start);
        self
    }
}

/// One input of the run, at the engine's time `t` (nanoseconds since the run started). (Its
/// input's fields are flattened into it, which serde cannot check for unknown fields; the
/// checksum guards the record.)
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Entry {
    /// Its number: 0, 1, 2, … in the order the engine received them.
    pub n: u64,
    /// The engine's time for it.
    pub t: u64,
    /// The steps the run had taken when it came in (the records of its trace, traced or not): a
    /// replay gives it at the same point of what the bodies ask. For a clock reading, the steps
    /// when it was read (a replay gives readings in order, wherever they are taken).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub at: u64,
    /// A body of the run gave it itself (an event it raised, a state variable it set): a replay
    /// runs the body again, which gives it again, and so does not give it from the journal.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub body: bool,
    /// What came in.
    #[serde(flatten)]
    pub input: Input,
}

/// What came in, as the engine received it. Nodes are named by their display numbers, which a
/// replay of the same inputs gives again.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "in", rename_all = "snake_case")]
pub enum Input {
    /// A node's action ended well, with its value when the value can be written (JSON).
    Ended {
        /// The node.
        node: u64,
        /// For a wiretap check on the node: the wiretap's number.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        tap: Option<u32>,
        /// Its value, if any was kept.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        value: Option<serde_json::Value>,
    },
    /// A node's action failed.
    Failed {
        /// The node.
        node: u64,
        /// For a wiretap check on the node: the wiretap's number.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        tap: Option<u32>,
        /// The exception's type name.
        exception: String,
        /// Its message.
        message: String,
        /// Its ancestors, nearest first.
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        ancestry: Vec<String>,
        /// What it carries, when it can be written (JSON).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        data: Option<serde_json::Value>,
    },
    /// A node's action stopped after it was cancelled.
    Stopped {
        /// The node.
        node: u64,
    },
    /// A cancelled action did not stop within its grace period.
    Overdue {
        /// The node.
        node: u64,
        /// The grace period, in nanoseconds.
        grace_ns: u64,
    },
    /// An external event was raised.
    External {
        /// Its name.
        name: String,
        /// Its data, if any.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        data: Option<serde_json::Value>,
    },
    /// A state variable was set.
    State {
        /// Its name.
        name: String,
        /// Its value, as the trace writes values.
        value: serde_json::Value,
    },
    /// Time passed with nothing else coming in: the timers due by `t` fired.
    Time,
    /// The engine read the run's clock, and `t` is what it read (for a command of a body, or an
    /// input given the clock's time): a replay gives the engine the same readings in order.
    Clock,
    /// A value a body read from outside the run through a journaled call (`tcm::Ctx::record`): a
    /// replay hands it to the body instead of reading again. No input of the engine's.
    Recorded {
        /// The body's node.
        node: u64,
        /// What it read.
        value: serde_json::Value,
    },
    /// A body wrote a line to the run's log (`tcm::Ctx::log`, TDL's `log`): a replay gives a
    /// command's again, as commands do not run in it.
    Log {
        /// The body's node.
        node: u64,
        /// The line.
        message: String,
    },
    /// An operation from outside the run (a steering request, a handler attached): what and who.
    Control {
        /// What was done.
        what: String,
        /// Who asked.
        by: String,
        /// The operation, as the engine records it (`tcm_core::SteerOp`), for a replay to carry
        /// out again; none for one it cannot (a handler or a wiretap attached, a fault with a
        /// value of the program's).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        op: Option<serde_json::Value>,
    },
}

/// What is wrong with a journal, or with writing one.
#[derive(Debug, thiserror::Error)]
pub enum JournalError {
    /// It cannot be opened, created or read.
    #[error("{file}: {source}")]
    Io {
        /// The file.
        file: String,
        /// Why.
        source: std::io::Error,
    },
    /// A write or sync failed (a full disk, a size limit): the run must not go on unjournaled.
    #[error(
        "{file}: cannot write the journal: {source}; the run stops rather than go on unjournaled"
    )]
    Write {
        /// The file.
        file: String,
        /// Why.
        source: std::io::Error,
    },
    /// An earlier write failed: the writer takes nothing more.
    #[error("{file}: the journal failed earlier ({why}); nothing more is written")]
    Failed {
        /// The file.
        file: String,
        /// The first failure.
        why: String,
    },
    /// It has no header, or its first line is not one.
    #[error("{file}: not a journal: {why}")]
    NotAJournal {
        /// The file.
        file: String,
        /// Why.
        why: String,
    },
    /// A record's checksum does not match: the file was changed or damaged there.
    #[error(
        "{file}:{line}: the record at byte {offset} does not match its checksum: the journal is damaged from there; nothing after it was read"
    )]
    Checksum {
        /// The file.
        file: String,
        /// The line, from 1.
        line: usize,
        /// The byte offset of the line's start.
        offset: u64,
    },
    /// A record whose checksum matches but which is no entry (written by another tool?).
    #[error("{file}:{line}: not a journal record: {why}")]
    BadRecord {
        /// The file.
        file: String,
        /// The line, from 1.
        line: usize,
        /// Why.
        why: String,
    },
    /// The journal is of another program.
    #[error(
        "{file}: the journal is of program {found}, not of {expected}: resume or replay it with the program that wrote it"
    )]
    OtherProgram {
        /// The file.
        file: String,
        /// The program given.
        expected: String,
        /// The program that wrote it.
        found: String,
    },
    /// The journal has a newer format than this reader knows.
    #[error(
        "{file}: the journal has format version {found}, and this reader reads versions 1 to {supported}: use a newer tdl"
    )]
    NewerFormat {
        /// The file.
        file: String,
        /// Its version.
        found: u32,
        /// The newest this reader reads.
        supported: u32,
    },
}

fn is_zero(n: &u64) -> bool {
    *n == 0
}

/// A record as a line: its checksum, a space, its JSON, a newline.
pub(crate) fn line(json: &str) -> String {
    format!("{:08x} {json}\n", crc32fast::hash(json.as_bytes()))
}
