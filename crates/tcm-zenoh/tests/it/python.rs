//! The Python agent (`python/tdl_agent`, on the `eclipse-zenoh` package from PyPI): a process of
//! its own, made from `python_agent.py` beside this file, serves remote tasks of the executive's
//! tree: a command's and a goal's values, a typed Python exception handled by the tree's handler
//! of its ancestor, termination cancelling the Python body and running its cleanup, a cancel
//! forged by a stranger failing the node with `RemoteCancelled`, and the process killed surfacing
//! as `AgentLost`. The venv comes from `test_support::python_venv`;
//! where Python 3 is absent, each test prints why and returns.

use crate::util::{Log, Net, Stranger, bounded, untimed};
use serde::Deserialize;
use serde_json::json;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex, mpsc};
use std::time::{Duration, Instant};
use tcm::testing::{assert_order, handler_choices, run_checked};
use tcm::{Handler, RunOutcome, Runtime, Task};
use tcm_zenoh::{AgentLost, At, Json, RemoteCancelled, RemoteError};

/// The zenoh release the Rust side is built with, which the Python side must match.
const ZENOH: &str = "eclipse-zenoh==1.10.2";

/// How long the Python agent may take to start (the interpreter, zenoh, the session).
const READY: Duration = Duration::from_secs(30);

/// The venv's interpreter, or `None` (with the reason printed) where Python 3 is absent.
fn python() -> Option<PathBuf> {
    if test_support::find_on_path("python3").is_none() {
        println!("skipped: python3 is not on PATH, so the Python agent cannot run");
        return None;
    }
    Some(test_support::python_venv(&[ZENOH]).unwrap_or_else(|why| panic!("{why}")))
}

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// A Python agent process and the lines it prints.
struct PythonAgent {
    child: Child,
    // The lines seen, and those to come. In a mutex: awaited across (`expect`), the process
    // must be `Sync`.
    lines: Mutex<(Vec<String>, mpsc::Receiver<String>)>,
}

impl PythonAgent {
    /// Starts the agent, connected to the executive's `ports[0]` and the other `ports`.
    fn spawn(python: &Path, system: &str, name: &str, ports: &[u16]) -> PythonAgent {
        PythonAgent::spawn_with(python, system, name, ports, None)
    }

    /// As [`PythonAgent::spawn`], over mutual TLS with `tls`' certificates if given.
    fn spawn_with(
        python: &Path,
        system: &str,
        name: &str,
        ports: &[u16],
        tls: Option<&tcm_zenoh::config::Certs>,
    ) -> PythonAgent {
        let env: Vec<(&str, String)> = tls
            .map(|c| {
                let files = [&c.authority, &c.certificate, &c.key].map(|p| p.display().to_string());
                ("TDL_AGENT_TLS", files.join(":"))
            })
            .into_iter()
            .collect();
        PythonAgent::spawn_env(python, system, name, ports, &env)
    }

    /// As [`PythonAgent::spawn`], with `env` in its environment (see `python_agent.py`).
    fn spawn_env(
        python: &Path,
        system: &str,
        name: &str,
        ports: &[u16],
        env: &[(&str, String)],
    ) -> PythonAgent {
        let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/it/python_agent.py");
        let mut command = Command::new(python);
        command.envs(env.iter().map(|(k, v)| (*k, v)));
        let mut child = command
            .arg(script)
            .args([system, name])
            .args(ports.iter().map(u16::to_string))
            .env("PYTHONPATH", repo().join("python"))
            .env("PYTHONUNBUFFERED", "1")
            .stdout(Stdio::piped())
            .spawn()
            .expect("the Python agent starts");
        let out = child.stdout.take().expect("its stdout");
        let (tx, lines) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(out).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        PythonAgent {
            child,
            lines: Mutex::new((Vec::new(), lines)),
        }
    }

    /// Starts the agent and waits until the executive sees it offer `task`.
    async fn join(python: &Path, net: &Net, name: &str, task: &str) -> PythonAgent {
        PythonAgent::join_with(python, net, name, task, &[net.port]).await
    }

    /// As [`PythonAgent::join`], connected to `ports` (the executive's first).
    async fn join_with(
        python: &Path,
        net: &Net,
        name: &str,
        task: &str,
        ports: &[u16],
    ) -> PythonAgent {
        let agent = PythonAgent::spawn(python, &net.system, name, ports);
        agent.expect("ready", READY).await;
        net.exec
            .wait_for(name, Some(task), crate::util::JOIN)
            .await
            .expect("the executive sees the Python agent");
        agent
    }

