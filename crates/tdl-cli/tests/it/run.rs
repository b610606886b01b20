//! `tdl run`: a program run without a Rust build, its report printed, its exit status the
//! outcome; a program with an error refused before anything starts; commands from a Python
//! agent, and that agent killed mid-run surfacing as `AgentLost`.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use crate::tdl;

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("tdl-run-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("a scratch directory");
    dir
}

#[test]
fn a_program_runs_without_a_build_and_the_exit_status_is_its_outcome() {
    let dir = scratch("steps");
    let trace = dir.join("t.jsonl");
    let trace_arg = trace.display().to_string();
    let (code, out, err) = tdl(&[
        "run",
        "tests/data/run/steps.tdl",
        "--args",
        "[3, 9]",
        "--trace",
        &trace_arg,
    ]);
    assert_eq!(code, 0, "{out}\n{err}");
    assert!(out.starts_with("completed after"), "{out}");
    let (code, checked, _) = tdl(&["trace", "check", &trace_arg]);
    assert_eq!(code, 0, "{checked}");
    // The third step fails, with no handler: the run completes, the status says it failed.
    let (code, out, err) = tdl(&["run", "tests/data/run/steps.tdl", "--args", "[3, 2]"]);
    assert_eq!(code, 3, "{out}\n{err}");
    assert!(out.contains("unhandled exception Tired"), "{out}");
    assert!(out.contains("Tired { at: 2 }"), "{out}");
}

#[test]
fn a_program_with_an_error_is_refused_with_located_diagnostics_and_nothing_starts() {
    let dir = scratch("refused");
    for (file, what, line) in [
        ("syntax_error.tdl", "expected", "syntax_error.tdl:"),
        (
            "unknown_command.tdl",
            "`dig` is not a task of the program",
            "unknown_command.tdl:3:11",
        ),
        (
            "unknown_exception.tdl",
            "Slipped",
            "unknown_exception.tdl:7",
        ),
    ] {
        let trace = dir.join(format!("{file}.jsonl"));
        let trace_arg = trace.display().to_string();
        let path = format!("tests/data/run/{file}");
        let port = tcm_zenoh::config::free_port()
            .expect("a free port")
            .to_string();
        let (code, out, err) = tdl(&[
            "run", &path, "--trace", &trace_arg, "--wait", "0.2", "--port", &port,
        ]);
        assert_eq!(code, 1, "{file}: {out}\n{err}");
        assert!(err.contains(what), "{file}: {err}");
        assert!(err.contains(line), "{file}: {err}");
        assert!(err.contains("nothing was started"), "{file}: {err}");
        assert!(!err.contains("running "), "{file}: {err}");
        assert!(!trace.exists(), "{file}: a trace was written");
    }
}

/// The zenoh release the Rust side is built with, which the Python side must match.
const ZENOH: &str = "eclipse-zenoh==1.10.2";

/// The workspace's root.
pub(crate) fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The example arm agent, started on `port`; waits until it prints `ready`.
fn arm(python: &Path, port: u16, system: &str) -> Child {
    let mut child = Command::new(python)
        .arg(repo().join("python/examples/pick_and_place.py"))
        .args([port.to_string(), system.to_string()])
        .env("PYTHONPATH", repo().join("python"))
        .env("PYTHONUNBUFFERED", "1")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .expect("the Python agent starts");
    let out = child.stdout.take().expect("its stdout");
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(out).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    let ready = rx.recv_timeout(Duration::from_secs(60));
    assert_eq!(
        ready.ok().as_deref(),
        Some("ready"),
        "the arm agent did not start"
    );
    std::thread::spawn(move || while rx.recv().is_ok() {});
    child
}

