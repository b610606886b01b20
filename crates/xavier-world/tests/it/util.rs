//! Helpers: run a task with a recorder, check the trace, render it as a story of transitions.

use tcm::{Report, Runtime, Task, TraceEvent};

/// Runs `task` with a recorder; asserts the run ends and the trace passes the checker.
pub(crate) async fn run_checked(task: Task) -> (Report, Vec<TraceEvent>) {
    tcm::testing::run_checked(Runtime::new(), task).await
}

pub(crate) use tcm::testing::{lines, story};
