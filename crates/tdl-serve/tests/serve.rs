//! A serving executive over zenoh on loopback, driven by a client as `tdl load`/`start`/`stop`
//! drive it: a program refused with its diagnostics while a run goes on untouched, recovery
//! loaded into a running patrol and taking its next failure, a new version swapped in for new
//! spawns and by restart, and a run stopped. Real time (zenoh needs it); every wait bounded;
//! every trace through the checker.

use std::time::{Duration, Instant};

use tdl_interp::Registry;
use tdl_serve::{Client, File, Reply, Request, Response, RunInfo, Server, Swap};

/// The patrol: `n` steps, one bump each, one after the other; a bump of an odd step is blocked.
const PATROL: &str = "\
exception Blocked;

pub goal patrol(n: i64) {
    for i in 0..n {
        spawn step(i) with sequential execution previous;
    }
}

goal step(i: i64) {
    spawn bump(i) with wait;
}
";

/// Recovery for `bump`, loaded on its own while the patrol runs.
const RECOVERY: &str = "\
exception Blocked;
extern command bump(i: i64);

handler back_off() handles Blocked for bump {
}
";

fn registry() -> Registry {
    let mut r = Registry::new();
    r.task("bump", |i: i64| {
        tdl::Task::command("bump", move |_| async move {
            tokio::time::sleep(Duration::from_millis(40)).await;
            if i % 2 == 1 {
                Err(tdl::Failure::new("Blocked", format!("step {i} is blocked")))
            } else {
                Ok(())
            }
        })
    });
    r
}

struct Fixture {
    client: Client,
    _serving: tdl_serve::Serving,
    exec: tcm_zenoh::Executive,
    dir: std::path::PathBuf,
}

