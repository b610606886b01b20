//! The one integration-test binary of the `tdl` CLI: runs the built binary on files in
//! `tests/data` and checks output and exit codes. `tdl graph` and `tdl doc` have their own
//! modules (`graph.rs`, `doc.rs`), as have `tdl trace export` (`export.rs`), `tdl verify`
//! (`verify.rs`) and `tdl sim` (`sim.rs`), and `tdl certs` (`certs.rs`); `tdl serve` is driven from
//! the command line (`serve.rs`) and by the Python client (`serve_python.rs`).

use std::process::Command;

#[cfg(feature = "net")]
mod certs;
mod doc;
mod durable;
mod export;
mod graph;
#[cfg(feature = "net")]
mod run;
#[cfg(feature = "net")]
mod serve;
#[cfg(feature = "net")]
mod serve_killed;
#[cfg(feature = "net")]
mod serve_python;
#[cfg(feature = "net")]
mod serve_tls;
mod sim;
mod steer;
mod verify;
mod view;

/// Starts `tdl ARGS`, waits for its first progress line on standard error (the search is under
/// way), sends it a real SIGINT (`kill -INT`), and returns its exit code, its standard output and
/// how long it took to exit after the signal.
#[cfg(unix)]
fn interrupted(args: &[&str]) -> (i32, String, std::time::Duration) {
    use std::io::{BufRead, Read};
    use std::process::Stdio;
    use std::time::{Duration, Instant};
    let mut child = Command::new(env!("CARGO_BIN_EXE_tdl"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run tdl");
    let stderr = child.stderr.take().expect("piped");
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in std::io::BufReader::new(stderr)
            .lines()
            .map_while(Result::ok)
        {
            let _ = tx.send(line);
        }
    });
    // Progress lines come once a second when standard error is not a terminal.
    let first = rx.recv_timeout(Duration::from_secs(120));
    let pid = child.id().to_string();
    let killed = Command::new("kill")
        .args(["-INT", &pid])
        .status()
        .expect("run kill");
    assert!(killed.success(), "kill -INT {pid}");
    let sent = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().expect("wait") {
            break status;
        }
        if sent.elapsed() > Duration::from_secs(60) {
            let _ = child.kill();
            panic!("tdl did not stop within a minute of SIGINT");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let took = sent.elapsed();
    let mut out = String::new();
    child
        .stdout
        .take()
        .expect("piped")
        .read_to_string(&mut out)
        .expect("reads");
    assert!(first.is_ok(), "no progress line before the signal:\n{out}");
    (status.code().unwrap_or(-1), out, took)
}

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
        .filter(|l| l.starts_with("error") || l.contains("--> "))
        .map(str::trim)
        .collect();
    assert_eq!(
        headers,
        [
            "error: unknown tag `nowhere`",
            "--> tests/data/three_mistakes.tdl:4:55",
            "error: `wait` on a task that is not spawned yet",
            "--> tests/data/three_mistakes.tdl:5:5",
            "error: this constraint can only be given on the spawn",
            "--> tests/data/three_mistakes.tdl:15:7",
        ],
        "{out}"
    );
    // Not a terminal: no colour.
    assert!(!out.contains('\u{1b}'), "{out:?}");
    assert_eq!(out.matches("= help:").count(), 3, "{out}");
    assert!(out.contains("5 |     later wait;"), "{out}");
}

#[test]
fn check_is_silent_on_a_good_file() {
    let (code, out, err) = tdl(&["check", "tests/data/good.tdl"]);
    assert_eq!((code, out.as_str(), err.as_str()), (0, "", ""));
}

/// The `.tdl` files of `tdl-syntax`'s `test_data/<kind>`, as paths relative to this crate.
fn syntax_data(kind: &str) -> Vec<String> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../tdl-syntax/test_data")
        .join(kind);
    let mut files: Vec<String> = std::fs::read_dir(&dir)
        .unwrap_or_else(|err| panic!("cannot read {}: {err}", dir.display()))
        .filter_map(Result::ok)
        .map(|it| it.path())
        .filter(|it| it.extension().is_some_and(|ext| ext == "tdl"))
        .map(|it| it.display().to_string())
        .collect();
    files.sort();
    files
}

/// Issue 12, point 5: what the parser data calls valid, `tdl check` (which also runs the code
/// generator) accepts, one file at a time; and every file of the error data is refused.
#[test]
fn check_accepts_every_ok_file_and_refuses_every_err_file() {
    let ok = syntax_data("ok");
    assert!(ok.len() >= 10, "{ok:?}");
    for file in &ok {
        let (code, out, err) = tdl(&["check", file]);
        assert_eq!(code, 0, "{file}:\n{out}{err}");
        assert!(
            !out.lines().any(|l| l.starts_with("error")),
            "{file}:\n{out}"
        );
    }
    let bad = syntax_data("err");
    assert!(bad.len() >= 15, "{bad:?}");
    for file in &bad {
        let (code, out, err) = tdl(&["check", file]);
        assert_eq!(code, 1, "{file}:\n{out}{err}");
        assert!(
            out.lines().any(|l| l.starts_with("error")),
            "{file}:\n{out}"
        );
    }
}

