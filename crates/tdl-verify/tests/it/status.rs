//! What a verification concludes as a whole ([`Report::status`], the exit status of `tdl verify`):
//! ok only when every property was decided and holds; undecided, with the bound named, when a
//! bound cut the search (`max_states`, `depth`, `max_memory`); violated with the counterexample
//! given as soon as it is found; an error for a property that names no node. And the built-in
//! properties one by one: a program meant to run until shutdown passes without `every run ends`.

use std::path::Path;

use tdl_verify::{
    Builtin, Control, Cut, NO_STUCK, Options, Program, Property, PropertyResult, RUNS_END, Report,
    SimOptions, Status, Verdict,
};

fn mission() -> Program {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../xavier/src/mission.tdl");
    let src = std::fs::read_to_string(&path).expect("the file reads");
    Program::load(&[(path.display().to_string(), src)]).expect("the program loads")
}

fn small() -> Options {
    Options {
        loops: 1,
        hangs: 0,
        ticks: 0,
        ..Options::default()
    }
}

fn verify(program: &Program, task: &str, options: &Options, properties: &[Property]) -> Report {
    tdl_verify::verify(
        program,
        task,
        options,
        properties,
        None,
        &Control::default(),
    )
}

fn undecided_by(report: &Report, property: &str, cut: &Cut) {
    match report.result(property).map(|r| &r.verdict) {
        Some(Verdict::Unknown(why)) => {
            assert_eq!(*why, format!("not decided: {cut}"), "{property}");
        }
        other => panic!("`{property}` should be undecided, got {other:?}"),
    }
}

#[test]
fn a_complete_search_is_ok_and_a_cut_one_undecided_by_its_bound() {
    let program = mission();
    let report = verify(&program, "deliver_all", &small(), &[]);
    assert_eq!(report.status(), Status::Ok);
    assert!(report.cuts.is_empty());
    for (options, cut) in [
        (
            Options {
                max_states: 10,
                ..small()
            },
            Cut::MaxStates(10),
        ),
        (
            Options {
                depth: 3,
                ..small()
            },
            Cut::Depth(3),
        ),
    ] {
        let report = verify(&program, "deliver_all", &options, &[]);
        assert_eq!(report.status(), Status::Undecided, "{cut:?}");
        assert_eq!(report.cuts, [cut]);
        assert!(!report.complete);
        for p in [NO_STUCK, RUNS_END] {
            undecided_by(&report, p, &cut);
        }
    }
    assert_eq!(Status::Ok.code(), 0);
    assert_eq!(Status::Violated.code(), 1);
    assert_eq!(Status::Error.code(), 2);
    assert_eq!(Status::Undecided.code(), 3);
}

/// At the memory bound the search ends as at any bound; a violation found before is kept, and was
/// given to the observer while the search ran.
#[test]
fn the_memory_bound_ends_the_search_and_keeps_what_was_found() {
    let program = mission();
    let detour = Property::parse("never active(detour)").expect("parses");
    let options = Options {
        max_memory: 1 << 20,
        ..Options::default()
    };
    let mut seen: Vec<String> = Vec::new();
    let report = tdl_verify::verify_observed(
        &program,
        "deliver_all",
        &options,
        std::slice::from_ref(&detour),
        None,
        &Control::default(),
        &mut |_| {},
        &mut |r: &PropertyResult| {
            assert!(r.is_violated());
            seen.push(r.property.clone());
        },
    );
    assert_eq!(seen, [detour.text()]);
    assert_eq!(report.status(), Status::Violated);
    let [Cut::MaxMemory { used, limit }] = report.cuts[..] else {
        panic!("cut by the memory bound: {:?}", report.cuts);
    };
    assert_eq!(limit, 1 << 20);
    assert!(used >= limit);
    assert!(
        report
            .result(detour.text())
            .is_some_and(PropertyResult::is_violated)
    );
    undecided_by(&report, NO_STUCK, &report.cuts[0]);
    // It stopped early: the whole search is millions of states.
    assert!(report.unique < 100_000, "{} states", report.unique);
    assert!(tdl_verify::default_max_memory() > 1 << 26);
}

