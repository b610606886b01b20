//! Agent loss: when an agent's liveliness token goes (its process was killed, or it left), each
//! remote task running there fails with `AgentLost` within the bound, handled like any failure,
//! and the executive goes on; an agent that comes back under the same name is used again.

use crate::util::{Log, Net, bounded, untimed};
use serde_json::json;
use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex, mpsc};
use std::time::{Duration, Instant};
use tcm::testing::{assert_order, handler_choices, run_checked};
use tcm::{Handler, RunOutcome, Runtime, Task};
use tcm_zenoh::{AgentLost, Json, RemoteCtx, RemoteFailure};

/// The bound the issue sets: at most 2 s from the loss to the failure.
const LOSS_BOUND: Duration = Duration::from_secs(2);

/// An agent process (`tcm-zenoh-agent`) and the lines it prints.
struct AgentProcess {
    child: Child,
    // In a mutex: awaited across (`expect`), the process must be `Sync`.
    lines: Mutex<mpsc::Receiver<String>>,
}

impl AgentProcess {
    fn spawn(system: &str, name: &str, port: u16) -> AgentProcess {
        let mut child = Command::new(env!("CARGO_BIN_EXE_tcm-zenoh-agent"))
            .args([system, name, &port.to_string()])
            .stdout(Stdio::piped())
            .spawn()
            .expect("the agent process starts");
        let out = child.stdout.take().expect("its stdout");
        let (tx, lines) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(out).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        AgentProcess {
            child,
            lines: Mutex::new(lines),
        }
    }

    /// Waits for a line that starts with `prefix`, at most `timeout` (polling, so it can run on a
    /// runtime's worker).
    async fn expect(&self, prefix: &str, timeout: Duration) -> String {
        let start = Instant::now();
        loop {
            let next = self.lines.lock().expect("lines").try_recv();
            match next {
                Ok(line) if line.starts_with(prefix) => return line,
                Ok(_) => {}
                Err(mpsc::TryRecvError::Empty) => {
                    assert!(
                        start.elapsed() < timeout,
                        "no line {prefix:?} within {timeout:?}"
                    );
                    tokio::time::sleep(Duration::from_millis(5)).await;
                }
                Err(mpsc::TryRecvError::Disconnected) => {
                    panic!("the agent exited before {prefix:?}")
                }
            }
        }
    }

    /// `kill -9`.
    fn kill(&mut self) {
        self.child.kill().expect("kill -9 the agent");
        self.child.wait().expect("reap the agent");
    }
}

