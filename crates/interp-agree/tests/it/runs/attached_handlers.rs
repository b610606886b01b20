//! `attached_handlers.tdl`: handlers attached with `for` to every node of a task, reading its
//! arguments and retrying it with new ones. The program calls `log`, a Rust function here.

use tdl_interp::{Registry, Value};

use crate::util::{Case, note};

include!(concat!(env!("OUT_DIR"), "/attached_handlers.rs"));

fn log(text: String) {
    note(text);
}

fn case() -> Case {
    let mut registry = Registry::new();
    registry.function("log", log);
    Case::new(&["attached_handlers"], &registry).attached(|| vec![raise_leg(), stop_walking()])
}

#[tokio::test(start_paused = true)]
async fn a_walk_retried_by_its_attached_handler_runs_alike() {
    case().alike(walk(), "walk", vec![]).await;
}

#[tokio::test(start_paused = true)]
async fn a_leg_move_that_touches_or_not_runs_alike() {
    let case = case();
    let args = |leg, lift| vec![Value::Int(leg), Value::Int(lift)];
    case.alike(move_leg(1, 150), "move_leg", args(1, 150)).await;
    case.alike(move_leg(2, 450), "move_leg", args(2, 450)).await;
}
