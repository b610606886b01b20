//! `blocking_commands.tdl`: commands whose bodies run on a blocking thread, with a value, a
//! resource and `persistent`. Every task is declared in the file.
//!
//! `deliver` runs `sweep` and `calibrate` at the same instant, each on a thread of its own: the
//! order in which their records interleave changes from one run to the next, compiled as
//! interpreted (two compiled runs differ). Its runs are compared node by node
//! ([`Compare::PerNode`]): each node's records in order, the outcome, the notes.

// The program as written (a variable it does not read) and as generated.
#![allow(unused_variables)]
// `pub blocking command plan_path`, public in a test crate.
#![allow(unreachable_pub)]

use tdl_interp::{Registry, Value};

use crate::util::{Case, Compare};

include!(concat!(env!("OUT_DIR"), "/blocking_commands.rs"));

fn case() -> Case {
    Case::new(&["blocking_commands"], &Registry::new())
}

#[tokio::test(start_paused = true)]
async fn a_goal_waiting_for_a_blocking_command_runs_alike() {
    let case = case().compare(Compare::PerNode);
    case.alike(deliver(4), "deliver", vec![Value::Int(4)]).await;
    case.alike(deliver(0), "deliver", vec![Value::Int(0)]).await;
}

#[tokio::test(start_paused = true)]
async fn blocking_commands_run_alike() {
    let case = case();
    case.alike(plan_path(5), "plan_path", vec![Value::Int(5)])
        .await;
    case.alike(calibrate(), "calibrate", vec![]).await;
    case.alike(sweep(), "sweep", vec![]).await;
    case.alike(log_done(), "log_done", vec![]).await;
}
