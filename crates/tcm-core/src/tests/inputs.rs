//! The inputs an engine records for a journal (`engine/inputs.rs`): each action's end with its
//! failure, a time with timers due, an external event, a state variable set, an operation from
//! outside, in the order the engine took them, at its times; nothing while recording is off.

use super::{AFTER_PREVIOUS, cmd, not_before, s};
use crate::sim::{Outcome, Sim, body, takes};
use crate::*;

#[test]
fn the_engine_records_its_inputs_in_order_with_their_times() {
    let mut sim = Sim::new();
    sim.engine.record_inputs(true);
    let root = sim.engine.root();
    let battery = sim
        .engine
        .declare_state("battery", Type::Float, Value::Float(1.0))
        .expect("declare");
    cmd(&mut sim.engine, root, "a", takes(s(1.0)), &[]);
    let fails = body(|_, _, _| Outcome::fail(s(1.0), "Blocked"));
    cmd(&mut sim.engine, root, "b", fails, &[AFTER_PREVIOUS]);
    cmd(
        &mut sim.engine,
        root,
        "late",
        takes(s(0.5)),
        &[not_before(5.0)],
    );
    sim.run_until(Time::ZERO + s(3.0));
    let go = sim.engine.external("go");
    sim.engine.handle_external(Time::ZERO + s(3.0), go);
    sim.engine
        .set_state(Time::ZERO + s(3.5), battery, Value::Float(0.4))
        .expect("set");
    sim.engine
        .note_control(Time::ZERO + s(4.0), "pause", "operator");
    sim.run();
    let mut got = Vec::new();
    let mut created: Vec<u64> = Vec::new();
    while let Some((t, nodes, mut input)) = sim.engine.poll_input() {
        created.push(nodes);
        // The scripted failure's message is the simulator's; its type is what matters here.
        if let InputRecord::Finished {
            failure: Some(f), ..
        } = &mut input
        {
            f.message.clear();
        }
        got.push((t.as_nanos() / 100_000_000, input));
    }
    let finished = |node: u64, failure: Option<&'static str>| InputRecord::Finished {
        node,
        tap: None,
        failure: failure.map(|e| Box::new(Failure::new(e, ""))),
    };
    assert_eq!(
        got,
        [
            (10, finished(1, None)),
            (20, finished(2, Some("Blocked"))),
            (30, InputRecord::External { name: "go".into() }),
            (
                35,
                InputRecord::State {
                    name: "battery".into(),
                    value: Value::Float(0.4)
                }
            ),
            (
                40,
                InputRecord::Control {
                    what: "pause".into(),
                    by: "operator".into(),
                    op: None,
                }
            ),
            (50, InputRecord::Time),
            (55, finished(3, None)),
        ]
    );
    // Each input with the steps the run had taken when it came in (each input or request given a
    // time is one): the places only grow.
    assert!(created.windows(2).all(|w| w[0] < w[1]), "{created:?}");
    assert!(created[6] < sim.engine.steps());
    // Off again: nothing more is recorded.
    sim.engine.record_inputs(false);
    sim.engine.handle_external(Time::ZERO + s(6.0), go);
    assert_eq!(sim.engine.poll_input(), None);
}

/// A reading of the shell's clock, taken for a command given the clock's time, is an input: a
/// replay gives the engine the same readings.
#[test]
fn each_reading_of_the_clock_is_recorded() {
    use std::sync::Arc;
    use std::sync::atomic::{AtomicU64, Ordering};
    let mut sim = Sim::new();
    let reading = Arc::new(AtomicU64::new(7_000_000_000));
    let clock = reading.clone();
    sim.engine.set_clock(Arc::new(move |_| {
        Time::from_nanos(clock.load(Ordering::Relaxed))
    }));
    sim.engine.record_inputs(true);
    let root = sim.engine.root();
    let now = sim.engine.at_clock();
    sim.engine
        .spawn(now, Spawn::new(root, NodeKind::Command, "a", takes(s(1.0))))
        .expect("spawn");
    assert_eq!(
        sim.engine.poll_input(),
        Some((Time::from_nanos(7_000_000_000), 1, InputRecord::Clock))
    );
    // Given a time, the engine reads no clock.
    reading.store(9_000_000_000, Ordering::Relaxed);
    sim.engine
        .spawn(
            Time::ZERO + s(8.0),
            Spawn::new(root, NodeKind::Command, "b", takes(s(1.0))),
        )
        .expect("spawn");
    assert_eq!(sim.engine.poll_input(), None);
}
