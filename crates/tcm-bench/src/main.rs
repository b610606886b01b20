//! `tcm-bench`: workloads of the TCM runtime, each printed beside a floor measured in the same
//! process, so the ratio survives a noisy machine.
//!
//! `cargo run --profile perf -p tcm-bench -- --json` prints one JSON object per line:
//! `{"workload","layer","n","ns_per_node","floor_ns_per_node","ratio","high_water"}`.
//! The floor is the same number of boxed no-op closures run through a `VecDeque`.
//! `layer` is `core` (the engine driven synchronously, actions finishing at once), `shell`
//! (the full async runtime on tokio: one task per action, with tracing off) or `interp` (the
//! same workload written in TDL and run by the interpreter on the shell, `interp.rs`), beside
//! `tdl` (that TDL compiled by `tdl!`, on the shell).
//!
//! Workloads: W1 a root spawns N no-op commands, each `serial previous`; W2 N unordered no-op
//! commands; W3 a goal spawning the same goal recursively to depth N, each child sequential on the
//! previous one; W5 N commands each disabled until the previous one's execution completed and each
//! with a `terminate in` timer that never fires; W4 a monitor polling every 1 ms for 2 s on real time, its lateness against the
//! ideal schedule beside a thread sleeping to the same deadlines; W6 N commands failing with an
//! exception handled three levels up; W7 1,000 blocking 1 ms actions on 1 and 2 blocking
//! threads, and a 1 kHz monitor beside them (see `w7.rs`); W8 an interpreted `loop {}` beside a
//! 1 kHz monitor, its lateness against the monitor alone; `load` the time to load and check the
//! Xavier mission at run time. W1 also runs at 10k, 100k and 1M to show the per-node cost does
//! not grow.
//!
//! `--workload W1|W2|W3|W4|W5|W6|W7|W8|load|W1-scale`, `--layer core|shell|shell-now|interp`,
//! `--n N` and `--depth D` run one workload, one layer (`shell-now`: W1, W2 and W3 written with
//! synchronous actions, `Task::command_now`), one size (W1-scale then runs only that size); `--hold` makes the core
//! layer's W1-scale spawn every command before any runs (layer `core-hold`), so all N are alive at
//! once as in the shell. `bench/compare` runs each workload in a process of its own with these, to
//! read its peak RSS and to match the sizes the other systems can handle.
//!
//! Every measurement runs on a heap kept between repeats (`heap.rs`); `--cold-heap` leaves glibc's
//! allocator its defaults, which give memory back to the system and take it again. Each line says
//! which (`heap`: `kept` or `cold`).

mod heap;
mod interp;
mod journal;
mod now;
mod w7;

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tcm::{Constraint, Facet, Failure, Handler, Monitor, NodeRef, Runtime, Task};
use tcm_core::{Effect, Engine, HandlerSpec, NodeKind, Spawn, Time};

/// Whether the heap is kept between measurements (`heap.rs`), set once at the start.
static HEAP_KEPT: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

fn heap_label() -> &'static str {
    if HEAP_KEPT.load(std::sync::atomic::Ordering::Relaxed) {
        "kept"
    } else {
        "cold"
    }
}

/// Repetitions of each measurement; the best is kept (least disturbed by the machine).
const REPEATS: usize = 3;

fn floor(n: usize) -> f64 {
    best(|| {
        let mut q: VecDeque<Box<dyn FnOnce() -> usize>> = VecDeque::with_capacity(16);
        let start = Instant::now();
        let mut acc = 0usize;
        for i in 0..n {
            q.push_back(Box::new(move || std::hint::black_box(i)));
            if let Some(f) = q.pop_front() {
                acc = acc.wrapping_add(f());
            }
        }
        std::hint::black_box(acc);
        start.elapsed().as_nanos() as f64 / n as f64
    })
}

fn best(mut f: impl FnMut() -> f64) -> f64 {
    (0..REPEATS).map(|_| f()).fold(f64::INFINITY, f64::min)
}

