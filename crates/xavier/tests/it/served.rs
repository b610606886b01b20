//! The mail round served by a serving executive (docs/distributed.md, "A serving executive"): the
//! mission's `.tdl` files loaded at run time into a `tdl_serve::Server` whose registry is the
//! robot's (its commands carried out by a robot agent process, `xavier robot-agent`, over zenoh on
//! 127.0.0.1), a round started by a client, and, while the round runs, a program of recovery
//! alone loaded beside it: a handler for `guardedMove`'s `Blocked`. The next blocked move is
//! recovered by it, as its record in the trace shows; no blocked move before the load was.

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use tdl_interp::{Host, Registry};
use tdl_serve::{Client, File, Reply, Request, Response, Server, Swap};
use xavier::mission::Mission;
use xavier::robot::Robot;

/// The round's entry: the mission and its rooms come from the executive's registry.
const ROUND: &str = "\
pub goal round() {
    spawn deliver_all(mission(), rooms()) with wait;
}
";

/// Recovery for a task of the mission, loaded on its own: a blocked guarded move is let go.
const RECOVERY: &str = "\
exception Blocked;
extern command guardedMove(d: f64);

handler back_off() handles Blocked for guardedMove {
}
";

/// The robot agent process, killed when dropped.
struct RobotAgent(Child);

impl Drop for RobotAgent {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn robot_agent(system: &str, port: u16) -> RobotAgent {
    let mut child = Command::new(env!("CARGO_BIN_EXE_xavier"))
        .arg("robot-agent")
        .args(["--system", system, "--port", &port.to_string()])
        .args([
            "--seed",
            "1",
            "--scenario",
            "blocked-corridor",
            "--speed",
            "20",
        ])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .expect("the robot agent starts");
    let out = child.stdout.take().expect("its stdout");
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let mut lines = BufReader::new(out).lines();
        let ready = lines.by_ref().map_while(Result::ok).any(|l| l == "ready");
        let _ = tx.send(ready);
        for _ in lines {}
    });
    let agent = RobotAgent(child);
    assert_eq!(
        rx.recv_timeout(Duration::from_secs(60)),
        Ok(true),
        "the robot agent is ready"
    );
    agent
}

async fn ask(client: &Client, request: Request) -> Response {
    for _ in 0..50 {
        match client.request("main", &request).await {
            Ok(r) => return r,
            Err(tdl_serve::Error::NoAnswer { .. }) => {}
            Err(e) => panic!("{e}"),
        }
    }
    panic!("the executive never answered")
}

#[test]
fn recovery_loaded_while_the_round_runs_recovers_the_next_blocked_move() {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("a runtime");
    rt.block_on(async {
        tokio::time::timeout(Duration::from_secs(150), served())
            .await
            .expect("the served round ends in time");
    });
}

async fn served() {
    let system = format!("xavier-served-{}", std::process::id());
    let (exec, port) = tcm_zenoh::Executive::open_loopback(&system)
        .await
        .expect("an executive");
    let _agent = robot_agent(&system, port);
    exec.wait_for("robot", Some("guardedMove"), Duration::from_secs(30))
        .await
        .expect("the robot agent joins");
    let mission = Mission::with_robot(Robot::remote(exec.clone(), "robot", "robot"));
    let mut registry: Registry = crate::interpreted::registry();
    registry
        .function("mission", move || Host(mission.clone()))
        .function("rooms", || xavier::DEFAULT_ROOMS.to_vec());
    let dir = std::env::temp_dir().join(format!("xavier-served-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let server = Server::new(registry, Some(exec.clone()), &dir);
    let _serving = tdl_serve::serve(server, exec.session(), &system, "main")
        .await
        .expect("serving");
    let config = tcm_zenoh::config::loopback_connect(port).expect("a config");
    let client = Client::open(&system, "operator", config)
        .await
        .expect("a client");

    let mission_file = format!("{}/src/mission.tdl", env!("CARGO_MANIFEST_DIR"));
    let files = vec![
        File {
            name: "mission.tdl".into(),
            text: std::fs::read_to_string(&mission_file).expect("the mission"),
        },
        File {
            name: "round.tdl".into(),
            text: ROUND.into(),
        },
    ];
    let loaded = ask(
        &client,
        Request::Load {
            name: "xavier".into(),
            files,
            swap: Swap::Spawns,
            verify: None,
        },
    )
    .await;
    assert!(
        matches!(loaded, Response::Ok(Reply::Loaded { .. })),
        "{loaded:?}"
    );
    let run = match ask(
        &client,
        Request::Start {
            program: "xavier".into(),
            task: Some("round".into()),
            args: serde_json::Value::Null,
        },
    )
    .await
    {
        Response::Ok(Reply::Started { run, .. }) => run,
        other => panic!("{other:?}"),
    };
    let recovery = ask(
        &client,
        Request::Load {
            name: "recovery".into(),
            files: vec![File {
                name: "recovery.tdl".into(),
                text: RECOVERY.into(),
            }],
            swap: Swap::Spawns,
            verify: None,
        },
    )
    .await;
    assert!(
        matches!(recovery, Response::Ok(Reply::Loaded { .. })),
        "{recovery:?}"
    );

    let deadline = Instant::now() + Duration::from_secs(120);
    let info = loop {
        match ask(&client, Request::Status { run: Some(run) }).await {
            Response::Ok(Reply::Runs(r)) if r[0].outcome.is_some() => break r[0].clone(),
            _ => {}
        }
        assert!(Instant::now() < deadline, "the round did not end");
        tokio::time::sleep(Duration::from_millis(100)).await;
    };
    client.close().await;
    exec.close().await;

    let file = std::fs::File::open(&info.trace).expect("the trace");
    let trace = tcm_trace::read_jsonl(BufReader::new(file)).expect("it reads");
    tdl::testing::assert_checked(&trace);
    let attached = trace
        .iter()
        .position(|e| matches!(&e.kind, tdl::TraceKind::HandlerAttached { task, handler, .. } if task == "guardedMove" && handler == "back_off"))
        .expect("the recovery is attached to the running round");
    // Every Blocked failure, and the handler that took it.
    let blocked: Vec<(usize, u64)> = trace
        .iter()
        .enumerate()
        .filter_map(|(i, e)| match &e.kind {
            tdl::TraceKind::Failed {
                node, exception, ..
            } if exception == "Blocked" => Some((i, *node)),
            _ => None,
        })
        .collect();
    let taken_by = |node: u64| {
        trace.iter().find_map(|e| match &e.kind {
            tdl::TraceKind::HandlerChosen {
                failing, handler, ..
            } if *failing == node => Some(handler.clone()),
            _ => None,
        })
    };
    let after: Vec<&(usize, u64)> = blocked.iter().filter(|(i, _)| *i > attached).collect();
    let first = after
        .first()
        .expect("a move is blocked after the recovery is loaded");
    assert_eq!(taken_by(first.1).as_deref(), Some("back_off"), "{info:?}");
    assert!(
        blocked
            .iter()
            .filter(|(i, _)| *i < attached)
            .all(|(_, n)| taken_by(*n).as_deref() != Some("back_off")),
        "nothing before the load took the new handler"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
