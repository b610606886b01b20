//! An executive that comes back (docs/distributed.md, "An executive that comes back"): a run
//! journals its remote tasks' placements; its process dies (here: its tokio runtime is shut
//! down, nothing sent on the way out); a new executive under the same id resumes the run from
//! the journal and re-attaches to the remote command in flight on an agent that held it. The
//! body runs once, and the node ends once: with the body's value if it ended meanwhile, on time
//! if it still runs, and with `AgentLost` if the agent's hold ended first.

use crate::util::{BOUND, bounded, system};
use std::sync::Arc;
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::Duration;
use tcm::testing::assert_checked;
use tcm::{Recorder, Runtime, Task};
use tcm_journal::{Durability, Writer};
use tcm_zenoh::{Agent, At, Executive, RemoteOptions};

/// The remote command a mission runs: `task` on `agent` with `args`, whose value must be `value`.
#[derive(Clone)]
pub(crate) struct Command {
    pub(crate) agent: &'static str,
    pub(crate) task: &'static str,
    pub(crate) args: serde_json::Value,
    pub(crate) value: u32,
}

/// The command of the Rust agent `arm`: `slow`, which returns 42.
fn slow() -> Command {
    Command {
        agent: "arm",
        task: "slow",
        args: serde_json::Value::Null,
        value: 42,
    }
}

/// The mission: one remote command, its value read as a `u32`; the run fails unless it is the
/// command's.
fn mission(exec: Executive, command: Command) -> Task {
    Task::goal("mission", move |ctx| {
        let (exec, command) = (exec.clone(), command.clone());
        async move {
            let v: u32 = ctx
                .spawn(
                    exec.remote(At::agent(command.agent), command.task, command.args)
                        .typed_task::<u32>(),
                )
                .wait_value()
                .await?;
            if v != command.value {
                return Err(tcm::Failure::new("Wrong", format!("got {v}")));
            }
            Ok(())
        }
    })
}

struct Case {
    // How long the body takes, how long the agent holds it, when the executive dies, and how
    // long it stays dead.
    body: Duration,
    hold: Duration,
    crash_after: Duration,
    dead_for: Duration,
}

/// When the executive dies: a while after the body started, and for how long.
pub(crate) struct Crash {
    pub(crate) after: Duration,
    pub(crate) dead_for: Duration,
}

/// The agent `arm` of `system`, listening on `port`, holding an absent executive's bodies for
/// `hold`, offering `slow`: counted in `starts`, it takes `body` and returns 42.
async fn arm(
    system: &str,
    port: u16,
    hold: Duration,
    body: Duration,
    starts: &Arc<AtomicU32>,
) -> Agent {
    let counted = starts.clone();
    Agent::builder(system.to_string(), "arm")
        .hold(hold)
        .command("slow", move |_ctx, (): ()| {
            counted.fetch_add(1, Ordering::SeqCst);
            async move {
                tokio::time::sleep(body).await;
                Ok::<_, tcm_zenoh::RemoteFailure>(42u32)
            }
        })
        .start(tcm_zenoh::config::loopback_listen(port).expect("config"))
        .await
        .expect("the agent starts")
}

/// The executive `id` of `system`, connected to the agent's `port`, once it sees the agent offer
/// `command`.
async fn executive(system: &str, port: u16, id: &str, command: &Command) -> Executive {
    let config = tcm_zenoh::config::loopback_connect(port).expect("config");
    let exec = Executive::open_as(system, id, config, RemoteOptions::default())
        .await
        .expect("the executive opens");
    exec.wait_for(command.agent, Some(command.task), Duration::from_secs(10))
        .await
        .expect("the agent joins");
    exec
}

/// A scratch journal for `system`.
fn journal_path(system: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("tcm-zenoh-{system}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch");
    dir.join("run.journal")
}

/// Resumes the mission from `journal` with a new executive `id` of `system` on the agent's
/// `port`: its report and trace.
async fn resume(
    system: &str,
    port: u16,
    id: &str,
    journal: tcm_journal::Journal,
    command: Command,
) -> (tcm::Report, Vec<tcm::TraceEvent>) {
    let exec = executive(system, port, id, &command).await;
    exec.resume_from(&journal);
    let rec = Recorder::new();
    let report = Runtime::new()
        .with_sink(rec.clone())
        .resume(journal)
        .run(mission(exec.clone(), command))
        .await
        .expect("the run resumes");
    exec.close().await;
    (report, rec.events())
}