    /// Waits until the agent printed a line that starts with `prefix` (now or before: lines of
    /// bodies running side by side come in any order), at most `timeout` (polling, so it can run
    /// on a runtime's worker).
    async fn expect(&self, prefix: &str, timeout: Duration) -> String {
        let start = Instant::now();
        loop {
            if let Some(line) = self.seen(prefix) {
                return line;
            }
            assert!(
                start.elapsed() < timeout,
                "no line {prefix:?} from the Python agent within {timeout:?}: {:?}",
                self.lines.lock().expect("lines").0
            );
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
    }

    /// The first line printed so far that starts with `prefix`.
    fn seen(&self, prefix: &str) -> Option<String> {
        let mut lines = self.lines.lock().expect("lines");
        loop {
            match lines.1.try_recv() {
                Ok(line) => lines.0.push(line),
                Err(mpsc::TryRecvError::Empty) => break,
                Err(mpsc::TryRecvError::Disconnected) => {
                    if !lines.0.iter().any(|l| l.starts_with(prefix)) {
                        panic!("the Python agent exited before {prefix:?}: {:?}", lines.0)
                    }
                    break;
                }
            }
        }
        lines.0.iter().find(|l| l.starts_with(prefix)).cloned()
    }

    /// How many lines printed so far start with `prefix`.
    fn count(&self, prefix: &str) -> usize {
        let _ = self.seen(prefix);
        let lines = self.lines.lock().expect("lines");
        lines.0.iter().filter(|l| l.starts_with(prefix)).count()
    }

    /// `kill -9`.
    fn kill(&mut self) {
        self.child.kill().expect("kill -9 the Python agent");
        self.child.wait().expect("reap the Python agent");
    }
}

impl Drop for PythonAgent {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_python_agent_serves_a_command_and_a_goal() {
    let Some(python) = python() else { return };
    bounded(async {
        let net = Net::new("py-serve").await;
        let agent = PythonAgent::join(&python, &net, "py", "add").await;
        let exec = net.exec.clone();
        let values: Arc<Mutex<Vec<Json>>> = Arc::default();
        let v = values.clone();
        let main = Task::goal("main", move |ctx| async move {
            let sum: Json = ctx
                .spawn(exec.remote("py", "add", [1.5, 2.0, 3.5]).task())
                .wait_value()
                .await?;
            let hello: Json = ctx
                .spawn(exec.remote(At::Any, "greet", "Xavier").goal().task())
                .wait_value()
                .await?;
            v.lock().expect("values").extend([sum, hello]);
            Ok(())
        });
        let (report, trace) = run_checked(Runtime::new(), main).await;
        assert!(report.is_clean(), "{report}");
        assert_eq!(
            *values.lock().expect("values"),
            [json!(7.0), json!("hello Xavier")]
        );
        agent.expect("start add", READY).await;
        agent.expect("start greet", READY).await;
        assert_order(
            &untimed(&trace),
            &["add handling completed", "greet handling completed"],
        );
        let placed = net.exec.placements();
        assert_eq!(placed.len(), 2);
        assert!(placed.iter().all(|p| p.agent == "py"), "{placed:?}");
        let stats = net.exec.stats();
        assert_eq!(
            (stats.succeeded, stats.duplicates, stats.late),
            (2, 0, 0),
            "{stats:?}"
        );
    })
    .await;
}

/// The Python test agent's `NoGrasp`, read on this side from its JSON value.
#[derive(Clone, Debug, PartialEq, Deserialize)]
struct NoGrasp {
    x: i32,
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_typed_python_exception_is_handled_by_the_trees_handler_of_its_ancestor() {
    let Some(python) = python() else { return };
    bounded(async {
        let net = Net::new("py-raise").await;
        let _agent = PythonAgent::join(&python, &net, "py", "grasp").await;
        let log = Log::default();
        let l = log.clone();
        let on_arm = Handler::new("on_arm", "ArmFailure", move |ctx| {
            let l = l.clone();
            async move {
                let e = tcm_zenoh::caught::<NoGrasp>(&ctx).expect("a NoGrasp, read from JSON");
                let f = ctx.failure().expect("in a handler");
                l.push(format!("{} {e:?}: {}", f.exception, f.message));
                Ok(())
            }
        });
        let l = log.clone();
        let on_remote = Handler::on::<RemoteError, _, _, _>("on_remote", move |ctx| {
            let l = l.clone();
            async move {
                let e = tcm_zenoh::caught::<RemoteError>(&ctx).expect("a RemoteError");
                l.push(e.message);
                Ok(())
            }
        });
        let exec = net.exec.clone();
        let main = Task::goal("main", move |ctx| async move {
            let grasp = ctx
                .spawn(exec.remote("py", "grasp", 41).task())
                .handler(on_arm)
                .start()?;
            ctx.spawn(exec.remote("py", "crash", ()).task())
                .handler(on_remote)
                .serial(grasp)
                .start()?;
            Ok(())
        });
        let (report, trace) = run_checked(Runtime::new(), main).await;
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        assert!(report.unhandled.is_empty(), "{report}");
        assert_eq!(
            handler_choices(&trace),
            ["on_arm<-NoGrasp", "on_remote<-RemoteError"]
        );
        assert_eq!(
            log.entries(),
            [
                "NoGrasp NoGrasp { x: 41 }: no grasp at 41",
                "crash raised KeyError: 'nothing here'",
            ]
        );
        assert_eq!(net.exec.stats().failed, 2);
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn terminating_a_python_body_cancels_it_and_runs_its_cleanup() {
    let Some(python) = python() else { return };
    bounded(async {
        let net = Net::new("py-cancel").await;
        let agent = Arc::new(PythonAgent::join(&python, &net, "py", "sleep").await);
        let exec = net.exec.clone();
        let a = agent.clone();
        let main = Task::goal("main", move |ctx| async move {
            ctx.hold_children(false)?;
            // An async body (cancelled at its await) and a plain function in a thread (told
            // through `ctx.cancelled`).
            let sleep = ctx
                .spawn(exec.remote("py", "sleep", 60_000).task())
                .start()?;
            let spin = ctx
                .spawn(exec.remote("py", "spin", 60_000).task())
                .start()?;
            a.expect("start sleep", READY).await;
            a.expect("start spin", READY).await;
            ctx.terminate(sleep)?;
            ctx.terminate(spin)?;
            Ok(())
        });
        let started = Instant::now();
        let (report, trace) = run_checked(Runtime::new(), main).await;
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        assert!(
            started.elapsed() < Duration::from_secs(30),
            "the bodies ran on"
        );
        let story = untimed(&trace);
        for task in ["sleep", "spin"] {
            assert_order(
                &story,
                &[
                    &format!("{task} handling active"),
                    &format!("{task} terminating"),
                    &format!("{task} terminated"),
                ],
            );
        }
        // The cleanup ran before the cancellation was confirmed, so before the node ended.
        agent.expect("cleanup sleep 60000", READY).await;
        agent.expect("cleanup spin 60000", READY).await;
        let stats = net.exec.stats();
        assert_eq!((stats.cancels, stats.cancelled), (2, 2), "{stats:?}");
    })
    .await;
}

/// A stranger linked with the Python agent forges the executive's `cancel`: the agent cannot tell
/// and cancels the body, but the executive, which sent no cancel, fails the node with
/// `RemoteCancelled` rather than make it a success.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_forged_cancel_to_a_python_agent_fails_the_node_with_remote_cancelled() {
    let Some(python) = python() else { return };
    bounded(async {
        let net = Net::new("py-forge").await;
        let stranger = Arc::new(Stranger::new().await);
        let agent = Arc::new(
            PythonAgent::join_with(&python, &net, "py", "sleep", &[net.port, stranger.port]).await,
        );
        let caught: Arc<Mutex<Option<RemoteCancelled>>> = Arc::default();
        let c = caught.clone();
        let on_cancelled = Handler::on::<RemoteError, _, _, _>("on_remote", move |ctx| {
            let c = c.clone();
            async move {
                *c.lock().expect("caught") = tcm_zenoh::caught::<RemoteCancelled>(&ctx);
                Ok(())
            }
        });
        let exec = net.exec.clone();
        let key = format!("tdl/{}/to-agent/py/{}", net.system, net.exec.id());
        let a = agent.clone();
        let main = Task::goal("main", move |ctx| async move {
            ctx.hold_children(false)?;
            let sleep = ctx
                .spawn(exec.remote("py", "sleep", 60_000).task())
                .handler(on_cancelled)
                .start()?;
            a.expect("start sleep", READY).await;
            // The start was message 1 of task 1; the forged cancel is number 2.
            stranger
                .forge(
                    key,
                    json!({"task": 1, "seq": 2, "body": {"kind": "cancel"}}),
                )
                .await;
            ctx.wait(sleep).await?;
            Ok(())
        });
        let (report, trace) = run_checked(Runtime::new(), main).await;
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        assert!(report.unhandled.is_empty(), "{report}");
        assert_eq!(handler_choices(&trace), ["on_remote<-RemoteCancelled"]);
        assert_eq!(
            *caught.lock().expect("caught"),
            Some(RemoteCancelled {
                agent: "py".into(),
                task: "sleep".into()
            })
        );
        agent.expect("cleanup sleep 60000", READY).await;
        let stats = net.exec.stats();
        assert_eq!(
            (
                stats.cancels,
                stats.cancelled,
                stats.succeeded,
                stats.failed
            ),
            (0, 0, 0, 1),
            "{stats:?}"
        );
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_python_agent_serves_over_mutual_tls() {
    let Some(python) = python() else { return };
    if Command::new("openssl").arg("version").output().is_err() {
        println!("skipped: openssl is not on PATH, so no certificates can be made");
        return;
    }
    bounded(async {
        let dir = crate::tls::scratch("py-tls");
        crate::tls::authority(&dir, "system");
        let exec_certs = crate::tls::certificate(&dir, "exec", "system");
        let py_certs = crate::tls::certificate(&dir, "py", "system");
        let system = crate::util::system("py-tls");
        let port = tcm_zenoh::config::free_port().expect("a port");
        let config = tcm_zenoh::config::loopback_tls_listen(port, &exec_certs).expect("config");
        let exec = tcm_zenoh::Executive::open(&system, config)
            .await
            .expect("the executive opens");
        let net = Net { exec, port, system };
        let agent = PythonAgent::spawn_with(&python, &net.system, "py", &[port], Some(&py_certs));
        agent.expect("ready", READY).await;
        net.exec
            .wait_for("py", Some("add"), crate::util::JOIN)
            .await
            .expect("the executive sees the Python agent over TLS");
        let exec = net.exec.clone();
        let main = Task::goal("main", move |ctx| async move {
            let sum: Json = ctx
                .spawn(exec.remote("py", "add", [1.5, 2.0]).task())
                .wait_value()
                .await?;
            assert_eq!(sum, json!(3.5));
            Ok(())
        });
        let (report, _) = run_checked(Runtime::new(), main).await;
        assert!(report.is_clean(), "{report}");
        agent.expect("start add", READY).await;
        drop(agent);
        net.exec.close().await;
        let _ = std::fs::remove_dir_all(&dir);
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn killing_the_python_agent_mid_task_raises_agent_lost() {
    let Some(python) = python() else { return };
    bounded(async {
        let net = Net::new("py-kill").await;
        let agent = PythonAgent::join(&python, &net, "py", "sleep").await;
        let exec = net.exec.clone();
        let lost: Arc<Mutex<Option<(Instant, AgentLost)>>> = Arc::default();
        let killed: Arc<Mutex<Option<Instant>>> = Arc::default();
        let (lost2, killed2) = (lost.clone(), killed.clone());
        let main = Task::goal("main", move |ctx| async move {
            ctx.hold_children(false)?;
            let on_lost = Handler::on::<AgentLost, _, _, _>("on_lost", move |ctx| {
                let lost = lost2.clone();
                async move {
                    let e = tcm_zenoh::caught::<AgentLost>(&ctx).expect("an AgentLost");
                    *lost.lock().expect("lost") = Some((Instant::now(), e));
                    Ok(())
                }
            });
            let sleeper = ctx
                .spawn(exec.remote("py", "sleep", 60_000).task())
                .handler(on_lost)
                .start()?;
            let mut agent = agent;
            agent.expect("start sleep", READY).await;
            *killed2.lock().expect("killed") = Some(Instant::now());
            agent.kill();
            ctx.wait(sleeper).await?;
            Ok(())
        });
        let (report, trace) = run_checked(Runtime::new(), main).await;
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        assert!(report.unhandled.is_empty(), "{report}");
        let killed = killed
            .lock()
            .expect("killed")
            .expect("the agent was killed");
        let (at, e) = lost
            .lock()
            .expect("lost")
            .clone()
            .expect("AgentLost was handled");
        assert_eq!(
            e,
            AgentLost {
                agent: "py".into(),
                task: "sleep".into()
            }
        );
        let after = at.duration_since(killed);
        eprintln!("AgentLost handled {after:?} after kill -9 of the Python agent");
        assert!(
            after <= Duration::from_secs(2),
            "AgentLost {after:?} after the kill"
        );
        assert_eq!(handler_choices(&trace), ["on_lost<-AgentLost"]);
        assert_eq!(net.exec.stats().agent_lost, 1);
    })
    .await;
}

/// An executive that comes back (docs/distributed.md, "An executive that comes back") to a
/// Python agent with a hold: the executive journals its run and dies while the Python body runs;
/// a new executive under the same id resumes the run and re-attaches. A body still running ends
/// the node on time, a body that ended while the executive was away gives its kept end; either
/// way the body ran once and was not cleaned up.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_python_agent_with_a_hold_is_reattached_by_an_executive_that_comes_back() {
    use crate::resume::{Command, Crash, crash_and_resume_on};
    let Some(python) = python() else { return };
    bounded(async {
        for (ms, after, dead_for) in [(3_000u32, 300, 300), (500, 100, 1_500)] {
            let system = crate::util::system("py-resume");
            let port = tcm_zenoh::config::free_port().expect("port");
            let env = [
                ("TDL_AGENT_LISTEN", port.to_string()),
                ("TDL_AGENT_HOLD", "20".into()),
            ];
            let agent = PythonAgent::spawn_env(&python, &system, "py", &[], &env);
            agent.expect("ready", READY).await;
            let command = Command {
                agent: "py",
                task: "sleep",
                args: json!(ms),
                value: ms,
            };
            let crash = Crash {
                after: Duration::from_millis(after),
                dead_for: Duration::from_millis(dead_for),
            };
            let started = || agent.seen("start sleep").is_some();
            let (report, events) =
                crash_and_resume_on(&system, port, command, crash, started).await;
            tcm::testing::assert_checked(&events);
            assert!(report.is_clean(), "a body of {ms} ms: {report}");
            assert_eq!(agent.count("start sleep"), 1, "a body of {ms} ms ran once");
            assert_eq!(
                agent.count("cleanup sleep"),
                0,
                "a body of {ms} ms was not cleaned up"
            );
        }
    })
    .await;
}

#[test]
fn the_python_modules_unit_tests_pass() {
    let Some(python) = python() else { return };
    let mut child = Command::new(python)
        .args(["-m", "unittest", "discover", "-s"])
        .arg(repo().join("python/tests"))
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("python runs");
    let start = Instant::now();
    while child.try_wait().expect("the unit tests run").is_none() {
        if start.elapsed() > crate::util::BOUND {
            let _ = child.kill();
            panic!(
                "the Python unit tests did not end within {:?}",
                crate::util::BOUND
            );
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let out = child.wait_with_output().expect("their output");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "the Python unit tests failed:\n{}{err}",
        String::from_utf8_lossy(&out.stdout)
    );
    // unittest reports on stderr: "Ran N tests", then "OK".
    assert!(err.contains("\nOK"), "{err}");
}

/// A Python body sets a state variable of the executive's run; a step waits on a condition over
/// it (docs/semantics.md, "State and conditions").
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_python_body_sets_a_state_variable_a_condition_waits_on() {
    let Some(python) = python() else { return };
    bounded(async {
        let net = Net::new("py-state").await;
        let agent = PythonAgent::join(&python, &net, "py", "sense").await;
        let exec = net.exec.clone();
        let battery = tcm::StateVar::new("battery", tcm::StateType::Float, 50.0);
        let rt = Runtime::new().state(battery.clone());
        let main = Task::goal("main", move |ctx| async move {
            let charged = ctx.condition(
                &[battery],
                tcm::Expr::bin(
                    tcm::BinOp::Gt,
                    tcm::Expr::var("battery"),
                    tcm::Expr::lit(80.0),
                ),
            )?;
            ctx.spawn(exec.remote("py", "sense", [20.0, 90.0]).task())
                .start()?;
            ctx.spawn(Task::command("drive", |_| async { Ok(()) }))
                .with(tcm::Constraint::disable(
                    tcm::Facet::Handling,
                    tcm::When::Condition(charged),
                ))
                .start()?;
            Ok(())
        });
        let (report, trace) = run_checked(rt, main).await;
        assert!(report.is_clean(), "{report}");
        agent.expect("start sense", READY).await;
        let story = untimed(&trace);
        assert_eq!(
            tcm::testing::only(&story, &["set battery"]),
            ["set battery = 20.0", "set battery = 90.0"]
        );
        assert_order(&story, &["set battery = 90.0", "drive handling active"]);
    })
    .await;
}
