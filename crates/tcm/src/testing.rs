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
//!
//! A panicking action (an `assert!` in a body) only fails its node, and the run goes on
//! (docs/semantics.md, "Exceptions and handlers"); here it fails the test instead, with the panic's
//! message: [`run_checked`] panics after the run, naming the action and its node's path. A test
//! about panics uses [`run_checked_allowing_panics`].

use crate::{Recorder, Report, Runtime, Task};
use tcm_trace::TraceEvent;
pub use tcm_trace::story::{assert_order, handler_choices, only, story};

/// Runs `task` on `rt` with a recorder, and asserts that the run ends, that no action panicked and
/// that its trace passes the trace checker. Returns the report and the trace.
pub async fn run_checked(rt: Runtime, task: Task) -> (Report, Vec<TraceEvent>) {
    let (report, trace) = run_checked_allowing_panics(rt, task).await;
    assert_no_panics(&report, &trace);
    (report, trace)
}

/// As [`run_checked`], but an action's panic only fails its node, as outside tests: for tests of
/// what a panic does. The panics are in [`Report::panics`].
pub async fn run_checked_allowing_panics(rt: Runtime, task: Task) -> (Report, Vec<TraceEvent>) {
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

/// Asserts that no action (or timer callback) of the run panicked: otherwise panics with each
/// panic's message, as `action <name> {<node>} (<path>) panicked: <message>`, and the story.
#[track_caller]
pub fn assert_no_panics(report: &Report, trace: &[TraceEvent]) {
    if !report.panics.is_empty() {
        let text: Vec<String> = report.panics.iter().map(ToString::to_string).collect();
        panic!("{}\n\nstory:\n{}", text.join("\n"), story(trace).join("\n"));
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

/// Asserts that two runs gave the same trace, record for record ([`lines`]), naming the first
/// record that differs (`what` says which runs, for the message).
#[track_caller]
pub fn assert_same_trace(first: &[TraceEvent], second: &[TraceEvent], what: &str) {
    let (a, b) = (lines(first), lines(second));
    for (i, (x, y)) in a.iter().zip(&b).enumerate() {
        assert_eq!(x, y, "{what}: record {} differs", i + 1);
    }
    assert_eq!(
        a.len(),
        b.len(),
        "{what}: the traces have different lengths"
    );
}
