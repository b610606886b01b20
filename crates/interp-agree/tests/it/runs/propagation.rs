//! `propagation.tdl`: steps that fail their sequence (`propagate`), a handler on it, how a child
//! ended as a value. Every task is declared in the file.

// The program as written (a variable it does not read) and as generated.
#![allow(unused_variables)]

use tdl_interp::{Registry, Value};

use crate::util::Case;

include!(concat!(env!("OUT_DIR"), "/propagation.rs"));

#[tokio::test(start_paused = true)]
async fn a_mission_over_propagating_steps_runs_alike() {
    let case = Case::new(&["propagation"], &Registry::new());
    case.alike(mission(), "mission", vec![]).await;
    case.alike(sequence(), "sequence", vec![]).await;
    case.alike(step(7), "step", vec![Value::Int(7)]).await;
    case.alike(measure(), "measure", vec![]).await;
}