/// Drives an engine whose actions finish as soon as they start. Returns the high-water mark.
fn drain(engine: &mut Engine<u8>) {
    while let Some(effect) = engine.poll_effect() {
        if let Effect::Start { node, .. } = effect {
            let _ = engine.handle_action_finished(Time::ZERO, node, Ok(()));
        }
    }
}

fn core_flat(n: usize, chained: bool) -> (f64, usize) {
    core_flat_with(n, chained, false)
}

/// W1 (`chained`) or W2 on the engine. With `hold`, every command is spawned before any runs (as
/// the shell's goal does), so all N are alive at once; without it each one runs as it is spawned.
fn core_flat_with(n: usize, chained: bool, hold: bool) -> (f64, usize) {
    let constraints: &[Constraint] = if chained {
        &[Constraint::Serial(NodeRef::Previous)]
    } else {
        &[]
    };
    core_children(n, hold, constraints)
}

/// A goal on the engine spawning `n` no-op commands, each with `constraints`, then completing;
/// returns ns per node and the high-water mark. Every node must be reclaimed and every timer stale.
fn core_children(n: usize, hold: bool, constraints: &[Constraint]) -> (f64, usize) {
    let mut hw = 0;
    let ns = best(|| {
        let mut e: Engine<u8> = Engine::new(1);
        e.set_tracing(false);
        let root = e.root();
        let start = Instant::now();
        let top = e
            .spawn(Time::ZERO, Spawn::new(root, NodeKind::Goal, "top", 0))
            .expect("spawn");
        // The top goal's action runs "inline": it spawns all children before finishing.
        let _ = e.poll_effect();
        for _ in 0..n {
            let mut spec = Spawn::new(top, NodeKind::Command, "noop", 0);
            spec.constraints.extend_from_slice(constraints);
            e.spawn(Time::ZERO, spec).expect("spawn");
            if !hold {
                drain(&mut e);
            }
        }
        let _ = e.handle_action_finished(Time::ZERO, top, Ok(()));
        drain(&mut e);
        let el = start.elapsed().as_nanos() as f64 / n as f64;
        assert_eq!(e.stats().live_nodes, 1, "everything reclaimed");
        assert!(
            e.poll_timeout().is_none(),
            "every timeout is stale once its node completed"
        );
        hw = e.stats().high_water;
        el
    });
    (ns, hw)
}

fn core_recursive(depth: usize) -> (f64, usize) {
    let mut hw = 0;
    let ns = best(|| {
        // The action payload is the goal's remaining depth; 0 marks a command.
        let mut e: Engine<usize> = Engine::new(1);
        e.set_tracing(false);
        let root = e.root();
        let start = Instant::now();
        e.spawn(Time::ZERO, Spawn::new(root, NodeKind::Goal, "g", depth))
            .expect("spawn");
        while let Some(effect) = e.poll_effect() {
            let Effect::Start { node, action: d } = effect else {
                continue;
            };
            if d > 1 {
                let c = e
                    .spawn(Time::ZERO, Spawn::new(node, NodeKind::Command, "c", 0))
                    .expect("spawn");
                let spec = Spawn::new(node, NodeKind::Goal, "g", d - 1)
                    .with(Constraint::Sequential(Facet::Execution, c.into()));
                e.spawn(Time::ZERO, spec).expect("spawn");
            }
            let _ = e.handle_action_finished(Time::ZERO, node, Ok(()));
        }
        let el = start.elapsed().as_nanos() as f64 / (2 * depth) as f64;
        assert_eq!(e.stats().live_nodes, 1, "everything reclaimed");
        hw = e.stats().high_water;
        el
    });
    (ns, hw)
}

fn shell<F: FnOnce() -> Task>(nodes: usize, make: F) -> (f64, usize) {
    shell_journaled(nodes, make, None)
}

