//! `tdl sim` on the Xavier mission (`-p xavier`) and on a copy with a timing bug that only some
//! seeds hit: the report, the exit codes, the command line printed to run a failing seed again,
//! and that it gives the same trace file, to the byte; the `tdl view` command printed to open a
//! failing run's trace on the record where it breaks its property.

use super::tdl;

fn out_dir(name: &str) -> String {
    let dir = std::env::temp_dir().join(format!("tdl-sim-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir.display().to_string()
}

#[test]
fn the_xavier_crate_passes_its_runs() {
    let dir = out_dir("xavier");
    let (code, out, err) = tdl(&["sim", "-p", "xavier", "--seeds", "300", "--out", &dir]);
    assert_eq!(code, 0, "{out}{err}");
    assert!(out.starts_with("simulating `deliver_all` of "), "{out}");
    assert!(out.contains("(seeds 0..300;"), "{out}");
    assert!(
        out.lines()
            .nth(1)
            .is_some_and(|l| l.starts_with("300 runs (")),
        "{out}"
    );
    for p in [
        "no stuck state",
        "no unhandled exception",
        "every run ends",
        "every trace passes the trace checker",
    ] {
        assert!(out.contains(&format!("  ok         {p}")), "{out}");
    }
    assert!(!std::path::Path::new(&dir).exists(), "no trace written");
}

#[test]
fn a_failing_seed_is_reported_and_runs_again_to_the_same_trace() {
    const PROPERTY: &str = "completed(look_for_door) before active(speak)";
    let dir = out_dir("bug");
    let file = "../tdl-verify/test_data/early_timeout.tdl";
    let (code, out, err) = tdl(&[
        "sim",
        file,
        "--seeds",
        "200",
        "--property",
        PROPERTY,
        "--out",
        &dir,
    ]);
    assert_eq!(code, 1, "{out}{err}");
    assert!(out.contains("  ok         no stuck state"), "{out}");
    let line = out
        .lines()
        .find(|l| l.starts_with(&format!("  VIOLATED   {PROPERTY}: in ")))
        .unwrap_or_else(|| panic!("no violation:\n{out}"));
    // `… in K of 200 runs (seeds S, …)`: some seeds, not all.
    let k: u32 = line
        .split(": in ")
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .and_then(|n| n.parse().ok())
        .expect("a count");
    assert!(k > 0 && k < 200, "{line}");
    let seed: u64 = line
        .split("(seeds ")
        .nth(1)
        .and_then(|r| r.split([',', ')']).next())
        .and_then(|n| n.parse().ok())
        .expect("a seed");
    let again =
        format!("reproduce: tdl sim {file} --property '{PROPERTY}' --out {dir} --seed {seed}");
    assert!(out.contains(&again), "{again}\n{out}");
    let trace =
        format!("{dir}/deliver_all-seed-{seed}-completed-look_for_door-before-active-speak.jsonl");
    assert!(out.contains(&format!("trace: {trace}")), "{out}");
    // The property is broken by the run's last record, where it stopped: the step to open.
    let failing = super::verify::failing_step(&out);
    assert_eq!(failing.file, trace);
    assert_eq!(Some(&failing.record), failing.records.last());
    let first = std::fs::read(&trace).expect("the trace is written");
    std::fs::remove_file(&trace).expect("removed");
    // The seed alone: the same failure and the same file.
    let seed = seed.to_string();
    let (code, out2, err) = tdl(&[
        "sim",
        file,
        "--property",
        PROPERTY,
        "--out",
        &dir,
        "--seed",
        &seed,
    ]);
    assert_eq!(code, 1, "{out2}{err}");
    assert!(
        out2.contains(&format!("in 1 of 1 runs (seeds {seed})")),
        "{out2}"
    );
    assert_eq!(std::fs::read(&trace).expect("written again"), first);
    // The story is the one `tdl trace story` gives: the centring terminated before it looked.
    let (code, story, err) = tdl(&["trace", "story", &trace]);
    assert_eq!(code, 0, "{err}");
    assert!(story.contains("center_on_door terminated"), "{story}");
    let (code, checked, _) = tdl(&["trace", "check", &trace]);
    assert_eq!(code, 0, "{checked}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A run whose failure nothing handles opens at the `failed` record of that failure.
#[test]
fn a_failure_nothing_handles_opens_at_its_failed_record() {
    let dir = out_dir("unhandled");
    let (code, out, err) = tdl(&[
        "sim",
        "../tdl-verify/test_data/removed_handler.tdl",
        "--seeds",
        "100",
        "--out",
        &dir,
    ]);
    assert_eq!(code, 1, "{out}{err}");
    let from = out
        .find("  VIOLATED   no unhandled exception: in ")
        .unwrap_or_else(|| panic!("no unhandled failure:\n{out}"));
    let failing = super::verify::failing_step(&out[from..]);
    assert!(
        failing.file.contains("-no-unhandled-exception.jsonl"),
        "{}",
        failing.file
    );
    assert_eq!(failing.record["ev"], "failed", "{}", failing.record);
    assert_eq!(failing.record["exception"], "DoorNotFound");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_probabilities_are_usage_errors() {
    let (code, _, err) = tdl(&["sim", "-p", "xavier", "--fail", "1.5"]);
    assert_eq!(code, 2);
    assert!(err.contains("--fail: 1.5 is not a probability"), "{err}");
}

/// Ctrl-C, as a real SIGINT: the runs stop after the current one, the report gives the runs made,
/// and the exit status is 3 (undecided).
#[cfg(unix)]
#[test]
fn sigint_stops_the_runs_with_what_was_found() {
    let dir = out_dir("sigint");
    let (code, out, took) =
        super::interrupted(&["sim", "-p", "xavier", "--seeds", "100000000", "--out", &dir]);
    assert_eq!(code, 3, "{out}");
    assert!(took < std::time::Duration::from_secs(20), "{took:?}");
    assert!(out.contains("interrupted: what was found so far"), "{out}");
    let runs: u64 = out
        .lines()
        .nth(1)
        .and_then(|l| l.split(' ').next())
        .and_then(|n| n.parse().ok())
        .expect("the runs made");
    assert!(runs > 0 && runs < 100_000_000, "{out}");
    assert!(out.contains("  ok         no stuck state"), "{out}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A program meant to run until it is shut down: every run goes on to `--depth`, a violation of
/// `every run ends` unless it is left unchecked; then the runs end at the bound.
#[test]
fn a_built_in_property_can_be_left_unchecked() {
    let dir = out_dir("forever");
    std::fs::create_dir_all(&dir).expect("a directory");
    let file = format!("{dir}/forever.tdl");
    std::fs::write(
        &file,
        "monitor watchdog() with period 1s { spawn read_sensor(); }\ngoal guard() { spawn watchdog(); }\n",
    )
    .expect("written");
    let base = [
        "sim", &file, "--seeds", "3", "--depth", "300", "--out", &dir,
    ];
    let (code, out, err) = tdl(&base);
    assert_eq!(code, 1, "{out}{err}");
    assert!(
        out.contains("  VIOLATED   every run ends: in 3 of 3 runs"),
        "{out}"
    );
    let mut args = base.to_vec();
    args.extend(["--no-builtin", "every-run-ends"]);
    let (code, out, err) = tdl(&args);
    assert_eq!(code, 0, "{out}{err}");
    assert!(
        out.contains("3 runs (0 ended, 3 ended at a bound)"),
        "{out}"
    );
    assert!(
        out.contains("not checked (--no-builtin): every run ends"),
        "{out}"
    );
    assert!(!out.contains("  ok         every run ends"), "{out}");
    assert!(
        out.ends_with("ok: no run broke a property (exit status 0)\n"),
        "{out}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_name_no_node_has_is_an_error() {
    let (code, out, err) = tdl(&[
        "sim",
        "-p",
        "xavier",
        "--property",
        "eventually completed(nobody)",
    ]);
    assert_eq!(code, 2, "{out}{err}");
    assert!(
        err.contains("names `nobody`, which no node of the program is named"),
        "{err}"
    );
}

/// `--faults FILE`: the Xavier mission simulated with the next `guarded_move` jammed; with a
/// fault nobody handles (an exception the mission has no handler for), every run reports it.
#[test]
fn faults_from_a_file_are_injected_into_every_run() {
    let dir = out_dir("faults");
    std::fs::create_dir_all(&dir).expect("a directory");
    let faults = format!("{dir}/faults.json");
    std::fs::write(
        &faults,
        r#"[{"task": "guarded_move", "exception": "Jammed", "message": "the wheels are jammed"}]"#,
    )
    .expect("write the faults");
    let (code, out, err) = tdl(&[
        "sim", "-p", "xavier", "--seeds", "5", "--fail", "0", "--faults", &faults, "--out", &dir,
    ]);
    assert_eq!(code, 1, "{out}{err}");
    assert!(out.contains("VIOLATED   no unhandled exception"), "{out}");
    assert!(
        out.contains("fault injected: fail Jammed: the wheels are jammed"),
        "{out}"
    );
    let (code, out, err) = tdl(&[
        "sim", "-p", "xavier", "--seeds", "5", "--fail", "0", "--out", &dir,
    ]);
    assert_eq!(code, 0, "without the fault: {out}{err}");
}
