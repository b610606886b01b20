//! The interpreter's workloads (issue 43): W1 and W2 written in TDL and run by `tdl-interp`
//! (layer `interp`, beside the hand-written `shell` rows of the same run); W8, a body spinning in
//! `loop {}` beside a 1 kHz monitor, the monitor's lateness against the same monitor alone; and
//! the time to load and check the Xavier mission.

use std::time::{Duration, Instant};

use std::sync::{Arc, Mutex};

use tcm::Runtime;
use tdl_interp::{Program, Registry, Value};

const FLAT: &str = "\
pub goal w1(n: u32) {
    for i in 0..n {
        spawn noop() with serial previous;
    }
}

pub goal w2(n: u32) {
    for i in 0..n {
        spawn noop();
    }
}

command noop() {}
";

/// The same program compiled by `tdl!` (layer `tdl`): what the interpreter is held to.
#[allow(clippy::all, unused_variables)]
mod compiled {
    tdl::tdl! {
        pub goal w1(n: u32) {
            for i in 0..n {
                spawn noop() with serial previous;
            }
        }

        pub goal w2(n: u32) {
            for i in 0..n {
                spawn noop();
            }
        }

        command noop() {}
    }
}

/// W1 (`chained`) or W2 compiled from TDL, on the shell.
pub(crate) fn tdl_flat(n: usize, chained: bool) -> (f64, usize) {
    let mut hw = 0;
    let ns = super::best(|| {
        let n32 = u32::try_from(n).unwrap_or(u32::MAX);
        let task = if chained {
            compiled::w1(n32)
        } else {
            compiled::w2(n32)
        };
        let (ns, h) = super::shell(n, || task);
        hw = h;
        ns
    });
    (ns, hw)
}

fn flat_program() -> Program {
    match Program::from_sources(&[("flat.tdl".into(), FLAT.into())], &Registry::new()) {
        Ok(p) => p,
        Err(e) => panic!("{e}"),
    }
}

/// W1 (`chained`) or W2 interpreted, on the shell: ns per node and the high-water mark.
pub(crate) fn interp_flat(n: usize, chained: bool) -> (f64, usize) {
    let program = flat_program();
    let name = if chained { "w1" } else { "w2" };
    let mut hw = 0;
    let ns = super::best(|| {
        let task = program
            .task(name, vec![Value::Int(n as i64)])
            .expect("the task");
        let (ns, h) = super::shell(n, || task);
        hw = h;
        ns
    });
    (ns, hw)
}

const SPIN: &str = "\
pub goal beside() {
    spawn tick();
    spawn spin() with terminate at tick execution completed;
}

pub goal alone() {
    spawn tick();
}

command spin() {
    loop {}
}

monitor tick() with period 1ms, maximum activate 2000 {
    mark();
}
";

/// The lateness of each activation of `tick` in a run of `task`: when its body ran (a registered
/// function reads the clock) against the ideal schedule from the run's start, in ns.
fn lateness(task: &str) -> Vec<u64> {
    let marks: Arc<Mutex<Vec<Instant>>> = Arc::default();
    let m2 = marks.clone();
    let mut registry = Registry::new();
    registry.function("mark", move || {
        if let Ok(mut v) = m2.lock() {
            v.push(Instant::now());
        }
    });
    let program = match Program::from_sources(&[("spin.tdl".into(), SPIN.into())], &registry) {
        Ok(p) => p,
        Err(e) => panic!("{e}"),
    };
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("tokio runtime");
    let t = program.task(task, vec![]).expect("the task");
    let t0 = Instant::now();
    rt.block_on(Runtime::new().precise_timer().run(t))
        .expect("run");
    let marks = marks.lock().map(|v| v.clone()).unwrap_or_default();
    marks
        .iter()
        .enumerate()
        .map(|(k, t)| {
            t.saturating_duration_since(t0 + PERIOD * k as u32)
                .as_nanos() as u64
        })
        .collect()
}

const PERIOD: Duration = Duration::from_millis(1);

