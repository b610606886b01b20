//! A run that keeps a journal (`Runtime::journal`; docs/semantics.md, "Durable runs"): each input
//! its engine takes is in it, in order, at the engine's times; a journal that cannot be written
//! ends the run with `JournalFailed` at the root. On tokio's paused clock.

use std::time::Duration;
use tcm::testing::assert_checked;
use tcm::{Failure, Recorder, RunOutcome, Runtime, Task};
use tcm_journal::{Durability, Input, Writer};

fn scratch(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("tcm-journaled-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("a scratch directory");
    dir.join("run.journal")
}

/// A goal: `a` (1 s), then `b`, which fails after 1 s; its failure taken by nobody.
fn mission() -> Task {
    Task::goal("mission", |ctx| async move {
        ctx.spawn(Task::command("a", |_| async {
            tokio::time::sleep(Duration::from_secs(1)).await;
            Ok(())
        }))
        .start()?;
        ctx.spawn(Task::command("b", |_| async {
            tokio::time::sleep(Duration::from_secs(1)).await;
            Err::<(), _>(Failure::new("Blocked", "in the way"))
        }))
        .serial(tcm::NodeRef::Previous)
        .start()?;
        Ok(())
    })
}

#[tokio::test(start_paused = true)]
async fn a_runs_inputs_are_in_its_journal_in_order() {
    let path = scratch("inputs");
    let writer = Writer::create(&path, "mission@1", Durability::EveryRecord).expect("create");
    let rec = Recorder::new();
    let rt = Runtime::new().with_sink(rec.clone()).journal(writer);
    let events = rt.events();
    tokio::spawn(async move {
        tokio::time::sleep(Duration::from_millis(1500)).await;
        events.raise("go").expect("raise");
        drop(events);
    });
    let report = rt.run(mission()).await.expect("run");
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_checked(&rec.events());
    let journal = tcm_journal::read(&path, Some("mission@1")).expect("read");
    assert_eq!(journal.warning, None);
    // The clock's readings are inputs too (a body's spawns are given the clock's time).
    assert!(journal.entries.iter().any(|e| e.input == Input::Clock));
    let got: Vec<(u64, String)> = journal
        .entries
        .iter()
        .filter(|e| e.input != Input::Clock)
        .map(|e| {
            let what = match &e.input {
                Input::Ended { node, .. } => format!("ended {node}"),
                Input::Failed {
                    node, exception, ..
                } => format!("failed {node} {exception}"),
                Input::External { name, .. } => format!("external {name}"),
                other => format!("{other:?}"),
            };
            (e.t / 100_000_000, what)
        })
        .collect();
    assert_eq!(
        got,
        [
            (0, "ended 1".to_string()),
            (10, "ended 2".to_string()),
            (15, "external go".to_string()),
            (20, "failed 3 Blocked".to_string()),
        ]
    );
}

/// A store that takes the header and fails every write after it, as a full disk does.
struct FullAfterHeader {
    header: bool,
}

impl std::io::Write for FullAfterHeader {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        if self.header {
            return Err(std::io::Error::from_raw_os_error(28));
        }
        self.header = true;
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl tcm_journal::Store for FullAfterHeader {
    fn sync(&self) -> std::io::Result<()> {
        Ok(())
    }
}

#[tokio::test(start_paused = true)]
async fn a_journal_that_cannot_be_written_ends_the_run_loudly() {
    let writer = Writer::on(
        "full.journal".into(),
        Box::new(FullAfterHeader { header: false }),
        "mission@1",
        Durability::EveryRecord,
    )
    .expect("the header is written");
    let rec = Recorder::new();
    let rt = Runtime::new().with_sink(rec.clone()).journal(writer);
    let report = rt.run(mission()).await.expect("run");
    match &report.outcome {
        RunOutcome::Fatal(f) => {
            assert_eq!(f.failure.exception, "JournalFailed");
            assert!(
                f.failure.message.contains("No space left on device"),
                "{}",
                f.failure.message
            );
        }
        other => panic!("the run must end loudly: {other:?}"),
    }
    // It ended at its first input: `a` never ended normally.
    let a_ended = rec
        .events()
        .iter()
        .filter(|e| {
            matches!(
                e.kind,
                tcm::TraceKind::Transition {
                    node: 2,
                    facet: tcm::Facet::Handling,
                    to: tcm::State::Completed,
                    ..
                }
            )
        })
        .count();
    assert_eq!(a_ended, 0);
}

/// An action's JSON value is in its entry.
#[tokio::test(start_paused = true)]
async fn a_json_value_is_journaled_with_its_end() {
    let path = scratch("values");
    let writer = Writer::create(&path, "p", Durability::EveryRecord).expect("create");
    let task = Task::command("measure", |_| async {
        Ok(serde_json::json!({"range": 2.5}))
    });
    let report = Runtime::new().journal(writer).run(task).await.expect("run");
    assert_eq!(report.outcome, RunOutcome::Completed);
    let journal = tcm_journal::read(&path, None).expect("read");
    assert!(
        journal.entries.iter().any(|e| matches!(&e.input,
            Input::Ended { node: 1, value: Some(v), .. } if *v == serde_json::json!({"range": 2.5}))),
        "{:?}",
        journal.entries
    );
}

/// A store that keeps what was written, and how much of it a sync made durable.
#[derive(Clone, Default)]
struct Watched(std::sync::Arc<std::sync::Mutex<(Vec<u8>, usize)>>);

impl Watched {
    /// The text synced so far.
    fn synced(&self) -> String {
        let s = self.0.lock().expect("store");
        String::from_utf8_lossy(&s.0[..s.1]).into_owned()
    }
}

impl std::io::Write for Watched {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.lock().expect("store").0.extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl tcm_journal::Store for Watched {
    fn sync(&self) -> std::io::Result<()> {
        let mut s = self.0.lock().expect("store");
        s.1 = s.0.len();
        Ok(())
    }
}

/// With `BeforeActing` durability, the end of `a` is on the disk before `b`, which it releases,
/// starts; with group commit alone (a minute here) it is not yet.
#[tokio::test(start_paused = true)]
async fn before_acting_the_inputs_that_start_a_command_are_synced() {
    let run = |durability: Durability| async move {
        let store = Watched::default();
        let writer = Writer::on(
            "watched.journal".into(),
            Box::new(store.clone()),
            "mission@1",
            durability,
        )
        .expect("the header is written");
        let seen = std::sync::Arc::new(std::sync::Mutex::new(String::new()));
        let at_b = seen.clone();
        let mission = Task::goal("mission", move |ctx| async move {
            ctx.spawn(Task::command("a", |_| async {
                tokio::time::sleep(Duration::from_secs(1)).await;
                Ok(())
            }))
            .start()?;
            ctx.spawn(Task::command("b", move |_| async move {
                *at_b.lock().expect("seen") = store.synced();
                Ok(())
            }))
            .serial(tcm::NodeRef::Previous)
            .start()?;
            Ok(())
        });
        let report = Runtime::new()
            .journal(writer)
            .run(mission)
            .await
            .expect("run");
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        let synced = seen.lock().expect("seen");
        synced.clone()
    };
    let a_ended = "\"in\":\"ended\",\"node\":2";
    let acting = run(Durability::BeforeActing(Duration::from_secs(60))).await;
    assert!(acting.contains(a_ended), "{acting}");
    let group = run(Durability::Group(Duration::from_secs(60))).await;
    assert!(
        group.contains("\"journal\":"),
        "the header is synced: {group}"
    );
    assert!(!group.contains(a_ended), "{group}");
}
