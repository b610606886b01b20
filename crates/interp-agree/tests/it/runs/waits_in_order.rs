//! `waits_in_order.tdl`: waits that end, on nodes spawned before the wait or that hold nothing.
//! `step` is a command built in Rust here, `step(n)` taking n × 100 ms.

use tdl::Task;
use tdl_interp::Registry;

use crate::util::{Case, command};

include!(concat!(env!("OUT_DIR"), "/waits_in_order.rs"));

fn step(n: u32) -> Task {
    command("step", 100 * u64::from(n))
}

#[tokio::test(start_paused = true)]
async fn waits_that_end_run_alike() {
    let mut registry = Registry::new();
    registry.task("step", step);
    let case = Case::new(&["waits_in_order"], &registry);
    for (compiled, name) in [
        (wait_after_both as fn() -> Task, "wait_after_both"),
        (later_spawn_waits_for_it, "later_spawn_waits_for_it"),
        (terminate_only, "terminate_only"),
        (command_expansion, "command_expansion"),
        (move_a, "move_a"),
    ] {
        case.alike(compiled(), name, vec![]).await;
    }
}
