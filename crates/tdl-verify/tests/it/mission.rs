//! The mission and its seeded bugs.

use std::path::{Path, PathBuf};
use std::time::Duration;

use tcm_trace::{Facet, State, TraceEvent, TraceKind};
use tdl_verify::{
    Arg, CommandModel, Control, Counterexample, Ending, NO_STUCK, NO_UNHANDLED, Options, Program,
    Property, RUNS_END, Report, TRACES_CHECK, Verdict,
};

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("test_data")
        .join(name)
}

fn mission() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../xavier/src/mission.tdl")
}

fn load(path: &Path) -> Program {
    let src = std::fs::read_to_string(path).expect("the file reads");
    Program::load(&[(path.display().to_string(), src)]).expect("the program loads")
}

/// Small bounds: each bug below shows within them.
fn small() -> Options {
    Options {
        loops: 1,
        hangs: 0,
        ticks: 0,
        ..Options::default()
    }
}

fn verify(
    path: &Path,
    options: &Options,
    properties: &[Property],
    model: Option<&dyn CommandModel>,
) -> Report {
    let program = load(path);
    let task = program.root_task(None).expect("one root goal");
    assert_eq!(task, "deliver_all");
    tdl_verify::verify(
        &program,
        &task,
        options,
        properties,
        model,
        &Control::default(),
    )
}

fn violated<'r>(report: &'r Report, property: &str) -> &'r Counterexample {
    match report.result(property).map(|r| &r.verdict) {
        Some(Verdict::Violated(c)) => c,
        other => panic!("`{property}` should be violated, got {other:?}"),
    }
}

fn holds(report: &Report, property: &str) {
    assert!(
        matches!(
            report.result(property).map(|r| &r.verdict),
            Some(Verdict::Holds)
        ),
        "`{property}` should hold: {:?}",
        report.result(property)
    );
}

/// The trace is a valid prefix of a run, reads back from its file, and tells the story.
fn trace_replays(c: &Counterexample) {
    assert!(c.trace_violations.is_empty(), "{:?}", c.trace_violations);
    let mut file = Vec::new();
    c.write_trace(&mut file).expect("the trace writes");
    let back = tcm_trace::read_jsonl(std::io::BufReader::new(file.as_slice())).expect("it reads");
    assert_eq!(back, c.trace);
    tcm_trace::check_prefix(&back).expect("the checker accepts it");
    assert!(!c.story().is_empty());
}

#[test]
fn the_mission_passes() {
    let report = verify(&mission(), &small(), &[], None);
    assert!(report.complete, "{report:?}");
    for p in [NO_STUCK, NO_UNHANDLED, RUNS_END, TRACES_CHECK] {
        holds(&report, p);
    }
    assert!(report.ok());
    assert!(report.unique > 100, "{} states", report.unique);
    assert!(report.traces_checked > 0);
}

#[test]
fn a_removed_handler_is_an_unhandled_exception() {
    let report = verify(&data("removed_handler.tdl"), &small(), &[], None);
    let c = violated(&report, NO_UNHANDLED);
    // One room, and the first command fails with the exception nothing handles any more.
    assert_eq!(c.len(), 2, "{:#?}", c.steps);
    assert!(
        c.steps[1].ends_with("fails with DoorNotFound"),
        "{:?}",
        c.steps
    );
    assert!(
        c.details[0].starts_with("DoorNotFound raised at deliver_all/deliver_mail/"),
        "{:?}",
        c.details
    );
    assert!(c.depends_on_conditions, "the number of rooms is a choice");
    trace_replays(c);
    // The failing step: the failure no handler takes, `navigate_to_locn`'s (its planner's, which
    // it takes, comes before), followed by the records of its end.
    let failed = failing_record(c);
    let navigate = spawned(c, "navigate_to_locn");
    assert!(
        matches!(&failed.kind, TraceKind::Failed { node, exception, .. }
            if *node == navigate && exception == "DoorNotFound"),
        "{failed:?}"
    );
    assert!(c.trace.last().is_some_and(|r| r.seq > failed.seq));
    holds(&report, NO_STUCK);
    holds(&report, RUNS_END);
}

