//! Compiles the programs of `tdl-syntax`'s `test_data/ok` that the interpreter runs, each a
//! program of its own (with its driver, for a program that has nothing to run by itself), into
//! `$OUT_DIR/<file stem>.rs`; the modules of `tests/it/runs/` include them beside the Rust items
//! the programs call. The programs the interpreter refuses are not compiled: their tests only
//! load them (`tests/it/refused.rs`). `tests/it/main.rs`'s `RUNS` names the same programs, and a
//! test checks that each was compiled.

/// The files of each program, relative to this package.
const PROGRAMS: [&[&str]; 22] = [
    &["allowed_warnings"],
    &["approvals"],
    &["attached_handlers"],
    &["attached_to_extern", "drivers/attached_to_extern_driver"],
    &["blocking_commands"],
    &["bounded_recursion"],
    &["exceptions_handlers"],
    &["external_events"],
    &["fig4_deliver_mail"],
    &["fig6_monitor_pickup", "drivers/fig6_monitor_pickup_driver"],
    &["forward_references"],
    &["handled_exceptions"],
    &["handlers_retry"],
    &["logging"],
    &["loops_iteration_tags"],
    &["near_cycles"],
    &[
        "node_refs_bind_parent",
        "drivers/node_refs_bind_parent_driver",
    ],
    &["outcome_events"],
    &["propagation"],
    &["resources"],
    &["waits_in_order"],
    &["with_groups_deliver_mail"],
];

fn main() {
    for files in PROGRAMS {
        tdl_build::compile_all(files.iter().map(|f| {
            if f.starts_with("drivers/") {
                format!("{f}.tdl")
            } else {
                format!("../tdl-syntax/test_data/ok/{f}.tdl")
            }
        }));
    }
}
