//! `tdl verify` on the Xavier mission (`-p xavier`) and on a copy with a seeded bug: the report,
//! the exit statuses (0 ok, 1 violated, 2 error, 3 undecided), the bound that cut a search, a
//! counterexample written as soon as it is found, and a counterexample trace that `tdl trace
//! story` replays. Small bounds, or bounds that cut the search early, keep the runs short (the
//! crate `tdl-verify` tests the rest).

use super::tdl;

const SMALL: [&str; 6] = ["--loops", "1", "--hangs", "0", "--ticks", "0"];

fn out_dir(name: &str) -> String {
    let dir = std::env::temp_dir().join(format!("tdl-verify-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir.display().to_string()
}

#[test]
fn a_seeded_bug_gives_a_counterexample_trace_and_exit_1() {
    let dir = out_dir("bug");
    let mut args = vec![
        "verify",
        "../tdl-verify/test_data/removed_handler.tdl",
        "--out",
        &dir,
    ];
    args.extend(SMALL);
    let (code, out, _) = tdl(&args);
    assert_eq!(code, 1, "{out}");
    assert!(out.contains("  ok         no stuck state"), "{out}");
    assert!(
        out.contains("  VIOLATED   no unhandled exception: a failure no handler takes"),
        "{out}"
    );
    assert!(out.contains("a path of 2 transitions"), "{out}");
    assert!(out.contains("fails with DoorNotFound"), "{out}");
    let file = format!("{dir}/deliver_all-no-unhandled-exception.jsonl");
    assert!(out.contains(&format!("trace: {file}")), "{out}");
    // The story printed is the one `tdl trace story` gives for the file.
    let (code, story, err) = tdl(&["trace", "story", &file]);
    assert_eq!(code, 0, "{err}");
    assert!(story.contains("plan_path failed DoorNotFound"), "{story}");
    for line in story.lines().take(5) {
        assert!(out.contains(line), "{line} missing from the report:\n{out}");
    }
    let (code, checked, _) = tdl(&["trace", "check", &file]);
    assert_eq!(code, 0, "{checked}");
    // The step it prints to open the trace at is the failure nothing handles.
    let failing = failing_step(&out);
    assert_eq!(failing.file, file);
    assert_eq!(failing.record["ev"], "failed", "{}", failing.record);
    assert_eq!(failing.record["exception"], "DoorNotFound");
    let _ = std::fs::remove_dir_all(&dir);
}

/// What a report says of the failing step: `open it at the failing step: tdl view FILE --at N`,
/// the first such line.
pub(crate) struct FailingStep {
    /// The trace file.
    pub(crate) file: String,
    /// Its record `seq` N, as JSON.
    pub(crate) record: serde_json::Value,
    /// Its records.
    pub(crate) records: Vec<serde_json::Value>,
}

/// The failing step a report prints, read from its trace file.
pub(crate) fn failing_step(out: &str) -> FailingStep {
    let command = out
        .lines()
        .find_map(|l| {
            l.trim()
                .strip_prefix("open it at the failing step: tdl view ")
        })
        .unwrap_or_else(|| panic!("no `tdl view` line:\n{out}"));
    let (file, seq) = command.rsplit_once(" --at ").expect("FILE --at N");
    let seq: u64 = seq.parse().expect("a record number");
    let records: Vec<serde_json::Value> = std::fs::read_to_string(file)
        .expect("the trace is written")
        .lines()
        .map(|l| serde_json::from_str(l).expect("a JSON record"))
        .collect();
    let record = records
        .iter()
        .find(|r| r["seq"] == seq)
        .unwrap_or_else(|| panic!("{file} has no record {seq}"))
        .clone();
    FailingStep {
        file: file.to_owned(),
        record,
        records,
    }
}

#[test]
fn a_stuck_run_opens_at_its_last_record() {
    let dir = out_dir("stuck");
    let mut args = vec![
        "verify",
        "../tdl-verify/test_data/constraint_cycle.tdl",
        "--out",
        &dir,
    ];
    args.extend(SMALL);
    let (code, out, err) = tdl(&args);
    assert_eq!(code, 1, "{out}{err}");
    assert!(out.contains("  VIOLATED   no stuck state: stuck"), "{out}");
    let failing = failing_step(&out);
    assert_eq!(
        failing.file,
        format!("{dir}/deliver_all-no-stuck-state.jsonl")
    );
    assert_eq!(Some(&failing.record), failing.records.last());
    // Printed beside the trace's path.
    let at = out
        .lines()
        .position(|l| l.contains("open it at the failing step: "))
        .expect("the line");
    assert!(
        out.lines()
            .nth(at - 1)
            .is_some_and(|l| l.contains(&format!("trace: {}", failing.file))),
        "{out}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A program meant to run until it is shut down: its watchdog polls forever.
const FOREVER: &str = "
monitor watchdog() with period 1s {
    spawn read_sensor();
}

goal guard() {
    spawn watchdog();
}
";

/// Writes `src` as `NAME.tdl` in a directory of its own; returns the file and the directory
/// (for `--out`).
fn program(name: &str, src: &str) -> (String, String) {
    let dir = out_dir(&format!("src-{name}"));
    std::fs::create_dir_all(&dir).expect("a directory");
    let file = format!("{dir}/{name}.tdl");
    std::fs::write(&file, src).expect("written");
    (file, dir)
}

/// The last line: the verdict as a whole and its exit status.
fn last_line(out: &str) -> &str {
    out.lines().last().unwrap_or_default()
}

#[test]
fn the_xavier_crate_passes() {
    let dir = out_dir("xavier");
    let mut args = vec!["verify", "-p", "xavier", "--out", &dir];
    args.extend(SMALL);
    let (code, out, err) = tdl(&args);
    assert_eq!(code, 0, "{out}{err}");
    assert!(out.starts_with("verifying `deliver_all` of "), "{out}");
    assert!(out.contains("mission.tdl"), "{out}");
    assert!(
        out.contains("every state within the bounds was explored"),
        "{out}"
    );
    for p in ["no stuck state", "no unhandled exception", "every run ends"] {
        assert!(out.contains(&format!("  ok         {p}")), "{out}");
    }
    // The handlers' Rust (`stop_the_rest(&ctx)?`, `give_up(&ctx, …)?`) is not run, and the
    // report says so.
    assert!(
        out.lines().any(|l| l.contains("mission.tdl:")
            && l.contains("Rust code that uses `ctx` is not run")
            && l.contains("(in `detour`)")),
        "{out}"
    );
    let stats = out.lines().nth(1).unwrap_or_default();
    assert!(
        stats.contains("states explored (") && stats.ends_with("states/s"),
        "{stats}"
    );
    assert_eq!(
        last_line(&out),
        "ok: every property checked holds within the bounds (exit status 0)"
    );
}

#[test]
fn a_search_cut_by_a_bound_is_undecided_and_names_the_bound() {
    for (bound, value, why) in [
        (
            "--max-states",
            "10",
            "the search stopped at the bound of 10 distinct states (--max-states)",
        ),
        (
            "--depth",
            "3",
            "a run was still going at the bound of 3 transitions (--depth)",
        ),
    ] {
        let mut args = vec!["verify", "-p", "xavier", bound, value];
        args.extend(SMALL);
        let (code, out, err) = tdl(&args);
        assert_eq!(code, 3, "{bound}: {out}{err}");
        assert!(
            out.contains(&format!("not every state was explored: {why}")),
            "{out}"
        );
        for p in ["no stuck state", "no unhandled exception", "every run ends"] {
            assert!(
                out.contains(&format!("  undecided  {p}: not decided: {why}\n")),
                "{bound}, {p}: {out}"
            );
        }
        assert!(!out.contains("VIOLATED"), "{out}");
        assert_eq!(
            last_line(&out),
            "undecided: nothing is broken, but not every property was decided (exit status 3)"
        );
    }
}

/// The default bounds on the mission are millions of states; a tiny memory bound ends the search
/// at its first look at the memory in use (after 1,024 states), undecided, and keeps what it
/// found before: the violation is printed before the report and its trace is on disk.
#[test]
fn a_memory_bound_ends_the_search_undecided_and_keeps_what_was_found() {
    let dir = out_dir("memory");
    let started = std::time::Instant::now();
    let (code, out, err) = tdl(&[
        "verify",
        "-p",
        "xavier",
        "--max-memory",
        "1M",
        "--out",
        &dir,
    ]);
    assert_eq!(code, 3, "{out}{err}");
    let why = "the search stopped at the memory bound of 1 MB (";
    assert!(
        out.contains(&format!("not every state was explored: {why}")),
        "{out}"
    );
    assert!(
        out.contains(&format!("  undecided  every run ends: not decided: {why}")),
        "{out}"
    );
    assert!(out.contains(" in use; --max-memory)"), "{out}");
    // A violation found before the cut: printed when found, its trace written.
    let property = "never active(detour)";
    let (code, out, err) = tdl(&[
        "verify",
        "-p",
        "xavier",
        "--max-memory",
        "1M",
        "--property",
        property,
        "--out",
        &dir,
    ]);
    assert_eq!(code, 1, "{out}{err}");
    assert!(
        started.elapsed() < std::time::Duration::from_secs(60),
        "{:?}",
        started.elapsed()
    );
    let lines: Vec<&str> = out.lines().collect();
    let found = lines
        .iter()
        .position(|l| l.starts_with(&format!("  VIOLATED   {property}: ")))
        .unwrap_or_else(|| panic!("not printed:\n{out}"));
    let stats = lines
        .iter()
        .position(|l| l.contains(" states explored ("))
        .unwrap_or_else(|| panic!("no statistics:\n{out}"));
    assert!(
        found < stats,
        "printed when found, before the report:\n{out}"
    );
    assert!(
        out.contains(&format!("not every state was explored: {why}")),
        "{out}"
    );
    let file = format!("{dir}/deliver_all-never-active-detour.jsonl");
    assert!(out.contains(&format!("trace: {file}")), "{out}");
    let (code, story, err) = tdl(&["trace", "story", &file]);
    assert_eq!(code, 0, "{err}");
    assert!(story.contains("detour handling active"), "{story}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The report a killed search leaves (the kernel's OOM killer, say): each violation and its trace
/// are out as soon as they are found, not at the end.
#[cfg(unix)]
#[test]
fn a_violation_is_on_disk_and_printed_before_the_search_ends() {
    use std::io::BufRead;
    use std::process::{Command, Stdio};
    let dir = out_dir("killed");
    let property = "never active(detour)";
    // The default bounds: minutes of search, killed as soon as the violation is printed.
    let mut child = Command::new(env!("CARGO_BIN_EXE_tdl"))
        .args([
            "verify",
            "-p",
            "xavier",
            "--property",
            property,
            "--out",
            &dir,
        ])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("run tdl");
    let stdout = child.stdout.take().expect("piped");
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in std::io::BufReader::new(stdout)
            .lines()
            .map_while(Result::ok)
        {
            let _ = tx.send(line);
        }
    });
    let mut printed = Vec::new();
    let seen = loop {
        match rx.recv_timeout(std::time::Duration::from_secs(60)) {
            Ok(line) => {
                let found = line.starts_with(&format!("  VIOLATED   {property}: "));
                printed.push(line);
                if found {
                    break true;
                }
            }
            Err(_) => break false,
        }
    };
    let still_running = child.try_wait().expect("wait").is_none();
    let _ = child.kill();
    let _ = child.wait();
    assert!(
        seen,
        "no violation printed within a minute:\n{}",
        printed.join("\n")
    );
    assert!(
        still_running,
        "the search was over already:\n{}",
        printed.join("\n")
    );
    let file = format!("{dir}/deliver_all-never-active-detour.jsonl");
    let (code, checked, err) = tdl(&["trace", "check", &file]);
    assert_eq!(code, 0, "{checked}{err}");
    let (_, story, _) = tdl(&["trace", "story", &file]);
    assert!(story.contains("detour handling active"), "{story}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_name_no_node_has_is_an_error() {
    let (code, out, err) = tdl(&[
        "verify",
        "-p",
        "xavier",
        "--property",
        "never active(no_such)",
    ]);
    assert_eq!(code, 2, "{out}{err}");
    assert!(
        err.contains(
            "property `never active(no_such)` names `no_such`, which no node of the program is named; the names are: "
        ),
        "{err}"
    );
    assert!(
        err.contains("plan_path") && err.contains("ACT-watch_motor"),
        "{err}"
    );
    // A task whose every spawn gives it another name: nodes have that name, not the task's.
    let (file, dir) = program(
        "named",
        "goal main() { spawn step() with name \"first\"; spawn step() with name \"second\"; }",
    );
    let (code, out, err) = tdl(&["verify", &file, "--property", "never active(step)"]);
    assert_eq!(code, 2, "{out}{err}");
    assert!(err.contains("names `step`"), "{err}");
    assert!(err.contains("the names are: first, main, second"), "{err}");
    let (code, out, err) = tdl(&[
        "verify",
        &file,
        "--property",
        "never active(first) and active(second)",
        "--out",
        &dir,
    ]);
    assert_eq!(code, 1, "{out}{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_program_with_errors_is_an_error() {
    let (file, dir) = program(
        "broken",
        "goal main() { spawn step() with sequential execution nope; }",
    );
    let (code, out, err) = tdl(&["verify", &file]);
    assert_eq!(code, 2, "{out}{err}");
    assert!(err.contains("the program has errors"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A program meant to run until it is shut down fails `every run ends`, and passes without it.
#[test]
fn a_built_in_property_can_be_left_unchecked() {
    let (file, dir) = program("forever", FOREVER);
    let (code, out, err) = tdl(&["verify", &file, "--out", &dir]);
    assert_eq!(code, 1, "{out}{err}");
    assert!(
        out.contains("  VIOLATED   every run ends: a run that never ends"),
        "{out}"
    );
    let (code, out, err) = tdl(&[
        "verify",
        &file,
        "--no-builtin",
        "every-run-ends",
        "--out",
        &dir,
    ]);
    assert_eq!(code, 0, "{out}{err}");
    assert!(
        out.contains("not checked (--no-builtin): every run ends"),
        "{out}"
    );
    assert!(!out.contains("  ok         every run ends"), "{out}");
    for p in [
        "no stuck state",
        "no unhandled exception",
        "every trace passes the trace checker",
    ] {
        assert!(out.contains(&format!("  ok         {p}")), "{out}");
    }
    let (code, _, err) = tdl(&["verify", &file, "--no-builtin", "every-run-end"]);
    assert_eq!(code, 2);
    assert!(
        err.contains("the built-in properties are no-stuck-state, no-unhandled-exception, every-run-ends, trace-checker"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_help_gives_the_exit_statuses_and_the_bounds() {
    let (code, out, err) = tdl(&["verify", "--help"]);
    assert_eq!(code, 0, "{err}");
    for s in [
        "Exit status (for CI):",
        "  0  ok:",
        "  1  violated:",
        "  3  undecided:",
        "  2  error:",
        "--max-memory <SIZE>",
        "--no-builtin <PROPERTY>",
    ] {
        assert!(out.contains(s), "{s}:\n{out}");
    }
}

#[test]
fn a_property_that_does_not_parse_is_a_usage_error() {
    let (code, _, err) = tdl(&[
        "verify",
        "-p",
        "xavier",
        "--property",
        "never active(turn) nand x",
    ]);
    assert_eq!(code, 2);
    assert!(err.contains("unexpected `nand`"), "{err}");
}

/// Ctrl-C, as a real SIGINT: the search stops promptly, prints what it found so far, and exits 3
/// (undecided).
#[cfg(unix)]
#[test]
fn sigint_stops_the_search_with_what_was_found() {
    let dir = out_dir("sigint");
    // The default bounds: a state space of millions of states, minutes of search.
    let (code, out, took) = super::interrupted(&["verify", "-p", "xavier", "--out", &dir]);
    assert_eq!(code, 3, "{out}");
    assert!(took < std::time::Duration::from_secs(20), "{took:?}");
    assert!(out.contains("interrupted: what was found so far"), "{out}");
    let stats = out.lines().nth(1).unwrap_or_default();
    assert!(stats.contains(" states explored ("), "{out}");
    let explored: u64 = stats
        .split(' ')
        .next()
        .and_then(|n| n.parse().ok())
        .expect("a count");
    assert!(explored > 0, "{stats}");
    // Properties not broken so far are undecided, not ok.
    assert!(
        out.contains("  undecided  every run ends: not decided: the search was interrupted"),
        "{out}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--quiet` leaves out the notes on what the checker abstracts and says how many there were,
/// in `tdl verify` and `tdl sim` alike; the verdict and the exit status are unchanged.
#[test]
fn quiet_leaves_out_the_notes_and_counts_them() {
    let (file, _) = program(
        "quiet",
        "command step() {}\ngoal main() {\n    raise (format!(\"done/{}\", 1));\n    spawn step();\n}\n",
    );
    for command in ["verify", "sim"] {
        let dir = out_dir(&format!("quiet-{command}"));
        let (code, out, _) = tdl(&[command, &file, "--out", &dir]);
        assert_eq!(code, 0, "{out}");
        assert!(out.contains("what the checker abstracts here:"), "{out}");
        assert!(
            out.contains("a raised event's name is computed in Rust"),
            "{out}"
        );
        let (code, quiet, _) = tdl(&[command, "--quiet", &file, "--out", &dir]);
        assert_eq!(code, 0, "{quiet}");
        assert!(
            !quiet.contains("what the checker abstracts here"),
            "{quiet}"
        );
        assert!(!quiet.contains("computed in Rust"), "{quiet}");
        assert!(
            quiet.contains("\n2 notes on what the checker abstracts not shown (--quiet)\n"),
            "{quiet}"
        );
        assert_eq!(last_line(&quiet), last_line(&out));
    }
}
