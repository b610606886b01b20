//! `allowed_warnings.tdl`: warnings accepted with `#[allow(tdl::NAME)]`. Every goal and command
//! is declared in the file; each runs alike, with arguments that take each branch, but
//! `patrol`: a patrol "that runs until it is terminated from outside" spawns itself again at the
//! instant its step fails (a `wait` on a failed child goes on), so it never lets virtual time
//! pass, compiled as interpreted.

// `patrol`, not run.
#![allow(dead_code)]

use tdl_interp::{Registry, Value};

use crate::util::Case;

include!(concat!(env!("OUT_DIR"), "/allowed_warnings.rs"));

fn case() -> Case {
    Case::new(&["allowed_warnings"], &Registry::new())
}

#[tokio::test(start_paused = true)]
async fn commands_that_fail_or_not_run_alike() {
    let case = case();
    case.alike(step(), "step", vec![]).await;
    case.alike(check(true), "check", vec![Value::Bool(true)])
        .await;
    case.alike(check(false), "check", vec![Value::Bool(false)])
        .await;
    case.alike(vague(), "vague", vec![]).await;
    case.alike(pick(0), "pick", vec![Value::Int(0)]).await;
    case.alike(pick(3), "pick", vec![Value::Int(3)]).await;
}

#[tokio::test(start_paused = true)]
async fn goals_run_alike() {
    let case = case();
    case.alike(maybe(true), "maybe", vec![Value::Bool(true)])
        .await;
    case.alike(maybe(false), "maybe", vec![Value::Bool(false)])
        .await;
    case.alike(odd(), "odd", vec![]).await;
    case.alike(quiet(), "quiet", vec![]).await;
}