/// `tdl run` of the pick-and-place example on `port`, started.
fn run_example(port: u16, system: &str, items: u32, trace: &Path) -> Child {
    Command::new(env!("CARGO_BIN_EXE_tdl"))
        .current_dir(repo())
        .args([
            "run",
            "python/examples/pick_and_place.tdl",
            "--args",
            &items.to_string(),
            "--port",
            &port.to_string(),
            "--system",
            system,
            "--wait",
            "30",
            "--trace",
            &trace.display().to_string(),
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run tdl")
}

/// The test venv's Python with `eclipse-zenoh`, or `None` (with the reason printed) where
/// `python3` is not on the path.
pub(crate) fn python() -> Option<PathBuf> {
    if test_support::find_on_path("python3").is_none() {
        println!("skipped: python3 is not on PATH, so the Python agent cannot run");
        return None;
    }
    Some(test_support::python_venv(&[ZENOH]).unwrap_or_else(|why| panic!("{why}")))
}

/// Waits for `child` at most `limit`; its exit code, standard output and error.
fn finish(mut child: Child, limit: Duration) -> (i32, String, String) {
    let start = Instant::now();
    while child.try_wait().expect("wait").is_none() {
        if start.elapsed() > limit {
            let _ = child.kill();
            panic!("tdl run did not end within {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let out = child.wait_with_output().expect("its output");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn a_mission_whose_commands_live_in_a_python_agent_completes() {
    let Some(python) = python() else { return };
    let port = tcm_zenoh::config::free_port().expect("a free port");
    let mut agent = arm(&python, port, "pick");
    let dir = scratch("python");
    let trace = dir.join("t.jsonl");
    let (code, out, err) = finish(
        run_example(port, "pick", 3, &trace),
        Duration::from_secs(120),
    );
    let _ = agent.kill();
    let _ = agent.wait();
    assert_eq!(code, 0, "{out}\n{err}");
    assert!(out.starts_with("completed after"), "{out}");
    assert!(err.contains("move_to on arm"), "{err}");
    let records = std::fs::read_to_string(&trace).expect("the trace");
    // Every command ran on the arm: `placed` records name it.
    assert!(records.matches("\"placed\"").count() >= 12, "{records}");
    // The third grasp misses; the handler's retry takes the item again.
    assert!(records.contains("NothingGrasped"), "{records}");
    let (code, checked, _) = tdl(&["trace", "check", &trace.display().to_string()]);
    assert_eq!(code, 0, "{checked}");
}

#[test]
fn killing_the_agent_mid_run_raises_agent_lost_in_the_tree() {
    let Some(python) = python() else { return };
    let port = tcm_zenoh::config::free_port().expect("a free port");
    let mut agent = arm(&python, port, "lost");
    let dir = scratch("lost");
    let trace = dir.join("t.jsonl");
    // Two items: the rest of the mission, with the agent gone, ends by the remote tasks'
    // schedule-to-start timeouts (10 s each).
    let run = run_example(port, "lost", 2, &trace);
    // Kill the agent once the mission is under way (its first move is placed).
    let start = Instant::now();
    loop {
        let text = std::fs::read_to_string(&trace).unwrap_or_default();
        if text.contains("\"placed\"") {
            break;
        }
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "the mission did not start"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    let _ = agent.kill();
    let _ = agent.wait();
    let (code, out, err) = finish(run, Duration::from_secs(120));
    assert_eq!(code, 3, "{out}\n{err}");
    assert!(out.contains("unhandled exception AgentLost"), "{out}");
    let records = std::fs::read_to_string(&trace).expect("the trace");
    assert!(
        records.contains("agent arm was lost while it ran"),
        "{records}"
    );
}

#[test]
fn with_view_the_run_is_served_live_and_after_it_ends() {
    let mut child = Command::new(env!("CARGO_BIN_EXE_tdl"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args([
            "run",
            "tests/data/run/steps.tdl",
            "--args",
            "[2, 9]",
            "--view",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run tdl");
    let stderr = child.stderr.take().expect("its stderr");
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    let addr = loop {
        let line = rx
            .recv_timeout(Duration::from_secs(60))
            .expect("tdl run prints the viewer's address");
        if let Some(rest) = line.strip_prefix("viewer: http://") {
            break rest.split('/').next().unwrap_or_default().to_string();
        }
    };
    // The run ends within a second; the viewer keeps serving it, finished, with its records.
    let start = Instant::now();
    let runs = loop {
        let runs = crate::view::get(&addr, "/api/runs");
        if runs.contains("\"finished\":true") || start.elapsed() > Duration::from_secs(30) {
            break runs;
        }
        std::thread::sleep(Duration::from_millis(100));
    };
    let _ = child.kill();
    let _ = child.wait();
    assert!(runs.contains("\"name\":\"steps\""), "{runs}");
    assert!(runs.contains("\"finished\":true"), "{runs}");
    assert!(!runs.contains("\"records\":0"), "{runs}");
}
