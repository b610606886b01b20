//! Budgets, not hangs: an interpreted body that loops without waiting yields to the runtime
//! every `Budget::yield_every` iterations, so a 1 kHz monitor beside it keeps its schedule on
//! real time; past `Budget::max_steps` iterations its node fails with `StepBudgetExceeded`,
//! naming the loop's place. (How late the monitor's activations are beside the loop, against the
//! same monitor alone, is a benchmark figure: `tcm-bench --workload W8`.)

use std::time::Duration;

use tdl::Recorder;
use tdl_interp::{Budget, Program, Registry};

const SPIN: &str = "\
pub goal spin_beside_monitor() {
    spawn tick();
    spawn spin() with terminate at tick execution completed;
}

pub goal spin_alone() {
    spawn spin();
}

command spin() {
    loop {}
}

monitor tick() with period 1ms, maximum activate 2000 {}
";

fn program(budget: Budget) -> Program {
    match Program::from_sources(&[("spin.tdl".into(), SPIN.into())], &Registry::new()) {
        Ok(p) => p.with_budget(budget),
        Err(e) => panic!("{e}"),
    }
}

fn real_time() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .expect("a runtime")
}

#[test]
fn a_monitor_beside_a_busy_loop_gets_every_activation_while_the_loop_spins() {
    let program = program(Budget::default());
    let task = program.task("spin_beside_monitor", vec![]).expect("a task");
    let rec = Recorder::new();
    let report = real_time()
        .block_on(tdl::Runtime::new().with_sink(rec.clone()).run(task))
        .expect("the run ends");
    let trace = rec.events();
    tdl::testing::assert_checked(&trace);
    let story = tdl::testing::story(&trace);
    let activations = story
        .iter()
        .filter(|l| l.contains("ACT-tick handling active"))
        .count();
    assert_eq!(activations, 2000, "{report}");
    // The loop spun the whole time: it ended by its termination, when the monitor completed,
    // not by itself nor by its budget.
    assert!(
        story.iter().any(|l| l.contains("spin terminated")),
        "{report}"
    );
    assert!(
        !story.iter().any(|l| l.contains("StepBudgetExceeded")),
        "{report}"
    );
    assert!(report.elapsed >= Duration::from_millis(1900), "{report}");
}

#[test]
fn a_loop_past_its_budget_fails_its_node_naming_the_loop() {
    let program = program(Budget {
        yield_every: 1024,
        max_steps: 200_000,
    });
    let task = program.task("spin_alone", vec![]).expect("a task");
    let report = real_time()
        .block_on(tdl::Runtime::new().run(task))
        .expect("the run ends");
    assert_eq!(report.unhandled.len(), 1, "{report}");
    let failure = &report.unhandled[0].failure;
    assert_eq!(failure.exception, "StepBudgetExceeded", "{report}");
    assert!(
        failure.message.contains("spin.tdl:11:5"),
        "{}",
        failure.message
    );
    assert!(
        failure.message.contains("200001 iterations"),
        "{}",
        failure.message
    );
}
