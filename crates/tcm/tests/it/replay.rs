//! Replaying and resuming a run from its journal (`Runtime::replay`, `Runtime::resume`;
//! docs/semantics.md, "Durable runs"): the replay's trace is the run's, record for record; a
//! journal cut by a crash resumes, commands in flight failing with `Interrupted`; a program that
//! differs is reported at its first difference. On tokio's paused clock.

use serde_json::json;
use std::time::Duration;
use tcm::testing::assert_checked;
use tcm::{Failure, Handler, NodeRef, Recorder, RunOutcome, Runtime, Task, TraceEvent};
use tcm_journal::{Durability, Journal, Writer};

fn scratch(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("tcm-replay-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("a scratch directory");
    dir.join("run.journal")
}

/// A command that takes `secs` of the run's time, logs, and returns `value`.
fn takes(name: &'static str, secs: f64, value: serde_json::Value) -> Task {
    Task::command(name, move |ctx| async move {
        ctx.sleep(Duration::from_secs_f64(secs)).await;
        ctx.log(format!("{name} took {secs} s"))?;
        Ok(value)
    })
}

/// A mission that reads a command's value, waits for an event, takes a failure in a handler,
/// and runs a timed step: `measure` (1 s, 2.5), then, as the value is above 2, `go` after the
/// event `start`; `blocked` fails with `Blocked`, which `detour` takes; `last` waits 2 s.
/// `extra` adds a step the run did not have (a changed program); `idempotent` declares `last`
/// safe to run twice.
fn mission(extra: bool, idempotent: bool) -> Task {
    Task::goal("mission", move |ctx| async move {
        let v: serde_json::Value = ctx
            .spawn(takes("measure", 1.0, json!(2.5)))
            .wait_value()
            .await?;
        ctx.log(format!("measured {v}"))?;
        if v.as_f64().unwrap_or(0.0) > 2.0 {
            let start = ctx.external("start")?;
            ctx.spawn(takes("go", 0.5, json!(null)))
                .with(tcm::Constraint::disable(
                    tcm::Facet::Handling,
                    tcm::When::External(start),
                ))
                .start()?;
        }
        if extra {
            ctx.spawn(takes("look", 0.1, json!(null))).start()?;
        }
        ctx.spawn(Task::command("blocked", |ctx| async move {
            ctx.sleep(Duration::from_millis(300)).await;
            Err::<(), _>(Failure::new("Blocked", "in the way"))
        }))
        .handler(Handler::new("detour", "Blocked", |ctx| async move {
            ctx.spawn(takes("around", 0.7, json!("left"))).start()?;
            Ok(())
        }))
        .start()?;
        let last = takes("last", 2.0, json!(1));
        let last = if idempotent { last.idempotent() } else { last };
        ctx.spawn(last).serial(NodeRef::Previous).start()?;
        Ok(())
    })
}

/// A recorded run of the mission, with its journal and trace.
async fn record(name: &str) -> (std::path::PathBuf, Vec<TraceEvent>, tcm::Report) {
    let path = scratch(name);
    let writer = Writer::create(&path, "mission@1", Durability::EveryRecord).expect("create");
    let rec = Recorder::new();
    let rt = Runtime::new().with_sink(rec.clone()).journal(writer);
    let events = rt.events();
    tokio::spawn(async move {
        tokio::time::sleep(Duration::from_millis(1700)).await;
        events.raise("start").expect("raise");
    });
    let report = rt.run(mission(false, false)).await.expect("run");
    (path, rec.events(), report)
}

/// The trace as JSON lines, the run's number left out (each `Runtime` of a process has its own).
fn lines(events: &[TraceEvent]) -> Vec<String> {
    events
        .iter()
        .map(|e| {
            let mut v = serde_json::to_value(e).expect("json");
            if let Some(o) = v.as_object_mut() {
                o.remove("run");
            }
            v.to_string()
        })
        .collect()
}

/// The two traces hold the same records, in the same order (the run's number left out).
fn assert_same_records(want: &[TraceEvent], got: &[TraceEvent]) {
    let (want, got) = (lines(want), lines(got));
    for (i, (w, g)) in want.iter().zip(&got).enumerate() {
        assert_eq!(w, g, "record {i} differs");
    }
    assert_eq!(want.len(), got.len());
}

/// A session journaled to a scratch file named after `name`, traced to its recorder.
fn journaled_session(name: &str) -> (std::path::PathBuf, tcm::Session, Recorder) {
    let path = scratch(name);
    let writer = Writer::create(&path, "mission@1", Durability::EveryRecord).expect("create");
    let rec = Recorder::new();
    let session = Runtime::new()
        .with_sink(rec.clone())
        .journal(writer)
        .start()
        .expect("start");
    (path, session, rec)
}

/// The replay of the journal at `path` in a session that spawns `task`: its report and trace.
async fn replayed_session(path: &std::path::Path, task: Task) -> (tcm::Report, Vec<TraceEvent>) {
    let rec = Recorder::new();
    let replay = Runtime::new()
        .with_sink(rec.clone())
        .replay(read(path))
        .start()
        .expect("start");
    replay.spawn(task).expect("spawn");
    let report = replay.finish().await.expect("finish");
    (report, rec.events())
}

/// The number of the node `name` was spawned as.
fn spawned(events: &[TraceEvent], name: &str) -> u64 {
    events
        .iter()
        .find_map(|e| match &e.kind {
            tcm::TraceKind::Spawned { node, name: n, .. } if n == name => Some(*node),
            _ => None,
        })
        .unwrap_or_else(|| panic!("`{name}` was spawned"))
}

fn read(path: &std::path::Path) -> Journal {
    tcm_journal::read(path, Some("mission@1")).expect("read the journal")
}

#[tokio::test(start_paused = true)]
async fn a_replay_gives_the_runs_trace_record_for_record() {
    let (path, recorded, report) = record("same").await;
    assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
    assert_checked(&recorded);
    // The lines bodies and commands logged, at the run's time when they did: a command's is
    // journaled, as the replay does not run commands.
    let logs: Vec<(u64, &str)> = recorded
        .iter()
        .filter_map(|e| match &e.kind {
            tcm::TraceKind::Log { message, .. } => Some((e.t / 1_000_000, message.as_str())),
            _ => None,
        })
        .collect();
    assert_eq!(
        logs,
        [
            (1000, "measure took 1 s"),
            (1000, "measured 2.5"),
            (2000, "around took 0.7 s"),
            (2200, "go took 0.5 s"),
            (4000, "last took 2 s")
        ]
    );
    let rec = Recorder::new();
    let replayed = Runtime::new()
        .with_sink(rec.clone())
        .replay(read(&path))
        .run(mission(false, false))
        .await
        .expect("replay");
    assert_eq!(replayed.outcome, RunOutcome::Completed, "{replayed}");
    assert_eq!(replayed.elapsed, report.elapsed);
    assert_same_records(&recorded, &rec.events());
}

#[tokio::test(start_paused = true)]
async fn a_changed_program_is_reported_at_its_first_difference() {
    let (path, _, _) = record("changed").await;
    let replayed = Runtime::new()
        .replay(read(&path))
        .run(mission(true, false))
        .await
        .expect("replay");
    match &replayed.outcome {
        RunOutcome::Diverged(why) => {
            assert!(why.starts_with("journal entry "), "{why}");
            assert!(why.contains("the program differs"), "{why}");
        }
        other => panic!("a changed program must be reported: {other:?}"),
    }
}

/// The journal cut after its first `cut` entries, as a crash leaves it.
fn cut(path: &std::path::Path, keep: impl Fn(&tcm_journal::Entry) -> bool) -> Journal {
    let mut j = read(path);
    let at = j
        .entries
        .iter()
        .position(|e| !keep(e))
        .unwrap_or(j.entries.len());
    j.entries.truncate(at);
    j
}

#[tokio::test(start_paused = true)]
async fn a_resumed_run_goes_on_and_a_command_in_flight_is_interrupted() {
    let (path, recorded, _) = record("resume").await;
    // Cut where `last` runs (started after `blocked` failed; its end not yet journaled): the
    // entries before its end.
    let last_node = spawned(&recorded, "last");
    let journal = cut(
        &path,
        |e| !matches!(e.input, tcm_journal::Input::Ended { node, .. } if node == last_node),
    );
    let given = journal.entries.len();
    let rec = Recorder::new();
    let report = Runtime::new()
        .with_sink(rec.clone())
        .resume(journal)
        .run(mission(false, false))
        .await
        .expect("resume");
    let events = rec.events();
    assert_checked(&events);
    // It says where it resumed, and `last`, whose end is unknown, failed with `Interrupted`.
    assert!(
        events.iter().any(|e| matches!(&e.kind,
            tcm::TraceKind::Control { what, by }
                if by == tcm::RESUMED_BY && what.contains("resumed after")
        )),
        "no record of the resumption"
    );
    let interrupted: Vec<u64> = report
        .unhandled
        .iter()
        .filter(|u| u.failure.exception == tcm::INTERRUPTED)
        .map(|u| u.node)
        .collect();
    assert_eq!(interrupted, [last_node], "{report}");
    assert!(given > 5);
    // Declared idempotent, `last` runs again instead, and the run ends as the uncrashed one did.
    let rec = Recorder::new();
    let again = Runtime::new()
        .with_sink(rec.clone())
        .resume(cut(
            &path,
            |e| !matches!(e.input, tcm_journal::Input::Ended { node, .. } if node == last_node),
        ))
        .run(mission(false, true))
        .await
        .expect("resume");
    assert_checked(&rec.events());
    assert!(again.is_clean(), "{again}");
    let ended_last = rec
        .events()
        .iter()
        .filter(|e| {
            matches!(e.kind, tcm::TraceKind::Transition { node, facet: tcm::Facet::Handling,
                to: tcm::State::Completed, .. } if node == last_node)
        })
        .count();
    assert_eq!(ended_last, 1);
}

/// A resumed run goes on writing its journal (`Writer::reopen`): the whole journal, both runs'
/// inputs, replays to the resumed run's trace, record for record.
#[tokio::test(start_paused = true)]
async fn a_resumed_run_journals_on_and_its_journal_replays() {
    let (path, recorded, _) = record("twice").await;
    let last_node = spawned(&recorded, "last");
    // The crash: the file cut in the middle of `last`'s end record.
    let text = std::fs::read_to_string(&path).expect("read");
    let at = text
        .find(&format!("\"in\":\"ended\",\"node\":{last_node}"))
        .expect("the end of `last`");
    std::fs::write(&path, &text[..at]).expect("cut");
    let journal = read(&path);
    assert!(journal.warning.is_some(), "the cut record is reported");
    let writer = Writer::reopen(&path, &journal, Durability::EveryRecord).expect("reopen");
    let rec = Recorder::new();
    let resumed = Runtime::new()
        .with_sink(rec.clone())
        .journal(writer)
        .resume(journal)
        .run(mission(false, true))
        .await
        .expect("resume");
    assert!(resumed.is_clean(), "{resumed}");
    let whole = read(&path);
    assert_eq!(whole.warning, None);
    let again = Recorder::new();
    let replayed = Runtime::new()
        .with_sink(again.clone())
        .replay(whole)
        .run(mission(false, true))
        .await
        .expect("replay");
    assert_eq!(replayed.outcome, RunOutcome::Completed, "{replayed}");
    assert_same_records(&rec.events(), &again.events());
}

/// A body that reads the world (here a counter) through `Ctx::record` reads, in a replay, what
/// the run read: it decides the same; one that reads it directly would not.
#[tokio::test(start_paused = true)]
async fn a_recorded_read_is_read_back_from_the_journal() {
    use std::sync::Arc;
    use std::sync::atomic::{AtomicU32, Ordering};
    let world = Arc::new(AtomicU32::new(0));
    let mission = |world: Arc<AtomicU32>| {
        Task::goal("mission", move |ctx| async move {
            let seen: u32 = ctx.record(|| world.fetch_add(1, Ordering::SeqCst))?;
            let step = if seen == 0 { "first" } else { "again" };
            ctx.spawn(takes(step, 1.0, json!(seen))).start()?;
            Ok(())
        })
    };
    let path = scratch("recorded");
    let writer = Writer::create(&path, "mission@1", Durability::EveryRecord).expect("create");
    let rec = Recorder::new();
    let report = Runtime::new()
        .with_sink(rec.clone())
        .journal(writer)
        .run(mission(world.clone()))
        .await
        .expect("run");
    assert!(report.is_clean(), "{report}");
    let journal = read(&path);
    assert!(
        journal.entries.iter().any(
            |e| matches!(&e.input, tcm_journal::Input::Recorded { value, .. } if *value == json!(0))
        ),
        "the read value is journaled"
    );
    // The world moved on (the counter is 1): the replay still reads 0, and spawns `first`.
    let again = Recorder::new();
    let replayed = Runtime::new()
        .with_sink(again.clone())
        .replay(journal)
        .run(mission(world.clone()))
        .await
        .expect("replay");
    assert_eq!(replayed.outcome, RunOutcome::Completed, "{replayed}");
    assert_eq!(lines(&rec.events()), lines(&again.events()));
    assert_eq!(
        world.load(Ordering::SeqCst),
        1,
        "the replay did not read the world"
    );
}

/// A body that reads the world directly, not through `Ctx::record`, and returns what it read: the
/// replay finds the value it returns differs from the run's, and says so.
#[tokio::test(start_paused = true)]
async fn a_body_returning_another_value_is_a_difference() {
    use std::sync::Arc;
    use std::sync::atomic::{AtomicU32, Ordering};
    let world = Arc::new(AtomicU32::new(0));
    let mission = |world: Arc<AtomicU32>| {
        Task::goal("mission", move |ctx| async move {
            ctx.spawn(takes("step", 1.0, json!(null))).start()?;
            Ok(json!(world.fetch_add(1, Ordering::SeqCst)))
        })
    };
    let path = scratch("value");
    let writer = Writer::create(&path, "mission@1", Durability::EveryRecord).expect("create");
    let report = Runtime::new()
        .journal(writer)
        .run(mission(world.clone()))
        .await
        .expect("run");
    assert!(report.is_clean(), "{report}");
    let replayed = Runtime::new()
        .replay(read(&path))
        .run(mission(world.clone()))
        .await
        .expect("replay");
    match &replayed.outcome {
        RunOutcome::Diverged(why) => assert!(
            why.contains("(mission) returned 0 in the run, and 1 in the replay"),
            "{why}"
        ),
        other => panic!("the difference must be reported: {other:?}"),
    }
}

/// A job server outside the run: a job started is counted, and its result is known once its
/// time has passed.
#[derive(Clone, Default)]
struct Jobs(std::sync::Arc<std::sync::Mutex<Vec<u32>>>);

impl Jobs {
    fn start(&self) -> u32 {
        let mut jobs = self.0.lock().expect("jobs");
        let next = 7 + jobs.len() as u32;
        jobs.push(next);
        *jobs.last().expect("a job")
    }
    fn started(&self) -> usize {
        self.0.lock().expect("jobs").len()
    }
}

/// A typed value (`Task::journaled`) read by its parent, then a job started outside through a
/// durable record (`Ctx::record_durable`), whose node re-attaches to it when the run resumes
/// (`Task::reattach`) and waits for its result there: `job + 1`, after 2 s.
fn outside(jobs: Jobs) -> Task {
    Task::goal("mission", move |ctx| {
        let jobs = jobs.clone();
        async move {
            let measured: u32 = ctx
                .spawn(
                    Task::command("measure", |ctx| async move {
                        ctx.sleep(Duration::from_secs(1)).await;
                        Ok(3u32)
                    })
                    .journaled::<u32>(),
                )
                .wait_value()
                .await?;
            let wait_for = |ctx: tcm::Ctx, job: u32| async move {
                ctx.sleep(Duration::from_secs(2)).await;
                Ok::<u32, Failure>(job + 1)
            };
            let j = jobs.clone();
            let job = Task::command("job", move |ctx| {
                let j = j.clone();
                async move {
                    let id = ctx.record_durable(j.start())?;
                    wait_for(ctx, id).await
                }
            })
            .journaled::<u32>()
            .reattach(move |ctx, recorded| async move {
                let id: u32 = recorded
                    .first()
                    .and_then(|v| serde_json::from_value(v.clone()).ok())
                    .ok_or_else(|| Failure::new("Lost", "no job was recorded"))?;
                wait_for(ctx, id).await
            });
            let result: u32 = ctx.spawn(job).wait_value().await?;
            if (measured, result) != (3, 8) {
                return Err(Failure::new(
                    "Wrong",
                    format!("read {measured} and {result}"),
                ));
            }
            ctx.spawn(takes("report", 0.1, json!(measured + result)))
                .start()?;
            Ok(())
        }
    })
}

#[tokio::test(start_paused = true)]
async fn a_resumed_run_reattaches_to_what_a_command_started_outside() {
    let path = scratch("reattach");
    let jobs = Jobs::default();
    let writer = Writer::create(
        &path,
        "mission@1",
        Durability::Group(Duration::from_secs(3600)),
    )
    .expect("create");
    let rec = Recorder::new();
    let report = Runtime::new()
        .with_sink(rec.clone())
        .journal(writer)
        .run(outside(jobs.clone()))
        .await
        .expect("run");
    assert!(report.is_clean(), "{report}");
    let uncrashed = rec.events();
    let job_node = spawned(&uncrashed, "job");
    assert_eq!(jobs.started(), 1);
    // The crash: the journal up to the job's end, its placement record in it.
    let journal = cut(
        &path,
        |e| !matches!(e.input, tcm_journal::Input::Ended { node, .. } if node == job_node),
    );
    assert!(
        journal.entries.iter().any(
            |e| matches!(&e.input, tcm_journal::Input::Recorded { node, value }
                if *node == job_node && *value == json!(7))
        ),
        "the job's start is in the journal"
    );
    let rec = Recorder::new();
    let resumed = Runtime::new()
        .with_sink(rec.clone())
        .resume(journal)
        .run(outside(jobs.clone()))
        .await
        .expect("resume");
    let events = rec.events();
    assert_checked(&events);
    assert!(resumed.is_clean(), "{resumed}");
    // The job was not started again, its node ended once, and the parent read both values as
    // `u32`s: the report's value is 3 + 8.
    assert_eq!(jobs.started(), 1);
    let completed = |node: u64| {
        events
            .iter()
            .filter(|e| {
                matches!(e.kind, tcm::TraceKind::Transition { node: n, facet: tcm::Facet::Handling,
                    to: tcm::State::Completed, .. } if n == node)
            })
            .count()
    };
    assert_eq!(completed(job_node), 1);
    assert_eq!(completed(spawned(&events, "report")), 1);
}

/// `mission` run with a journal (a sync per record), then replayed from it: the run's report and
/// trace, the replay's report and trace.
async fn journaled_and_replayed(
    name: &str,
    mission: impl Fn() -> Task,
) -> (tcm::Report, Vec<TraceEvent>, tcm::Report, Vec<TraceEvent>) {
    let path = scratch(name);
    let writer = Writer::create(&path, "mission@1", Durability::EveryRecord).expect("create");
    let rec = Recorder::new();
    let report = Runtime::new()
        .with_sink(rec.clone())
        .journal(writer)
        .run(mission())
        .await
        .expect("run");
    let again = Recorder::new();
    let replayed = Runtime::new()
        .with_sink(again.clone())
        .replay(read(&path))
        .run(mission())
        .await
        .expect("replay");
    (report, rec.events(), replayed, again.events())
}

/// A body that raises an event itself and sets a state variable: the replay's body does both
/// again, and the journal's copies of them are not given a second time.
#[tokio::test(start_paused = true)]
async fn what_a_body_gives_the_engine_itself_is_given_once_in_the_replay() {
    let mission = || {
        Task::goal("mission", |ctx| async move {
            ctx.spawn(takes("first", 1.0, json!(1))).wait().await?;
            ctx.raise("ready")?;
            let ready = ctx.external("ready")?;
            ctx.spawn(takes("after", 0.5, json!(2)))
                .with(tcm::Constraint::disable(
                    tcm::Facet::Handling,
                    tcm::When::External(ready),
                ))
                .wait()
                .await?;
            ctx.spawn(takes("last", 0.5, json!(3))).wait().await?;
            Ok(())
        })
    };
    let (report, recorded, replayed, again) = journaled_and_replayed("body-inputs", mission).await;
    assert!(report.is_clean(), "{report}");
    assert!(
        !matches!(replayed.outcome, RunOutcome::Diverged(_)),
        "{:?}",
        replayed.outcome
    );
    assert_eq!(lines(&again), lines(&recorded));
}

/// An action that outlives its node (a remote command's late message, after the command was
/// terminated and left the tree) warns through the `Ctx` it kept: the run takes no step for it,
/// as the replay, which does not run the command, does not make the request, so the replay does
/// not stop `Diverged` at the next input. The late warning is the only record the replay lacks.
#[tokio::test(start_paused = true)]
async fn a_request_of_an_action_that_outlived_its_node_is_no_step_of_the_run() {
    let mission = || {
        Task::goal("mission", |ctx| async move {
            ctx.spawn(Task::command("remote", |ctx| async move {
                let late = ctx.clone();
                tokio::spawn(async move {
                    tokio::time::sleep(Duration::from_millis(1500)).await;
                    let _ = late.warn("a late end of remote task 7, ignored");
                });
                std::future::pending::<()>().await;
                Ok(())
            }))
            .with(tcm::Constraint::terminate(tcm::When::In(
                Duration::from_secs(1),
            )))
            .start()?;
            ctx.spawn(takes("after", 2.0, json!(2))).wait().await?;
            ctx.spawn(takes("last", 0.5, json!(3))).wait().await?;
            Ok(())
        })
    };
    let (report, recorded, replayed, again) = journaled_and_replayed("outlived", mission).await;
    assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
    assert_checked(&recorded);
    let late = |e: &TraceEvent| matches!(&e.kind, tcm::TraceKind::Warning { message, .. } if message.starts_with("a late end"));
    assert_eq!(recorded.iter().filter(|e| late(e)).count(), 1);
    assert_eq!(replayed.outcome, RunOutcome::Completed, "{replayed}");
    let without = |events: &[TraceEvent]| {
        let kept: Vec<TraceEvent> = events.iter().filter(|e| !late(e)).cloned().collect();
        lines(&kept)
            .into_iter()
            .map(|l| {
                let mut v: serde_json::Value = serde_json::from_str(&l).expect("json");
                v.as_object_mut().map(|o| o.remove("seq"));
                v.to_string()
            })
            .collect::<Vec<_>>()
    };
    assert_eq!(without(&again), without(&recorded));
}

/// A steered run's operations from outside are journaled with what they did, and its replay
/// carries each out again at the run's step: a breakpoint before `last`, an approval rule that
/// holds `around` until the operator approves it, a fault that makes `go` succeed at once, an
/// event the operator raised (noted, then given), and the operator's resumption after the
/// breakpoint. The replay's trace is the run's, record for record.
#[tokio::test(start_paused = true)]
async fn a_steered_runs_replay_carries_out_its_operations_again() {
    use tcm::{Approval, BreakAt, Breakpoint, Fault, FaultOutcome, Matcher};
    let (path, session, rec) = journaled_session("steered");
    let control = session.control();
    let by = "operator";
    control
        .add_breakpoint(
            Breakpoint {
                at: BreakAt::Start,
                on: Matcher::Task("last".into()),
            },
            by,
        )
        .expect("breakpoint");
    control
        .require_approval(
            Approval {
                on: Matcher::Task("around".into()),
                timeout: None,
            },
            by,
        )
        .expect("approval rule");
    control
        .inject(
            Fault {
                on: Matcher::Task("go".into()),
                times: 1,
                outcome: FaultOutcome::Succeed(None),
            },
            by,
        )
        .expect("fault");
    let (events, operator) = (session.events(), control.clone());
    tokio::spawn(async move {
        tokio::time::sleep(Duration::from_millis(1700)).await;
        // Noted as an operation, and given as the event it is.
        operator
            .note_input("raise start", "operator")
            .expect("note");
        events.raise("start").expect("raise");
        tokio::time::sleep(Duration::from_millis(800)).await;
        for node in operator.held().expect("held") {
            operator.approve(node, "operator").expect("approve");
        }
        tokio::time::sleep(Duration::from_secs(3)).await;
        assert!(
            operator.is_paused().expect("paused"),
            "the breakpoint paused"
        );
        operator.resume("operator").expect("resume");
    });
    session.spawn(mission(false, false)).expect("spawn");
    let report = session.finish().await.expect("finish");
    assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
    let recorded = rec.events();
    assert_checked(&recorded);
    let controls: Vec<String> = recorded
        .iter()
        .filter_map(|e| match &e.kind {
            tcm::TraceKind::Control { what, .. } => Some(what.clone()),
            _ => None,
        })
        .collect();
    assert_eq!(controls.len(), 6, "{controls:?}");
    assert_eq!(controls[3], "raise start");
    assert!(controls[4].starts_with("approve around"), "{controls:?}");
    assert_eq!(controls[5], "continue");

    let rec2 = Recorder::new();
    let replay = Runtime::new()
        .with_sink(rec2.clone())
        .replay(read(&path))
        .start()
        .expect("start");
    // An operation from outside while the journal is replayed would come among its inputs: it
    // is refused until the run goes on live.
    let outside = replay.control();
    assert!(outside.replaying().expect("replaying"));
    assert!(matches!(outside.pause("late"), Err(tcm::Error::Replaying)));
    replay.spawn(mission(false, false)).expect("spawn");
    let replayed = replay.finish().await.expect("finish");
    assert_eq!(replayed.outcome, RunOutcome::Completed, "{replayed}");
    assert_same_records(&recorded, &rec2.events());
}

/// An operator's suspension, its end and a termination from outside (`Control::suspend`,
/// `Control::unsuspend`, `Control::terminate_as`, as the viewer asks them) are journaled as
/// operations, and the replay carries them out again: the same trace, record for record.
#[tokio::test(start_paused = true)]
async fn an_operators_suspension_and_termination_replay() {
    let task = || {
        Task::goal("pair", |ctx| async move {
            ctx.spawn(takes("slow", 2.0, json!(null))).start()?;
            ctx.spawn(takes("long", 10.0, json!(null))).start()?;
            Ok(())
        })
    };
    let (path, session, rec) = journaled_session("operator");
    let top = session.spawn(task()).expect("spawn");
    let control = session.control();
    tokio::time::sleep(Duration::from_millis(500)).await;
    control.suspend(top, "operator").expect("suspend");
    tokio::time::sleep(Duration::from_millis(1000)).await;
    control.unsuspend(top, "operator").expect("unsuspend");
    let long = control
        .node_by_number(spawned(&rec.events(), "long"))
        .expect("query")
        .expect("`long` is alive");
    control.terminate_as(long, "operator").expect("terminate");
    let report = session.finish().await.expect("finish");
    assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
    let recorded = rec.events();
    assert_checked(&recorded);
    let controls = recorded
        .iter()
        .filter(|e| matches!(e.kind, tcm::TraceKind::Control { .. }))
        .count();
    assert_eq!(controls, 3);

    let (replayed, events) = replayed_session(&path, task()).await;
    assert_eq!(replayed.outcome, RunOutcome::Completed, "{replayed}");
    assert_same_records(&recorded, &events);
}
