//! The `xavier` binary: a short nominal round exits 0 and names the room delivered; a bad flag
//! exits 2 with clap's message; `--trace` writes a trace the checker accepts, even when the run is killed.

use std::process::Command;

fn xavier(args: &[&str]) -> std::process::Output {
    match Command::new(env!("CARGO_BIN_EXE_xavier"))
        .args(args)
        .output()
    {
        Ok(out) => out,
        Err(e) => panic!("cannot run xavier: {e}"),
    }
}

#[test]
fn one_room_nominal_exits_0_and_names_room_3_as_delivered() {
    let out = xavier(&["--rooms", "3", "--scenario", "nominal"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stdout}\n{stderr}");
    assert!(stdout.contains("delivered:       3\n"), "{stdout}");
    assert!(stdout.contains("undeliverable:   none"), "{stdout}");
    assert!(stdout.contains("simulated time:"), "{stdout}");
    assert!(stdout.contains("wall time:"), "{stdout}");
    // Not a terminal: plain lines, no escapes.
    assert!(!stdout.contains('\x1b'), "{stdout}");
    assert!(stdout.contains("monitor_pickup"), "{stdout}");
}

#[test]
fn a_bad_flag_exits_2_with_a_message() {
    for args in [
        &["--scenario", "flooded"][..],
        &["--rooms", "3,x"],
        &["--rooms", "13"],
        &["--no-such-flag"],
    ] {
        let out = xavier(args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains("error:"), "{args:?}: {stderr}");
    }
}

#[test]
fn trace_and_log_files_are_written() {
    let dir = std::env::temp_dir().join(format!("xavier-it-{}", std::process::id()));
    if let Err(e) = std::fs::create_dir_all(&dir) {
        panic!("cannot create {}: {e}", dir.display());
    }
    let (trace, log) = (dir.join("run.jsonl"), dir.join("run.log"));
    let out = xavier(&[
        "--rooms",
        "7",
        "--scenario",
        "blocked-corridor",
        "--trace",
        &trace.to_string_lossy(),
        "--log",
        &log.to_string_lossy(),
    ]);
    assert_eq!(out.status.code(), Some(0));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("-> handler detour"), "{stdout}");
    let file = match std::fs::File::open(&trace) {
        Ok(f) => f,
        Err(e) => panic!("no trace file: {e}"),
    };
    let events = match tcm_trace::read_jsonl(std::io::BufReader::new(file)) {
        Ok(events) => events,
        Err(e) => panic!("bad trace file: {e}"),
    };
    assert!(tcm_trace::check(&events).is_ok());
    let text = std::fs::read_to_string(&log).unwrap_or_default();
    assert!(text.contains("guardedMove"), "{text}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A run killed with SIGKILL loses at most its last trace record: every complete line of the
/// trace file parses, and the records form a prefix the trace checker accepts.
#[test]
fn a_killed_run_leaves_a_trace_whose_every_line_parses_and_checks() {
    let dir = std::env::temp_dir().join(format!("xavier-kill-{}", std::process::id()));
    if let Err(e) = std::fs::create_dir_all(&dir) {
        panic!("cannot create {}: {e}", dir.display());
    }
    let trace = dir.join("killed.jsonl");
    // On real time the round takes tens of seconds: it is surely still running when killed.
    let mut child = match Command::new(env!("CARGO_BIN_EXE_xavier"))
        .args(["--real-time", "--rooms", "3,7,12", "--trace"])
        .arg(&trace)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
    {
        Ok(c) => c,
        Err(e) => panic!("cannot run xavier: {e}"),
    };
    // Wait until the run has written a good part of its trace (the robot is driving by then).
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    let mut lines_seen = 0;
    while lines_seen < 100 && std::time::Instant::now() < deadline {
        std::thread::sleep(std::time::Duration::from_millis(20));
        lines_seen = std::fs::read(&trace)
            .map(|b| b.iter().filter(|&&c| c == b'\n').count())
            .unwrap_or(0);
    }
    // `kill` sends SIGKILL on Unix: no destructor, no flush.
    if let Err(e) = child.kill() {
        panic!("cannot kill xavier: {e}");
    }
    let status = match child.wait() {
        Ok(s) => s,
        Err(e) => panic!("cannot wait for xavier: {e}"),
    };
    assert!(!status.success(), "the run ended before it was killed");
    assert!(
        lines_seen >= 100,
        "only {lines_seen} trace lines after 60 s"
    );
    let bytes = std::fs::read(&trace).unwrap_or_default();
    let text = String::from_utf8_lossy(&bytes);
    // Only the record being written when the process died may be cut: the text after the last
    // newline.
    let complete = match text.rfind('\n') {
        Some(i) => &text[..=i],
        None => "",
    };
    let cut = &text[complete.len()..];
    assert!(cut.len() < 4096, "a long unterminated tail: {cut}");
    let events = match tcm_trace::read_jsonl(complete.as_bytes()) {
        Ok(events) => events,
        Err(e) => panic!("a line of the killed run's trace does not parse: {e}"),
    };
    assert!(events.len() >= 100, "{} records", events.len());
    if let Err(vs) = tcm_trace::check_prefix(&events) {
        let text: Vec<String> = vs.iter().map(ToString::to_string).collect();
        panic!(
            "the prefix breaks the checker's rules:\n{}",
            text.join("\n")
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
