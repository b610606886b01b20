//! Figures of a serving executive (docs/distributed.md, "A serving executive"), each beside a
//! baseline measured in the same run:
//!
//! 1. Load-to-start: a client loads a new version of a 100-task program and starts its root task;
//!    the time from sending the load to the start's answer, against a bare zenoh query's round
//!    trip on the same link.
//! 2. Churn beside a 1 kHz monitor: a run whose monitor is activated every millisecond, 2,000
//!    times, while a client loads and unloads a program of handlers 100 times; the monitor's
//!    activations and the run's length, against the same run with no churn.
//!
//! `cargo run --release -p tdl-serve --example serve_bench`

use std::time::{Duration, Instant};

use tdl_interp::Registry;
use tdl_serve::{Client, File, Reply, Request, Response, Server, Swap};

fn hundred_tasks(version: u32) -> String {
    let mut text = format!("// version {version}\npub goal root() {{\n");
    for i in 1..100 {
        text.push_str(&format!("    spawn t{i}();\n"));
    }
    text.push_str("}\n");
    for i in 1..100 {
        text.push_str(&format!("goal t{i}() {{\n}}\n"));
    }
    text
}

const TICKING: &str = "\
pub goal ticking() {
    spawn tick();
}

monitor tick() with period 1ms, maximum activate 2000 {
}
";

const HANDLERS: &str = "\
exception Jammed;
extern goal tick_body();

handler clear() handles Jammed for tick_body {
}
";

async fn ask(client: &Client, request: Request) -> Reply {
    for _ in 0..50 {
        match client.request("main", &request).await {
            Ok(Response::Ok(r)) => return r,
            Ok(Response::Refused(why)) => panic!("refused: {why}"),
            Err(tdl_serve::Error::NoAnswer { .. }) => continue,
            Err(e) => panic!("{e}"),
        }
    }
    panic!("no answer")
}

fn median(mut v: Vec<Duration>) -> Duration {
    v.sort();
    v[v.len() / 2]
}

async fn run_ticking(client: &Client, dir: &std::path::Path, churn: bool) -> (usize, String) {
    let run = match ask(
        client,
        Request::Start {
            program: "ticking".into(),
            task: None,
            args: serde_json::Value::Null,
        },
    )
    .await
    {
        Reply::Started { run, .. } => run,
        other => panic!("{other:?}"),
    };
    if churn {
        for i in 0..100 {
            let files = vec![File {
                name: "handlers.tdl".into(),
                text: format!("{HANDLERS}// {i}\n"),
            }];
            ask(
                client,
                Request::Load {
                    name: "handlers".into(),
                    files,
                    swap: Swap::Spawns,
                    verify: None,
                },
            )
            .await;
            ask(
                client,
                Request::Unload {
                    name: "handlers".into(),
                },
            )
            .await;
        }
    }
    let outcome = loop {
        match ask(client, Request::Status { run: Some(run) }).await {
            Reply::Runs(r) if r[0].outcome.is_some() => {
                break r[0].outcome.clone().unwrap_or_default();
            }
            _ => tokio::time::sleep(Duration::from_millis(20)).await,
        }
    };
    let text = std::fs::read_to_string(dir.join(format!("run-{run}.jsonl"))).unwrap_or_default();
    let activations = text.matches("\"ev\":\"activated\"").count();
    (activations, outcome)
}

#[tokio::main(flavor = "multi_thread", worker_threads = 2)]
async fn main() -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
    let (exec, port) = tcm_zenoh::Executive::open_loopback("bench").await?;
    let dir = std::env::temp_dir().join(format!("tdl-serve-bench-{}", std::process::id()));
    let server = Server::new(Registry::new(), Some(exec.clone()), &dir);
    let _serving = tdl_serve::serve(server, exec.session(), "bench", "main").await?;
    // A bare queryable beside it: the baseline round trip.
    let echo = exec.session().declare_queryable("bench/echo").await?;
    tokio::spawn(async move {
        while let Ok(q) = echo.recv_async().await {
            let _ = q.reply("bench/echo", b"ok".to_vec()).await;
        }
    });
    let client = Client::open("bench", "bench", tcm_zenoh::config::loopback_connect(port)?).await?;
    let bare = zenoh::open(tcm_zenoh::config::loopback_connect(port)?).await?;
    ask(&client, Request::List).await;

    let (mut load_start, mut round_trip) = (Vec::new(), Vec::new());
    for v in 0..30 {
        let t = Instant::now();
        let replies = bare
            .get("bench/echo")
            .timeout(Duration::from_secs(5))
            .await?;
        let _ = replies.recv_async().await;
        round_trip.push(t.elapsed());
        let files = vec![File {
            name: "hundred.tdl".into(),
            text: hundred_tasks(v),
        }];
        let t = Instant::now();
        ask(
            &client,
            Request::Load {
                name: "hundred".into(),
                files,
                swap: Swap::Spawns,
                verify: None,
            },
        )
        .await;
        ask(
            &client,
            Request::Start {
                program: "hundred".into(),
                task: Some("root".into()),
                args: serde_json::Value::Null,
            },
        )
        .await;
        load_start.push(t.elapsed());
    }
    let (ls, rt) = (median(load_start), median(round_trip));
    println!("load-to-start of a 100-task program, median of 30: {ls:?} (target < 50 ms)");
    println!(
        "  a bare zenoh query's round trip on the same link: {rt:?}; ratio {:.1}",
        ls.as_secs_f64() / rt.as_secs_f64()
    );

    ask(
        &client,
        Request::Load {
            name: "ticking".into(),
            files: vec![File {
                name: "ticking.tdl".into(),
                text: TICKING.into(),
            }],
            swap: Swap::Spawns,
            verify: None,
        },
    )
    .await;
    let (quiet, quiet_outcome) = run_ticking(&client, &dir, false).await;
    let (busy, busy_outcome) = run_ticking(&client, &dir, true).await;
    println!("a 1 kHz monitor, 2,000 activations:");
    println!("  alone: {quiet} activations, {quiet_outcome}");
    println!("  beside 100 loads and unloads of handlers: {busy} activations, {busy_outcome}");
    client.close().await;
    exec.close().await;
    let _ = std::fs::remove_dir_all(&dir);
    Ok(())
}
