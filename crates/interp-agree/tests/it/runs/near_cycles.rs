//! `near_cycles.tdl`: constraints that look circular but can be satisfied, and one the run
//! refuses (`too_late`). `step` and `report` are commands built in Rust here, `step(n)` taking
//! n × 100 ms. Every goal and command runs.

use tdl::Task;
use tdl_interp::{Registry, Value};

use crate::util::{Case, command};

include!(concat!(env!("OUT_DIR"), "/near_cycles.rs"));

fn step(n: u32) -> Task {
    command("step", 100 * u64::from(n))
}

fn report() -> Task {
    command("report", 50)
}

fn case() -> Case {
    let mut registry = Registry::new();
    registry.task("step", step).task("report", report);
    Case::new(&["near_cycles"], &registry)
}

#[tokio::test(start_paused = true)]
async fn a_spawn_that_may_not_run_runs_alike() {
    let case = case();
    case.alike(conditional(true), "conditional", vec![Value::Bool(true)])
        .await;
    case.alike(conditional(false), "conditional", vec![Value::Bool(false)])
        .await;
}

#[tokio::test(start_paused = true)]
async fn terminations_and_activations_run_alike() {
    let case = case();
    case.alike(terminations(), "terminations", vec![]).await;
    case.alike(activations(), "activations", vec![]).await;
}

#[tokio::test(start_paused = true)]
async fn void_and_facet_constraints_run_alike() {
    let case = case();
    case.alike(commands(), "commands", vec![]).await;
    case.alike(executions(), "executions", vec![]).await;
    case.alike(after_the_body(), "after_the_body", vec![]).await;
    for (compiled, name) in [
        (move_a as fn() -> Task, "move_a"),
        (move_b, "move_b"),
        (plan_a, "plan_a"),
        (plan_b, "plan_b"),
    ] {
        case.alike(compiled(), name, vec![]).await;
    }
}

#[tokio::test(start_paused = true)]
async fn iterations_in_turn_run_alike() {
    case()
        .alike(in_loops(4), "in_loops", vec![Value::Int(4)])
        .await;
}

#[tokio::test(start_paused = true)]
async fn a_constraint_refused_at_run_time_runs_alike() {
    case().alike(too_late(), "too_late", vec![]).await;
}
