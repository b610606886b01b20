//! `tdl run` steered from its terminal: a breakpoint pauses the run, a step starts one node and
//! pauses again, removing the breakpoint and continuing lets it end; faults from a file and a
//! node held for approval, approved by its number, the rest released when standard input closes.
//! Each trace passes `tdl trace check`.

use std::io::{BufRead, BufReader, Write};
use std::path::PathBuf;
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::{Receiver, channel};
use std::time::Duration;

use crate::tdl;

/// Long enough for a loaded machine; the run itself takes a fraction of a second.
const PATIENCE: Duration = Duration::from_secs(60);

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("tdl-steer-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("a scratch directory");
    dir
}

/// `tdl run` of the three steps with `extra`, its standard input and error piped.
struct Steered {
    child: Child,
    stdin: Option<ChildStdin>,
    lines: Receiver<String>,
    seen: Vec<String>,
}

impl Steered {
    fn start(trace: &std::path::Path, extra: &[&str]) -> Steered {
        let mut child = Command::new(env!("CARGO_BIN_EXE_tdl"))
            .args([
                "run",
                "tests/data/run/steps.tdl",
                "--args",
                "[3, 9]",
                "--trace",
            ])
            .arg(trace)
            .args(extra)
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("run tdl");
        let stderr = child.stderr.take().expect("stderr");
        let (tx, lines) = channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        let stdin = child.stdin.take();
        Steered {
            child,
            stdin,
            lines,
            seen: Vec::new(),
        }
    }

    /// Waits for a line of standard error containing `text`; returns it.
    fn expect(&mut self, text: &str) -> String {
        loop {
            match self.lines.recv_timeout(PATIENCE) {
                Ok(line) => {
                    self.seen.push(line.clone());
                    if line.contains(text) {
                        return line;
                    }
                }
                Err(_) => panic!("no line with {text:?}; seen:\n{}", self.seen.join("\n")),
            }
        }
    }

    /// Waits until lines containing each of `texts` came, in any order (what the command reader
    /// says and what the run prints come from two threads).
    fn expect_all(&mut self, texts: &[&str]) {
        let mut missing: Vec<&str> = texts.to_vec();
        while !missing.is_empty() {
            match self.lines.recv_timeout(PATIENCE) {
                Ok(line) => {
                    missing.retain(|t| !line.contains(t));
                    self.seen.push(line);
                }
                Err(_) => panic!("no line with {missing:?}; seen:\n{}", self.seen.join("\n")),
            }
        }
    }

    fn send(&mut self, command: &str) {
        let stdin = self.stdin.as_mut().expect("stdin open");
        writeln!(stdin, "{command}").expect("write a command");
        stdin.flush().expect("flush");
    }