/// Warnings are printed, and do not fail the check.
#[test]
fn check_prints_warnings_and_exits_0_on_every_warn_file() {
    let warn = syntax_data("warn");
    assert!(warn.len() >= 2, "{warn:?}");
    for file in &warn {
        let (code, out, err) = tdl(&["check", file]);
        assert_eq!(code, 0, "{file}:\n{out}{err}");
        assert!(
            out.lines().any(|l| l.starts_with("warning: ")),
            "{file}:\n{out}"
        );
        assert!(
            !out.lines().any(|l| l.starts_with("error")),
            "{file}:\n{out}"
        );
    }
}

/// Issue 48, point 4: `--quiet` prints the errors only, and one line with how many warnings it
/// did not show, on `tdl check` (standard output) and on `tdl graph` and `tdl doc` (standard
/// error, where their diagnostics go); the exit status is unchanged.
#[test]
fn quiet_prints_errors_only_and_counts_the_warnings_it_hides() {
    let warn = "../tdl-syntax/test_data/warn/unhandled_exception.tdl";
    let (code, out, _) = tdl(&["check", warn]);
    assert_eq!(code, 0, "{out}");
    let warnings = out.lines().filter(|l| l.starts_with("warning: ")).count();
    assert_eq!(warnings, 3, "{out}");
    let hidden = "3 warnings not shown (--quiet)\n";
    assert_eq!(
        tdl(&["check", "--quiet", warn]),
        (0, hidden.to_owned(), String::new())
    );

    // Errors are still printed, warnings not.
    let (code, out, _) = tdl(&["check", "-q", "../tdl-syntax/test_data/err/warnings.tdl"]);
    assert_eq!(code, 1, "{out}");
    let errors = out.lines().filter(|l| l.starts_with("error: ")).count();
    assert_eq!(errors, 2, "{out}");
    assert!(!out.contains("warning: "), "{out}");
    assert!(out.ends_with("\n4 warnings not shown (--quiet)\n"), "{out}");

    let (code, out, err) = tdl(&["graph", "--quiet", warn]);
    assert_eq!((code, err.as_str()), (0, hidden), "{out}");
    assert!(out.starts_with("digraph"), "{out}");
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("tdl-doc-quiet");
    let dir = dir.display().to_string();
    let (code, out, err) = tdl(&["doc", "--quiet", warn, "-o", &dir]);
    assert_eq!((code, err.as_str()), (0, hidden), "{out}");

    // A clean file says nothing, quiet or not.
    assert_eq!(
        tdl(&["check", "--quiet", "tests/data/good.tdl"]),
        (0, String::new(), String::new())
    );
}

/// Issue 48, point 4: every warning accepted at its site with `#[allow(tdl::…)]` leaves `tdl
/// check` silent; an allow that accepts nothing is itself a warning.
#[test]
fn allowed_warnings_are_not_printed_and_unused_allows_are() {
    let allowed = "../tdl-syntax/test_data/ok/allowed_warnings.tdl";
    assert_eq!(tdl(&["check", allowed]), (0, String::new(), String::new()));
    let (code, out, _) = tdl(&["check", "../tdl-syntax/test_data/warn/unused_allow.tdl"]);
    assert_eq!(code, 0, "{out}");
    assert_eq!(out.matches("accepts no warning").count(), 3, "{out}");
}

/// Issue 12, point 3: `tdl check` takes the files of one program and resolves names across them.
#[test]
fn check_resolves_names_across_the_files_of_a_program() {
    let (code, out, err) = tdl(&["check", "tests/data/faults.tdl", "tests/data/walk.tdl"]);
    assert_eq!((code, out.as_str(), err.as_str()), (0, "", ""));
    let (code, out, _) = tdl(&["check", "tests/data/faults.tdl", "tests/data/walk_typo.tdl"]);
    assert_eq!(code, 1, "{out}");
    assert!(
        out.starts_with(
            "error: unknown exception `TerainFault`\n --> tests/data/walk_typo.tdl:2:29\n"
        ),
        "{out}"
    );
    assert!(out.contains("Fault, TerrainFault"), "{out}");
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
    // The run was cut while the mail was being delivered: valid, and said not to have ended,
    // with the innermost nodes still open.
    assert!(
        out.contains(
            "the run did not end: at its last record (0.000 s) 10 node(s) had not completed"
        ),
        "{out}"
    );
    assert!(
        out.contains("  deliver_all/deliver_mail/center_on_door {4}: handling disabled, expansion disabled, execution disabled\n"),
        "{out}"
    );
    // A run that ended says nothing more.
    let (code, out, _) = tdl(&["trace", "check", "tests/data/handled_run.jsonl"]);
    assert_eq!(code, 0, "{out}");
    assert!(!out.contains("did not end"), "{out}");
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
        out.lines()
            .any(|l| l == "0 {1} deliver_all handling active"),
        "{out}"
    );
    let (code, _, err) = tdl(&["trace", "story", "tests/data/missing.jsonl"]);
    assert_eq!(code, 2);
    assert!(
        err.contains("cannot read tests/data/missing.jsonl"),
        "{err}"
    );
}

