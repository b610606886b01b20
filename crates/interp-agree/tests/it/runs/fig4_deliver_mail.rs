//! `fig4_deliver_mail.tdl`: the TDL paper's Figure 4, a delivery that centres on a door by
//! recursion. The robot is Rust here: `robot::look_for_door` sees the door to the left, then to
//! the right, then ahead (so the recursion ends), `robot::move_by` takes a second per metre and
//! stalls (an error `?` passes on) beyond 20; `navigate_to_locn`, `speak` and
//! `monitor_pickup` are commands built in Rust.

use tdl::Task;
use tdl_interp::{Registry, Value};

use crate::util::{Case, command};

include!(concat!(env!("OUT_DIR"), "/fig4_deliver_mail.rs"));

fn get_room_coordinates(room: u32) -> (f64, f64) {
    (f64::from(room) * 2.0, 0.5)
}

fn navigate_to_locn(_x: f64, _y: f64) -> Task {
    command("navigate_to_locn", 3000)
}

fn speak(_text: &str) -> Task {
    command("speak", 800)
}

fn monitor_pickup() -> Task {
    command("monitor_pickup", 5000)
}

mod robot {
    use std::time::Duration;

    /// The robot could not move that far.
    #[derive(Clone, Debug)]
    pub(super) struct Stalled {
        pub(super) dist: f64,
    }

    impl std::fmt::Display for Stalled {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            write!(f, "stalled moving {}", self.dist)
        }
    }

    impl std::error::Error for Stalled {}

    pub(super) async fn look_for_door() -> i32 {
        tokio::time::sleep(Duration::from_millis(400)).await;
        match crate::util::tick("door") {
            0 => -1,
            1 => 1,
            _ => 0,
        }
    }

    pub(super) async fn move_by(dist: f64) -> Result<(), Stalled> {
        tokio::time::sleep(Duration::from_secs_f64(dist.abs())).await;
        if dist.abs() > 20.0 {
            return Err(Stalled { dist });
        }
        Ok(())
    }
}

fn case() -> Case {
    let mut registry = Registry::new();
    registry
        .function("get_room_coordinates", get_room_coordinates)
        .task("navigate_to_locn", navigate_to_locn)
        .task("speak", |text: String| speak(&text))
        .task("monitor_pickup", monitor_pickup)
        .async_function("robot::look_for_door", robot::look_for_door)
        .async_function("robot::move_by", robot::move_by);
    Case::new(&["fig4_deliver_mail"], &registry)
}

#[tokio::test(start_paused = true)]
async fn delivering_mail_runs_alike() {
    case()
        .alike(deliver_mail(3), "deliver_mail", vec![Value::Int(3)])
        .await;
}

#[tokio::test(start_paused = true)]
async fn centring_on_a_door_by_recursion_runs_alike() {
    let args = vec![Value::Float(6.0), Value::Float(0.5)];
    case()
        .alike(center_on_door(6.0, 0.5), "center_on_door", args)
        .await;
}

#[tokio::test(start_paused = true)]
async fn the_commands_run_alike() {
    let case = case();
    case.alike(look_for_door(), "look_for_door", vec![]).await;
    case.alike(move_by(-10.0), "move_by", vec![Value::Float(-10.0)])
        .await;
    case.alike(move_by(30.0), "move_by", vec![Value::Float(30.0)])
        .await;
}