    /// Closes standard input and waits for the exit status.
    fn finish(mut self) -> i32 {
        drop(self.stdin.take());
        let deadline = std::time::Instant::now() + PATIENCE;
        loop {
            if let Some(status) = self.child.try_wait().expect("wait") {
                return status.code().unwrap_or(-1);
            }
            if std::time::Instant::now() > deadline {
                let _ = self.child.kill();
                panic!("tdl run did not end; seen:\n{}", self.seen.join("\n"));
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

/// The trace file's records, after `tdl trace check` passed it.
fn checked(trace: &std::path::Path) -> Vec<tcm_trace::TraceEvent> {
    let (code, out, err) = tdl(&["trace", "check", &trace.display().to_string()]);
    assert_eq!(code, 0, "{out}{err}");
    let text = std::fs::read_to_string(trace).expect("the trace");
    tcm_trace::read_jsonl(text.as_bytes()).expect("a trace")
}

#[test]
fn a_breakpoint_pauses_tdl_run_and_commands_step_and_continue() {
    let dir = scratch("break");
    let trace = dir.join("trace.jsonl");
    let mut run = Steered::start(&trace, &["--break", "step"]);
    run.expect("run paused: breakpoint #1: before step {2}");
    run.send("s");
    run.expect_all(&["> step", "run paused: step"]);
    run.send("d 1");
    run.expect("> removed");
    run.send("c");
    run.expect("> continue");
    assert_eq!(run.finish(), 0);
    let trace = checked(&trace);
    let pauses = trace
        .iter()
        .filter(|e| matches!(e.kind, tcm_trace::TraceKind::Paused { .. }))
        .count();
    assert_eq!(pauses, 2);
    let controls: Vec<&str> = trace
        .iter()
        .filter_map(|e| match &e.kind {
            tcm_trace::TraceKind::Control { what, by } if by == "terminal" => Some(what.as_str()),
            _ => None,
        })
        .collect();
    assert_eq!(
        controls,
        [
            "breakpoint before the start of task step (#1)",
            "step",
            "removed #1",
            "continue"
        ]
    );
}

#[test]
fn faults_from_a_file_and_approvals_from_the_terminal() {
    let dir = scratch("approve");
    let trace = dir.join("trace.jsonl");
    let faults = dir.join("faults.json");
    std::fs::write(
        &faults,
        r#"[{"task": "step", "exception": "Tired", "message": "injected at the first step"}]"#,
    )
    .expect("write the faults");
    let faults = faults.display().to_string();
    let mut run = Steered::start(&trace, &["--faults", &faults, "--approve", "step"]);
    run.expect("step {2}: held for approval");
    run.send("h");
    run.expect("> held: step {2}");
    run.send("a 2");
    run.expect_all(&[
        "> approved",
        "step {2}: fault injected: fail Tired: injected at the first step",
    ]);
    run.send("a 2");
    let refused = run.expect("> ");
    assert!(
        refused.contains("not held for approval") || refused.contains("no live node numbered 2"),
        "{refused}"
    );
    // Standard input closed: the other steps are released and run.
    assert_eq!(run.finish(), 3, "the injected failure is unhandled");
    let trace = checked(&trace);
    let approved: Vec<&str> = trace
        .iter()
        .filter_map(|e| match &e.kind {
            tcm_trace::TraceKind::Approved { by, .. } => Some(by.as_str()),
            _ => None,
        })
        .collect();
    assert_eq!(approved[0], "terminal");
    assert!(approved.len() >= 2, "{approved:?}");
    assert!(
        approved[1..]
            .iter()
            .all(|b| *b == "terminal (standard input closed)")
    );
    let bad = dir.join("bad.json");
    std::fs::write(&bad, "[{\"task\": \"step\", \"never\": tru}]").expect("write");
    let (code, _, err) = tdl(&[
        "run",
        "tests/data/run/steps.tdl",
        "--args",
        "[3, 9]",
        "--faults",
        &bad.display().to_string(),
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("bad.json:1:"), "{err}");
}

/// A fault whose value stands for a command's: the survey reads the injected range, not the one
/// `measure` would have returned, and backs off.
#[test]
fn a_value_from_a_faults_file_stands_for_a_commands() {
    let dir = scratch("value");
    let faults = dir.join("faults.json");
    std::fs::write(&faults, r#"[{"task": "measure", "value": 0.5}]"#).expect("write");
    let spawned = |extra: &[&str]| {
        let trace = dir.join("trace.jsonl");
        let trace_arg = trace.display().to_string();
        let mut args = vec!["run", "tests/data/run/measure.tdl", "--trace", &trace_arg];
        args.extend_from_slice(extra);
        let (code, out, err) = tdl(&args);
        assert_eq!(code, 0, "{out}{err}");
        let names: Vec<String> = checked(&trace)
            .iter()
            .filter_map(|e| match &e.kind {
                tcm_trace::TraceKind::Spawned { name, .. } => Some(name.clone()),
                _ => None,
            })
            .collect();
        names
    };
    assert_eq!(spawned(&[]), ["survey", "measure"]);
    let faults = faults.display().to_string();
    assert_eq!(
        spawned(&["--faults", &faults]),
        ["survey", "measure", "back_off"]
    );
}

/// A fault's exception carries data from the file, which an interpreted handler reads as the
/// exception's fields.
#[test]
fn an_exception_from_a_faults_file_carries_its_data_to_the_handler() {
    let dir = scratch("data");
    let spawned = |data: &str| {
        let faults = dir.join("faults.json");
        let rule =
            format!(r#"[{{"task": "step", "exception": "Blocked", "data": {{"at": {data}}}}}]"#);
        std::fs::write(&faults, rule).expect("write");
        let trace = dir.join("trace.jsonl");
        let (code, out, err) = tdl(&[
            "run",
            "tests/data/run/blocked.tdl",
            "--trace",
            &trace.display().to_string(),
            "--faults",
            &faults.display().to_string(),
        ]);
        assert_eq!(code, 0, "{out}{err}");
        checked(&trace)
            .iter()
            .filter_map(|e| match &e.kind {
                tcm_trace::TraceKind::Spawned { name, .. } => Some(name.clone()),
                _ => None,
            })
            .collect::<Vec<_>>()
    };
    assert_eq!(spawned("9"), ["walk", "step", "go_around", "far_around"]);
    assert_eq!(spawned("2"), ["walk", "step", "go_around", "around"]);
}

/// `tdl run --journal FILE`: the run's inputs are in the journal, which names the program by its
/// hash; a second run does not overwrite it.
#[test]
fn tdl_run_keeps_a_journal_of_its_inputs() {
    let dir = scratch("journal");
    let journal = dir.join("run.journal");
    let journal_arg = journal.display().to_string();
    let args = [
        "run",
        "tests/data/run/steps.tdl",
        "--args",
        "[3, 9]",
        "--journal",
        &journal_arg,
        "--journal-sync",
        "every",
    ];
    let (code, out, err) = tdl(&args);
    assert_eq!(code, 0, "{out}{err}");
    let read = tcm_journal::read(&journal, None).expect("a journal");
    assert_eq!(read.header.program.len(), 12, "the program's content hash");
    let ended: Vec<u64> = read
        .entries
        .iter()
        .filter_map(|e| match e.input {
            tcm_journal::Input::Ended { node, .. } => Some(node),
            _ => None,
        })
        .collect();
    // The goal's body, then its three steps, in order.
    assert_eq!(ended, [1, 2, 3, 4]);
    let (code, _, err) = tdl(&args);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("exists already: resume from it, or remove it first"),
        "{err}"
    );
    let (code, _, err) = tdl(&[
        "run",
        "tests/data/run/steps.tdl",
        "--args",
        "[3, 9]",
        "--journal",
        &dir.join("other.journal").display().to_string(),
        "--journal-sync",
        "sometimes",
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("give `every`, `group:MS` or `acting:MS`"),
        "{err}"
    );
}

/// The journal of an interpreted run holds each command's value, as JSON.
#[test]
fn a_journal_holds_the_values_of_interpreted_commands() {
    let dir = scratch("journal-values");
    let journal = dir.join("run.journal");
    let (code, out, err) = tdl(&[
        "run",
        "tests/data/run/measure.tdl",
        "--journal",
        &journal.display().to_string(),
    ]);
    assert_eq!(code, 0, "{out}{err}");
    let read = tcm_journal::read(&journal, None).expect("a journal");
    let values: Vec<(u64, Option<serde_json::Value>)> = read
        .entries
        .iter()
        .filter_map(|e| match &e.input {
            tcm_journal::Input::Ended { node, value, .. } => Some((*node, value.clone())),
            _ => None,
        })
        .collect();
    // `measure` {2} returned 10.0; the goal's body returned nothing (unit, written as null).
    assert!(
        values.contains(&(2, Some(serde_json::json!(10.0)))),
        "{values:?}"
    );
}