/// W8: the lateness of a 1 kHz monitor beside an interpreted `loop {}`, against the same monitor
/// alone, both measured now.
pub(crate) fn w8(json: bool) {
    let floor = lateness("alone");
    let ours = lateness("beside");
    let activations = ours.len();
    let (m, p99, max) = super::stats(ours);
    let (fm, fp99, fmax) = super::stats(floor);
    let ratio = m / fm.max(1.0);
    if json {
        let v = serde_json::json!({
            "workload": "W8", "layer": "interp", "n": activations,
            "mean_late_ns": m.round(), "p99_late_ns": p99, "max_late_ns": max,
            "floor_mean_late_ns": fm.round(), "floor_p99_late_ns": fp99, "floor_max_late_ns": fmax,
            "ratio": (ratio * 100.0).round() / 100.0,
        });
        println!("{v}");
    } else {
        println!(
            "W8   interp {activations} activations beside loop {{}}   late mean {:.1} us p99 {:.1} us max {:.1} us   alone mean {:.1} us p99 {:.1} us max {:.1} us   ratio {ratio:.2}",
            m / 1e3,
            p99 as f64 / 1e3,
            max as f64 / 1e3,
            fm / 1e3,
            fp99 as f64 / 1e3,
            fmax as f64 / 1e3
        );
    }
}

/// The Xavier mission's registry by name and arity only: loading and checking do not call it.
fn xavier_registry() -> Registry {
    let mut r = Registry::new();
    let task = |_: &[Value]| Ok(tcm::Task::command("stub", |_| async { Ok(()) }));
    for name in [
        "plan_path",
        "turn",
        "guarded_move",
        "look_for_door",
        "speak",
        "mail_gone",
        "motor_temperature",
    ] {
        r.task_dynamic(name, task);
    }
    for ty in ["Mission", "Robot", "Point", "Pose", "Leg"] {
        r.host_type(ty);
    }
    r.alias("Waypoint", "Point");
    r.dynamic_function(
        "legs",
        tdl_interp::Function::dynamic(2, |_| Ok(Value::Unit)),
    )
    .dynamic_function(
        "pose_now",
        tdl_interp::Function::dynamic(2, |_| Ok(Value::Unit)),
    )
    .dynamic_function(
        "stretches",
        tdl_interp::Function::dynamic(1, |_| Ok(Value::Unit)),
    )
    .dynamic_function(
        "stop_the_rest",
        tdl_interp::Function::dynamic(1, |_| Ok(Value::Unit)),
    )
    .dynamic_function(
        "give_up",
        tdl_interp::Function::dynamic(3, |_| Ok(Value::Unit)),
    )
    .method("Mission", "notified", |_: Value, _: u32| ())
    .method("Robot", "pose", |_: Value| ())
    .method("Robot", "motor_temperature", |_: Value| ())
    .field("Mission", "robot", |m: Value| m)
    .field("Leg", "turn", |_: Value| 0.0)
    .field("Leg", "distance", |_: Value| 0.0);
    for c in [
        "TURN_EPSILON",
        "CENTRING_STEP",
        "MOTOR_COOL_C",
        "OVERHEAT_WARNING_C",
    ] {
        r.constant(c, 1.0);
    }
    r.constant("NOTIFY_TIME", Duration::from_millis(300))
        .constant("COOLING_POLL", Duration::from_secs(1));
    r
}

/// The time to load and check the Xavier mission (parse, resolve, the static checks, lowering),
/// best of ten.
pub(crate) fn load_xavier(json: bool) {
    let src = include_str!("../../xavier/src/mission.tdl");
    let registry = xavier_registry();
    let mut best = Duration::MAX;
    for _ in 0..10 {
        let start = Instant::now();
        let program = Program::from_sources(&[("mission.tdl".into(), src.into())], &registry);
        let took = start.elapsed();
        if let Err(e) = program {
            panic!("{e}");
        }
        best = best.min(took);
    }
    let ms = best.as_secs_f64() * 1e3;
    if json {
        let v = serde_json::json!({
            "workload": "load-xavier", "layer": "interp", "ms": (ms * 100.0).round() / 100.0,
        });
        println!("{v}");
    } else {
        println!("load xavier mission: {ms:.2} ms (parse, check, lower)");
    }
}
