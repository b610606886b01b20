//! Benchmark of remote tasks on loopback: the round trip of a remote no-op command (from its spawn
//! to the completion of its execution, seen by the parent that waits for it), beside a bare zenoh
//! query round trip between the same two sessions and a local no-op command, measured in the same
//! run (each series alone, then the two alternately, which exposes both to the same load on a
//! small machine); then the throughput of many remote no-op commands in flight at once.
//!
//! `cargo run --release -p tcm-zenoh --example round_trip [-- <round trips> <in flight>]`
//! (defaults 2000 and 20000). The executive and the agent are two zenoh sessions of this process
//! (peer mode, 127.0.0.1, multicast scouting off). With `--tls <dir>`, they are linked by mutual
//! TLS (docs/distributed.md, "Mutual TLS"), with the certificates of `<dir>`: `authority.pem`,
//! `exec.pem` and `exec.key`, `agent.pem` and `agent.key` (the bare query goes over the same
//! link).

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tcm::{Runtime, Task};
use tcm_zenoh::{Agent, Executive, RemoteCtx, RemoteFailure};

type Error = Box<dyn std::error::Error + Send + Sync>;

/// p50 and p99 of `samples`, in microseconds.
fn percentiles(mut samples: Vec<Duration>) -> (f64, f64) {
    samples.sort();
    let at = |q: f64| {
        let i = ((samples.len() as f64 - 1.0) * q).round() as usize;
        samples[i].as_secs_f64() * 1e6
    };
    (at(0.50), at(0.99))
}

/// A goal that spawns `make()` `n` times in a row, waiting for each, and keeps each round trip.
fn rounds(n: usize, make: impl Fn() -> Task + Send + 'static) -> (Task, Arc<Mutex<Vec<Duration>>>) {
    let samples = Arc::new(Mutex::new(Vec::with_capacity(n)));
    let keep = samples.clone();
    let task = Task::goal("rounds", move |ctx| async move {
        for _ in 0..n {
            let t0 = Instant::now();
            ctx.spawn(make()).wait().await?;
            let dt = t0.elapsed();
            keep.lock()
                .map_err(|_| tcm::Failure::new("Poisoned", "samples"))?
                .push(dt);
        }
        Ok(())
    });
    (task, samples)
}

