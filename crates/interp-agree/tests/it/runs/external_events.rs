//! `external_events.tdl`: spawns held, terminated and activated by named external events. The
//! program spawns `drive`, `follow_path` and `external` without declaring them: commands built in
//! Rust here. The test raises the events it waits for during the run, at the same virtual
//! times in both runs, and once more each of those a monitor counts.

use tdl::Task;
use tdl_interp::{Registry, Value};

use crate::util::{Case, command};

include!(concat!(env!("OUT_DIR"), "/external_events.rs"));

fn drive() -> Task {
    command("drive", 1500)
}

fn follow_path() -> Task {
    command("follow_path", 20_000)
}

fn external() -> Task {
    command("external", 2500)
}

fn case(events: &[(u64, &str)]) -> Case {
    let mut registry = Registry::new();
    registry
        .task("drive", drive)
        .task("follow_path", follow_path)
        .task("external", external);
    Case::new(&["external_events"], &registry).events(events)
}

#[tokio::test(start_paused = true)]
async fn a_navigation_driven_by_events_runs_alike() {
    let events = [
        (500, "map_ready"),
        (1250, "go"),
        (2100, "tick"),
        (2600, "bump"),
        (3300, "tick"),
        (4700, "goal_updated"),
        (5900, "nav/cancel"),
        (7100, "abort"),
        (8300, "stop"),
    ];
    case(&events)
        .alike(navigate("nav".into()), "navigate", vec![Value::str("nav")])
        .await;
}

#[tokio::test(start_paused = true)]
async fn a_navigation_stopped_early_runs_alike() {
    let events = [(300, "stop"), (900, "go"), (1800, "map_ready")];
    case(&events)
        .alike(navigate("nav".into()), "navigate", vec![Value::str("nav")])
        .await;
}
