//! `handled_exceptions.tdl`: every exception raised has a handler on some way up (at the spawn,
//! two levels up, attached with `for`, a handler's own failure handled above), or the body takes
//! the failure. `log` and `backup` (a command) are Rust here. Every goal and command runs,
//! `lift` and `carry` recovered by `unjam`, attached `for lift` and without parameters (it reads
//! no arguments of the node it recovers).

use tdl::Task;
use tdl_interp::Registry;

use crate::util::{Case, command, note};

include!(concat!(env!("OUT_DIR"), "/handled_exceptions.rs"));

fn log(text: &str) {
    note(text);
}

fn backup() -> Task {
    command("backup", 600)
}

fn case() -> Case {
    let mut registry = Registry::new();
    registry
        .function("log", |text: String| log(&text))
        .task("backup", backup);
    Case::new(&["handled_exceptions"], &registry).attached(|| vec![unjam()])
}

#[tokio::test(start_paused = true)]
async fn goals_whose_failures_are_handled_run_alike() {
    let case = case();
    case.alike(walk(), "walk", vec![]).await;
    case.alike(mission(), "mission", vec![]).await;
    case.alike(supervised(), "supervised", vec![]).await;
    case.alike(arm(), "arm", vec![]).await;
}

#[tokio::test(start_paused = true)]
async fn goals_that_take_a_failure_run_alike() {
    let case = case();
    case.alike(look(), "look", vec![]).await;
    case.alike(fallback(), "fallback", vec![]).await;
    case.alike(stage(), "stage", vec![]).await;
    case.alike(wrist(), "wrist", vec![]).await;
}

#[tokio::test(start_paused = true)]
async fn failing_commands_run_alike() {
    let case = case();
    for (compiled, name) in [
        (step as fn() -> Task, "step"),
        (grip, "grip"),
        (probe, "probe"),
        (try_first, "try_first"),
        (jammer, "jammer"),
        (reset, "reset"),
        (finger, "finger"),
    ] {
        case.alike(compiled(), name, vec![]).await;
    }
}

#[tokio::test(start_paused = true)]
async fn a_goal_recovered_by_an_attached_handler_without_parameters_runs_alike() {
    case().alike(carry(), "carry", vec![]).await;
}

#[tokio::test(start_paused = true)]
async fn a_command_recovered_by_an_attached_handler_without_parameters_runs_alike() {
    case().alike(lift(), "lift", vec![]).await;
}