/// The record a counterexample opens at ([`Counterexample::failing_seq`]).
fn failing_record(c: &Counterexample) -> &TraceEvent {
    let seq = c.failing_seq().expect("a trace");
    c.trace
        .iter()
        .find(|r| r.seq == seq)
        .unwrap_or_else(|| panic!("no record {seq}"))
}

/// The number of the first node named `name` in the counterexample's trace.
fn spawned(c: &Counterexample, name: &str) -> u64 {
    c.trace
        .iter()
        .find_map(|r| match &r.kind {
            TraceKind::Spawned { node, name: n, .. } if n == name => Some(*node),
            _ => None,
        })
        .unwrap_or_else(|| panic!("no {name} spawned"))
}

#[test]
fn a_constraint_cycle_in_a_branch_is_a_stuck_run() {
    let report = verify(&data("constraint_cycle.tdl"), &small(), &[], None);
    let c = violated(&report, NO_STUCK);
    // A room; the navigation ends at once (its planner fails and is given up); the door is
    // found to one side, so the centring step is spawned, waiting for its own parent; the
    // 30 s termination of the centring comes and does not free it.
    assert_eq!(c.len(), 5, "{:#?}", c.steps);
    assert!(
        c.steps[3].contains("takes the `if` branch"),
        "{:?}",
        c.steps
    );
    assert_eq!(c.steps[4], "time passes to 30 s");
    assert!(
        c.details
            .iter()
            .any(|d| d.contains("waits for center_on_door")),
        "{:?}",
        c.details
    );
    trace_replays(c);
    // Stuck: the failing step is the last record.
    assert_eq!(failing_record(c), c.trace.last().expect("a trace"));
    holds(&report, NO_UNHANDLED);
}

#[test]
fn a_monitor_without_terminate_at_never_ends() {
    let report = verify(&data("missing_terminate.tdl"), &small(), &[], None);
    let c = violated(&report, RUNS_END);
    let from = c.repeats_from.expect("a loop");
    // Everything but the motor monitor is done after 8 transitions; then it polls forever.
    assert_eq!((from, c.len()), (8, 12), "{:#?}", c.steps);
    let looped = &c.steps[from..];
    assert!(
        looped.iter().any(|s| s.starts_with("time passes")),
        "{looped:?}"
    );
    assert!(
        looped
            .iter()
            .all(|s| s.contains("watch_motor") || s.starts_with("time")),
        "{looped:?}"
    );
    trace_replays(c);
    // The failing step is the first record of the part that repeats: the first activation's
    // handling completing (its body ends at step 9), after its poll's end at step 8.
    let failed = failing_record(c);
    let activation = spawned(c, "ACT-watch_motor");
    assert!(
        matches!(failed.kind, TraceKind::Transition { node, facet: Facet::Handling, to: State::Completed, .. }
            if node == activation),
        "{failed:?}"
    );
    let before = &c.trace[c
        .trace
        .iter()
        .position(|r| r.seq == failed.seq)
        .expect("there")
        - 1];
    let poll = spawned(c, "motor_temperature");
    assert!(
        matches!(before.kind, TraceKind::Reclaimed { node } if node == poll),
        "{before:?}"
    );
    holds(&report, NO_STUCK);
    holds(&report, NO_UNHANDLED);
}

/// Every command succeeds at once: the behaviours left are the bodies' choices.
struct AllSucceed;

impl CommandModel for AllSucceed {
    fn endings(&self, _task: &str, _args: &[Arg]) -> Option<Vec<Ending>> {
        Some(vec![Ending::Succeeds(Duration::ZERO)])
    }
}

#[test]
fn two_motion_commands_together_break_a_user_property() {
    let motion = Property::parse("never active(turn) and active(guarded_move)").expect("parses");
    let options = Options {
        loops: 2,
        ..small()
    };
    let report = verify(
        &data("concurrent_motion.tdl"),
        &options,
        std::slice::from_ref(&motion),
        Some(&AllSucceed),
    );
    let c = violated(&report, motion.text());
    // Two legs: the first without a turn and with one move, the second with a turn, which no
    // longer waits for the move.
    assert_eq!(c.len(), 10, "{:#?}", c.steps);
    trace_replays(c);
    // The trace stops where both are active: each started, neither completed.
    let story = c.story();
    for started in ["turn handling active", "guarded_move handling active"] {
        assert!(story.iter().any(|l| l.ends_with(started)), "{story:#?}");
    }
    for ended in ["turn handling completed", "guarded_move handling completed"] {
        assert!(!story.iter().any(|l| l.ends_with(ended)), "{story:#?}");
    }
    // The mission keeps them apart.
    let report = verify(
        &mission(),
        &options,
        std::slice::from_ref(&motion),
        Some(&AllSucceed),
    );
    holds(&report, motion.text());
}

