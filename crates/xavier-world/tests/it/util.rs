//! Helpers: run a task with a recorder, check the trace, render it as a story of transitions.

use std::collections::BTreeMap;
use tcm::{Recorder, Report, Runtime, Task, TraceEvent, TraceKind};

/// Runs `task` with a recorder; asserts the run ends and the trace passes the checker.
pub(crate) async fn run_checked(task: Task) -> (Report, Vec<TraceEvent>) {
    let rec = Recorder::new();
    let res = Runtime::new().with_sink(rec.clone()).run(task).await;
    let trace = rec.events();
    let report = match res {
        Ok(report) => report,
        Err(e) => panic!("run failed: {e}\nstory:\n{}", story(&trace).join("\n")),
    };
    match tcm_trace::check(&trace) {
        Ok(checked) => assert!(checked.n_transitions > 0, "the checker saw no transitions"),
        Err(violations) => {
            let text: Vec<String> = violations.iter().map(|v| format!("{v}")).collect();
            panic!(
                "trace checker found violations:\n{}\n\nstory:\n{}",
                text.join("\n"),
                story(&trace).join("\n")
            );
        }
    }
    (report, trace)
}

/// One line per transition or failure: `<seconds> <name> <facet> <state>` or `<name> failed <E>`.
pub(crate) fn story(trace: &[TraceEvent]) -> Vec<String> {
    let mut names: BTreeMap<u64, String> = BTreeMap::new();
    let mut out = Vec::new();
    for ev in trace {
        let t = ev.t as f64 / 1e9;
        let name = |names: &BTreeMap<u64, String>, id: &u64| {
            names.get(id).cloned().unwrap_or_else(|| format!("#{id}"))
        };
        let line = match &ev.kind {
            TraceKind::Spawned { node, name, .. } | TraceKind::Reserved { node, name, .. } => {
                names.insert(*node, name.clone());
                continue;
            }
            TraceKind::Transition {
                node, facet, to, ..
            } => format!("{} {facet} {to}", name(&names, node)),
            TraceKind::Terminated { node } => format!("{} terminated", name(&names, node)),
            TraceKind::Failed {
                node, exception, ..
            } => format!("{} failed {exception}", name(&names, node)),
            _ => continue,
        };
        out.push(format!("{t} {line}"));
    }
    out
}

/// The trace without its first record (whose run number differs between runs), as JSON lines.
pub(crate) fn lines(trace: &[TraceEvent]) -> Vec<String> {
    trace.iter().skip(1).map(tcm_trace::to_line).collect()
}
