//! A property test of adversarial message sequences (docs/distributed.md, "Exactly once"): the
//! agent a remote task runs on is played by hand and sends its real messages in order, while
//! forged ones are mixed in before and after each (replays of numbers already used, with other
//! bodies; jumps past the next number, up to 2^64-1; kinds nobody sends; bytes that do not read;
//! the next number, sent as another agent; messages of tasks never placed). In every case the
//! node's outcome is the one the real agent caused: its value, or its typed failure.
//!
//! The cases are drawn from seeded generators (a failing case prints its seed; `ADVERSARY_SEED`
//! runs that one alone), not with proptest: no dependency is added for it.

use crate::util::{JOIN, Net, bounded};
use serde_json::{Value, json};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tcm::testing::run_checked;
use tcm::{Ended, RunOutcome, Runtime, Task};
use tcm_zenoh::{Json, RemoteFailure};
use zenoh::qos::CongestionControl;

/// How many cases run.
const CASES: u64 = 16;

/// splitmix64: a small, seeded, well-mixed generator.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
}

/// What the real agent does: heartbeats, then a value or a typed failure.
#[derive(Debug)]
struct Script {
    heartbeats: u64,
    end: Result<i64, String>,
}

/// One message as sent: where (as which agent) and what.
#[derive(Debug)]
enum Put {
    As(&'static str, Value),
    Bytes(Vec<u8>),
}

/// The body of a message an agent sends, forged or real.
fn forged_body(rng: &mut Rng) -> Value {
    match rng.below(6) {
        0 => json!({"kind": "started"}),
        1 => json!({"kind": "heartbeat"}),
        2 => json!({"kind": "done", "result": {"Ok": 666}}),
        3 => {
            json!({"kind": "done", "result": {"Err": {"exception": "Forged", "message": "forged"}}})
        }
        4 => json!({"kind": "cancelled"}),
        _ => json!({"kind": "call", "call": 1, "op": {"op": "raise", "event": "forged"}}),
    }
}

/// The forged messages to mix in when the real agent's last number is `last`, for task `task`.
fn forgeries(rng: &mut Rng, task: u64, last: u64) -> Vec<Put> {
    let mut out = Vec::new();
    for _ in 0..rng.below(4) {
        let put = match rng.below(6) {
            // A replay of a number already used, with any body.
            0 if last > 0 => Put::As(
                "arm",
                json!({"task": task, "seq": 1 + rng.below(last), "body": forged_body(rng)}),
            ),
            // A jump past the next number.
            1 | 0 => {
                let seq = match rng.below(3) {
                    0 => u64::MAX,
                    _ => last + 2 + rng.below(5),
                };
                Put::As(
                    "arm",
                    json!({"task": task, "seq": seq, "body": forged_body(rng)}),
                )
            }
            // A kind nobody sends, numbered next: it must not take the number.
            2 => Put::As(
                "arm",
                json!({"task": task, "seq": last + 1, "body": {"kind": "bogus"}}),
            ),
            // Bytes that do not read.
            3 => Put::Bytes(match rng.below(3) {
                0 => b"{\"task\":".to_vec(),
                1 => vec![b'['; 1000],
                _ => format!("{{\"task\":{task},\"seq\":{},\"body\":7}}", last + 1).into_bytes(),
            }),
            // The next number, as another agent.
            4 => Put::As(
                "ghost",
                json!({"task": task, "seq": last + 1, "body": forged_body(rng)}),
            ),
            // A task never placed.
            _ => Put::As(
                "arm",
                json!({"task": task + 1000 + rng.below(1000), "seq": 1 + rng.below(3),
                       "body": forged_body(rng)}),
            ),
        };
        out.push(put);
    }
    out
}

/// Runs case `seed`: the real agent's script, with forgeries around every message.
async fn case(seed: u64) {
    let mut rng = Rng(seed);
    let script = Script {
        heartbeats: rng.below(3),
        end: if rng.below(2) == 0 {
            Ok(rng.below(1000) as i64)
        } else {
            Err(format!("failure {}", rng.below(1000)))
        },
    };
    let net = Net::new("adversary").await;
    let sys = net.system.clone();
    let peer = zenoh::open(tcm_zenoh::config::loopback_connect(net.port).expect("config"))
        .await
        .expect("the agent's session");
    let inbox = peer
        .declare_subscriber(format!("tdl/{sys}/to-agent/arm/*"))
        .await
        .expect("an inbox");
    let _offer = peer
        .liveliness()
        .declare_token(format!("tdl/{sys}/offers/work/arm"))
        .await
        .expect("a token");
    let _token = peer
        .liveliness()
        .declare_token(format!("tdl/{sys}/agents/arm"))
        .await
        .expect("a token");
    net.exec
        .wait_for("arm", Some("work"), JOIN)
        .await
        .expect("the executive sees the agent");
    let exec = net.exec.clone();
    let outcome: Arc<Mutex<Option<Ended<Json>>>> = Arc::default();
    let o = outcome.clone();
    let run = tokio::spawn(async move {
        let main = Task::goal("main", move |ctx| async move {
            let ended = ctx
                .spawn(exec.remote("arm", "work", ()).task())
                .wait_outcome::<Json>()
                .await?;
            *o.lock().expect("outcome") = Some(ended);
            Ok(())
        });
        run_checked(Runtime::new(), main).await
    });
    let start = tokio::time::timeout(JOIN, inbox.recv_async())
        .await
        .expect("a start within the bound")
        .expect("a start");
    let start: Value = serde_json::from_slice(&start.payload().to_bytes()).expect("JSON");
    let task = start["task"].as_u64().expect("a task id");
    let key = |who: &str| format!("tdl/{sys}/to-exec/{}/{who}", net.exec.id());
    let arm = peer
        .declare_publisher(key("arm"))
        .congestion_control(CongestionControl::Block)
        .await
        .expect("a publisher");
    let ghost = peer
        .declare_publisher(key("ghost"))
        .congestion_control(CongestionControl::Block)
        .await
        .expect("a publisher");
    let mut real = vec![json!({"kind": "started"})];
    real.extend((0..script.heartbeats).map(|_| json!({"kind": "heartbeat"})));
    real.push(match &script.end {
        Ok(v) => json!({"kind": "done", "result": {"Ok": v}}),
        Err(m) => json!({"kind": "done", "result": {"Err": {"exception": "Real", "message": m}}}),
    });
    let mut sent = Vec::new();
    for (i, body) in real.into_iter().enumerate() {
        let last = i as u64;
        let mut puts = forgeries(&mut rng, task, last);
        puts.push(Put::As(
            "arm",
            json!({"task": task, "seq": last + 1, "body": body}),
        ));
        puts.extend(forgeries(&mut rng, task, last + 1));
        for put in puts {
            let (p, bytes) = match &put {
                Put::As("ghost", v) => (&ghost, serde_json::to_vec(v).expect("JSON")),
                Put::As(_, v) => (&arm, serde_json::to_vec(v).expect("JSON")),
                Put::Bytes(b) => (&arm, b.clone()),
            };
            p.put(bytes).await.expect("a put");
            sent.push(put);
        }
    }
    let (report, _trace) = tokio::time::timeout(JOIN, run)
        .await
        .unwrap_or_else(|_| panic!("seed {seed}: the run did not end; sent {sent:#?}"))
        .expect("the run");
    assert_eq!(
        report.outcome,
        RunOutcome::Completed,
        "seed {seed}: {report}"
    );
    let ended = outcome
        .lock()
        .expect("outcome")
        .take()
        .unwrap_or_else(|| panic!("seed {seed}: no outcome: {report}"));
    match (&script.end, &ended) {
        (Ok(v), Ended::Succeeded(got)) => {
            assert_eq!(*got, json!(v), "seed {seed}: {script:?}, sent {sent:#?}")
        }
        (Err(m), Ended::Failed(f)) => {
            let r = f.data::<RemoteFailure>();
            assert_eq!(
                r.map(|r| (r.exception.clone(), r.message.clone())),
                Some(("Real".to_string(), m.clone())),
                "seed {seed}: {script:?}, sent {sent:#?}"
            );
        }
        _ => panic!("seed {seed}: {script:?} ended {ended:?}; sent {sent:#?}"),
    }
    let stats = net.exec.stats();
    assert_eq!(
        (stats.placed, stats.succeeded + stats.failed),
        (1, 1),
        "seed {seed}: {stats:?}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_node_ends_as_the_real_agent_said_whatever_is_mixed_in() {
    bounded(async {
        let seeds: Vec<u64> = match std::env::var("ADVERSARY_SEED") {
            Ok(s) => vec![s.parse().expect("a seed")],
            Err(_) => (0..CASES).collect(),
        };
        for seed in seeds {
            case(seed).await;
            tokio::time::sleep(Duration::from_millis(1)).await;
        }
    })
    .await;
}