/// Resources are modelled: the base (capacity 1) that every motion uses keeps a turn that lost
/// its ordering from running with a move; without the base, it runs with one.
#[test]
fn the_base_resource_keeps_two_motions_apart() {
    let motion = Property::parse("never active(turn) and active(guarded_move)").expect("parses");
    let options = Options {
        loops: 2,
        ..small()
    };
    let path = data("unordered_motion.tdl");
    let report = verify(
        &path,
        &options,
        std::slice::from_ref(&motion),
        Some(&AllSucceed),
    );
    holds(&report, motion.text());
    holds(&report, NO_STUCK);
    assert!(report.complete);
    // The same program without the turn's use of the base.
    let src = std::fs::read_to_string(&path).expect("reads");
    let old = "spawn turn(&m.world, leg.turn) with uses base;";
    assert_eq!(src.matches(old).count(), 1);
    let without = src.replace(old, "spawn turn(&m.world, leg.turn);");
    let program = Program::load(&[("without_base.tdl".into(), without)]).expect("loads");
    let report = tdl_verify::verify(
        &program,
        "deliver_all",
        &options,
        std::slice::from_ref(&motion),
        Some(&AllSucceed),
        &Control::default(),
    );
    let c = violated(&report, motion.text());
    trace_replays(c);
    // No resource constraint is left out any more.
    let notes = load(&path).notes().to_vec();
    assert!(notes.iter().all(|n| !n.contains("resource")), "{notes:?}");
}

#[test]
fn a_stop_gives_what_was_found_so_far() {
    let program = load(&mission());
    let control = Control::default();
    control
        .stop
        .store(true, std::sync::atomic::Ordering::Relaxed);
    let report = tdl_verify::verify(&program, "deliver_all", &small(), &[], None, &control);
    assert!(report.interrupted && !report.complete);
    assert!(matches!(
        report.result(NO_STUCK).map(|r| &r.verdict),
        Some(Verdict::Unknown(why)) if why.contains("interrupted")
    ));
}

#[test]
fn event_properties_are_followed_along_each_path() {
    let parse = |p: &str| Property::parse(p).expect("parses");
    let planned_first = parse("completed(plan_path) before active(guarded_move)");
    let delivered_first = parse("completed(deliver_mail) before active(plan_path)");
    let some_delivery = parse("eventually completed(deliver_mail)");
    let props = [
        planned_first.clone(),
        delivered_first.clone(),
        some_delivery.clone(),
    ];
    let report = verify(&mission(), &small(), &props, None);
    holds(&report, planned_first.text());
    // The first planner starts before any delivery ended.
    let c = violated(&report, delivered_first.text());
    assert_eq!(c.len(), 1, "{:#?}", c.steps);
    // With no room to deliver to, the round ends without a delivery.
    let c = violated(&report, some_delivery.text());
    assert_eq!(c.len(), 1, "{:#?}", c.steps);
    assert!(
        c.steps[0].starts_with("deliver_all leaves the loop at "),
        "{:?}",
        c.steps
    );
}

#[test]
fn liveness_is_refused_on_a_graph_with_a_cycle() {
    // Every run that ends saw the round start, but with the monitor polling forever some runs
    // never end, and on those `eventually` cannot be decided.
    let started = Property::parse("always eventually active(deliver_all)").expect("parses");
    let report = verify(
        &data("missing_terminate.tdl"),
        &small(),
        std::slice::from_ref(&started),
        None,
    );
    violated(&report, RUNS_END);
    match report.result(started.text()).map(|r| &r.verdict) {
        Some(Verdict::Unknown(why)) => {
            assert!(
                why.starts_with("refused: the state graph has a cycle"),
                "{why}"
            );
        }
        other => panic!("{other:?}"),
    }
    // Without the cycle it is decided.
    let report = verify(&mission(), &small(), std::slice::from_ref(&started), None);
    holds(&report, started.text());
}
