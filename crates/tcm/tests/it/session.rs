//! A top-level program in TCM's style (issue 11, point 17): `main` spawns several top-level tasks,
//! processes the agenda until nothing more can run (`Session::quiescent`, TCM's
//! `TCM_ProcessAgenda`), inspects and terminates them, then finishes.

use crate::util::{assert_order, story};
use std::time::Duration;
use tcm::testing::assert_checked;
use tcm::{
    Constraint, Error, Facet, Failure, FailurePolicy, Point, Recorder, RunOutcome, Runtime,
    Session, State, Task, WatchOutcome, When,
};

fn secs(s: u64) -> Duration {
    Duration::from_secs(s)
}

/// Longer than any run here: a run that does not end fails instead of hanging `cargo test`.
const NEVER: Duration = Duration::from_secs(24 * 3600);

fn sleeper(name: &'static str, d: u64) -> Task {
    Task::command(name, move |_| async move {
        tokio::time::sleep(secs(d)).await;
        Ok(())
    })
}

use crate::util::recorded_session as start;

async fn quiescent(session: &Session) -> Result<(), Error> {
    tokio::time::timeout(NEVER, session.quiescent())
        .await
        .expect("the run becomes quiescent")
}

async fn finish(session: Session, rec: &Recorder) -> tcm::Report {
    let report = tokio::time::timeout(NEVER, session.finish())
        .await
        .expect("the run ends")
        .expect("finish");
    let trace = rec.events();
    assert_checked(&trace);
    tcm::testing::assert_no_panics(&report, &trace);
    report
}

#[tokio::test(start_paused = true)]
async fn spawn_roots_process_the_agenda_inspect_terminate_finish() {
    let (session, rec) = start();
    let a = session.spawn(sleeper("a", 2)).expect("spawn");
    let go = session.external("go").expect("external");
    let b = session
        .spawn(
            Task::goal("b", |ctx| async move {
                ctx.spawn(sleeper("b1", 1)).start()?;
                Ok(())
            })
            .with(Constraint::disable(Facet::Expansion, When::External(go))),
        )
        .expect("spawn");
    let c = session.spawn(sleeper("c", 10).named("c-1")).expect("spawn");
    quiescent(&session).await.expect("quiescent");
    // `a` and `c` ran to their end; `b` waits for an event nobody raises.
    assert_eq!(session.now(), secs(10));
    assert_eq!(
        session.outcome(a).expect("outcome"),
        Some(WatchOutcome::Reached)
    );
    assert_eq!(
        session.outcome(c).expect("outcome"),
        Some(WatchOutcome::Reached)
    );
    assert_eq!(session.info(a).expect("info"), None, "reclaimed");
    assert_eq!(session.outcome(b).expect("outcome"), None);
    let info = session.info(b).expect("info").expect("b waits");
    assert_eq!(info.state(Facet::Expansion), State::Disabled);
    assert_eq!(session.children(session.root()).expect("children"), [b]);
    session.terminate(b).expect("terminate");
    let report = finish(session, &rec).await;
    assert_eq!(report.outcome, RunOutcome::Terminated);
    assert_eq!(report.elapsed, secs(10));
    assert_order(
        &story(&rec.events()),
        &[
            "2 a execution completed",
            "10 c-1 execution completed",
            "10 b terminating",
            "10 b terminated",
        ],
    );
}

#[tokio::test(start_paused = true)]
async fn quiescent_counts_actions_parked_on_the_engine_as_done() {
    // `waiter` awaits `b`, which waits for an event: the run can do nothing more by itself.
    let (session, rec) = start();
    let go = session.external("go").expect("external");
    let b = session
        .spawn(
            Task::command("b", |_| async { Ok(()) })
                .with(Constraint::disable(Facet::Handling, When::External(go))),
        )
        .expect("spawn");
    let w = session
        .spawn(Task::command("waiter", move |ctx| async move {
            ctx.wait(b).await?;
            Ok(())
        }))
        .expect("spawn");
    quiescent(&session).await.expect("quiescent");
    assert_eq!(session.now(), secs(0));
    let waiter = session.info(w).expect("info").expect("alive");
    assert!(waiter.reached(Facet::Handling, Point::Active));
    // The program raises the event: both end, and the run is quiescent again.
    session.raise("go").expect("raise");
    quiescent(&session).await.expect("quiescent");
    assert_eq!(
        session.outcome(w).expect("outcome"),
        Some(WatchOutcome::Reached)
    );
    let report = finish(session, &rec).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
}

#[tokio::test(start_paused = true)]
async fn quiescent_waits_for_timers_and_callbacks() {
    let (session, rec) = start();
    let a = session
        .spawn(
            Task::command("a", |_| async { Ok(()) })
                .with(Constraint::disable(Facet::Handling, When::In(secs(3)))),
        )
        .expect("spawn");
    session
        .invoke_after("late", secs(7), move |ctx| {
            let _ = ctx.raise("late");
        })
        .expect("invoke");
    quiescent(&session).await.expect("quiescent");
    assert_eq!(session.now(), secs(7));
    assert_eq!(
        session.outcome(a).expect("outcome"),
        Some(WatchOutcome::Reached)
    );
    let report = finish(session, &rec).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_order(
        &story(&rec.events()),
        &["3 a handling active", "7 callback late ran"],
    );
}

#[tokio::test(start_paused = true)]
async fn finish_waits_for_every_root_and_ends_stuck_when_nothing_can_progress() {
    let (session, rec) = start();
    session.spawn(sleeper("a", 4)).expect("spawn");
    let report = finish(session, &rec).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(report.elapsed, secs(4));

    let (session, rec) = start();
    let never = session.external("never").expect("external");
    session.spawn(sleeper("a", 4)).expect("spawn");
    session
        .spawn(
            Task::command("b", |_| async { Ok(()) })
                .with(Constraint::disable(Facet::Handling, When::External(never))),
        )
        .expect("spawn");
    let report = finish(session, &rec).await;
    let RunOutcome::Stuck(blocked) = report.outcome else {
        panic!("expected stuck, got {:?}", report.outcome);
    };
    assert_eq!(
        blocked.iter().map(ToString::to_string).collect::<Vec<_>>(),
        ["b {2} handling waits for external event `never`"]
    );
    assert_eq!(report.elapsed, secs(4));
}

#[tokio::test(start_paused = true)]
async fn a_fatal_failure_ends_the_session_run() {
    let rec = Recorder::new();
    let session = Runtime::new()
        .failure_policy(FailurePolicy::Fatal)
        .with_sink(rec.clone())
        .start()
        .expect("start");
    session
        .spawn(Task::command("bad", |_| async {
            tokio::time::sleep(secs(1)).await;
            Err::<(), _>(Failure::new("Broken", "it broke"))
        }))
        .expect("spawn");
    session.spawn(sleeper("long", 100)).expect("spawn");
    assert!(matches!(quiescent(&session).await, Err(Error::RunEnded)));
    assert!(matches!(
        session.spawn(sleeper("late", 1)),
        Err(Error::RunEnded)
    ));
    let report = finish(session, &rec).await;
    match report.outcome {
        RunOutcome::Fatal(f) => assert_eq!(f.path, "bad"),
        other => panic!("expected fatal, got {other:?}"),
    }
    assert_eq!(report.elapsed, secs(1));
}

#[test]
fn start_outside_a_tokio_runtime_is_an_error() {
    assert!(matches!(Runtime::new().start(), Err(Error::NoRuntime)));
}
