//! Helpers for testing programs built on `tcm`: run a task with a recorder, check its trace with
//! the trace checker, and read it as a story (one line per transition) to assert on.
//!
//! ```
//! # #[tokio::main(flavor = "current_thread", start_paused = true)]
//! # async fn main() {
//! use tcm::testing::{assert_order, run_checked, story};
//! use tcm::{Runtime, Task};
//!
//! let (_, trace) = run_checked(Runtime::new(), Task::command("beep", |_| async { Ok(()) })).await;
//! assert_order(&story(&trace), &["0 beep handling active", "0 beep handling completed"]);
//! # }
//! ```
//!
//! These are test helpers: they panic, with the story of the run, when something is wrong.

use crate::{Recorder, Report, Runtime, Task};
use tcm_trace::TraceEvent;
pub use tcm_trace::story::{assert_order, handler_choices, only, story};

/// Runs `task` on `rt` with a recorder, and asserts that the run ends and that its trace passes
/// the trace checker. Returns the report and the trace.
pub async fn run_checked(rt: Runtime, task: Task) -> (Report, Vec<TraceEvent>) {
    let rec = Recorder::new();
    let res = rt.with_sink(rec.clone()).run(task).await;
    let trace = rec.events();
    match res {
        Ok(report) => {
            assert_checked(&trace);
            (report, trace)
        }
        Err(e) => panic!("the run failed: {e}\nstory:\n{}", story(&trace).join("\n")),
    }
}

/// Asserts that the trace passes the trace checker, and that the checker saw transitions.
#[track_caller]
pub fn assert_checked(trace: &[TraceEvent]) {
    match tcm_trace::check(trace) {
        Ok(report) => assert!(report.n_transitions > 0, "the checker saw no transitions"),
        Err(violations) => {
            let text: Vec<String> = violations.iter().map(ToString::to_string).collect();
            panic!(
                "trace checker found violations:\n{}\n\nstory:\n{}",
                text.join("\n"),
                story(trace).join("\n")
            );
        }
    }
}

/// The trace as JSON lines without its first record (whose run number differs between runs), for
/// comparing two runs of the same program byte for byte.
pub fn lines(trace: &[TraceEvent]) -> Vec<String> {
    trace.iter().skip(1).map(tcm_trace::to_line).collect()
}
