//! The task-tree viewer: see what a run did, or what it is doing.
//!
//! `tdl view TRACE.jsonl` serves a trace file; a program serves its own runs live with
//! [`Viewer::serve`] and [`Viewer::live`], whose [`LiveSink`] is a trace sink like any other.
//! The page (served from the binary, no build step) shows the task tree coloured by its facets'
//! states, a timeline with a time cursor that replays the tree as it was, why a node waits,
//! each exception's story, counts and durations per task, the state variables' values over the
//! run (a lane each), and the records themselves, filtered.
//! It folds no record itself: the model and the page read the rows of the one fold of the trace,
//! [`tcm_trace::Replay`]; a live page gets each record (docs/trace-format.md) with the rows it
//! changed, framed as `docs/viewer.md` says.

mod model;
mod server;
mod state;
mod why;

pub use model::{
    EventFilter, ExceptionStory, Failure, M_DEAD, M_FAILED, M_RECLAIMED, M_RESERVED, M_SKIPPED,
    M_SPAWNED, M_TERMINATED, M_TERMINATING, MARKS, Mark, NameStats, Problem, Restriction, Row,
    RunModel, Step, m_point,
};
pub use server::{
    DEFAULT_ADDR, LiveSink, ViewError, Viewer, exposure_warning, record_json, snapshot_json,
};
pub use state::{StateLane, VarAt};
pub use why::{CondView, EventView, NodeView, Wait};
