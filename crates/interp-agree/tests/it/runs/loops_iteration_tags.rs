//! `loops_iteration_tags.tdl`: spawns in `for`, nested and labelled loops, `while`, `loop` and
//! `match` arms, with constraints on iteration-indexed tags. The robot is Rust here: commands of
//! different lengths, `blocked` at row 1, column 1 (so `break 'rows` ends a 3 × 3 grid early),
//! a door open from the third look, and `mode`, an enum of the test's that the program matches
//! (`Mode::Fast`, `Mode::Careful`), a variant value for the interpreter. In `square`, the
//! statement `move_by[i] sequential execution turn[i - 1]` constrains a node after its spawn,
//! while the body still holds it: the checker accepts the enablement of a facet still disabled.

// The program as generated.
#![allow(clippy::unused_unit, clippy::explicit_counter_loop)]

use std::cell::Cell;

use tdl::Task;
use tdl_interp::{Registry, Value};

use crate::util::{Case, command, tick};

include!(concat!(env!("OUT_DIR"), "/loops_iteration_tags.rs"));

/// How the robot goes.
#[derive(Clone, Copy, Debug)]
enum Mode {
    Fast,
    Careful,
    Idle,
}

impl Mode {
    fn value(self) -> Value {
        Value::variant("Mode", &format!("{self:?}"), vec![])
    }
}

thread_local! {
    static MODE: Cell<Mode> = const { Cell::new(Mode::Idle) };
}

fn mode() -> Mode {
    MODE.with(Cell::get)
}

fn blocked(row: usize, col: usize) -> bool {
    row == 1 && col == 1
}

fn door_open() -> bool {
    tick("door") >= 2
}

fn move_by(side: f64) -> Task {
    command("move_by", (side * 100.0) as u64)
}

fn turn(_degrees: f64) -> Task {
    command("turn", 250)
}

fn visit(row: usize, col: usize) -> Task {
    command("visit", 100 + 50 * (row as u64) + 20 * (col as u64))
}

fn report() -> Task {
    command("report", 100)
}

fn scan(n: u32) -> Task {
    command("scan", 100 * u64::from(n + 1))
}

fn wait_for_door() -> Task {
    command("wait_for_door", 500)
}

fn sprint() -> Task {
    command("sprint", 200)
}

fn creep() -> Task {
    command("creep", 900)
}

fn case(now: Mode) -> Case {
    let mut registry = Registry::new();
    registry
        .function("blocked", blocked)
        .function("door_open", door_open)
        .function("mode", || mode().value())
        .task("move_by", move_by)
        .task("turn", turn)
        .task("visit", visit)
        .task("report", report)
        .task("scan", scan)
        .task("wait_for_door", wait_for_door)
        .task("sprint", sprint)
        .task("creep", creep);
    Case::new(&["loops_iteration_tags"], &registry).before(move || MODE.with(|m| m.set(now)))
}

#[tokio::test(start_paused = true)]
async fn a_square_with_iteration_tags_traces_alike() {
    case(Mode::Idle)
        .alike(square(2.5), "square", vec![Value::Float(2.5)])
        .await;
}

#[tokio::test(start_paused = true)]
async fn a_grid_of_nested_loops_runs_alike() {
    let case = case(Mode::Idle);
    case.alike(grid(3), "grid", vec![Value::Int(3)]).await;
    case.alike(grid(1), "grid", vec![Value::Int(1)]).await;
    case.alike(grid(0), "grid", vec![Value::Int(0)]).await;
}

#[tokio::test(start_paused = true)]
async fn a_search_in_every_mode_runs_alike() {
    for mode in [Mode::Fast, Mode::Careful, Mode::Idle] {
        case(mode).alike(search(), "search", vec![]).await;
    }
}
