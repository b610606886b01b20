//! The interpreter held to the compiler on every program of `tdl-syntax`'s `test_data/ok`.
//!
//! A program the interpreter runs (`RUNS`) is compiled by the build script and included in its
//! module of `runs/`, which runs each of its goals and commands compiled and interpreted on
//! virtual time and asserts the same trace, record for record (`util.rs`). A program it refuses
//! (`REFUSED`) is loaded and its diagnostics snapshotted (`refused.rs`). A file of
//! `test_data/ok` in neither list fails `every_ok_program_is_classified`.

mod refused;
mod runs;
mod util;

use std::path::Path;

/// The programs the interpreter runs as the compiler does: each compiled by `build.rs`, with a
/// module of its own in `runs/`.
const RUNS: [&str; 22] = [
    "allowed_warnings",
    "approvals",
    "attached_handlers",
    "attached_to_extern",
    "blocking_commands",
    "bounded_recursion",
    "exceptions_handlers",
    "external_events",
    "fig4_deliver_mail",
    "fig6_monitor_pickup",
    "forward_references",
    "handled_exceptions",
    "handlers_retry",
    "logging",
    "loops_iteration_tags",
    "near_cycles",
    "node_refs_bind_parent",
    "outcome_events",
    "propagation",
    "resources",
    "waits_in_order",
    "with_groups_deliver_mail",
];

/// The programs the interpreter refuses, each for Rust outside its subset: a snapshot of the
/// diagnostics each in `snapshots/`.
const REFUSED: [&str; 5] = [
    "conditional_spawns",
    "every_constraint",
    "monitors_all_params",
    "rust_items",
    "state_conditions",
];

/// The stems of the `.tdl` files of `test_data/ok`, sorted.
fn ok_programs() -> Vec<String> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tdl-syntax/test_data/ok");
    let mut stems: Vec<String> = std::fs::read_dir(&dir)
        .expect("test_data/ok reads")
        .filter_map(Result::ok)
        .map(|it| it.path())
        .filter(|it| it.extension().is_some_and(|ext| ext == "tdl"))
        .filter_map(|it| Some(it.file_stem()?.to_string_lossy().into_owned()))
        .collect();
    stems.sort();
    stems
}

/// A new program of `test_data/ok` must be classified: run (and compiled, with a module of its
/// own) or refused (with its snapshot); and no list names a program that is gone.
#[test]
fn every_ok_program_is_classified() {
    let ok = ok_programs();
    assert!(ok.len() >= 24, "expected the ok/ corpus, found {ok:?}");
    for stem in &ok {
        let runs = RUNS.contains(&stem.as_str());
        let refused = REFUSED.contains(&stem.as_str());
        assert!(
            runs != refused,
            "test_data/ok/{stem}.tdl must be in exactly one of RUNS and REFUSED (tests/it/main.rs): \
             a module in tests/it/runs/ and an entry in build.rs if the interpreter runs it, a \
             snapshot test in tests/it/refused.rs if it refuses it"
        );
    }
    let here = Path::new(env!("CARGO_MANIFEST_DIR"));
    for stem in RUNS {
        assert!(
            ok.iter().any(|it| it == stem),
            "{stem} is not in test_data/ok"
        );
        let compiled = Path::new(env!("OUT_DIR")).join(format!("{stem}.rs"));
        assert!(compiled.exists(), "build.rs does not compile {stem}");
        let module = here.join(format!("tests/it/runs/{stem}.rs"));
        assert!(module.exists(), "{stem} has no module in tests/it/runs");
    }
    for stem in REFUSED {
        assert!(
            ok.iter().any(|it| it == stem),
            "{stem} is not in test_data/ok"
        );
        let snapshot = here.join(format!("tests/it/snapshots/{stem}.snap"));
        assert!(snapshot.exists(), "{stem} has no snapshot of its refusal");
    }
}