/// The shell, keeping a journal of its inputs with `journal` durability if given, in a new file
/// of the temporary directory (on this machine's disk), removed after: its writes and syncs, and
/// its close at the run's end, are in the time.
fn shell_journaled<F: FnOnce() -> Task>(
    nodes: usize,
    make: F,
    journal: Option<tcm_journal::Durability>,
) -> (f64, usize) {
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_time()
        .build()
        .expect("tokio runtime");
    let mut run = Runtime::new();
    let path = std::env::temp_dir().join(format!("tcm-bench-{}.journal", std::process::id()));
    let _ = std::fs::remove_file(&path);
    if let Some(d) = journal {
        let writer = tcm_journal::Writer::create(&path, "bench", d).expect("a journal");
        run = run.journal(writer);
    }
    let start = Instant::now();
    let report = rt.block_on(run.run(make())).expect("run");
    let ns = start.elapsed().as_nanos() as f64 / nodes as f64;
    let _ = std::fs::remove_file(&path);
    (ns, report.stats.high_water)
}

fn shell_flat(n: usize, chained: bool) -> (f64, usize) {
    shell_flat_journaled(n, chained, None)
}

/// The journal's group commit in the benchmarks: every 10 ms.
const GROUP_COMMIT: tcm_journal::Durability =
    tcm_journal::Durability::Group(std::time::Duration::from_millis(10));

fn shell_flat_journaled(
    n: usize,
    chained: bool,
    journal: Option<tcm_journal::Durability>,
) -> (f64, usize) {
    let mut hw = 0;
    let ns = best(|| {
        let (ns, h) = shell_journaled(
            n,
            || {
                Task::goal("top", move |ctx| async move {
                    for _ in 0..n {
                        let s = ctx.spawn(Task::command("noop", |_| async { Ok(()) }));
                        let s = if chained {
                            s.serial(NodeRef::Previous)
                        } else {
                            s
                        };
                        s.start()?;
                    }
                    Ok(())
                })
            },
            journal,
        );
        hw = h;
        ns
    });
    (ns, hw)
}

/// The two constraints of each W5 node: wait for the previous one's execution, and a timeout that
/// never fires (the timer heap holds one stale entry per node until compaction).
fn w5_constraints() -> [Constraint; 2] {
    use tcm::{Event, Point, When};
    [
        Constraint::disable(
            Facet::Handling,
            When::Event(Event::on(
                NodeRef::Previous,
                Facet::Execution,
                Point::Completed,
            )),
        ),
        Constraint::terminate(When::In(Duration::from_secs(3600))),
    ]
}

/// W5 on the engine: N commands, each disabled until the previous one's execution completed and
/// each with a `terminate in` timer that never fires.
fn core_constrained(n: usize) -> (f64, usize) {
    core_children(n, false, &w5_constraints())
}

/// W5 through the async runtime.
fn shell_constrained(n: usize) -> (f64, usize) {
    let mut hw = 0;
    let ns = best(|| {
        let (ns, h) = shell(n, || {
            Task::goal("top", move |ctx| async move {
                for _ in 0..n {
                    let [a, b] = w5_constraints();
                    ctx.spawn(Task::command("step", |_| async { Ok(()) }))
                        .with(a)
                        .with(b)
                        .start()?;
                }
                Ok(())
            })
        });
        hw = h;
        ns
    });
    (ns, hw)
}

/// W6 on the engine: top (with the handler) > mid > low > N failing commands.
fn core_exceptions(n: usize) -> f64 {
    best(|| {
        // Action payloads: 1 top, 2 mid, 3 low, 4 a failing command. Factories: 0, the handler.
        let mut e: Engine<u8, u8> = Engine::new(1);
        e.set_tracing(false);
        let root = e.root();
        let start = Instant::now();
        let mut top = Spawn::new(root, NodeKind::Goal, "top", 1);
        top.handlers.push(HandlerSpec {
            name: "recover".into(),
            exception: "Boom".into(),
            max_activations: None,
            body: 0,
        });
        e.spawn(Time::ZERO, top).expect("spawn");
        let mut handled = 0;
        while let Some(effect) = e.poll_effect() {
            match effect {
                Effect::Start { node, action } => {
                    let res = match action {
                        1 | 2 => {
                            e.spawn(
                                Time::ZERO,
                                Spawn::new(node, NodeKind::Goal, "level", action + 1),
                            )
                            .expect("spawn");
                            Ok(())
                        }
                        3 => {
                            for _ in 0..n {
                                e.spawn(Time::ZERO, Spawn::new(node, NodeKind::Command, "boom", 4))
                                    .expect("spawn");
                            }
                            Ok(())
                        }
                        _ => Err(Failure::new("Boom", "")),
                    };
                    let _ = e.handle_action_finished(Time::ZERO, node, res);
                }
                Effect::Invoke { job, .. } => {
                    handled += 1;
                    let _ = e.handle_action_finished(Time::ZERO, job, Ok(()));
                }
                _ => {}
            }
        }
        assert_eq!(handled, n, "every exception was handled");
        start.elapsed().as_nanos() as f64 / n as f64
    })
}