async fn fixture(test: &str) -> Fixture {
    let (exec, port) = tcm_zenoh::Executive::open_loopback("serve-test")
        .await
        .expect("an executive");
    let dir = std::env::temp_dir().join(format!("tdl-serve-{test}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let server = Server::new(registry(), Some(exec.clone()), &dir);
    let serving = tdl_serve::serve(server, exec.session(), "serve-test", "main")
        .await
        .expect("serving");
    let config = tcm_zenoh::config::loopback_connect(port).expect("a config");
    let client = Client::open("serve-test", "operator", config)
        .await
        .expect("a client")
        .with_timeout(Duration::from_secs(5));
    Fixture {
        client,
        _serving: serving,
        exec,
        dir,
    }
}

impl Fixture {
    async fn ask(&self, request: Request) -> Response {
        // The client's first query may go out before its link to the executive is up.
        for _ in 0..50 {
            match self.client.request("main", &request).await {
                Ok(r) => return r,
                Err(tdl_serve::Error::NoAnswer { .. }) => {}
                Err(e) => panic!("{e}"),
            }
        }
        panic!("the executive never answered")
    }

    async fn ok(&self, request: Request) -> Reply {
        match self.ask(request).await {
            Response::Ok(r) => r,
            Response::Refused(why) => panic!("refused: {why}"),
        }
    }

    async fn load(&self, name: &str, text: &str, swap: Swap) -> Response {
        self.ask(Request::Load {
            name: name.into(),
            files: vec![File {
                name: format!("{name}.tdl"),
                text: text.into(),
            }],
            swap,
            verify: None,
        })
        .await
    }

    async fn status(&self, run: u64) -> RunInfo {
        match self.ok(Request::Status { run: Some(run) }).await {
            Reply::Runs(mut runs) if runs.len() == 1 => runs.remove(0),
            other => panic!("{other:?}"),
        }
    }

    /// Waits (at most 20 s) for run `run` to end; its status then.
    async fn ended(&self, run: u64) -> RunInfo {
        for _ in 0..400 {
            let s = self.status(run).await;
            if !s.running && s.outcome.is_some() {
                return s;
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
        panic!("run {run} did not end")
    }

    fn trace(&self, info: &RunInfo) -> Vec<tdl::TraceEvent> {
        let file = std::fs::File::open(&info.trace).expect("the trace");
        let trace = tcm_trace::read_jsonl(std::io::BufReader::new(file)).expect("it reads");
        tdl::testing::assert_checked(&trace);
        trace
    }

    async fn close(self) {
        self.client.close().await;
        self.exec.close().await;
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

fn started(reply: Reply) -> u64 {
    match reply {
        Reply::Started { run, .. } => run,
        other => panic!("{other:?}"),
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn recovery_loaded_while_the_patrol_runs_takes_its_next_failures_and_a_bad_load_changes_nothing()
 {
    let f = fixture("recovery").await;
    assert!(matches!(
        f.load("patrol", PATROL, Swap::Spawns).await,
        Response::Ok(Reply::Loaded {
            unchanged: false,
            ..
        })
    ));
    let run = started(
        f.ok(Request::Start {
            program: "patrol".into(),
            task: None,
            args: serde_json::json!(40),
        })
        .await,
    );
    tokio::time::sleep(Duration::from_millis(300)).await;
    let live = f.status(run).await;
    assert!(live.running && live.live_nodes > 0, "{live:?}");

    // A program with an error: refused with its located diagnostics; the patrol goes on.
    let bad = RECOVERY.replace("handles Blocked", "handles Blokced");
    match f.load("recovery", &bad, Swap::Spawns).await {
        Response::Refused(why) => {
            assert!(why.contains("recovery.tdl:4"), "{why}");
            assert!(why.contains("Blokced"), "{why}");
        }
        other => panic!("{other:?}"),
    }
    match f.ok(Request::List).await {
        Reply::Programs(p) => assert_eq!(p.len(), 1, "{p:?}"),
        other => panic!("{other:?}"),
    }
    assert!(f.status(run).await.running);

    let Response::Ok(Reply::Loaded { version, .. }) =
        f.load("recovery", RECOVERY, Swap::Spawns).await
    else {
        panic!("the recovery loads")
    };
    let end = f.ended(run).await;
    assert!(
        end.outcome
            .as_deref()
            .is_some_and(|o| o.starts_with("completed")),
        "{end:?}"
    );
    let trace = f.trace(&end);
    let at = |pred: &dyn Fn(&tdl::TraceKind) -> bool| trace.iter().position(|e| pred(&e.kind));
    let attached = at(&|k| matches!(k, tdl::TraceKind::HandlerAttached { task, handler, .. } if task == "bump" && handler == "back_off"))
        .expect("the handler is attached in the run");
    assert!(trace.iter().any(|e| matches!(&e.kind, tdl::TraceKind::Control { what, by } if *what == format!("load {version}") && by == "operator")));
    let chosen: Vec<usize> = trace
        .iter()
        .enumerate()
        .filter(|(_, e)| matches!(e.kind, tdl::TraceKind::HandlerChosen { .. }))
        .map(|(i, _)| i)
        .collect();
    let unhandled: Vec<usize> = trace
        .iter()
        .enumerate()
        .filter(|(_, e)| matches!(&e.kind, tdl::TraceKind::Warning { message, .. } if message.contains("No exception handler")))
        .map(|(i, _)| i)
        .collect();
    assert!(!chosen.is_empty(), "the recovery took failures");
    assert!(
        chosen.iter().all(|i| *i > attached),
        "only after it was loaded"
    );
    assert!(
        unhandled.iter().all(|i| *i < attached),
        "none unhandled after it"
    );
    assert!(!unhandled.is_empty(), "failures before it were not handled");
    f.close().await;
}

/// A patrol whose steps are spawned one after the other, each bump of an even number (never
/// blocked): version 1.
const SWAP_V1: &str = "\
pub goal patrol(n: i64) {
    for i in 0..n {
        spawn step(i) with wait;
    }
}

goal step(i: i64) {
    spawn bump(i * 2) with wait;
}
";

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_new_version_takes_new_spawns_then_a_restart_and_a_stop_end_the_run() {
    let f = fixture("swap").await;
    let Response::Ok(Reply::Loaded { version: v1, .. }) =
        f.load("patrol", SWAP_V1, Swap::Spawns).await
    else {
        panic!("v1 loads")
    };
    let run = started(
        f.ok(Request::Start {
            program: "patrol".into(),
            task: Some("patrol".into()),
            args: serde_json::json!(400),
        })
        .await,
    );
    tokio::time::sleep(Duration::from_millis(300)).await;
    // Version 2: two bumps a step.
    let v2_text = SWAP_V1.replace(
        "    spawn bump(i * 2) with wait;\n",
        "    spawn bump(i * 2) with wait;\n    spawn bump(i * 2 + 2) with wait;\n",
    );
    assert_ne!(v2_text, SWAP_V1);
    let v2 = match f.load("patrol", &v2_text, Swap::Spawns).await {
        Response::Ok(Reply::Loaded {
            version, swapped, ..
        }) => {
            assert_eq!(swapped, vec![run]);
            version
        }
        other => panic!("{other:?}"),
    };
    assert_ne!(v1, v2);
    // The same version again: nothing changes.
    assert!(matches!(
        f.load("patrol", &v2_text, Swap::Spawns).await,
        Response::Ok(Reply::Loaded {
            unchanged: true,
            ..
        })
    ));
    tokio::time::sleep(Duration::from_millis(300)).await;
    // A version whose step takes other arguments cannot take new spawns...
    let v3_text = v2_text
        .replace("goal step(i: i64)", "goal step(i: f64)")
        .replace("spawn step(i)", "spawn step(i as f64)")
        .replace("bump(i * 2)", "bump(0)")
        .replace("bump(i * 2 + 2)", "bump(0)");
    match f.load("patrol", &v3_text, Swap::Spawns).await {
        Response::Refused(why) => assert!(why.contains("`step` changes parameters"), "{why}"),
        other => panic!("{other:?}"),
    }
    // ...but it can restart the run's patrol.
    let v3 = match f.load("patrol", &v3_text, Swap::Now).await {
        Response::Ok(Reply::Loaded {
            version, swapped, ..
        }) => {
            assert_eq!(swapped, vec![run]);
            version
        }
        other => panic!("{other:?}"),
    };
    tokio::time::sleep(Duration::from_millis(300)).await;
    let s = f.status(run).await;
    assert!(s.running, "{s:?}");
    assert_eq!(s.version, v3);
    assert!(matches!(
        f.ask(Request::Unload {
            name: "patrol".into()
        })
        .await,
        Response::Refused(_)
    ));
    assert_eq!(f.ok(Request::Stop { run }).await, Reply::Done);
    let end = f.ended(run).await;
    assert!(
        end.outcome
            .as_deref()
            .is_some_and(|o| o.starts_with("terminated")),
        "{end:?}"
    );
    assert!(
        matches!(f.ask(Request::Stop { run }).await, Response::Refused(_)),
        "stopped already"
    );

    let trace = f.trace(&end);
    let versions: Vec<(String, Option<String>)> = trace
        .iter()
        .filter_map(|e| match &e.kind {
            tdl::TraceKind::Spawned { name, version, .. } if name == "step" || name == "patrol" => {
                Some((name.clone(), version.clone()))
            }
            _ => None,
        })
        .collect();
    let of = |v: &str| {
        versions
            .iter()
            .filter(|(_, x)| x.as_deref() == Some(v))
            .count()
    };
    assert!(of(&v1) >= 2 && of(&v2) >= 1 && of(&v3) >= 2, "{versions:?}");
    // The patrols: the first of version 1, the restarted one of version 3.
    let patrols: Vec<&Option<String>> = versions
        .iter()
        .filter(|(n, _)| n == "patrol")
        .map(|(_, v)| v)
        .collect();
    assert_eq!(patrols, vec![&Some(v1.clone()), &Some(v3.clone())]);
    assert!(trace.iter().any(|e| matches!(&e.kind, tdl::TraceKind::Control { what, .. } if *what == format!("swapped to {v3}"))));
    assert!(trace.iter().any(|e| matches!(&e.kind, tdl::TraceKind::Control { what, by } if what == "stop" && by == "operator")));
    f.close().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_client_of_no_executive_is_told_so_and_requests_for_nothing_are_refused() {
    let f = fixture("nothing").await;
    assert!(
        matches!(f.ask(Request::Stop { run: 7 }).await, Response::Refused(w) if w.contains("no run 7"))
    );
    assert!(matches!(
        f.ask(Request::Start { program: "none".into(), task: None, args: serde_json::Value::Null }).await,
        Response::Refused(w) if w.contains("no program `none`")
    ));
    let lost = Client::open(
        "serve-test",
        "operator",
        tcm_zenoh::config::loopback_connect(1).expect("config"),
    )
    .await
    .expect("a client")
    .with_timeout(Duration::from_millis(200));
    match lost.request("main", &Request::List).await {
        Err(e @ tdl_serve::Error::NoAnswer { .. }) => assert!(e.to_string().contains("tdl serve")),
        other => panic!("{other:?}"),
    }
    lost.close().await;
    f.close().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_swap_after_a_task_restarts_the_run_when_that_task_next_completes() {
    let f = fixture("after").await;
    let Response::Ok(Reply::Loaded { version: v1, .. }) =
        f.load("patrol", SWAP_V1, Swap::Spawns).await
    else {
        panic!("v1 loads")
    };
    let run = started(
        f.ok(Request::Start {
            program: "patrol".into(),
            task: None,
            args: serde_json::json!(400),
        })
        .await,
    );
    tokio::time::sleep(Duration::from_millis(200)).await;
    // A new patrol whose steps take a float: it cannot take new spawns, so it restarts the run,
    // at the next completion of a step.
    let v2_text = SWAP_V1
        .replace("goal step(i: i64)", "goal step(i: f64)")
        .replace("spawn step(i)", "spawn step(i as f64)")
        .replace("bump(i * 2)", "bump(4)");
    let v2 = match f
        .load(
            "patrol",
            &v2_text,
            Swap::After {
                task: "step".into(),
            },
        )
        .await
    {
        Response::Ok(Reply::Loaded {
            version, swapped, ..
        }) => {
            assert_eq!(swapped, vec![run]);
            version
        }
        other => panic!("{other:?}"),
    };
    let deadline = Instant::now() + Duration::from_secs(20);
    while f.status(run).await.version != v2 {
        assert!(Instant::now() < deadline, "the run never took version 2");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    assert_eq!(f.ok(Request::Stop { run }).await, Reply::Done);
    let end = f.ended(run).await;
    let trace = f.trace(&end);
    // The restart came right after a step of version 1 completed: the first patrol was
    // terminated after that, and the next patrol is version 2's.
    let tap = trace
        .iter()
        .position(|e| matches!(&e.kind, tdl::TraceKind::TapAdded { task, when, .. } if task == "step" && when == "after"))
        .expect("the swap waits on step's completion");
    let tapped = trace[tap..]
        .iter()
        .position(|e| matches!(e.kind, tdl::TraceKind::Tapped { .. }))
        .map(|i| i + tap)
        .expect("a step completed after the load");
    let terminating = trace
        .iter()
        .position(|e| matches!(e.kind, tdl::TraceKind::Terminating { node } if node == 1))
        .expect("the first patrol is terminated");
    assert!(tapped < terminating, "terminated after the step completed");
    let patrols: Vec<Option<String>> = trace
        .iter()
        .filter_map(|e| match &e.kind {
            tdl::TraceKind::Spawned { name, version, .. } if name == "patrol" => {
                Some(version.clone())
            }
            _ => None,
        })
        .collect();
    assert_eq!(patrols, vec![Some(v1), Some(v2)]);
    // Its wiretap is removed once the swap is made.
    assert!(
        trace
            .iter()
            .any(|e| matches!(e.kind, tdl::TraceKind::TapRemoved { .. }))
    );
    f.close().await;
}

#[test]
fn a_load_that_asks_for_a_model_check_is_refused_when_a_property_is_broken() {
    let server = Server::new(Registry::new(), None, std::env::temp_dir());
    let careless = "\
exception Broken;

pub goal go() {
    spawn step();
}

command step() {
    fail Broken;
}
";
    let load = |text: &str, verify: Option<tdl_serve::Verify>| {
        server.handle(
            Request::Load {
                name: "careless".into(),
                files: vec![File {
                    name: "careless.tdl".into(),
                    text: text.into(),
                }],
                swap: Swap::Spawns,
                verify,
            },
            "test",
        )
    };
    match load(careless, Some(tdl_serve::Verify::default())) {
        Response::Refused(why) => {
            assert!(why.contains("VIOLATED no unhandled exception"), "{why}");
        }
        other => panic!("{other:?}"),
    }
    match server.handle(Request::List, "test") {
        Response::Ok(Reply::Programs(p)) => assert!(p.is_empty(), "nothing was loaded: {p:?}"),
        other => panic!("{other:?}"),
    }
    // The same program handling its exception passes, and says what the check found.
    let careful = careless.replace(
        "pub goal go() {",
        "handler shrug() handles Broken {\n}\n\npub goal go() with exception handler shrug() {",
    );
    match load(&careful, Some(tdl_serve::Verify::default())) {
        Response::Ok(Reply::Loaded {
            verified: Some(v), ..
        }) => assert!(v.starts_with("ok"), "{v}"),
        other => panic!("{other:?}"),
    }
    // Without a check, a broken program loads: only the static checks apply.
    assert!(matches!(
        load(careless, None),
        Response::Ok(Reply::Loaded { verified: None, .. })
    ));
}

/// A wiretap monitor loaded on its own: every bump that returns while it is loaded fails.
const VETO: &str = "\
exception Unsafe;
extern command bump(i: i64);

wiretap veto() after bump {
    fail Unsafe;
}
";

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_wiretap_loaded_while_the_patrol_runs_checks_the_next_bumps_until_unloaded() {
    let f = fixture("wiretap").await;
    assert!(matches!(
        f.load("patrol", PATROL, Swap::Spawns).await,
        Response::Ok(Reply::Loaded { .. })
    ));
    let run = started(
        f.ok(Request::Start {
            program: "patrol".into(),
            task: None,
            args: serde_json::json!(60),
        })
        .await,
    );
    tokio::time::sleep(Duration::from_millis(300)).await;
    assert!(matches!(
        f.load("veto", VETO, Swap::Spawns).await,
        Response::Ok(Reply::Loaded { .. })
    ));
    match f.ok(Request::List).await {
        Reply::Programs(p) => {
            assert!(
                p.iter()
                    .any(|p| p.name == "veto" && p.taps == vec!["bump".to_string()])
            )
        }
        other => panic!("{other:?}"),
    }
    tokio::time::sleep(Duration::from_millis(300)).await;
    assert_eq!(
        f.ok(Request::Unload {
            name: "veto".into()
        })
        .await,
        Reply::Unloaded
    );
    let end = f.ended(run).await;
    let trace = f.trace(&end);
    let at = |pred: &dyn Fn(&tdl::TraceKind) -> bool| trace.iter().position(|e| pred(&e.kind));
    let added = at(&|k| matches!(k, tdl::TraceKind::TapAdded { task, .. } if task == "bump"))
        .expect("the wiretap is added to the running patrol");
    let removed =
        at(&|k| matches!(k, tdl::TraceKind::TapRemoved { .. })).expect("and removed when unloaded");
    let vetoed: Vec<usize> = trace
        .iter()
        .enumerate()
        .filter(|(_, e)| matches!(&e.kind, tdl::TraceKind::Failed { exception, .. } if exception == "Unsafe"))
        .map(|(i, _)| i)
        .collect();
    assert!(!vetoed.is_empty(), "bumps were vetoed while it was loaded");
    assert!(
        vetoed.iter().all(|i| *i > added),
        "only once it was loaded: {vetoed:?}, added at {added}"
    );
    let tapped_after = trace[removed..]
        .iter()
        .filter(|e| matches!(e.kind, tdl::TraceKind::Tapped { .. }))
        .count();
    assert_eq!(tapped_after, 0, "no check starts once it is removed");
    f.close().await;
}
