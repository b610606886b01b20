//! W7, true concurrency: 1,000 CPU-bound blocking actions of about 1 ms each (a calibrated spin)
//! under one goal, unordered, run on 1 and then on 2 blocking threads (tokio's
//! `max_blocking_threads`, one async worker): the speedup of 2 threads over 1. Then a 1 kHz
//! polling monitor (2,000 activations, the precise timer) runs for 2 s beside batches of the same
//! 1,000 actions on 2 threads, one batch after the other for as long as the monitor runs; its
//! activations and its lateness against `start + k × 1 ms` are printed beside the floor, the same
//! monitor alone on the same runtime, measured in the same process just before: once with the
//! bodies at their threads' priority, once at nice 19 (`Runtime::blocking_nice`).

use std::hint::black_box;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tcm::{Monitor, NodeKind, Runtime, Task};

/// Actions per batch.
const N: usize = 1_000;
/// Activations of the monitor: 2 s at 1 kHz.
const ACTIVATIONS: u32 = 2_000;

/// Work that takes about `iters` steps of a multiply-add chain (no memory traffic).
fn spin(iters: u64) -> u64 {
    let mut x = 1u64;
    for i in 0..iters {
        x = black_box(x.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(i));
    }
    x
}

/// Steps of `spin` that take about 1 ms on this machine (the fastest of several tries).
fn calibrate() -> u64 {
    const PROBE: u64 = 200_000;
    let best = (0..20)
        .map(|_| {
            let t = Instant::now();
            black_box(spin(PROBE));
            t.elapsed()
        })
        .min()
        .unwrap_or(Duration::from_millis(1));
    let per_ms = PROBE as f64 / (best.as_secs_f64() * 1e3);
    per_ms.round().max(1.0) as u64
}

/// A multi-thread runtime with one async worker and `threads` blocking threads.
fn runtime(threads: usize) -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .max_blocking_threads(threads)
        .enable_all()
        .build()
        .expect("tokio runtime")
}

fn work(iters: u64) -> Task {
    Task::blocking(NodeKind::Command, "work", move |_| {
        black_box(spin(iters));
        Ok(())
    })
}

/// One batch: a goal spawning `N` blocking actions, unordered.
fn batch(iters: u64) -> Task {
    Task::goal("batch", move |ctx| async move {
        for _ in 0..N {
            ctx.spawn(work(iters)).start()?;
        }
        Ok(())
    })
}

/// Wall time of one batch on `threads` blocking threads (the best of 3).
fn batch_time(iters: u64, threads: usize) -> Duration {
    (0..3)
        .map(|_| {
            let rt = runtime(threads);
            let t = Instant::now();
            let report = rt.block_on(Runtime::new().run(batch(iters))).expect("run");
            assert_eq!(report.outcome, tcm::RunOutcome::Completed);
            t.elapsed()
        })
        .min()
        .unwrap_or_default()
}

/// The monitor's lateness samples (ns, activation k against `t0 + k periods`), alone or beside
/// batches of the load on 2 threads, whose bodies run at nice `nice`; and how many load actions
/// ran meanwhile.
fn monitor_lateness(iters: u64, loaded: bool, nice: i32) -> (Vec<u64>, usize) {
    let period = Duration::from_millis(1);
    let stamps: Arc<Mutex<Vec<Instant>>> = Arc::default();
    let s2 = stamps.clone();
    let params = Monitor {
        max_activations: Some(ACTIVATIONS),
        period: Some(period),
        ..Monitor::default()
    };
    let monitor = Task::monitor("poll", params, move |_| {
        let s = s2.clone();
        async move {
            if let Ok(mut v) = s.lock() {
                v.push(Instant::now());
            }
            Ok(())
        }
    });
    let batches = Arc::new(Mutex::new(0usize));
    let b2 = batches.clone();
    let task = Task::goal("w7", move |ctx| async move {
        ctx.hold_children(false)?;
        let poll = ctx.spawn(monitor).start()?;
        if !loaded {
            return Ok(());
        }
        // Batch after batch, for as long as the monitor runs.
        while ctx
            .monitor_counts(poll)?
            .is_some_and(|(a, _)| a < ACTIVATIONS)
        {
            ctx.spawn(batch(iters)).wait().await?;
            if let Ok(mut b) = b2.lock() {
                *b += 1;
            }
        }
        Ok(())
    });
    let rt = runtime(2);
    let t0 = Instant::now();
    let report = rt
        .block_on(Runtime::new().precise_timer().blocking_nice(nice).run(task))
        .expect("run");
    assert_eq!(report.outcome, tcm::RunOutcome::Completed);
    let starts = stamps.lock().map(|v| v.clone()).unwrap_or_default();
    let late = starts
        .iter()
        .enumerate()
        .map(|(k, t)| {
            t.saturating_duration_since(t0 + period * k as u32)
                .as_nanos() as u64
        })
        .collect();
    let actions = batches.lock().map(|b| *b * N).unwrap_or(0);
    (late, actions)
}

/// Runs W7 and prints its two lines (or JSON objects).
pub(crate) fn run(json: bool) {
    let iters = calibrate();
    let one = batch_time(iters, 1);
    let two = batch_time(iters, 2);
    let speedup = one.as_secs_f64() / two.as_secs_f64().max(1e-9);
    if json {
        let v = serde_json::json!({
            "workload": "W7", "layer": "shell", "n": N,
            "ms_1_thread": (one.as_secs_f64() * 1e4).round() / 10.0,
            "ms_2_threads": (two.as_secs_f64() * 1e4).round() / 10.0,
            "speedup": (speedup * 100.0).round() / 100.0,
        });
        println!("{v}");
    } else {
        println!(
            "W7   shell  n={N:<9} 1 thread {:.1} ms   2 threads {:.1} ms   speedup {speedup:.2}",
            one.as_secs_f64() * 1e3,
            two.as_secs_f64() * 1e3,
        );
    }
    let (floor, _) = monitor_lateness(iters, false, 0);
    let (fm, fp99, fmax) = crate::stats(floor.clone());
    for nice in [0, 19] {
        let (ours, actions) = monitor_lateness(iters, true, nice);
        let activations = ours.len();
        let (m, p99, max) = crate::stats(ours);
        let ratio = m / fm.max(1.0);
        if json {
            let v = serde_json::json!({
                "workload": "W7-monitor", "layer": "shell", "n": activations,
                "nice": nice, "actions_beside": actions,
                "mean_late_ns": m.round(), "p99_late_ns": p99, "max_late_ns": max,
                "floor_n": floor.len(),
                "floor_mean_late_ns": fm.round(), "floor_p99_late_ns": fp99, "floor_max_late_ns": fmax,
                "ratio": (ratio * 100.0).round() / 100.0,
            });
            println!("{v}");
        } else {
            println!(
                "W7   monitor nice {nice:<2} {activations} activations beside {actions} actions   late mean {:.1} us p99 {:.1} us max {:.1} us   alone ({}) mean {:.1} us p99 {:.1} us max {:.1} us   ratio {ratio:.2}",
                m / 1e3,
                p99 as f64 / 1e3,
                max as f64 / 1e3,
                floor.len(),
                fm / 1e3,
                fp99 as f64 / 1e3,
                fmax as f64 / 1e3
            );
        }
    }
}