impl Drop for AgentProcess {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn killing_an_agent_process_mid_task_raises_agent_lost_within_the_bound() {
    bounded(async {
        let net = Net::new("kill").await;
        let first = AgentProcess::spawn(&net.system, "proc", net.port);
        first.expect("ready", Duration::from_secs(30)).await;
        net.exec
            .wait_for("proc", Some("sleep"), crate::util::JOIN)
            .await
            .expect("the executive sees the agent process");
        let system = net.system.clone();
        let port = net.port;
        let exec = net.exec.clone();
        let lost_at: Arc<Mutex<Option<(Instant, AgentLost)>>> = Arc::default();
        let killed_at: Arc<Mutex<Option<Instant>>> = Arc::default();
        let log = Log::default();
        let (lost, killed, l) = (lost_at.clone(), killed_at.clone(), log.clone());
        let main = Task::goal("main", move |ctx| async move {
            ctx.hold_children(false)?;
            let handler = Handler::on::<AgentLost, _, _, _>("on_lost", move |ctx| {
                let lost = lost.clone();
                async move {
                    let e = tcm_zenoh::caught::<AgentLost>(&ctx).expect("an AgentLost");
                    *lost.lock().expect("lost") = Some((Instant::now(), e));
                    Ok(())
                }
            });
            let sleeper = ctx
                .spawn(exec.remote("proc", "sleep", 60_000).task())
                .handler(handler)
                .start()?;
            let mut first = first;
            first.expect("start sleep", Duration::from_secs(10)).await;
            *killed.lock().expect("killed") = Some(Instant::now());
            first.kill();
            ctx.wait(sleeper).await?;
            l.push("went on");
            // The agent comes back under the same name, and is used again.
            let second = AgentProcess::spawn(&system, "proc", port);
            second.expect("ready", Duration::from_secs(30)).await;
            exec.wait_for("proc", Some("echo"), crate::util::JOIN)
                .await
                .map_err(tcm::Failure::from)?;
            let v: Json = ctx
                .spawn(exec.remote("proc", "echo", json!({"again": true})).task())
                .wait_value()
                .await?;
            l.push(format!("echo {v}"));
            drop(second);
            Ok(())
        });
        let (report, trace) = run_checked(Runtime::new(), main).await;
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        assert!(report.unhandled.is_empty(), "{report}");
        let killed = killed_at
            .lock()
            .expect("killed")
            .expect("the agent was killed");
        let (at, e) = lost_at
            .lock()
            .expect("lost")
            .clone()
            .expect("AgentLost was handled");
        assert_eq!(
            e,
            AgentLost {
                agent: "proc".into(),
                task: "sleep".into()
            }
        );
        let after = at.duration_since(killed);
        eprintln!("AgentLost handled {after:?} after kill -9");
        assert!(after <= LOSS_BOUND, "AgentLost {after:?} after the kill");
        assert_eq!(handler_choices(&trace), ["on_lost<-AgentLost"]);
        assert_order(
            &untimed(&trace),
            &[
                "sleep handling active",
                "sleep failed AgentLost",
                "on_lost handling completed",
                "echo handling completed",
            ],
        );
        assert_eq!(log.entries(), ["went on", r#"echo {"again":true}"#]);
        assert_eq!(net.exec.stats().agent_lost, 1);
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_agent_that_leaves_fails_its_tasks_and_one_that_comes_back_is_used_again() {
    bounded(async {
        let net = Net::new("leave").await;
        let log = Log::default();
        let builder = |log: Log| {
            net.agent("worker")
                .command("work", move |_: RemoteCtx, ms: u64| {
                    let log = log.clone();
                    async move {
                        log.push(format!("work {ms}"));
                        tokio::time::sleep(Duration::from_millis(ms)).await;
                        Ok::<_, RemoteFailure>(ms)
                    }
                })
        };
        let worker = net.join(builder(log.clone()), "worker").await;
        let exec = net.exec.clone();
        let watch = log.clone();
        let config = tcm_zenoh::config::loopback_connect(net.port).expect("config");
        let again = builder(log.clone());
        let main = Task::goal("main", move |ctx| async move {
            // The body waits for how `work` ends while the agent leaves under it.
            let leave = async {
                watch.wait_for("work 60000", Duration::from_secs(10)).await;
                let left = Instant::now();
                worker.close().await;
                left
            };
            let wait = ctx
                .spawn(exec.remote("worker", "work", 60_000).task())
                .wait_outcome::<Json>();
            let (ended, left) = tokio::join!(wait, leave);
            assert!(
                left.elapsed() <= LOSS_BOUND,
                "failed {:?} after the loss",
                left.elapsed()
            );
            let failure = ended?.failure().cloned().expect("work failed");
            assert_eq!(failure.exception, "AgentLost");
            assert!(failure.is_a("RemoteError"));
            let _back = again.start(config).await.map_err(tcm::Failure::from)?;
            exec.wait_for("worker", Some("work"), crate::util::JOIN)
                .await
                .map_err(tcm::Failure::from)?;
            let v: Json = ctx
                .spawn(exec.remote("worker", "work", 5).task())
                .wait_value()
                .await?;
            assert_eq!(v, json!(5));
            Ok(())
        });
        let (report, trace) = run_checked(Runtime::new(), main).await;
        assert!(report.is_clean(), "{report}");
        assert_order(
            &untimed(&trace),
            &["work failed AgentLost", "work handling completed"],
        );
        assert_eq!(log.entries(), ["work 60000", "work 5"]);
    })
    .await;
}
