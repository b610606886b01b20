//! State variables and conditions under the model checker (docs/verification.md, "State and
//! conditions"): the program's own `set`s and `raise`s are transitions it follows, conditions
//! constrain the tree as in a run, and a property may read the variables. A step held by `pause
//! while` never starts while the lander is unhealthy; with the pause dropped (a seeded bug) the
//! checker finds the run where it does, and its counterexample passes the trace checker.

use tdl_verify::{Control, Options, Program, Property, Report, Status, Verdict};

fn load(src: &str) -> Program {
    Program::load(&[("state.tdl".to_owned(), src.to_owned())]).expect("the program loads")
}

fn verify(program: &Program, task: &str, properties: &[Property]) -> Report {
    let options = Options {
        loops: 1,
        hangs: 0,
        ticks: 0,
        ..Options::default()
    };
    tdl_verify::verify(
        program,
        task,
        &options,
        properties,
        None,
        &Control::default(),
    )
}

const HELD: &str = r#"
state healthy: bool = true;
command work() {}
command fault() { set healthy = false; }
command repair() { set healthy = true; }
goal steps() {
    spawn work();
    spawn work() with sequential execution previous;
}
goal main() {
    spawn fault();
    spawn repair() with sequential execution previous;
    spawn steps() with pause while !healthy;
}
"#;

#[test]
fn a_paused_step_never_starts_while_its_condition_holds_and_the_dropped_pause_is_found() {
    let held = Property::parse("never active(work) while not healthy").expect("parses");
    let report = verify(&load(HELD), "main", std::slice::from_ref(&held));
    assert_eq!(report.status(), Status::Ok, "{:?}", report.results);
    assert!(report.unique > 10, "{} states", report.unique);

    let bug = HELD.replace(" with pause while !healthy", "");
    let report = verify(&load(&bug), "main", std::slice::from_ref(&held));
    assert_eq!(report.status(), Status::Violated);
    let Some(Verdict::Violated(cx)) = report.result(held.text()).map(|r| &r.verdict) else {
        panic!("violated: {:?}", report.results);
    };
    assert!(cx.trace_violations.is_empty(), "{:?}", cx.trace_violations);
    // The shortest: the fault's `set` comes first, then a step starts.
    let steps = cx.steps.join("\n");
    let set = steps.find("fault").expect("the fault runs");
    let work = steps.rfind("work").expect("a step starts");
    assert!(set < work, "{steps}");
    assert!(
        cx.trace.iter().any(
            |r| matches!(&r.kind, tcm_trace::TraceKind::StateSet { var, value }
                if var == "healthy" && *value == false.into())
        ),
        "the trace records the set"
    );
}

const CONDITIONS: &str = r#"
state armed: bool = false;
state count: int = 0;
command arm() { set armed = true; }
command fire() {}
command count_up() { set count = 1; }
command never_run() {}
goal main() {
    spawn arm();
    spawn fire() with disable execution until armed;
    spawn count_up() with sequential execution previous;
    spawn never_run() with sequential execution previous, skip if count > 0;
    raise "done";
}
"#;

#[test]
fn conditions_set_and_raise_are_followed() {
    let program = load(CONDITIONS);
    // `fire` waits for `arm`'s set (which comes while `arm` runs, before it completes);
    // `never_run` is always skipped.
    let props = [
        Property::parse("never active(fire) while not armed").expect("parses"),
        Property::parse("active(arm) before active(fire)").expect("parses"),
        Property::parse("never active(never_run)").expect("parses"),
        Property::parse("eventually completed(never_run)").expect("parses"),
    ];
    let report = verify(&program, "main", &props);
    assert_eq!(report.status(), Status::Ok, "{:?}", report.results);
}

#[test]
fn a_property_over_a_variable_the_program_does_not_declare_is_an_error() {
    let p = Property::parse("never active(work) while battery < 20.0").expect("parses");
    let report = verify(&load(HELD), "main", std::slice::from_ref(&p));
    assert_eq!(report.status(), Status::Error);
    assert!(
        report.errors[0].contains(
            "names `battery`, which no state variable of the program is named; the names are: healthy"
        ),
        "{:?}",
        report.errors
    );
}

