//! The `xavier` binary: a short nominal round exits 0 and names the room delivered; a bad flag
//! exits 2 with clap's message; `--trace` writes a trace the checker accepts.

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
