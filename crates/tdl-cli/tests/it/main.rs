//! The one integration-test binary of the `tdl` CLI: runs the built binary on files in
//! `tests/data` and checks output and exit codes.

use std::process::Command;

fn tdl(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_tdl"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("run tdl");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn check_prints_every_mistake_with_position_and_hint_and_exits_1() {
    let (code, out, _) = tdl(&["check", "tests/data/three_mistakes.tdl"]);
    assert_eq!(code, 1, "{out}");
    let headers: Vec<&str> = out
        .lines()
        .filter(|l| l.starts_with("tests/data/"))
        .collect();
    assert_eq!(
        headers,
        [
            "tests/data/three_mistakes.tdl:4:55: error: unknown tag `nowhere`",
            "tests/data/three_mistakes.tdl:5:5: error: `wait` on a task that is not spawned yet",
            "tests/data/three_mistakes.tdl:15:7: error: this constraint can only be given on the spawn",
        ],
        "{out}"
    );
    assert_eq!(out.matches("= help:").count(), 3, "{out}");
    assert!(out.contains("5 |     later wait;"), "{out}");
}

#[test]
fn check_is_silent_on_a_good_file() {
    let (code, out, err) = tdl(&["check", "tests/data/good.tdl"]);
    assert_eq!((code, out.as_str(), err.as_str()), (0, "", ""));
}

#[test]
fn expand_prints_readable_rust() {
    let (code, out, _) = tdl(&["expand", "tests/data/good.tdl"]);
    assert_eq!(code, 0);
    assert!(
        out.contains("fn deliver_mail(room: u32) -> ::tdl::Task {"),
        "{out}"
    );
    assert!(
        out.contains("::tdl::When::In(::std::time::Duration::from_secs(30))")
            && out.contains("::tdl::Then::Terminate"),
        "{out}"
    );
    assert!(
        out.contains("let tdl_monitor_pickup = ctx.reserve(\"monitor_pickup\")?;"),
        "{out}"
    );
}

#[test]
fn usage_and_io_errors_exit_2() {
    assert_eq!(tdl(&["check"]).0, 2);
    let (code, _, err) = tdl(&["check", "tests/data/missing.tdl"]);
    assert_eq!(code, 2);
    assert!(err.contains("cannot read tests/data/missing.tdl"), "{err}");
}

#[test]
fn trace_check_accepts_a_good_trace_and_names_the_violations_of_a_bad_one() {
    let (code, out, _) = tdl(&["trace", "check", "tests/data/run.jsonl"]);
    assert_eq!(code, 0, "{out}");
    assert!(
        out.starts_with("tests/data/run.jsonl: ok (60 records"),
        "{out}"
    );
    let (code, out, _) = tdl(&["trace", "check", "tests/data/broken_run.jsonl"]);
    assert_eq!(code, 1, "{out}");
    assert!(out.contains("[transition-from]"), "{out}");
}

#[test]
fn trace_log_tree_and_story_read_a_trace() {
    let (code, out, _) = tdl(&["trace", "log", "tests/data/run.jsonl"]);
    assert_eq!(code, 0);
    assert!(
        out.starts_with(
            "Goal          deliver_all {1}:        TCM {0} --> ON HOLD         (Inactive)\n"
        ),
        "{out}"
    );
    let (code, out, _) = tdl(&["trace", "tree", "tests/data/run.jsonl", "--at", "0"]);
    assert_eq!(code, 0);
    assert!(
        out.lines()
            .any(|l| l.trim_start().starts_with("deliver_all {1}")),
        "{out}"
    );
    let (code, out, _) = tdl(&["trace", "story", "tests/data/run.jsonl"]);
    assert_eq!(code, 0);
    assert!(
        out.lines().any(|l| l == "0 deliver_all handling active"),
        "{out}"
    );
    let (code, _, err) = tdl(&["trace", "story", "tests/data/missing.jsonl"]);
    assert_eq!(code, 2);
    assert!(
        err.contains("cannot read tests/data/missing.jsonl"),
        "{err}"
    );
}