#[tokio::main(flavor = "multi_thread", worker_threads = 2)]
async fn main() -> Result<(), Error> {
    // Warnings (zenoh's and this crate's) to stderr, filtered by RUST_LOG.
    tcm_zenoh::log_to_stderr();
    let argv: Vec<String> = std::env::args().skip(1).collect();
    let tls = argv
        .iter()
        .position(|a| a == "--tls")
        .map(|i| argv.get(i + 1).map(std::path::PathBuf::from))
        .map(|d| d.ok_or("--tls needs a directory"))
        .transpose()?;
    let args: Vec<usize> = argv.iter().filter_map(|a| a.parse().ok()).collect();
    let n = args.first().copied().unwrap_or(2000);
    let in_flight = args.get(1).copied().unwrap_or(20_000);

    let builder = Agent::builder("bench", "agent").command("noop", |_: RemoteCtx, (): ()| async {
        Ok::<_, RemoteFailure>(())
    });
    let (exec, agent) = match &tls {
        None => {
            let (exec, port) = Executive::open_loopback("bench").await?;
            let agent = builder
                .start(tcm_zenoh::config::loopback_connect(port)?)
                .await?;
            (exec, agent)
        }
        Some(dir) => {
            use tcm_zenoh::config::{Certs, free_port, loopback_tls_connect, loopback_tls_listen};
            let certs = |who: &str| Certs {
                authority: dir.join("authority.pem"),
                certificate: dir.join(format!("{who}.pem")),
                key: dir.join(format!("{who}.key")),
            };
            let port = free_port()?;
            let exec = Executive::open("bench", loopback_tls_listen(port, &certs("exec"))?).await?;
            let agent = builder
                .start(loopback_tls_connect(port, &certs("agent"))?)
                .await?;
            println!("over mutual TLS");
            (exec, agent)
        }
    };
    exec.wait_for("agent", Some("noop"), Duration::from_secs(10))
        .await?;
    let _echo = agent
        .session()
        .declare_queryable("bench/echo")
        .callback(|query| {
            use zenoh::Wait;
            let payload = query
                .payload()
                .map(|p| p.to_bytes().into_owned())
                .unwrap_or_default();
            if let Err(e) = query.reply(query.key_expr().clone(), payload).wait() {
                eprintln!("reply: {e}");
            }
        })
        .await?;

    // Bare zenoh: a query with a payload of the size of a start message, and its reply.
    let payload = br#"{"task":1,"seq":1,"body":{"kind":"start","node":3,"name":"noop","task_kind":"command","args":null}}"#.to_vec();
    let session = exec.session().clone();
    let bare = move || {
        let session = session.clone();
        let payload = payload.clone();
        async move {
            let t0 = Instant::now();
            let replies = session
                .get("bench/echo")
                .payload(payload)
                .await
                .map_err(|e| tcm::Failure::new("Zenoh", e.to_string()))?;
            let mut n = 0;
            while let Ok(reply) = replies.recv_async().await {
                if reply.result().is_err() {
                    return Err(tcm::Failure::new("Zenoh", "error reply"));
                }
                n += 1;
            }
            if n != 1 {
                return Err(tcm::Failure::new("Zenoh", format!("{n} replies")));
            }
            Ok(t0.elapsed())
        }
    };

    // The queryable's declaration reaches the executive's session shortly after it is made.
    let t0 = Instant::now();
    while bare().await.is_err() {
        if t0.elapsed() > Duration::from_secs(10) {
            return Err("the echo queryable is not reachable".into());
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }

    // Each alone first: `n` bare queries in a row, then `n` remote no-op commands in a row.
    let mut bare_alone = Vec::with_capacity(n);
    for i in 0..n + 200 {
        let dt = bare().await.map_err(|f| f.to_string())?;
        if i >= 200 {
            bare_alone.push(dt);
        }
    }
    let alone_exec = exec.clone();
    let (task, remote_alone) = rounds(n + 200, move || {
        alone_exec.remote("agent", "noop", ()).task()
    });
    Runtime::new().run(task).await?;
    let remote_alone: Vec<Duration> = remote_alone
        .lock()
        .map(|v| v.iter().skip(200).copied().collect())
        .unwrap_or_default();

    // A local no-op command: the runtime's own share of a round trip.
    let (task, local) = rounds(n, || Task::command("noop", |_| async { Ok(()) }));
    Runtime::new().run(task).await?;

    // The bare query and the remote no-op command, alternately, from one action, so that both
    // see the same machine: warm-up rounds first, then `n` of each.
    let remote_exec = exec.clone();
    let samples: Arc<Mutex<(Vec<Duration>, Vec<Duration>)>> = Arc::default();
    let keep = samples.clone();
    let alternate = Task::goal("alternate", move |ctx| async move {
        for i in 0..n + 200 {
            let b = bare().await?;
            let t0 = Instant::now();
            ctx.spawn(remote_exec.remote("agent", "noop", ()).task())
                .wait()
                .await?;
            let r = t0.elapsed();
            if i >= 200 {
                let mut s = keep
                    .lock()
                    .map_err(|_| tcm::Failure::new("Poisoned", "samples"))?;
                s.0.push(b);
                s.1.push(r);
            }
        }
        Ok(())
    });
    let report = Runtime::new().run(alternate).await?;
    if !report.is_clean() {
        return Err(format!("the remote rounds did not run cleanly: {report}").into());
    }
    let (bare_samples, remote_samples) = samples.lock().map(|s| s.clone()).unwrap_or_default();

    let (a50, a99) = percentiles(bare_alone);
    let (ra50, ra99) = percentiles(remote_alone);
    let (b50, b99) = percentiles(bare_samples);
    let take = |s: Arc<Mutex<Vec<Duration>>>| s.lock().map(|v| v.clone()).unwrap_or_default();
    let (l50, l99) = percentiles(take(local));
    let (r50, r99) = percentiles(remote_samples);
    println!("round trip over loopback, n = {n} (µs)      p50      p99");
    println!("  local no-op command                  {l50:8.1} {l99:8.1}");
    println!("each alone, one series after the other:");
    println!("  bare zenoh query                     {a50:8.1} {a99:8.1}");
    println!("  remote no-op command                 {ra50:8.1} {ra99:8.1}");
    println!(
        "  remote / bare                        {:8.2} {:8.2}",
        ra50 / a50,
        ra99 / a99
    );
    println!("alternately, one of each in turn:");
    println!("  bare zenoh query                     {b50:8.1} {b99:8.1}");
    println!("  remote no-op command                 {r50:8.1} {r99:8.1}");
    println!(
        "  remote / bare                        {:8.2} {:8.2}",
        r50 / b50,
        r99 / b99
    );

    // Throughput: `in_flight` remote no-op commands spawned by one goal, all released when its
    // body ends, so all are in flight together.
    let flight = exec.clone();
    let many = Task::goal("many", move |ctx| async move {
        for _ in 0..in_flight {
            ctx.spawn(flight.remote("agent", "noop", ()).task())
                .start()?;
        }
        Ok(())
    });
    let t0 = Instant::now();
    let report = Runtime::new().run(many).await?;
    let elapsed = t0.elapsed();
    if !report.is_clean() {
        return Err(format!("the throughput run did not run cleanly: {report}").into());
    }
    println!(
        "throughput: {in_flight} remote no-op commands in flight: {:.2} s, {:.0} tasks/s",
        elapsed.as_secs_f64(),
        in_flight as f64 / elapsed.as_secs_f64()
    );
    let stats = exec.stats();
    println!(
        "executive: {} placed, {} succeeded, {} duplicates, {} late",
        stats.placed, stats.succeeded, stats.duplicates, stats.late
    );
    agent.close().await;
    Ok(())
}
