//! `tdl serve` driven by the Python client (`tdl_agent.Client`, `python/tdl_agent/client.py`):
//! the example `python/examples/serve_client.py` loads a program with an error (refused, located
//! at its line), loads and starts `watch`, sees it running, raises an event, stops it, waits until
//! it ended `terminated`, unloads it and gets no answer from an executive no one runs; the run's
//! trace checks, and its `control` records name the Python client as who asked. Loopback only;
//! the server and the Python process are killed whatever happens. The venv comes from
//! `test_support::python_venv`; where Python 3 is absent, the test prints why and returns.

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use crate::run::{python, repo};
use crate::serve::serving;
use crate::tdl;

/// How long the Python client may take, interpreter and zenoh included.
const LIMIT: Duration = Duration::from_secs(120);

#[test]
fn a_python_client_loads_starts_raises_and_stops_and_the_trace_names_it() {
    let Some(python) = python() else { return };
    let dir = std::env::temp_dir().join(format!("tdl-serve-python-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let (_serving, port) = serving(&dir);

    let mut child = Command::new(python)
        .arg(repo().join("python/examples/serve_client.py"))
        .args(["--port", &port, "--client", "py_tester"])
        .args(["tests/data/serve/broken.tdl", "tests/data/serve/watch.tdl"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env("PYTHONPATH", repo().join("python"))
        .env("PYTHONUNBUFFERED", "1")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the Python client starts");
    let start = Instant::now();
    while child.try_wait().expect("wait").is_none() {
        if start.elapsed() > LIMIT {
            let _ = child.kill();
            let _ = child.wait();
            panic!("the Python client did not end within {LIMIT:?}");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let out = child.wait_with_output().expect("its output");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stdout}\n{stderr}");
    let lines: Vec<&str> = stdout.lines().collect();
    // The refusal carries the located diagnostic of line 3, and the run went through its life.
    for (i, expected) in [
        "refused at tests/data/serve/broken.tdl:3",
        "loaded watch@",
        "started run 1",
        "running watch of watch@",
        "raised door_open",
        "stopped",
        "ended terminated",
        "trace: ",
        "second stop refused: run 1 has ended",
        "unloaded",
        "no answer: no executive `nobody` of system `tdl` answered",
        "ok",
    ]
    .into_iter()
    .enumerate()
    {
        let line = lines.get(i).copied().unwrap_or_default();
        assert!(line.starts_with(expected), "line {i}: {line:?}\n{stdout}");
    }
    assert_eq!(lines.len(), 12, "{stdout}");

    // What the Python client did, the command line sees: the program is gone, the run ended.
    let (code, listed, _) = tdl(&["programs", "--port", &port]);
    assert_eq!((code, listed.as_str()), (0, ""));
    let (code, status, _) = tdl(&["status", "1", "--port", &port]);
    assert_eq!(code, 0);
    assert!(status.contains("terminated"), "{status}");

    let trace = dir.join("run-1.jsonl");
    assert_eq!(lines[7], format!("trace: {}", trace.display()));
    let trace_arg = trace.display().to_string();
    let (code, checked, err) = tdl(&["trace", "check", &trace_arg]);
    assert_eq!(code, 0, "{checked}\n{err}");
    let text = std::fs::read_to_string(&trace).expect("the trace");
    let controls: Vec<(String, String)> = text
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).expect("a JSON record"))
        .filter(|r| r["ev"] == "control")
        .map(|r| {
            (
                r["what"].as_str().unwrap_or_default().to_string(),
                r["by"].as_str().unwrap_or_default().to_string(),
            )
        })
        .collect();
    let whats: Vec<&str> = controls.iter().map(|(w, _)| w.as_str()).collect();
    assert_eq!(whats.len(), 3, "{controls:?}");
    assert!(
        whats[0].starts_with("start watch of watch@"),
        "{controls:?}"
    );
    assert_eq!(&whats[1..], ["raise door_open", "stop"], "{controls:?}");
    assert!(
        controls.iter().all(|(_, by)| by == "py_tester"),
        "{controls:?}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
