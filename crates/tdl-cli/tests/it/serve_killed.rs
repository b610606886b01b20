//! A client of `tdl serve` killed in the middle of its request changes nothing it did not finish:
//! after `tdl load` processes killed at once and a few milliseconds in, the executive still
//! answers, holds either no new program or the whole one (its version is the file's), and the run
//! it was running goes on. The server is killed at the end whatever happens.

use std::process::{Command, Stdio};
use std::time::Duration;

use crate::tdl;

#[test]
fn a_client_killed_mid_request_changes_nothing_it_did_not_finish() {
    let dir = std::env::temp_dir().join(format!("tdl-serve-killed-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let (_serving, port) = crate::serve::serving(&dir);
    let (code, _, err) = tdl(&["load", "tests/data/serve/watch.tdl", "--port", &port]);
    assert_eq!(code, 0, "{err}");
    let (code, _, err) = tdl(&["start", "watch", "--port", &port]);
    assert_eq!(code, 0, "{err}");

    for (i, after) in [0u64, 2, 5, 10, 20, 40].into_iter().enumerate() {
        let name = format!("killed{i}");
        let mut client = Command::new(env!("CARGO_BIN_EXE_tdl"))
            .args([
                "load",
                "tests/data/serve/watch.tdl",
                "--name",
                &name,
                "--port",
                &port,
            ])
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("a client starts");
        std::thread::sleep(Duration::from_millis(after));
        let _ = client.kill();
        let _ = client.wait();
    }
    let (code, listed, err) = tdl(&["programs", "--port", &port]);
    assert_eq!(code, 0, "the executive still answers: {err}");
    // Every program it holds is whole: the same version as the one loaded in full.
    let version = listed
        .lines()
        .find(|l| l.starts_with("watch@"))
        .and_then(|l| l.split_whitespace().next())
        .and_then(|v| v.split('@').nth(1))
        .expect("watch is held")
        .to_string();
    for line in listed.lines() {
        assert!(
            line.contains(&format!("@{version}")),
            "{line} is not the whole program"
        );
        assert!(line.contains("tasks: watch"), "{line}");
    }
    let (_, status, _) = tdl(&["status", "1", "--port", &port]);
    assert!(status.contains("running"), "the run goes on: {status}");
    let (code, _, err) = tdl(&["stop", "1", "--port", &port]);
    assert_eq!(code, 0, "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}
