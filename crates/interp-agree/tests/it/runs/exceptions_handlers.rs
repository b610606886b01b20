//! `exceptions_handlers.tdl`: exceptions with data and ancestors, handlers that bypass, keep a
//! persistent count, or recover by spawning. The robot it calls is Rust here: a planner that
//! finds no path to a negative `x`, a motor whose temperature the test sets (`cool_down` brings
//! it down), and `robot::follow`, which takes a second per waypoint and fails beyond `x = 50`.

use std::cell::Cell;
use std::time::Duration;

use tdl::{NodeKind, Task};
use tdl_interp::{Registry, Value};

use crate::util::{Case, command};

include!(concat!(env!("OUT_DIR"), "/exceptions_handlers.rs"));

thread_local! {
    static HEAT: Cell<f64> = const { Cell::new(60.0) };
}

fn motor_temperature() -> f64 {
    HEAT.with(Cell::get)
}

fn temperature_is_critical() -> bool {
    motor_temperature() > 100.0
}

fn plan_path(x: f64, y: f64) -> Vec<(f64, f64)> {
    if x < 0.0 {
        return Vec::new();
    }
    vec![(0.0, 0.0), (x / 2.0, y / 2.0), (x, y)]
}

fn here() -> (f64, f64) {
    (0.0, 0.0)
}

mod robot {
    use std::time::Duration;

    pub(super) async fn follow(path: Vec<(f64, f64)>) -> bool {
        let n = u64::try_from(path.len()).unwrap_or(u64::MAX);
        tokio::time::sleep(Duration::from_secs(n)).await;
        path.iter().all(|(x, _)| *x <= 50.0)
    }
}

fn cool_down() -> Task {
    Task::new(NodeKind::Command, "cool_down", |_ctx| async {
        tokio::time::sleep(Duration::from_secs(2)).await;
        HEAT.with(|h| h.set(60.0));
        Ok::<(), tdl::Failure>(())
    })
}

fn call_for_help() -> Task {
    command("call_for_help", 500)
}

fn replan() -> Task {
    command("replan", 700)
}

fn case(heat: f64) -> Case {
    let mut registry = Registry::new();
    registry
        .function("motor_temperature", motor_temperature)
        .function("temperature_is_critical", temperature_is_critical)
        .function("plan_path", plan_path)
        .function("here", here)
        .async_function("robot::follow", robot::follow)
        .task("cool_down", cool_down)
        .task("call_for_help", call_for_help)
        .task("replan", replan);
    Case::new(&["exceptions_handlers"], &registry).before(move || HEAT.with(|h| h.set(heat)))
}

fn at(x: f64, y: f64) -> Vec<Value> {
    vec![Value::Float(x), Value::Float(y)]
}

#[tokio::test(start_paused = true)]
async fn a_navigation_that_works_runs_alike() {
    case(60.0)
        .alike(navigate_to_locn(4.0, 2.0), "navigate_to_locn", at(4.0, 2.0))
        .await;
}

#[tokio::test(start_paused = true)]
async fn no_path_handled_with_a_persistent_count_runs_alike() {
    case(60.0)
        .alike(
            navigate_to_locn(-1.0, 2.0),
            "navigate_to_locn",
            at(-1.0, 2.0),
        )
        .await;
}

#[tokio::test(start_paused = true)]
async fn a_hardware_failure_handled_at_the_spawn_runs_alike() {
    case(60.0)
        .alike(
            navigate_to_locn(80.0, 0.0),
            "navigate_to_locn",
            at(80.0, 0.0),
        )
        .await;
}

#[tokio::test(start_paused = true)]
async fn overheating_cooled_down_runs_alike() {
    let case = case(90.0);
    case.alike(navigate_to_locn(4.0, 2.0), "navigate_to_locn", at(4.0, 2.0))
        .await;
}

#[tokio::test(start_paused = true)]
async fn critical_overheating_bypassed_runs_alike() {
    case(120.0)
        .alike(navigate_to_locn(4.0, 2.0), "navigate_to_locn", at(4.0, 2.0))
        .await;
}

#[tokio::test(start_paused = true)]
async fn following_a_path_runs_alike() {
    let path = |points: &[(f64, f64)]| {
        let items = points
            .iter()
            .map(|(x, y)| Value::tuple(vec![Value::Float(*x), Value::Float(*y)]));
        vec![Value::list(items)]
    };
    let case = case(60.0);
    let points = [(1.0, 1.0), (2.0, 2.0)];
    case.alike(follow_path(points.to_vec()), "follow_path", path(&points))
        .await;
    let far = [(1.0, 1.0), (70.0, 2.0)];
    case.alike(follow_path(far.to_vec()), "follow_path", path(&far))
        .await;
}