/// Issue 12, point 10: without `--at` the tree is the whole run, reclaimed nodes included (they
/// all are at the end of `handled_run.jsonl`, a run of `crates/tdl/tests/it/warnings.rs`'s `walk(2)`
/// with a wiretap on `log_step`); `--live` gives the old view, only the root.
#[test]
fn trace_tree_shows_the_whole_run() {
    let (code, out, _) = tdl(&["trace", "tree", "tests/data/handled_run.jsonl"]);
    assert_eq!(code, 0);
    assert_eq!(out.lines().count(), 20, "{out}");
    assert!(
        out.contains(
            "    step 1 {7}  handling=completed expansion=completed execution=completed failed reclaimed\n      count_up {16}"
        ),
        "{out}"
    );
    let (code, out, _) = tdl(&["trace", "tree", "tests/data/handled_run.jsonl", "--live"]);
    assert_eq!(code, 0);
    assert_eq!(
        out,
        "Root Node {0}  handling=active expansion=active execution=active\n"
    );
}

/// Issue 12, point 10: the story has node numbers, shows wiretap, handler-chosen, bypass and retry
/// records, and filters by kind, name, path, node and time.
#[test]
fn trace_story_shows_handlers_retries_wiretaps_and_filters() {
    let file = "tests/data/handled_run.jsonl";
    let (code, out, _) = tdl(&["trace", "story", file, "--kind", "handler,retry,wiretap"]);
    assert_eq!(code, 0);
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(
        lines[..4],
        [
            "0.02 {5} log_step wiretap 0 checks before",
            "0.03 {7} step 1 handler count_up {16} chosen for TerrainFault (attached to walk {1})",
            "0.03 {16} count_up bypasses TerrainFault",
            "0.03 {7} step 1 handler recover {17} chosen for TerrainFault (attached to walk {1})",
        ],
        "{out}"
    );
    assert!(
        lines.contains(&"0.03 {18} step 1 retries step 1 {7}"),
        "{out}"
    );
    // By name: only `recover`'s records.
    let (_, out, _) = tdl(&[
        "trace",
        "story",
        file,
        "--name",
        "recover",
        "--kind",
        "transition",
    ]);
    assert!(!out.is_empty());
    assert!(out.lines().all(|l| l.contains("{17} recover ")), "{out}");
    // By path: the subtree of `walk/step 1`, which holds the handlers and the retry.
    let (_, out, _) = tdl(&[
        "trace",
        "story",
        file,
        "--path",
        "walk/step 1",
        "--kind",
        "spawn",
    ]);
    let spawned: Vec<&str> = out.lines().filter(|l| l.contains(" spawned ")).collect();
    assert_eq!(spawned.len(), 5, "{out}");
    // By node and time.
    let (_, out, _) = tdl(&[
        "trace", "story", file, "--node", "18", "--from", "0.04", "--to", "0.04",
    ]);
    assert!(!out.is_empty());
    assert!(
        out.lines()
            .all(|l| l.starts_with("0.04 {18} ") || l.starts_with("0.04 {19} ")),
        "{out}"
    );
    // A bad kind is a usage error.
    let (code, _, _) = tdl(&["trace", "story", file, "--kind", "nonsense"]);
    assert_eq!(code, 2);
}

/// Built without the feature `net` (the plain install), the commands that need zenoh say how to
/// build them in, each with the usage error status, instead of being unknown commands.
#[cfg(not(feature = "net"))]
#[test]
fn without_net_the_commands_that_need_zenoh_say_how_to_build_them_in() {
    for cmd in ["serve", "load", "start", "status", "certs"] {
        let (code, out, err) = tdl(&[cmd]);
        assert_eq!(code, 2, "{cmd}: {err}");
        assert!(out.is_empty(), "{cmd}: {out}");
        assert!(
            err.contains(&format!("`tdl {cmd}` needs zenoh"))
                && err.contains("cargo install --path crates/tdl-cli --features net"),
            "{cmd}: {err}"
        );
    }
}
