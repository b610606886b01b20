//! `with_groups_deliver_mail.tdl`: the paper's rewrite of deliverMail with `with` groups, and
//! nested, labelled serial and parallel groups. The tasks it spawns without declaring them are
//! commands built in Rust here, of different lengths (`center_on_door` outlasts its 30 s).

use tdl::Task;
use tdl_interp::{Registry, Value};

use crate::util::{Case, command};

include!(concat!(env!("OUT_DIR"), "/with_groups_deliver_mail.rs"));

fn get_room_coordinates(room: u32) -> (f64, f64) {
    (f64::from(room) * 2.0, 0.5)
}

fn navigate_to_locn(_x: f64, _y: f64) -> Task {
    command("navigate_to_locn", 3000)
}

fn center_on_door(x: f64, _y: f64) -> Task {
    command("center_on_door", (x * 10_000.0) as u64)
}

fn speak(_text: &str) -> Task {
    command("speak", 800)
}

fn monitor_pickup() -> Task {
    command("monitor_pickup", 5000)
}

fn go_to(n: u32) -> Task {
    command("go_to", 1000 * u64::from(n))
}

fn look_left() -> Task {
    command("look_left", 400)
}

fn look_right() -> Task {
    command("look_right", 600)
}

fn report() -> Task {
    command("report", 100)
}

fn beep() -> Task {
    command("beep", 10)
}

fn case() -> Case {
    let mut registry = Registry::new();
    registry
        .function("get_room_coordinates", get_room_coordinates)
        .task("navigate_to_locn", navigate_to_locn)
        .task("center_on_door", center_on_door)
        .task("speak", |text: String| speak(&text))
        .task("monitor_pickup", monitor_pickup)
        .task("go_to", go_to)
        .task("look_left", look_left)
        .task("look_right", look_right)
        .task("report", report)
        .task("beep", beep);
    Case::new(&["with_groups_deliver_mail"], &registry)
}

#[tokio::test(start_paused = true)]
async fn delivering_mail_in_groups_runs_alike() {
    let case = case();
    // Centring takes 20 s in room 1, 40 s (cut at 30 s) in room 2.
    case.alike(deliver_mail(1), "deliver_mail", vec![Value::Int(1)])
        .await;
    case.alike(deliver_mail(2), "deliver_mail", vec![Value::Int(2)])
        .await;
}

#[tokio::test(start_paused = true)]
async fn a_patrol_in_nested_groups_runs_alike() {
    case().alike(patrol(), "patrol", vec![]).await;
}