/// W6 through the async runtime.
fn shell_exceptions(n: usize) -> f64 {
    best(|| {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_time()
            .build()
            .expect("tokio runtime");
        let handled = Arc::new(Mutex::new(0usize));
        let h = handled.clone();
        let start = Instant::now();
        let task = Task::goal("top", move |ctx| async move {
            ctx.spawn(Task::goal("mid", move |ctx| async move {
                ctx.spawn(Task::goal("low", move |ctx| async move {
                    for _ in 0..n {
                        ctx.spawn(Task::command("boom", |_| async {
                            Err::<(), _>(Failure::new("Boom", ""))
                        }))
                        .start()?;
                    }
                    Ok(())
                }))
                .start()?;
                Ok(())
            }))
            .start()?;
            Ok(())
        })
        .handler(Handler::new("recover", "Boom", move |_| {
            let h = h.clone();
            async move {
                if let Ok(mut c) = h.lock() {
                    *c += 1;
                }
                Ok(())
            }
        }));
        let report = rt.block_on(Runtime::new().run(task)).expect("run");
        assert_eq!(report.outcome, tcm::RunOutcome::Completed);
        assert_eq!(handled.lock().map(|c| *c).unwrap_or(0), n);
        start.elapsed().as_nanos() as f64 / n as f64
    })
}

/// Mean, p99 and max of lateness samples (ns).
fn stats(mut v: Vec<u64>) -> (f64, u64, u64) {
    v.sort_unstable();
    let mean = v.iter().sum::<u64>() as f64 / v.len().max(1) as f64;
    let p99 = v.get(v.len() * 99 / 100).copied().unwrap_or(0);
    (mean, p99, v.last().copied().unwrap_or(0))
}

/// W4: a 1 ms polling monitor for 2 s on real time, against a thread sleeping to the same deadlines.
fn w4(json: bool) {
    const N: u32 = 2000;
    let period = Duration::from_millis(1);
    // The floor: a plain thread sleeping to absolute deadlines.
    let floor = std::thread::spawn(move || {
        let t0 = Instant::now();
        let mut late = Vec::with_capacity(N as usize);
        for k in 1..N {
            let deadline = t0 + period * k;
            let now = Instant::now();
            if deadline > now {
                std::thread::sleep(deadline - now);
            }
            late.push((Instant::now() - deadline).as_nanos() as u64);
        }
        late
    })
    .join()
    .unwrap_or_default();
    // Ours: a polling monitor with the precise timer on a real multi-thread runtime.
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("tokio runtime");
    let samples: Arc<Mutex<Vec<Instant>>> = Arc::default();
    let s2 = samples.clone();
    let params = Monitor {
        max_activations: Some(N),
        period: Some(period),
        ..Monitor::default()
    };
    let task = Task::monitor("poll", params, move |_| {
        let s = s2.clone();
        async move {
            if let Ok(mut v) = s.lock() {
                v.push(Instant::now());
            }
            Ok(())
        }
    });
    // The ideal schedule starts when the run starts: activation k is due at t0 + k periods (the
    // monitor starts a few microseconds after t0, which counts against us).
    let t0 = Instant::now();
    let report = rt
        .block_on(Runtime::new().precise_timer().run(task))
        .expect("run");
    let starts = samples.lock().map(|v| v.clone()).unwrap_or_default();
    let activations = starts.len();
    let ours: Vec<u64> = starts
        .iter()
        .enumerate()
        .map(|(k, t)| {
            t.saturating_duration_since(t0 + period * k as u32)
                .as_nanos() as u64
        })
        .collect();
    let (m, p99, max) = stats(ours);
    let (fm, fp99, fmax) = stats(floor);
    let ratio = m / fm.max(1.0);
    if json {
        let v = serde_json::json!({
            "workload": "W4", "layer": "shell", "n": activations,
            "mean_late_ns": m.round(), "p99_late_ns": p99, "max_late_ns": max,
            "floor_mean_late_ns": fm.round(), "floor_p99_late_ns": fp99, "floor_max_late_ns": fmax,
            "ratio": (ratio * 100.0).round() / 100.0, "outcome": format!("{:?}", report.outcome),
        });
        println!("{v}");
    } else {
        println!(
            "W4   shell  {activations} activations   late mean {:.1} us p99 {:.1} us max {:.1} us   floor mean {:.1} us p99 {:.1} us max {:.1} us   ratio {ratio:.2}",
            m / 1e3,
            p99 as f64 / 1e3,
            max as f64 / 1e3,
            fm / 1e3,
            fp99 as f64 / 1e3,
            fmax as f64 / 1e3
        );
    }
}

