//! `tdl serve` and its clients as a user drives them from a shell: a program refused with located
//! diagnostics (exit 1, nothing loaded), a program loaded and listed, a task started, its run's
//! status, an event raised, the run stopped and its trace checked; a client of no executive exits
//! 2. Loopback only; the server is killed at the end whatever happens.

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use crate::tdl;

/// The server, killed when dropped.
pub(crate) struct Serving(Child);

impl Drop for Serving {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn status_of(port: &str, run: &str) -> (i32, String, String) {
    tdl(&["status", run, "--port", port, "--client", "tester"])
}

/// `tdl serve` on a free port of 127.0.0.1, writing its traces in `dir`, once it answers: the
/// server (killed when dropped) and its port.
pub(crate) fn serving(dir: &Path) -> (Serving, String) {
    serving_with(dir, &[], &[])
}

/// As [`serving`], with `extra` arguments for the server, asked whether it answers with `probe`
/// arguments for the client (its TLS and client name, say).
pub(crate) fn serving_with(dir: &Path, extra: &[&str], probe: &[&str]) -> (Serving, String) {
    let port = tcm_zenoh::config::free_port()
        .expect("a free port")
        .to_string();
    let serving = Serving(
        Command::new(env!("CARGO_BIN_EXE_tdl"))
            .args(["serve", "--port", &port])
            .args(extra)
            .arg("--traces")
            .arg(dir)
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("tdl serve starts"),
    );
    // The server answers once it listens.
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        let mut args = vec!["programs", "--port", &port, "--timeout", "0.5"];
        args.extend_from_slice(probe);
        let (code, _, _) = tdl(&args);
        if code == 0 {
            break;
        }
        assert!(Instant::now() < deadline, "tdl serve never answered");
        std::thread::sleep(Duration::from_millis(100));
    }
    (serving, port)
}

#[test]
fn programs_are_loaded_started_stopped_and_asked_about_through_the_command_line() {
    let dir = std::env::temp_dir().join(format!("tdl-serve-cli-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let (_serving, port) = serving(&dir);

    let (code, out, err) = tdl(&[
        "load",
        "tests/data/serve/broken.tdl",
        "--name",
        "watch",
        "--port",
        &port,
    ]);
    assert_eq!(code, 1, "{out}\n{err}");
    assert!(err.contains("broken.tdl:3"), "{err}");
    let (_, listed, _) = tdl(&["programs", "--port", &port]);
    assert_eq!(listed, "", "nothing was loaded");

    let (code, out, err) = tdl(&[
        "load",
        "tests/data/serve/watch.tdl",
        "--port",
        &port,
        "--client",
        "tester",
    ]);
    assert_eq!(code, 0, "{out}\n{err}");
    assert!(out.starts_with("loaded watch@"), "{out}");
    let (_, listed, _) = tdl(&["programs", "--port", &port]);
    assert!(
        listed.contains("tasks: watch") && listed.contains("loaded by tester"),
        "{listed}"
    );

    let (code, out, err) = tdl(&["start", "watch", "--port", &port, "--client", "tester"]);
    assert_eq!(code, 0, "{out}\n{err}");
    assert!(out.starts_with("run 1 started"), "{out}");
    std::thread::sleep(Duration::from_millis(400));
    let (code, out, _) = status_of(&port, "1");
    assert_eq!(code, 0);
    assert!(out.contains("running"), "{out}");
    let (code, _, err) = tdl(&[
        "raise",
        "1",
        "door_open",
        "--port",
        &port,
        "--client",
        "tester",
    ]);
    assert_eq!(code, 0, "{err}");
    let (code, _, err) = tdl(&["stop", "1", "--port", &port, "--client", "tester"]);
    assert_eq!(code, 0, "{err}");
    let deadline = Instant::now() + Duration::from_secs(20);
    let ended = loop {
        let (_, out, _) = status_of(&port, "1");
        if out.contains("terminated") {
            break out;
        }
        assert!(Instant::now() < deadline, "the run never ended: {out}");
        std::thread::sleep(Duration::from_millis(100));
    };
    let (code, _, err) = tdl(&["stop", "1", "--port", &port]);
    assert_eq!(code, 1, "a run that ended cannot be stopped: {err}");

    let trace = dir.join("run-1.jsonl");
    assert!(ended.contains(&trace.display().to_string()), "{ended}");
    let trace_arg = trace.display().to_string();
    let (code, checked, err) = tdl(&["trace", "check", &trace_arg]);
    assert_eq!(code, 0, "{checked}\n{err}");
    let text = std::fs::read_to_string(&trace).expect("the trace");
    for what in [
        "start watch of watch@",
        "raise door_open",
        "\"what\":\"stop\"",
    ] {
        assert!(text.contains(what), "{what} in the trace");
    }
    assert!(text.contains("\"by\":\"tester\""));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_client_of_no_executive_says_so_and_exits_2() {
    let port = tcm_zenoh::config::free_port()
        .expect("a free port")
        .to_string();
    let (code, _, err) = tdl(&["status", "--port", &port, "--timeout", "0.3"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("no executive `main`"), "{err}");
}
