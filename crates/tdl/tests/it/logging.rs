//! The `log` statement (issue 48, item 5; docs/language.md, "Logging"): a line for the run's log,
//! formatted as `format!` formats and stamped with the run's time, from goals, commands, monitors
//! and handlers. It is a `log` record of the trace about the node whose body wrote it, so the
//! text log, the story and the viewer show it where it happened, and a test asserts on it.

use crate::util::{run_checked, story};
use std::time::Duration;
use tcm_trace::{TextLog, TextLogOptions};
use tdl::{RunOutcome, Runtime, TraceEvent, TraceKind};

async fn sleep_s(s: u64) {
    tokio::time::sleep(Duration::from_secs(s)).await;
}

tdl::tdl! {
    state charge: float = 80.0;
    exception Stalled;

    command drive(room: u32) {
        log "driving to room {room}";
        sleep_s(2).await;
        if room == 0 { fail Stalled; }
        set charge = state!(charge).unwrap_or(0.0) - 10.0;
        log "room {} reached, charge {:.1}", room, state!(charge).unwrap_or(0.0);
    }

    monitor low(limit: f64) {
        log "charge below {limit}: {:?}", state!(charge);
    }

    handler recover(room: u32) handles Stalled {
        log "{what} on the way to room {room}", what = "stalled";
    }

    command report(name: String) {
        log "report of [{name:>6}]";
    }

    goal tour(rooms: Vec<u32>, name: String) {
        log "tour {name} of {} rooms", rooms.len();
        for room in rooms {
            spawn drive(room) with sequential execution previous, exception handler recover(room);
        }
        done: spawn report(name) with sequential execution previous;
        spawn low(65.0) with activate when charge < 65.0, terminate at done completed;
        // `name` went to `report` above: TDL passes arguments by value, so it is still here.
        log "{name} planned";
    }
}

/// The `log` records of `trace`: (seconds, node's name, line).
fn logs(trace: &[TraceEvent]) -> Vec<(f64, String, String)> {
    let names: std::collections::HashMap<u64, String> = trace
        .iter()
        .filter_map(|e| match &e.kind {
            TraceKind::Spawned { node, name, .. } => Some((*node, name.clone())),
            _ => None,
        })
        .collect();
    trace
        .iter()
        .filter_map(|e| match &e.kind {
            TraceKind::Log { node, message } => Some((
                e.t as f64 / 1e9,
                names.get(node).cloned().unwrap_or_default(),
                message.clone(),
            )),
            _ => None,
        })
        .collect()
}

#[tokio::test(start_paused = true)]
async fn each_line_is_stamped_with_the_time_its_body_wrote_it() {
    let (report, trace) = run_checked(Runtime::new(), tour(vec![3, 0, 5], "east".into())).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let logs = logs(&trace);
    let got: Vec<(f64, &str, &str)> = logs
        .iter()
        .map(|(t, n, l)| (*t, n.as_str(), l.as_str()))
        .collect();
    let s = |t: f64, n: &'static str, l: &'static str| (t, n, l);
    assert_eq!(
        got,
        [
            s(0.0, "tour", "tour east of 3 rooms"),
            s(0.0, "tour", "east planned"),
            s(0.0, "drive", "driving to room 3"),
            s(2.0, "drive", "room 3 reached, charge 70.0"),
            s(2.0, "drive", "driving to room 0"),
            s(4.0, "recover", "stalled on the way to room 0"),
            s(4.0, "drive", "driving to room 5"),
            s(6.0, "drive", "room 5 reached, charge 60.0"),
            s(6.0, "ACT-low", "charge below 65: Some(60.0)"),
            s(6.0, "report", "report of [  east]"),
        ]
    );
    // The story and TCM's text log show each line with its node.
    let story = story(&trace);
    assert!(
        story.contains(&"4 recover logs: stalled on the way to room 0".to_string()),
        "{story:#?}"
    );
    let mut text = TextLog::new(TextLogOptions::default());
    let lines: Vec<String> = trace.iter().filter_map(|ev| text.push(ev)).collect();
    assert!(
        lines.iter().any(|l| l == "report {2}: report of [  east]"),
        "{lines:#?}"
    );
}
