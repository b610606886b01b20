//! Compiled and interpreted, the same program gives the same trace.

use tdl::Runtime;
use tdl_interp::{Registry, Value};

use crate::both;
use crate::util::{assert_same, load, trace_of};

both!(sequence {
    pub goal patrol(rooms: u32) {
        for room in 0..rooms {
            spawn visit(room) with sequential execution previous;
        }
        spawn report() with sequential execution previous, terminate in 30s;
    }

    command visit(room: u32) {
        if room == 1 {
            fail DoorLocked { room };
        }
    }

    command report() {}

    exception DoorLocked { room: u32 }
});

#[tokio::test(start_paused = true)]
async fn a_sequence_with_a_failure_runs_alike() {
    let compiled = trace_of(Runtime::new(), sequence::patrol(3)).await;
    let program = load(sequence::SRC, &Registry::new());
    let task = program.task("patrol", vec![Value::Int(3)]).expect("a task");
    let interpreted = trace_of(Runtime::new(), task).await;
    assert_same(&compiled, &interpreted);
}

/// Runs `name(args)` compiled and interpreted, and compares the traces.
async fn alike(compiled: tdl::Task, src: &str, name: &str, args: Vec<Value>) {
    alike_with(compiled, src, &Registry::new(), name, args).await;
}

async fn alike_with(
    compiled: tdl::Task,
    src: &str,
    registry: &Registry,
    name: &str,
    args: Vec<Value>,
) {
    let compiled = trace_of(Runtime::new(), compiled).await;
    let program = load(src, registry);
    let task = program.task(name, args).expect("a task");
    let interpreted = trace_of(Runtime::new(), task).await;
    assert_same(&compiled, &interpreted);
}

both!(groups {
    pub goal deliver(rooms: u32) {
        first: spawn plan(rooms) with wait;
        with (sequential execution previous) {
            spawn go(1.5);
            spawn go(2.5);
        }
        spawn announce() with sequential execution previous;
        spawn watch() with terminate at announce execution completed;
    }

    command plan(rooms: u32) -> u32 {
        rooms * 2
    }

    command go(secs: f64) {
        tokio::time::sleep(std::time::Duration::from_secs_f64(secs)).await;
    }

    command announce() {
        tokio::time::sleep(std::time::Duration::from_millis(300)).await;
    }

    monitor watch() with period 1s, persistent ticks: u32 = 0 {
        ticks += 1;
        if ticks > 100 {
            trigger;
        }
    }
});

#[tokio::test(start_paused = true)]
async fn groups_previous_and_a_polling_monitor_run_alike() {
    alike(
        groups::deliver(2),
        groups::SRC,
        "deliver",
        vec![Value::Int(2)],
    )
    .await;
}

both!(values {
    pub goal total(n: u32) -> u32 {
        let mut sum: u32 = 0;
        for i in 0..n {
            let v: u32 = spawn square(i) with wait;
            sum += v;
        }
        let o = spawn may_fail(sum) with outcome;
        match o {
            tdl::Ended::Succeeded(v) => sum + v,
            tdl::Ended::Failed(_) => sum,
            tdl::Ended::Terminated | tdl::Ended::Skipped => 0,
        }
    }

    command square(i: u32) -> u32 {
        i * i
    }

    command may_fail(x: u32) -> u32 {
        if x % 2 == 0 {
            fail Odd { x };
        }
        x + 1
    }

    exception Odd { x: u32 }
});

#[tokio::test(start_paused = true)]
async fn waited_values_and_outcomes_run_alike() {
    alike(values::total(4), values::SRC, "total", vec![Value::Int(4)]).await;
    alike(values::total(3), values::SRC, "total", vec![Value::Int(3)]).await;
}

both!(recovery {
    pub goal mission() with exception handler retry_once() maximum activate 2 {
        spawn step(0) with wait;
        spawn risky(1) with sequential execution previous;
    }

    command step(n: u32) {
        tokio::time::sleep(std::time::Duration::from_millis(100)).await;
    }

    command risky(attempt: u32) {
        if attempt < 3 {
            fail Slipped { attempt, height: 0.25 };
        }
    }

    handler retry_once() handles Hazard as h {
        let attempt = h.downcast::<Slipped>().map_or(0, |it| it.attempt);
        retry with (attempt + 1);
    }

    exception Hazard;
    exception Slipped: Hazard { attempt: u32, height: f64 }
});

#[tokio::test(start_paused = true)]
async fn handlers_that_retry_with_new_arguments_run_alike() {
    alike(recovery::mission(), recovery::SRC, "mission", vec![]).await;
}

both!(iterations {
    pub goal steps(n: u32) {
        for i in 1..n {
            leg[i] disable execution until body[i - 1] execution completed;
        }
        for i in 0..n {
            leg: spawn lift(i);
            body: spawn shift(i) with sequential execution leg[.];
        }
        spawn done() with sequential execution body;
    }

    command lift(i: u32) {
        tokio::time::sleep(std::time::Duration::from_millis(10 * u64::from(i) + 5)).await;
    }

    command shift(i: u32) {
        tokio::time::sleep(std::time::Duration::from_millis(20)).await;
    }

    command done() {}
});

#[tokio::test(start_paused = true)]
async fn iteration_indexed_tags_run_alike() {
    alike(
        iterations::steps(4),
        iterations::SRC,
        "steps",
        vec![Value::Int(4)],
    )
    .await;
}

both!(events {
    resource arm(1);

    pub goal wait_for_go() {
        spawn grab(1) with uses arm, disable until external "go";
        spawn grab(2) with uses arm;
        spawn signal() with disable for 2s;
    }

    command grab(n: u32) {
        tokio::time::sleep(std::time::Duration::from_millis(500)).await;
    }

    command signal() {
        raise "go";
    }
});

#[tokio::test(start_paused = true)]
async fn resources_and_external_events_run_alike() {
    alike(events::wait_for_go(), events::SRC, "wait_for_go", vec![]).await;
}

#[tokio::test(start_paused = true)]
async fn an_extern_task_is_typed_by_its_declaration() {
    let mut r = Registry::new();
    r.task_returning::<f64, _>("dig", |x: f64, y: f64| {
        tdl::Task::command(
            "dig",
            move |_| async move { Ok::<f64, tdl::Failure>(x * y) },
        )
    });
    let src = "extern command dig(x: f64, y: f64) -> f64;\n\
               pub goal g(x: i64) -> f64 {\n    let d = spawn dig(x, 2.5) with wait;\n    d + 1.0\n}\n\
               pub goal bad() {\n    spawn dig(\"far\", 2.5) with wait;\n}\n";
    let program = load(src, &r);
    // An integer for an `f64` parameter is converted, as a literal would be.
    let task = program.task("g", vec![Value::Int(4)]).expect("a task");
    let trace = trace_of(Runtime::new(), task).await;
    assert!(
        trace.iter().any(|l| l.contains("\"name\":\"dig\"")),
        "{trace:?}"
    );
    // A string for an `f64` fails the spawning node with a typed exception.
    let task = program.task("bad", vec![]).expect("a task");
    let trace = trace_of(Runtime::new(), task).await;
    let failed = trace
        .iter()
        .find(|l| l.contains("\"ev\":\"failed\""))
        .expect("the node failed");
    assert!(failed.contains("TypeMismatch"), "{failed}");
    assert!(failed.contains("expected f64"), "{failed}");
}
