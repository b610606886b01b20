//! The trace of a TCM run: its schema and the tools that read it.
//!
//! The engine (`tcm-core`) emits one [`TraceEvent`] per state transition and per decision. This crate
//! defines those records and everything that reads them without needing the engine:
//!
//! - [`jsonl`]: the JSON-lines codec ([`write_line`], [`read_jsonl`]), schema in `docs/trace-format.md`;
//! - [`Replay`]: the one fold of a trace: the task tree and each node's history ([`Row`]: when it
//!   reached each point), exception stories, resource restrictions, rebuilt record by record and
//!   read by every reader below and by the viewer, the demo's summary and `tdl trace`;
//! - [`RecordClass`] and [`TraceKind::describe`]: each record's class and its text for people;
//! - [`TextLog`]: TCM's terminal log, column for column, and [`dump_tcm`] and [`dump_modern`]: tree
//!   dumps in TCM's form and ours (docs/semantics.md, "TCM-compatible output");
//! - [`check`]: the trace checker every runtime test runs, with its [`Rule`]s;
//! - [`story`]: one line per transition, what tests assert on.
//!
//! Viewers and the CLI depend on this crate only.
//!
//! ```
//! use tcm_trace::{NodeKind, TraceEvent, TraceKind, TextLog, TextLogOptions, TRACE_FORMAT_VERSION};
//!
//! let trace = vec![
//!     TraceEvent { seq: 0, t: 0, kind: TraceKind::RunStarted { version: TRACE_FORMAT_VERSION, run: 0 } },
//!     TraceEvent {
//!         seq: 1,
//!         t: 0,
//!         kind: TraceKind::Spawned { node: 1, parent: 0, kind: NodeKind::Goal, name: "A".into(), version: None, args: None },
//!     },
//! ];
//! let text = TextLog::render(TextLogOptions::default(), &trace);
//! assert_eq!(text, "Goal                    A {1}:        TCM {0} --> ON HOLD         (Inactive)\n");
//! assert!(tcm_trace::check(&trace).is_ok());
//! let line = tcm_trace::jsonl::to_line(&trace[1]);
//! assert_eq!(tcm_trace::read_jsonl(line.as_bytes()).ok(), Some(vec![trace[1].clone()]));
//! ```
//!
//! Architecture Invariants: this crate has no dependency on the engine and does no I/O of its own (the
//! codecs take a reader or writer); reading a trace never panics on bad input, it returns an error that
//! names the line.
#![warn(missing_docs)]

mod check;
mod describe;
mod dump;
mod event;
pub mod jsonl;
mod replay;
mod state;
pub mod story;
mod textlog;

#[cfg(test)]
mod test_util;

pub use check::{CheckReport, Checker, MAX_VIOLATIONS, Rule, Violation, check, check_prefix};
pub use describe::RecordClass;
pub use dump::{dump_modern, dump_tcm};
pub use event::{
    OLDEST_READABLE_VERSION, ResourceUse, TRACE_FORMAT_VERSION, TraceConstraint, TraceEvent,
    TraceEventRef, TraceKind, TraceThen, TraceWhen,
};
pub use jsonl::{JsonlReader, ReadError, read_jsonl, to_line, write_line};
pub use replay::{
    ExceptionStory, Failure, M_DEAD, M_FAILED, M_RECLAIMED, M_RESERVED, M_SKIPPED, M_SPAWNED,
    M_TERMINATED, M_TERMINATING, MARKS, Mark, MonitorInfo, NUMBER_SLACK, ROOT_NAME, Replay,
    ReplayError, ReplayNode, ReplayResource, Restriction, Row, Step, m_point,
};
pub use state::{Facet, NodeKind, Outcome, Point, State, Termination};
pub use textlog::{TextLog, TextLogOptions, tcm_state_word, time_suffix};