/// Runs the case: what the resumed run reported, its trace, and how often the body started.
async fn crash_and_resume(
    case: Case,
) -> (
    tcm::Report,
    Vec<tcm::TraceEvent>,
    u32,
    tcm_zenoh::AgentStats,
) {
    let system = system("resume");
    let port = tcm_zenoh::config::free_port().expect("port");
    let starts = Arc::new(AtomicU32::new(0));
    let arm = arm(&system, port, case.hold, case.body, &starts).await;
    let crash = Crash {
        after: case.crash_after,
        dead_for: case.dead_for,
    };
    let counted = starts.clone();
    let started = move || counted.load(Ordering::SeqCst) > 0;
    let (report, events) = crash_and_resume_on(&system, port, slow(), crash, started).await;
    let stats = arm.stats();
    arm.close().await;
    (report, events, starts.load(Ordering::SeqCst), stats)
}

/// Runs `command` on the agent listening on `port` from an executive `exec-a` of `system` that
/// journals its run and dies `crash.after` the body `started`, then resumes it from its journal
/// under the same id `crash.dead_for` later: what the resumed run reported, and its trace.
pub(crate) async fn crash_and_resume_on(
    system: &str,
    port: u16,
    command: Command,
    crash: Crash,
    started: impl Fn() -> bool,
) -> (tcm::Report, Vec<tcm::TraceEvent>) {
    let path = journal_path(system);
    let dir = path.parent().expect("its directory").to_path_buf();

    // The first executive, in a runtime of its own that dies with it.
    let first = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
        .expect("runtime");
    let (sys, p, c) = (system.to_string(), path.clone(), command.clone());
    let (give, session) = tokio::sync::oneshot::channel();
    first.spawn(async move {
        let exec = executive(&sys, port, "exec-a", &c).await;
        let _ = give.send(exec.session().clone());
        let writer = Writer::create(&p, "mission@1", Durability::EveryRecord).expect("journal");
        let _ = Runtime::new().journal(writer).run(mission(exec, c)).await;
    });
    // Until the body runs on the agent, then a while more.
    let deadline = tokio::time::Instant::now() + BOUND / 2;
    while !started() {
        assert!(
            tokio::time::Instant::now() < deadline,
            "the body never started"
        );
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    tokio::time::sleep(crash.after).await;
    // The crash: the journal as it is now; nothing the first executive's tasks would still send
    // goes out, and its session's link breaks (its token goes).
    let crashed = dir.join("crashed.journal");
    std::fs::copy(&path, &crashed).expect("the journal at the crash");
    first.shutdown_background();
    session
        .await
        .expect("the first executive's session")
        .close()
        .await
        .expect("closed");
    tokio::time::sleep(crash.dead_for).await;

    let journal = tcm_journal::read(&crashed, Some("mission@1")).expect("the journal reads");
    resume(system, port, "exec-a", journal, command).await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_command_still_running_is_reattached_and_ends_once() {
    let (report, events, starts, stats) = bounded(crash_and_resume(Case {
        body: Duration::from_secs(3),
        hold: Duration::from_secs(20),
        crash_after: Duration::from_millis(300),
        dead_for: Duration::from_millis(300),
    }))
    .await;
    assert_checked(&events);
    assert!(report.is_clean(), "{report}");
    assert_eq!((starts, stats.reattached, stats.orphaned), (1, 1, 0));
    let placed = events
        .iter()
        .filter(|e| matches!(&e.kind, tcm::TraceKind::Placed { agent, .. } if agent == "arm"))
        .count();
    assert_eq!(placed, 1, "placed again where it runs, once");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_command_that_ended_meanwhile_gives_its_kept_end() {
    let (report, events, starts, stats) = bounded(crash_and_resume(Case {
        body: Duration::from_millis(500),
        hold: Duration::from_secs(20),
        crash_after: Duration::from_millis(100),
        dead_for: Duration::from_millis(1500),
    }))
    .await;
    assert_checked(&events);
    assert!(report.is_clean(), "{report}");
    assert_eq!((starts, stats.reattached, stats.orphaned), (1, 1, 0));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_command_whose_hold_ended_fails_with_agent_lost() {
    let (report, events, starts, stats) = bounded(crash_and_resume(Case {
        body: Duration::from_secs(30),
        hold: Duration::from_millis(200),
        crash_after: Duration::from_millis(100),
        dead_for: Duration::from_millis(1500),
    }))
    .await;
    assert_checked(&events);
    assert_eq!(starts, 1, "not started again");
    assert_eq!((stats.reattached, stats.orphaned), (0, 1));
    let lost: Vec<&str> = report
        .unhandled
        .iter()
        .map(|u| u.failure.exception.as_ref())
        .collect();
    assert_eq!(lost, ["AgentLost"], "{report}");
}

/// The crash came between a placement's record and its start: the agent never had the task, so
/// the resumed executive sends the start now, and the body runs once, there.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_command_whose_start_never_left_is_started_when_the_run_resumes() {
    bounded(async {
        let system = system("unstarted");
        let path = journal_path(&system);
        // A whole run, journaled; then its journal cut after the placement's record, before the
        // command's end, as a crash before the start left would leave it.
        let (hold, body) = (Duration::from_secs(20), Duration::from_millis(200));
        let port = tcm_zenoh::config::free_port().expect("port");
        let first = Arc::new(AtomicU32::new(0));
        let agent = arm(&system, port, hold, body, &first).await;
        let exec = executive(&system, port, "exec-b", &slow()).await;
        let writer = Writer::create(&path, "mission@1", Durability::EveryRecord).expect("journal");
        let report = Runtime::new()
            .journal(writer)
            .run(mission(exec.clone(), slow()))
            .await
            .expect("run");
        assert!(report.is_clean(), "{report}");
        exec.close().await;
        agent.close().await;
        let mut journal = tcm_journal::read(&path, Some("mission@1")).expect("reads");
        let placed = journal
            .entries
            .iter()
            .position(|e| matches!(e.input, tcm_journal::Input::Recorded { .. }))
            .expect("the placement was recorded");
        journal.entries.truncate(placed + 1);
        // A new agent under the same name, which never had the task.
        let port = tcm_zenoh::config::free_port().expect("port");
        let second = Arc::new(AtomicU32::new(0));
        let agent = arm(&system, port, hold, body, &second).await;
        let (report, events) = resume(&system, port, "exec-b", journal, slow()).await;
        agent.close().await;
        assert_checked(&events);
        assert!(report.is_clean(), "{report}");
        assert_eq!(
            second.load(Ordering::SeqCst),
            1,
            "started once, on the new agent"
        );
    })
    .await;
}

/// An executive that came back while the agent still saw its old token (a link that broke
/// silently, whose token goes only when its lease runs out): the old token's deletion comes after
/// the new executive holds the same token, and the executive is still live, so the agent leaves
/// its bodies alone instead of holding them again and aborting them when the hold ends.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_old_token_going_after_the_executive_came_back_leaves_its_bodies_alone() {
    bounded(async {
        let system = system("late-token");
        let port = tcm_zenoh::config::free_port().expect("port");
        let starts = Arc::new(AtomicU32::new(0));
        let hold = Duration::from_millis(300);
        let agent = arm(&system, port, hold, Duration::from_secs(30), &starts).await;
        let old = executive(&system, port, "exec-c", &slow()).await;
        let running = tokio::spawn(Runtime::new().run(mission(old.clone(), slow())));
        while starts.load(Ordering::SeqCst) == 0 {
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        // The executive comes back under the same id while its old token is still there; then
        // the old one goes.
        let new = executive(&system, port, "exec-c", &slow()).await;
        old.session().clone().close().await.expect("closed");
        running.abort();
        tokio::time::sleep(hold * 3).await;
        let stats = agent.stats();
        assert_eq!(
            (stats.started, stats.orphaned),
            (1, 0),
            "the body of a live executive is not aborted"
        );
        new.close().await;
        // Its token gone for good: the body is held, and aborted when the hold ends.
        tokio::time::sleep(hold * 3).await;
        assert_eq!(agent.stats().orphaned, 1);
        agent.close().await;
    })
    .await;
}
