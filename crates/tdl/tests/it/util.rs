//! Helpers: run a task with a recorder, check the trace, render it as a story.

use std::collections::BTreeMap;
use tdl::{Recorder, Report, Runtime, Task, TraceEvent, TraceKind};

/// Runs `task` on `rt` with a recorder; asserts the trace passes the checker.
pub(crate) async fn run_checked(rt: Runtime, task: Task) -> (Report, Vec<TraceEvent>) {
    let rec = Recorder::new();
    let report = rt.with_sink(rec.clone()).run(task).await.expect("run");
    let trace = rec.events();
    assert_checked(&trace);
    (report, trace)
}

/// Asserts the trace passes the checker and that the checker looked at it.
#[track_caller]
pub(crate) fn assert_checked(trace: &[TraceEvent]) {
    match tcm_trace::check(trace) {
        Ok(report) => assert!(report.n_transitions > 0, "the checker saw no transitions"),
        Err(violations) => {
            let text: Vec<String> = violations.iter().map(|v| format!("{v}")).collect();
            panic!(
                "trace checker found violations:\n{}\n\nstory:\n{}",
                text.join("\n"),
                story(trace).join("\n")
            );
        }
    }
}

/// One line per transition: `<seconds> <name>{<id>} <facet> <state>`, plus termination records.
pub(crate) fn story(trace: &[TraceEvent]) -> Vec<String> {
    let mut names: BTreeMap<u64, String> = BTreeMap::new();
    let mut out = Vec::new();
    for ev in trace {
        let t = ev.t as f64 / 1e9;
        let n = |names: &BTreeMap<u64, String>, id: &u64| {
            names.get(id).cloned().unwrap_or_else(|| format!("#{id}"))
        };
        let line = match &ev.kind {
            TraceKind::Spawned { node, name, .. } | TraceKind::Reserved { node, name, .. } => {
                names.insert(*node, name.clone());
                continue;
            }
            TraceKind::Transition {
                node, facet, to, ..
            } => format!("{} {facet} {to}", n(&names, node)),
            TraceKind::Terminating { node } => format!("{} terminating", n(&names, node)),
            TraceKind::Terminated { node } => format!("{} terminated", n(&names, node)),
            TraceKind::Failed {
                node, exception, ..
            } => format!("{} failed {exception}", n(&names, node)),
            TraceKind::Suspended { node } => format!("{} suspended", n(&names, node)),
            TraceKind::Unsuspended { node } => format!("{} unsuspended", n(&names, node)),
            _ => continue,
        };
        out.push(format!("{t} {line}"));
    }
    out
}

/// Asserts that `needles` occur in `lines` in this order.
#[track_caller]
pub(crate) fn assert_order(lines: &[String], needles: &[&str]) {
    let mut it = lines.iter();
    for n in needles {
        assert!(
            it.any(|l| l == n),
            "missing or out of order: {n:?}\nstory:\n{}",
            lines.join("\n")
        );
    }
}

/// The lines mentioning any of `words`.
pub(crate) fn only(lines: &[String], words: &[&str]) -> Vec<String> {
    lines
        .iter()
        .filter(|l| words.iter().any(|w| l.contains(w)))
        .cloned()
        .collect()
}