fn report(
    json: bool,
    workload: &str,
    layer: &str,
    n: usize,
    (ns, hw): (f64, usize),
    floor_ns: f64,
) {
    let ratio = ns / floor_ns;
    if json {
        let v = serde_json::json!({
            "workload": workload,
            "layer": layer,
            "n": n,
            "ns_per_node": (ns * 10.0).round() / 10.0,
            "floor_ns_per_node": (floor_ns * 10.0).round() / 10.0,
            "ratio": (ratio * 10.0).round() / 10.0,
            "high_water": hw,
            "heap": heap_label(),
        });
        println!("{v}");
    } else {
        println!(
            "{workload:<4} {layer:<6} n={n:<9} {ns:>9.1} ns/node   floor {floor_ns:>6.1} ns   ratio {ratio:>7.1}   high-water {hw}   heap {}",
            heap_label()
        );
    }
}

/// Command-line options. Without `--workload`, `--layer`, `--n` or `--depth` every workload runs at
/// its default size, as before; `bench/compare` uses them to run one workload per process (so its
/// peak RSS can be read) at the sizes the other systems can handle.
struct Options {
    json: bool,
    quick: bool,
    /// Only this workload (`W1` … `W7` or `W1-scale`).
    workload: Option<String>,
    /// Only this layer (`core` or `shell`).
    layer: Option<String>,
    /// Number of nodes for W1, W2, W6 and W1-scale (one size instead of the scaling set).
    n: Option<usize>,
    /// W1-scale core only: spawn all N before running any (reported as layer `core-hold`).
    hold: bool,
    /// Recursion depth for W3 (it reports `n` = 2 × depth nodes: a goal and a command per level).
    depth: Option<usize>,
    /// Leave glibc's allocator its defaults instead of keeping the heap (`heap.rs`).
    cold_heap: bool,
}

const USAGE: &str = "usage: tcm-bench [--json] [--quick] [--workload W1|W2|W3|W4|W5|W6|W7|W8|load|W1-scale] \
[--layer core|shell|shell-now|interp|journal|shell-journal] [--n N] [--depth D] [--hold] [--cold-heap]";

fn parse_args() -> Result<Options, String> {
    let mut o = Options {
        json: false,
        quick: false,
        workload: None,
        layer: None,
        n: None,
        depth: None,
        hold: false,
        cold_heap: false,
    };
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = |name: &str| args.next().ok_or(format!("{name} needs a value"));
        let number = |v: String| {
            v.replace('_', "")
                .parse::<usize>()
                .ok()
                .filter(|n| *n > 0)
                .ok_or(format!("not a positive number: {v:?}"))
        };
        match a.as_str() {
            "--json" => o.json = true,
            "--quick" => o.quick = true,
            "--hold" => o.hold = true,
            "--cold-heap" => o.cold_heap = true,
            "--workload" => {
                let w = value("--workload")?;
                if !matches!(
                    w.as_str(),
                    "W1" | "W2" | "W3" | "W4" | "W5" | "W6" | "W7" | "W8" | "load" | "W1-scale"
                ) {
                    return Err(format!("unknown workload {w:?}"));
                }
                o.workload = Some(w);
            }
            "--layer" => {
                let l = value("--layer")?;
                if !matches!(
                    l.as_str(),
                    "core" | "shell" | "shell-now" | "interp" | "journal" | "shell-journal"
                ) {
                    return Err(format!("unknown layer {l:?}"));
                }
                o.layer = Some(l);
            }
            "--n" => o.n = Some(number(value("--n")?)?),
            "--depth" => o.depth = Some(number(value("--depth")?)?),
            _ => return Err(format!("unknown argument {a:?}")),
        }
    }
    Ok(o)
}

