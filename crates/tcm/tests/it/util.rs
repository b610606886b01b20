//! Helpers: run a task with a recorder, check the trace, render it as a story.

use tcm::{Recorder, Report, Runtime, Task, TraceEvent};

/// Runs `task` on `rt` with a recorder; asserts the trace passes the checker.
pub(crate) async fn run_checked(rt: Runtime, task: Task) -> (Report, Vec<TraceEvent>) {
    let rec = Recorder::new();
    let report = rt.with_sink(rec.clone()).run(task).await.expect("run");
    let trace = rec.events();
    assert_checked(&trace);
    (report, trace)
}

/// Asserts the trace passes the checker and that the checker looked at it.
#[track_caller]
pub(crate) fn assert_checked(trace: &[TraceEvent]) {
    match tcm_trace::check(trace) {
        Ok(report) => assert!(report.n_transitions > 0, "the checker saw no transitions"),
        Err(violations) => {
            let text: Vec<String> = violations.iter().map(|v| format!("{v}")).collect();
            panic!(
                "trace checker found violations:\n{}\n\nstory:\n{}",
                text.join("\n"),
                story(trace).join("\n")
            );
        }
    }
}

pub(crate) use tcm_trace::story::{assert_order, only, story};
