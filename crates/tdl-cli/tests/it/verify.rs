//! `tdl verify` on the Xavier mission (`-p xavier`) and on a copy with a seeded bug: the report,
//! the exit codes, and a counterexample trace that `tdl trace story` replays. Small bounds keep
//! the runs short (the crate `tdl-verify` tests the rest).

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
    let _ = std::fs::remove_dir_all(&dir);
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

/// Ctrl-C, as a real SIGINT: the search stops promptly, prints what it found so far, and exits 1.
#[cfg(unix)]
#[test]
fn sigint_stops_the_search_with_what_was_found() {
    let dir = out_dir("sigint");
    // The default bounds: a state space of millions of states, minutes of search.
    let (code, out, took) = super::interrupted(&["verify", "-p", "xavier", "--out", &dir]);
    assert_eq!(code, 1, "{out}");
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