fn main() {
    let o = match parse_args() {
        Ok(o) => o,
        Err(e) => {
            eprintln!("{e}\n{USAGE}");
            std::process::exit(2);
        }
    };
    if !o.cold_heap {
        let kept = heap::keep();
        if !kept {
            eprintln!("note: could not keep the heap (not glibc?); figures are for a cold heap");
        }
        HEAP_KEPT.store(kept, std::sync::atomic::Ordering::Relaxed);
    }
    let json = o.json;
    let quick = o.quick;
    if cfg!(debug_assertions) {
        eprintln!("note: a debug build; run with --release for meaningful figures");
    }
    let on = |w: &str| o.workload.as_deref().is_none_or(|x| x == w);
    let core = o.layer.as_deref().is_none_or(|l| l == "core");
    let shell = o.layer.as_deref().is_none_or(|l| l == "shell");
    // The shell with synchronous actions (`Task::command_now`): W1, W2 and W3.
    let shell_now = o.layer.as_deref().is_none_or(|l| l == "shell-now");
    let interp = o.layer.as_deref().is_none_or(|l| l == "interp");
    // Only when asked for: a sync per record makes it slow.
    let journal = o.layer.as_deref() == Some("journal");
    // The shell with a journal by group commit alone, one workload, for a profile.
    let shell_journal = o.layer.as_deref() == Some("shell-journal");
    let n = o.n.unwrap_or(if quick { 10_000 } else { 100_000 });
    let depth = o.depth.unwrap_or(if quick { 1_000 } else { 10_000 });
    if on("W1") || on("W2") {
        let f = floor(n);
        if on("W1") {
            if core {
                report(json, "W1", "core", n, core_flat(n, true), f);
            }
            if shell {
                report(json, "W1", "shell", n, shell_flat(n, true), f);
            }
            if shell_now {
                report(json, "W1", "shell-now", n, now::shell_flat_now(n, true), f);
            }
            if shell_journal {
                let group = shell_flat_journaled(n, true, Some(GROUP_COMMIT));
                report(json, "W1", "shell+journal-group", n, group, f);
            }
            if interp {
                report(json, "W1", "tdl", n, interp::tdl_flat(n, true), f);
                report(json, "W1", "interp", n, interp::interp_flat(n, true), f);
            }
        }
        if on("W2") {
            if core {
                report(json, "W2", "core", n, core_flat(n, false), f);
            }
            if shell {
                report(json, "W2", "shell", n, shell_flat(n, false), f);
            }
            if shell_now {
                report(json, "W2", "shell-now", n, now::shell_flat_now(n, false), f);
            }
            if shell_journal {
                let group = shell_flat_journaled(n, false, Some(GROUP_COMMIT));
                report(json, "W2", "shell+journal-group", n, group, f);
            }
            if interp {
                report(json, "W2", "tdl", n, interp::tdl_flat(n, false), f);
                report(json, "W2", "interp", n, interp::interp_flat(n, false), f);
            }
        }
    }
    if journal {
        // The shell beside itself keeping a journal: group commit every 10 ms at the workloads'
        // size, and a sync per record and a sync before acting at a size where a sync each
        // (about 0.1 ms on a disk) keeps the run short; each line's ratio is to the floor, the last the costs against the shell
        // of the same size.
        let nj = o.n.unwrap_or(if quick { 10_000 } else { 100_000 });
        let ne = nj.min(2_000);
        for (w, chained) in [("W1", true), ("W2", false)] {
            if !on(w) {
                continue;
            }
            let plain = shell_flat(nj, chained);
            let group = shell_flat_journaled(nj, chained, Some(GROUP_COMMIT));
            let plain_e = shell_flat(ne, chained);
            let every =
                shell_flat_journaled(ne, chained, Some(tcm_journal::Durability::EveryRecord));
            let acting = shell_flat_journaled(
                ne,
                chained,
                Some(tcm_journal::Durability::BeforeActing(
                    std::time::Duration::from_millis(10),
                )),
            );
            report(json, w, "shell", nj, plain, floor(nj));
            report(json, w, "shell+journal-group", nj, group, floor(nj));
            report(json, w, "shell", ne, plain_e, floor(ne));
            report(json, w, "shell+journal-every", ne, every, floor(ne));
            report(json, w, "shell+journal-acting", ne, acting, floor(ne));
            if !json {
                println!(
                    "{w}: a journal costs {:+.1}% with group commit (n={nj}), x{:.0} with a sync per record, x{:.1} synced before acting (n={ne})",
                    100.0 * (group.0 / plain.0 - 1.0),
                    every.0 / plain_e.0,
                    acting.0 / plain_e.0
                );
            }
        }
        // Resuming: a journal of about a million records (W2 of a million commands, one end
        // each), read and replayed; the target is under 2 s.
        let nr = if quick { 100_000 } else { 1_000_000 };
        let (records, secs) = journal::resume_from_journal(nr);
        if json {
            println!(
                "{{\"workload\":\"resume\",\"layer\":\"journal\",\"n\":{records},\"seconds\":{secs:.3}}}"
            );
        } else {
            println!(
                "resume: a journal of {records} records read and replayed in {secs:.2} s ({:.0} ns a record)",
                secs * 1e9 / records as f64
            );
        }
    }
    if on("W3") {
        let fd = floor(2 * depth);
        if core {
            report(json, "W3", "core", 2 * depth, core_recursive(depth), fd);
        }
        if shell {
            report(
                json,
                "W3",
                "shell",
                2 * depth,
                now::shell_recursive(depth, false),
                fd,
            );
        }
        if shell_now {
            let w3 = now::shell_recursive(depth, true);
            report(json, "W3", "shell-now", 2 * depth, w3, fd);
        }
    }
    if on("W5") {
        let nc = o.n.unwrap_or(if quick { 1_000 } else { 10_000 });
        let fc = floor(nc);
        if core {
            report(json, "W5", "core", nc, core_constrained(nc), fc);
        }
        if shell {
            report(json, "W5", "shell", nc, shell_constrained(nc), fc);
        }
    }
    if on("W6") {
        let ne = o.n.unwrap_or(if quick { 1_000 } else { 10_000 });
        let fe = floor(ne);
        if core {
            report(json, "W6", "core", ne, (core_exceptions(ne), 0), fe);
        }
        if shell {
            report(json, "W6", "shell", ne, (shell_exceptions(ne), 0), fe);
        }
    }
    if on("W4") && shell {
        w4(json);
    }
    if on("W7") && shell {
        w7::run(json);
    }
    if on("W8") && interp {
        interp::w8(json);
    }
    if on("load") && interp {
        interp::load_xavier(json);
    }
    if on("W1-scale") {
        let default: &[usize] = if quick {
            &[1_000, 10_000]
        } else {
            &[10_000, 100_000, 1_000_000]
        };
        let one = o.n.map(|s| [s]);
        let sizes: &[usize] = match &one {
            Some(s) => s,
            None => default,
        };
        for &s in sizes {
            let fs = floor(s);
            if core && o.hold {
                report(
                    json,
                    "W1-scale",
                    "core-hold",
                    s,
                    core_flat_with(s, true, true),
                    fs,
                );
            } else if core {
                report(json, "W1-scale", "core", s, core_flat(s, true), fs);
            }
            if shell {
                report(json, "W1-scale", "shell", s, shell_flat(s, true), fs);
            }
        }
    }
}
