//! The programs of `test_data/ok` the interpreter refuses, each for Rust outside the interpreted
//! subset: loaded with a registry offering every task and function they name that the file
//! does not declare (so that only the refusal is left), and the rendered diagnostics snapshotted
//! (`snapshots/<stem>.snap`). Each must say where (`ok/<stem>.tdl:line`) and what.

use tdl::{NodeKind, Task};
use tdl_interp::{LoadError, Registry};

use crate::util::try_load;

/// A task of the registry that the program never runs.
fn idle() -> Task {
    Task::new(NodeKind::Command, "idle", |_ctx| async {
        Ok::<(), tdl::Failure>(())
    })
}

/// Loads `stem` with `registry`, asserts the refusal and snapshots its text.
#[track_caller]
fn assert_refused(stem: &str, registry: &Registry, construct: &str) {
    let text = match try_load(&[stem], registry) {
        Ok(_) => panic!("the interpreter loads {stem}: move it to RUNS, with a module in runs/"),
        Err(LoadError::Invalid(text)) => text,
        Err(other) => panic!("{stem} is refused for another reason: {other}"),
    };
    assert!(
        text.contains(&format!("--> ok/{stem}.tdl:")),
        "the refusal is not located: {text}"
    );
    assert!(
        text.contains(construct),
        "the refusal does not name {construct}: {text}"
    );
    insta::with_settings!({
        snapshot_path => "snapshots",
        prepend_module_to_snapshot => false,
        description => format!("ok/{stem}.tdl, refused by the interpreter"),
        omit_expression => true,
    }, {
        insta::assert_snapshot!(stem, text);
    });
}

#[test]
fn conditional_spawns_is_refused_for_a_log_macro() {
    let mut r = Registry::new();
    r.task("lift_arm", idle)
        .task("drive", |_: f64| idle())
        .task("creep", |_: f64| idle())
        .task("stay", idle)
        .task("grasp", idle)
        .task("point_at", |_: u32| idle())
        .function("find_target", || Some(7_u32));
    assert_refused(
        "conditional_spawns",
        &r,
        "the macro `log::info!` is not in the interpreted subset",
    );
}

#[test]
fn every_constraint_is_refused_for_a_log_macro() {
    let mut r = Registry::new();
    r.task("step", |_: u32| idle())
        .task("clean_up", |_: u32| idle())
        .exception("StepFailed", &[]);
    assert_refused(
        "every_constraint",
        &r,
        "the macro `log::warn!` is not in the interpreted subset",
    );
}

#[test]
fn monitors_all_params_is_refused_for_a_computed_period() {
    let mut r = Registry::new();
    r.task("log_stop", |_: String| idle())
        .task("drive_forward", idle)
        .function("battery_level", || 0.5)
        .function("sonar_min", || 1.5)
        .function("sonar_period_s", || 0.4);
    assert_refused(
        "monitors_all_params",
        &r,
        "a computed monitor period is not in the interpreted subset",
    );
}

#[test]
fn rust_items_is_refused_for_its_rust_items() {
    let mut r = Registry::new();
    r.task("go_to", |_: f64, _: f64| idle());
    assert_refused(
        "rust_items",
        &r,
        "a Rust item in a TDL file is not in the interpreted subset",
    );
}

#[test]
fn state_conditions_is_refused_for_a_log_macro() {
    let mut r = Registry::new();
    r.async_function("robot::step", |_: u32| async {});
    assert_refused(
        "state_conditions",
        &r,
        "the macro `log::info!` is not in the interpreted subset",
    );
}
