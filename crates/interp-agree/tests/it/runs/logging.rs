//! `logging.tdl`: `log` statements in a goal, commands, a monitor and a handler, formatted every
//! way `format!` formats, with state read by `state!`. Every task is declared in the file; the
//! runs' `log` records (their lines and times) are part of the traces compared.

use std::time::Duration;

use tdl_interp::{Registry, Value};

use crate::util::Case;

include!(concat!(env!("OUT_DIR"), "/logging.rs"));

fn case() -> Case {
    Case::new(&["logging"], &Registry::new())
}

#[tokio::test(start_paused = true)]
async fn a_tour_that_logs_as_it_goes_runs_alike() {
    let rooms = [3u32, 0, 5];
    let values = rooms.iter().map(|r| Value::Int(i64::from(*r)));
    case()
        .alike(
            tour(rooms.to_vec(), "east".into()),
            "tour",
            vec![Value::list(values), Value::str("east")],
        )
        .await;
}

#[tokio::test(start_paused = true)]
async fn tasks_that_log_run_alike() {
    let case = case();
    case.alike(drive(4), "drive", vec![Value::Int(4)]).await;
    case.alike(drive(0), "drive", vec![Value::Int(0)]).await;
    case.alike(report("west".into()), "report", vec![Value::str("west")])
        .await;
}
