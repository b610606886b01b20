//! TDL's `on AGENT` (docs/distributed.md, "TDL"): a spawn placed on an agent asks the run's
//! `Placer` for its task, with the arguments as JSON (none `null`, one itself, several an array),
//! keeps every other constraint of the spawn, and a waited value comes back typed from JSON. A run
//! without a placer fails the spawning body with an error that says what to do. The placer here
//! stands in for `tcm_zenoh::Executive` (tested with real agents in crates/tcm-zenoh): it runs
//! the task in this process and records where it was placed. Every trace through the checker.

use crate::util::{run_checked, story};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tdl::{Error, Json, NodeKind, Placer, RunOutcome, Runtime, Task};

tdl::tdl! {
    goal survey(rows: u32) -> u32 {
        ctx.sleep(Duration::from_secs(u64::from(rows))).await;
        rows * 10
    }

    command note(what: f64) { let _ = what; }

    goal mission() {
        spawn grasp(2.0) with on "arm";
        let reading: f64 = spawn read_range() with on "eye", wait;
        spawn note(reading);
        spawn lift(1.5, "box") with on "arm", sequential execution grasp;
        let cells: u32 = spawn survey(3) with on "*", wait;
        spawn note(f64::from(cells));
    }

    goal unplaced() {
        spawn grasp(1.0) with on "arm";
    }
}

/// Where each task was placed, with what.
type Log = Arc<Mutex<Vec<(String, String, NodeKind, Json)>>>;

/// Runs each placed task here for a second, its value standing for the agent's: 2.5 for
/// `read_range`, 30 for `survey`, null otherwise.
struct Here(Log);

impl Placer for Here {
    fn place(&self, agent: &str, name: &str, kind: NodeKind, args: Json) -> Result<Task, Error> {
        self.0
            .lock()
            .expect("log")
            .push((agent.into(), name.into(), kind, args));
        let agent = agent.to_string();
        let value = match name {
            "read_range" => serde_json::json!(2.5),
            "survey" => serde_json::json!(30),
            _ => Json::Null,
        };
        Ok(Task::new(kind, name.to_string(), move |ctx| async move {
            ctx.placed(&agent)?;
            tdl::tokio::time::sleep(Duration::from_secs(1)).await;
            Ok::<_, tdl::Failure>(value)
        }))
    }
}

#[tdl::tokio::test(crate = "tdl::tokio", start_paused = true)]
async fn placed_spawns_go_to_the_placer_with_json_arguments_and_keep_their_constraints() {
    let log = Log::default();
    let (report, trace) = run_checked(Runtime::new().placer(Here(log.clone())), mission()).await;
    assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
    let placed = log.lock().expect("log").clone();
    assert_eq!(
        placed,
        [
            (
                "arm".into(),
                "grasp".into(),
                NodeKind::Command,
                serde_json::json!(2.0)
            ),
            (
                "eye".into(),
                "read_range".into(),
                NodeKind::Command,
                Json::Null
            ),
            (
                "arm".into(),
                "lift".into(),
                NodeKind::Command,
                serde_json::json!([1.5, "box"])
            ),
            (
                "*".into(),
                "survey".into(),
                NodeKind::Goal,
                serde_json::json!(3)
            ),
        ]
    );
    let s = story(&trace);
    // The waited values came back typed: `note(2.5)`, then `note(30.0)`.
    let notes: Vec<_> = s
        .iter()
        .filter(|l| l.contains("note handling active"))
        .collect();
    assert_eq!(notes.len(), 2, "{s:#?}");
    // `lift` kept its `sequential execution grasp`: it started when grasp had finished.
    let at = |line: &str| {
        s.iter()
            .position(|l| l.ends_with(line))
            .unwrap_or_else(|| panic!("no {line:?} in {s:#?}"))
    };
    assert!(at("grasp execution completed") < at("lift execution active"));
    let agents: Vec<(u64, String)> = trace
        .iter()
        .filter_map(|ev| match &ev.kind {
            tdl::TraceKind::Placed { node, agent } => Some((*node, agent.clone())),
            _ => None,
        })
        .collect();
    assert_eq!(agents.len(), 4, "{agents:?}");
}

#[tdl::tokio::test(crate = "tdl::tokio", start_paused = true)]
async fn a_placed_spawn_without_a_placer_fails_saying_what_to_do() {
    let (report, _trace) = run_checked(Runtime::new(), unplaced()).await;
    let RunOutcome::TaskFailed(failure) = &report.outcome else {
        panic!("{report}");
    };
    let text = failure.message.clone();
    assert!(
        text.contains(
            "task `grasp` is placed on agent `arm`, but this run has no distribution layer"
        ),
        "{text}"
    );
}
