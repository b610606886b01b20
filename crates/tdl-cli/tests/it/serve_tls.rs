//! `tdl serve` with the secure configuration on loopback (mutual TLS and the system's access
//! rules): the allowed client loads, starts and stops; a member of the system that is not a
//! client, a client holding another authority's certificate, and a client on plain TCP can
//! neither load, start, stop nor raise, and nothing they asked changes anything. The server is
//! killed at the end whatever happens.

use std::path::Path;
use std::time::{Duration, Instant};

use crate::tdl;

fn certs(dir: &Path, system: &str, members: &[&str]) {
    let out = dir.display().to_string();
    let mut args = vec!["certs", "--system", system, "--out", &out];
    args.extend_from_slice(members);
    let (code, _, err) = tdl(&args);
    assert_eq!(code, 0, "{err}");
}

#[test]
fn with_mutual_tls_only_the_allowed_client_can_drive_the_executive() {
    let base = std::env::temp_dir().join(format!("tdl-serve-tls-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&base);
    let (system, stranger, traces) = (
        base.join("system"),
        base.join("stranger"),
        base.join("runs"),
    );
    certs(&system, "tdl", &["main", "operator", "arm"]);
    certs(&stranger, "other", &["operator"]);
    let sys = system.display().to_string();
    let (_serving, port) = crate::serve::serving_with(
        &traces,
        &["--tls", &sys, "--agents", "arm", "--clients", "operator"],
        &["--tls", &sys, "--client", "operator"],
    );
    let as_operator = |args: &[&str]| {
        let mut all = args.to_vec();
        all.extend_from_slice(&["--port", &port, "--tls", &sys, "--client", "operator"]);
        tdl(&all)
    };
    let (code, out, err) = as_operator(&["load", "tests/data/serve/watch.tdl"]);
    assert_eq!(code, 0, "{out}\n{err}");
    let (code, out, err) = as_operator(&["start", "watch"]);
    assert_eq!(code, 0, "{out}\n{err}");
    assert!(out.starts_with("run 1 started"), "{out}");

    let strangers = base.join("stranger").display().to_string();
    let identities: [(&str, Vec<&str>); 3] = [
        (
            "a member that is no client",
            vec!["--tls", &sys, "--client", "arm"],
        ),
        (
            "another authority's client",
            vec!["--tls", &strangers, "--client", "operator"],
        ),
        ("a client on plain TCP", vec!["--client", "operator"]),
    ];
    for (who, identity) in &identities {
        for request in [
            vec!["load", "tests/data/serve/broken.tdl", "--name", "watch"],
            vec!["start", "watch"],
            vec!["stop", "1"],
            vec!["raise", "1", "intruder"],
        ] {
            let mut args = request.clone();
            args.extend_from_slice(&["--port", &port, "--timeout", "0.4"]);
            args.extend_from_slice(identity);
            let (code, out, err) = tdl(&args);
            assert_eq!(code, 2, "{who}, {request:?}: {out}\n{err}");
        }
    }
    // Nothing they asked happened: one program, one run, still running, no `intruder` raised.
    let (_, listed, _) = as_operator(&["programs"]);
    assert_eq!(listed.lines().count(), 1, "{listed}");
    let (_, status, _) = as_operator(&["status"]);
    assert_eq!(status.lines().count(), 1, "{status}");
    assert!(status.contains("running"), "{status}");
    let (code, _, err) = as_operator(&["stop", "1"]);
    assert_eq!(code, 0, "{err}");
    let deadline = Instant::now() + Duration::from_secs(20);
    while !as_operator(&["status", "1"]).1.contains("terminated") {
        assert!(Instant::now() < deadline, "the run never ended");
        std::thread::sleep(Duration::from_millis(100));
    }
    let text = std::fs::read_to_string(traces.join("run-1.jsonl")).expect("the trace");
    assert!(!text.contains("intruder"));
    assert!(text.contains("\"by\":\"operator\""));
    let _ = std::fs::remove_dir_all(&base);
}
