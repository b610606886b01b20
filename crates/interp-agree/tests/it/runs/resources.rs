//! `resources.tdl`: resources with capacities and a pending limit, `uses`, `priority`,
//! `deny if busy`, `lock`, `reserve`, and handlers of the runtime's own exceptions
//! (`ResourceDenied`, `ResourceDropped`), which the program handles without declaring them.
//! Every task is declared in the file: the registry is empty.

// The program as written (a variable it does not read) and as generated.
#![allow(unused_variables, unused_parens, clippy::double_parens)]

use tdl::Task;
use tdl_interp::{Registry, Value};

use crate::util::Case;

include!(concat!(env!("OUT_DIR"), "/resources.rs"));

fn case() -> Case {
    Case::new(&["resources"], &Registry::new())
}

#[tokio::test(start_paused = true)]
async fn fetching_with_resources_runs_alike() {
    let case = case();
    case.alike(fetch(1), "fetch", vec![Value::Int(1)]).await;
    case.alike(fetch(2), "fetch", vec![Value::Int(2)]).await;
    case.alike(fetch(3), "fetch", vec![Value::Int(3)]).await;
}

#[tokio::test(start_paused = true)]
async fn commands_using_resources_run_alike() {
    let case = case();
    case.alike(drive(1.5), "drive", vec![Value::Float(1.5)])
        .await;
    for (compiled, name) in [
        (plan_path as fn() -> Task, "plan_path"),
        (grasp, "grasp"),
        (snap, "snap"),
    ] {
        case.alike(compiled(), name, vec![]).await;
    }
}
