//! `tdl verify` on the lander's day with its environment declaration: every property holds
//! within the default bounds and nothing is reported that cannot happen; with a seeded bug (the
//! steps' `pause while` dropped) the checker finds a step that starts while the lander is
//! unhealthy, with a counterexample the trace checker accepts.

use std::path::Path;
use tdl_verify::{Control, Options, Program, Property, Status, Verdict};

fn source() -> (String, String) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("src/day.tdl");
    let src = std::fs::read_to_string(&path).expect("the plan reads");
    (path.display().to_string(), src)
}

fn properties() -> Vec<Property> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("day.properties");
    let text = std::fs::read_to_string(&path).expect("the properties read");
    Property::parse_file("day.properties", &text).expect("they parse")
}

fn verify(src: String, name: String) -> tdl_verify::Report {
    let program = Program::load(&[(name, src)]).expect("the plan loads");
    tdl_verify::verify(
        &program,
        "day",
        &Options::default(),
        &properties(),
        None,
        &Control::default(),
    )
}

#[test]
fn the_day_holds_every_property_within_the_default_bounds() {
    let (name, src) = source();
    let report = verify(src, name);
    let broken: Vec<&str> = report
        .results
        .iter()
        .filter(|r| !matches!(r.verdict, Verdict::Holds))
        .map(|r| r.property.as_str())
        .collect();
    assert_eq!(report.status(), Status::Ok, "not holding: {broken:?}");
    assert!(report.complete, "the whole state space within the bounds");
    assert!(report.errors.is_empty(), "{:?}", report.errors);
    // Nothing the checker could not follow but what the plan computes in Rust.
    assert!(
        report.notes.iter().all(|n| !n.contains("no environment")),
        "{:?}",
        report.notes
    );
}

#[test]
fn a_step_held_by_nothing_is_found_starting_while_the_lander_is_unhealthy() {
    let (name, src) = source();
    let pause = " with pause while battery < 20.0 || temperature > 40.0";
    assert!(src.contains(pause), "the plan holds its steps");
    let report = verify(src.replace(pause, ""), name);
    assert_eq!(report.status(), Status::Violated);
    // The warm-up starts at once, before the outside can act; the panorama after it.
    let panorama = properties().remove(1);
    assert!(panorama.text().starts_with("never active(panorama)"));
    let Some(Verdict::Violated(cx)) = report.result(panorama.text()).map(|r| &r.verdict) else {
        panic!("{} is not violated", panorama.text());
    };
    // The shortest run: the charge falls, the warm-up ends, and the panorama starts.
    assert_eq!(
        cx.steps,
        [
            "the environment sets battery = 15.0",
            "day/steps/warm_up succeeds"
        ]
    );
    assert!(cx.trace_violations.is_empty(), "{:?}", cx.trace_violations);
}

fn simulate(src: String, name: String, seeds: std::ops::Range<u64>) -> tdl_verify::SimReport {
    let program = Program::load(&[(name, src)]).expect("the plan loads");
    tdl_verify::simulate(
        &program,
        "day",
        &tdl_verify::SimOptions::default(),
        &properties(),
        None,
        seeds,
        &Control::default(),
        &mut |_| {},
    )
}

/// `tdl sim` draws the outside's changes from the environment declaration: the day passes 300
/// seeded runs; without the pause, some seed starts a step while the charge is low.
#[test]
fn seeded_runs_draw_the_environment_and_find_the_dropped_pause() {
    let (name, src) = source();
    let report = simulate(src.clone(), name.clone(), 0..300);
    assert_eq!(report.runs, 300);
    assert!(report.ok(), "{:#?}", report.results);
    assert!(report.finished > 200, "{report:#?}");

    let pause = " with pause while battery < 20.0 || temperature > 40.0";
    let report = simulate(src.replace(pause, ""), name, 0..300);
    let broken: u64 = report
        .results
        .iter()
        .filter(|r| r.property.starts_with("never active("))
        .map(|r| r.failures)
        .sum();
    assert!(broken > 0, "{:#?}", report.results);
}