#[test]
fn a_property_that_names_no_node_is_an_error() {
    let program = mission();
    let nobody = Property::parse("completed(plan_path) before active(nobody)").expect("parses");
    let report = verify(
        &program,
        "deliver_all",
        &small(),
        std::slice::from_ref(&nobody),
    );
    assert_eq!(report.status(), Status::Error);
    assert!(report.results.is_empty());
    assert!(
        report.errors[0].starts_with(
            "property `completed(plan_path) before active(nobody)` names `nobody`, which no node of the program is named; the names are: ACT-monitor_pickup, ACT-watch_motor, center_on_door"
        ),
        "{:?}",
        report.errors
    );
    let e = tdl_verify::check_names(&program, "deliver_all", &[nobody]).expect_err("unknown");
    assert_eq!(e.name, "nobody");
    // A name given at the spawn replaces the task's; one computed in Rust could be anything.
    let names = |src: &str, text: &str| {
        let program = Program::load(&[("named.tdl".into(), src.into())]).expect("loads");
        tdl_verify::check_names(&program, "main", &[Property::parse(text).expect("parses")])
    };
    let literal = r#"goal main() { spawn step() with name "first"; spawn step(); }"#;
    assert!(names(literal, "never active(step) and active(first)").is_ok());
    let literal = r#"goal main() { spawn step() with name "first"; }"#;
    let e = names(literal, "never active(step)").expect_err("`step` is named `first`");
    assert_eq!(e.known, ["first", "main"]);
    let computed = r#"goal main() { spawn probe() with name format!("probe-{}", 1); }"#;
    assert!(names(computed, "never active(probe-7)").is_ok());
}

/// A watchdog meant to run until the robot shuts down.
const FOREVER: &str = "
monitor watchdog() with period 1s {
    spawn read_sensor();
}

goal guard() {
    spawn watchdog();
}
";

#[test]
fn every_run_ends_can_be_left_unchecked_for_a_program_that_runs_until_shutdown() {
    let program = Program::load(&[("forever.tdl".into(), FOREVER.into())]).expect("loads");
    let report = verify(&program, "guard", &Options::default(), &[]);
    assert_eq!(report.status(), Status::Violated);
    assert!(
        report
            .result(RUNS_END)
            .is_some_and(PropertyResult::is_violated)
    );
    let options = Options {
        unchecked: vec![Builtin::RunsEnd],
        ..Options::default()
    };
    let report = verify(&program, "guard", &options, &[]);
    assert_eq!(report.status(), Status::Ok, "{report:?}");
    assert!(report.result(RUNS_END).is_none());
    assert_eq!(report.results.len(), 3);
    // The seeded simulation likewise: runs go on to the depth bound, which then only ends them.
    let sim = |unchecked: Vec<Builtin>| {
        let options = SimOptions {
            bounds: Options {
                depth: 200,
                unchecked,
                ..Options::default()
            },
            ..SimOptions::default()
        };
        tdl_verify::simulate(
            &program,
            "guard",
            &options,
            &[],
            None,
            0..3,
            &Control::default(),
            &mut |_| {},
        )
    };
    let report = sim(Vec::new());
    assert_eq!(report.status(), Status::Violated);
    assert_eq!(report.result(RUNS_END).map(|r| r.failures), Some(3));
    let report = sim(vec![Builtin::RunsEnd]);
    assert_eq!(report.status(), Status::Ok);
    assert_eq!((report.runs, report.cut), (3, 3));
    assert!(report.result(RUNS_END).is_none());
    for b in Builtin::ALL {
        assert_eq!(Builtin::from_id(b.id()), Some(b));
    }
}

/// A goal whose body fails as it expands fails before any transition: the initial state already
/// holds the unhandled failure, and both the search and the simulation report it.
#[test]
fn a_failure_in_the_initial_state_is_found() {
    let src = "\
exception Broken;

pub goal go() {
    spawn step();
}

goal step() {
    spawn other();
    fail Broken;
}

command other() {
}
";
    let program = Program::load(&[("broken.tdl".to_string(), src.to_string())]).expect("loads");
    let report = verify(&program, "go", &small(), &[]);
    assert_eq!(report.status(), Status::Violated);
    match report.result(tdl_verify::NO_UNHANDLED).map(|r| &r.verdict) {
        Some(Verdict::Violated(c)) => assert!(c.summary.contains("no handler"), "{}", c.summary),
        other => panic!("{other:?}"),
    }
    let handled = src.replace(
        "pub goal go() {",
        "handler shrug() handles Broken {\n}\n\npub goal go() with exception handler shrug() {",
    );
    let program = Program::load(&[("handled.tdl".to_string(), handled)]).expect("loads");
    assert_eq!(verify(&program, "go", &small(), &[]).status(), Status::Ok);
    let sim = tdl_verify::simulate(
        &program_of(src),
        "go",
        &SimOptions::default(),
        &[],
        None,
        0..3,
        &Control::default(),
        &mut |_| {},
    );
    assert!(
        sim.results
            .iter()
            .any(|r| r.property == tdl_verify::NO_UNHANDLED && r.failures == 3),
        "the simulation finds it in every run: {:?}",
        sim.results
    );
}

fn program_of(src: &str) -> Program {
    Program::load(&[("broken.tdl".to_string(), src.to_string())]).expect("loads")
}
