//! Faults from a file make the navigation's recoveries run in turn without touching the servers
//! (docs/semantics.md, "Steering a run", rule 4): four failures of `follow_path` injected, and the
//! recoveries are those of a controller that failed four times. The same through the binary's
//! `--faults`, and a bad file refused with where and what. Virtual time; traces checked.

use nav2::servers::Nav;
use std::path::PathBuf;
use tdl::testing::run_checked;
use tdl::{Runtime, TraceKind};

const FOUR_BLOCKS: &str = r#"[
  {"task": "follow_path", "times": 4, "exception": "Recoverable",
   "ancestry": ["NavFailure"], "message": "injected: no progress"}
]"#;

/// Writes `text` to a file of this name: each test its own, since tests run at once and a file
/// written again while another test reads it is read cut short.
fn faults_file(name: &str, text: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("nav2-faults");
    std::fs::create_dir_all(&dir).expect("a directory for the faults files");
    let path = dir.join(name);
    std::fs::write(&path, text).expect("write the faults file");
    path
}

/// The recoveries of four failures in a row, as `navigate.rs` asserts them for a controller that
/// fails four times: the inner clearing, a round (both costmaps), the inner clearing, the spin.
const IN_TURN: [&str; 5] = [
    "recovery clear_local",
    "recovery clear_local",
    "recovery clear_global",
    "recovery clear_local",
    "recovery spin",
];

#[tokio::test(start_paused = true)]
async fn injected_failures_run_the_recoveries_in_turn() {
    let nav = Nav::new(3.0);
    let mut rt = Runtime::new();
    for fault in tdl::read_faults(&faults_file("four.json", FOUR_BLOCKS)).expect("valid") {
        rt = rt.inject(fault);
    }
    let (report, trace) =
        run_checked(rt, nav2::navigate_to_pose(nav.clone(), nav.recoveries())).await;
    assert!(report.is_clean(), "{report}");
    let recoveries: Vec<String> = nav
        .log()
        .into_iter()
        .filter(|e| e.what.starts_with("recovery"))
        .map(|e| e.what)
        .collect();
    assert_eq!(recoveries, IN_TURN);
    let injected = trace
        .iter()
        .filter(|e| matches!(&e.kind, TraceKind::Injected { outcome, .. } if outcome == "fail Recoverable: injected: no progress"))
        .count();
    assert_eq!(injected, 4);
    let handlers: Vec<&str> = trace
        .iter()
        .filter_map(|e| match &e.kind {
            TraceKind::HandlerChosen { handler, .. } => Some(handler.as_str()),
            _ => None,
        })
        .collect();
    assert_eq!(
        handlers,
        [
            "clear_local_and_retry",
            "recover",
            "clear_local_and_retry",
            "recover"
        ]
    );
    assert!(
        nav.log().iter().any(|e| e.what == "navigation succeeded"),
        "the fifth follow gets through"
    );
}

#[test]
fn the_binary_takes_faults_from_a_file_and_refuses_a_bad_one() {
    let bin = env!("CARGO_BIN_EXE_nav2");
    let trace = faults_file("four.jsonl", "");
    let out = std::process::Command::new(bin)
        .arg("--faults")
        .arg(faults_file("four-binary.json", FOUR_BLOCKS))
        .arg("--trace")
        .arg(&trace)
        .output()
        .expect("run nav2");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}");
    let recoveries: Vec<&str> = stdout
        .lines()
        .filter_map(|l| l.trim_start().split_once("  ").map(|(_, what)| what))
        .filter(|w| w.starts_with("recovery"))
        .collect();
    assert_eq!(recoveries, IN_TURN, "{stdout}");
    let text = std::fs::read_to_string(&trace).expect("the trace");
    let records = tcm_trace::read_jsonl(text.as_bytes()).expect("a trace file");
    assert!(
        records
            .iter()
            .any(|e| matches!(e.kind, TraceKind::Injected { .. }))
    );
    tdl::testing::assert_checked(&records);

    let bad = faults_file("bad.json", r#"[{"task": "follow_path"}]"#);
    let out = std::process::Command::new(bin)
        .arg("--faults")
        .arg(&bad)
        .output()
        .expect("run nav2");
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("bad.json: rule 1 (counting from 1): say what stands for the end"),
        "{stderr}"
    );
}
