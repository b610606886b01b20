//! `bounded_recursion.tdl`: recursive goals with a base case, or that something may stop. The
//! program spawns `work`, `attempt` and `check` without declaring them: commands built in Rust
//! here, `check` (a waited value) saying yes twice, then failing, so that the recursion through
//! it ends. `watched`, `stoppable`, `on_failure` and `per_item` with an item expand their
//! recursive spawn at once, whatever holds its execution, and so recurse without end at the
//! same instant, compiled as interpreted: they are not run (`per_item` of no items is).

// The program as written (a variable it does not read) and as generated.
#![allow(unused_variables)]
// `watched`, `stoppable` and `on_failure`, not run.
#![allow(dead_code)]

use std::time::Duration;

use tdl::{Failure, NodeKind, Task};
use tdl_interp::{Registry, Value};

use crate::util::{Case, command, tick};

include!(concat!(env!("OUT_DIR"), "/bounded_recursion.rs"));

fn work() -> Task {
    command("work", 300)
}

fn attempt() -> Task {
    Task::new(NodeKind::Command, "attempt", |_ctx| async {
        tokio::time::sleep(Duration::from_millis(100)).await;
        Err::<(), _>(Failure::new("Missed", "the attempt missed"))
    })
}

fn check() -> Task {
    Task::new(NodeKind::Command, "check", |_ctx| async {
        tokio::time::sleep(Duration::from_millis(50)).await;
        if tick("check") < 2 {
            return Ok(true);
        }
        Err(Failure::new("Broken", "the check broke"))
    })
}

fn case() -> Case {
    let mut registry = Registry::new();
    registry
        .task("work", work)
        .task("attempt", attempt)
        .task("check", check);
    Case::new(&["bounded_recursion"], &registry)
}

#[tokio::test(start_paused = true)]
async fn recursions_with_a_base_case_run_alike() {
    let case = case();
    case.alike(count_down(3), "count_down", vec![Value::Int(3)])
        .await;
    case.alike(retry_until(2), "retry_until", vec![Value::Int(2)])
        .await;
    case.alike(per_item(vec![]), "per_item", vec![Value::list([])])
        .await;
}

#[tokio::test(start_paused = true)]
async fn a_recursion_that_a_failed_wait_ends_runs_alike() {
    case().alike(fallible(), "fallible", vec![]).await;
}

#[tokio::test(start_paused = true)]
async fn a_command_with_a_handler_runs_alike() {
    case().alike(lift(), "lift", vec![]).await;
}