const OUTSIDE: &str = r#"
state healthy: bool = true;
state mode: string = "auto";
environment {
    healthy: false, true at most 2;
    mode: "manual" when !healthy;
    external "go";
}
command work() {}
command drive() {}
goal steps() {
    spawn work();
    spawn work() with sequential execution previous;
}
goal main() {
    spawn steps() with pause while !healthy;
    spawn drive() with disable execution until external "go";
}
"#;

#[test]
fn the_environment_declaration_says_what_the_outside_may_change() {
    let program = load(OUTSIDE);
    let props = [
        Property::parse("never active(work) while not healthy").expect("parses"),
        // False: `mode` stays manual once set. The shortest run that shows it sets `healthy`
        // false first, as `when !healthy` asks, and healthy again.
        Property::parse("never healthy and mode == \"manual\"").expect("parses"),
    ];
    let report = verify(&program, "main", &props);
    assert_eq!(report.status(), Status::Violated, "{:?}", report.results);
    for builtin in ["no stuck state", "every run ends", props[0].text()] {
        assert!(
            matches!(
                report.result(builtin).map(|r| &r.verdict),
                Some(Verdict::Holds)
            ),
            "{builtin}: {:?}",
            report.results
        );
    }
    let Some(Verdict::Violated(cx)) = report.result(props[1].text()).map(|r| &r.verdict) else {
        panic!("violated: {:?}", report.results);
    };
    assert_eq!(
        cx.steps,
        [
            "the environment sets healthy = false",
            "the environment sets mode = \"manual\"",
            "the environment sets healthy = true",
        ]
    );
    assert!(
        report.notes.iter().all(|n| !n.contains("no environment")),
        "{:?}",
        report.notes
    );

    let bug = OUTSIDE.replace(" with pause while !healthy", "");
    let report = verify(&load(&bug), "main", &props[..1]);
    let Some(Verdict::Violated(cx)) = report.result(props[0].text()).map(|r| &r.verdict) else {
        panic!("violated: {:?}", report.results);
    };
    assert!(
        cx.steps
            .iter()
            .any(|s| s == "the environment sets healthy = false"),
        "{:?}",
        cx.steps
    );
    assert!(cx.trace_violations.is_empty(), "{:?}", cx.trace_violations);
}

#[test]
fn without_an_environment_declaration_the_checker_says_so_once() {
    let report = verify(&load(HELD), "main", &[]);
    let notes: Vec<&String> = report
        .notes
        .iter()
        .filter(|n| n.contains("no environment declaration"))
        .collect();
    assert_eq!(notes.len(), 1, "{:?}", report.notes);
}

const LOGGED: &str = r#"
state healthy: bool = true;
command work(n: u32) { log "work {n} at charge {:?}", state!(healthy); }
command fault() { set healthy = false; log "fault"; }
goal main() {
    log "start";
    spawn fault();
    spawn work(1) with pause while !healthy;
}
"#;

#[test]
fn a_log_line_changes_nothing_the_checker_explores_and_needs_no_note() {
    let report = verify(&load(LOGGED), "main", &[]);
    assert_eq!(report.status(), Status::Ok, "{:?}", report.results);
    assert!(
        report.notes.iter().all(|n| !n.contains("ctx")),
        "{:?}",
        report.notes
    );
    // The same program without its lines: the same states.
    let bare: String = LOGGED
        .lines()
        .map(|l| match l.find("log \"") {
            Some(at) => format!("{}{}", &l[..at], if l.ends_with('}') { "}" } else { "" }),
            None => l.to_owned(),
        })
        .collect::<Vec<_>>()
        .join("\n");
    assert!(!bare.contains("log"), "{bare}");
    let without = verify(&load(&bare), "main", &[]);
    assert_eq!(
        (report.unique, report.explored, report.ended),
        (without.unique, without.explored, without.ended)
    );
    // Written as Rust on `ctx`, the same line is code the checker does not run, and says so.
    let by_hand = LOGGED.replace("log \"fault\";", "ctx.log(\"fault\")?;");
    let report = verify(&load(&by_hand), "main", &[]);
    assert!(
        report
            .notes
            .iter()
            .any(|n| n.contains("uses `ctx` is not run")),
        "{:?}",
        report.notes
    );
}
