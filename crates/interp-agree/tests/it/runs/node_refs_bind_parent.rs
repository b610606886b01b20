//! `node_refs_bind_parent.tdl`: node references both ways, `bind`, spawns under another node,
//! labelled on-terminate tasks, monitor limits set after the spawn. `grasp` takes a node of the
//! run: `drivers/node_refs_bind_parent_driver.tdl` spawns it with the node of a supervising
//! command. The commands it spawns without declaring them are built in Rust here, and `log`
//! notes the two nodes it is given.

// The program as written (a variable it does not read) and as generated.
#![allow(
    unused_variables,
    unused_parens,
    clippy::double_parens,
    clippy::explicit_counter_loop
)]

use tdl::{NodeId, Task};
use tdl_interp::Registry;

use crate::util::{Case, command, note};

include!(concat!(env!("OUT_DIR"), "/node_refs_bind_parent.rs"));
include!(concat!(env!("OUT_DIR"), "/node_refs_bind_parent_driver.rs"));

fn log(step: NodeId, this: NodeId) {
    note(format!("{step:?} in {this:?}"));
}

fn supervise() -> Task {
    command("supervise", 3000)
}

fn hold() -> Task {
    command("hold", 1200)
}

fn release() -> Task {
    command("release", 200)
}

fn stow() -> Task {
    command("stow", 400)
}

fn report(_of: NodeId) -> Task {
    command("report", 100)
}

fn step(i: u32) -> Task {
    command("step", 100 * u64::from(i + 1))
}

#[tokio::test(start_paused = true)]
async fn a_grasp_under_a_bound_node_runs_alike() {
    let mut registry = Registry::new();
    registry
        .function("log", log)
        .task("supervise", supervise)
        .task("hold", hold)
        .task("release", release)
        .task("stow", stow)
        .task("report", report)
        .task("step", step);
    Case::new(
        &["node_refs_bind_parent", "node_refs_bind_parent_driver"],
        &registry,
    )
    .alike(drive_grasp(), "drive_grasp", vec![])
    .await;
}
