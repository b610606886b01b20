//! Steering stories (`engine/steer.rs`): a breakpoint before a start, stepping, continuing; timers
//! and polling schedules held by a pause; breakpoints after an end, on an exception and on a
//! handler; faults that fail a node or keep it running; approvals given, refused and timed out.

use super::{AFTER_PREVIOUS, assert_checked, cmd, goal, never, not_before, s, spawns, stop_in};
use crate::sim::{Body, Outcome, Sim, body, factory, takes};
use crate::*;
use std::cell::Cell;
use std::rc::Rc;
use tcm_trace::{TraceEvent, TraceKind};

/// Seconds as engine time.
fn at(secs: f64) -> Time {
    Time::ZERO + s(secs)
}

/// The time (seconds) and display number of each `handling active` of a node named `name`.
fn starts(trace: &[TraceEvent], name: &str) -> Vec<f64> {
    let names = names(trace);
    trace
        .iter()
        .filter_map(|e| match e.kind {
            TraceKind::Transition {
                node,
                facet: Facet::Handling,
                to: State::Active,
                ..
            } if names.get(&node).is_some_and(|n| n == name) => Some(e.t as f64 / 1e9),
            _ => None,
        })
        .collect()
}

fn names(trace: &[TraceEvent]) -> std::collections::BTreeMap<u64, String> {
    trace
        .iter()
        .filter_map(|e| match &e.kind {
            TraceKind::Spawned { node, name, .. } => Some((*node, name.clone())),
            _ => None,
        })
        .collect()
}

/// The `why` of each `paused` record, in order.
fn pauses(trace: &[TraceEvent]) -> Vec<String> {
    trace
        .iter()
        .filter_map(|e| match &e.kind {
            TraceKind::Paused { why, .. } => Some(why.clone()),
            _ => None,
        })
        .collect()
}

/// A goal `g` whose body spawns the commands `a`, `b`, `c` in sequence, each taking a second.
fn three_in_a_row(sim: &mut Sim) {
    let root = sim.engine.root();
    goal(
        &mut sim.engine,
        root,
        "g",
        spawns(0.0, |e, me, _| {
            cmd(e, me, "a", takes(s(1.0)), &[]);
            cmd(e, me, "b", takes(s(1.0)), &[AFTER_PREVIOUS]);
            cmd(e, me, "c", takes(s(1.0)), &[AFTER_PREVIOUS]);
        }),
        &[],
    );
}

#[test]
fn a_breakpoint_pauses_before_the_start_then_steps_and_continues() {
    let mut sim = Sim::new();
    sim.engine.add_breakpoint(
        Time::ZERO,
        Breakpoint {
            at: BreakAt::Start,
            on: Matcher::Task("b".into()),
        },
        "tester",
    );
    three_in_a_row(&mut sim);
    // The clock stops at the pause, with `b` ready and not started.
    assert_eq!(sim.run(), at(1.0));
    assert!(sim.engine.is_paused());
    assert!(starts(sim.trace(), "b").is_empty());
    let last_pause = sim.trace().iter().rev().find_map(|e| match &e.kind {
        TraceKind::Paused { node, why } => Some((*node, why.clone())),
        _ => None,
    });
    assert_eq!(
        last_pause,
        Some((Some(3), "breakpoint #1: before b {3}".into()))
    );
    // A step starts `b` (its breakpoint passed) and pauses again; nothing else moves.
    assert!(sim.engine.step(at(1.0), "tester"));
    sim.run();
    assert!(sim.engine.is_paused());
    assert_eq!(starts(sim.trace(), "b"), vec![1.0]);
    assert_eq!(sim.run(), at(1.0), "paused: the clock stays");
    // Continue: `b` ends, `c` runs, the run ends.
    assert!(sim.engine.resume(at(1.0), "tester"));
    sim.run();
    assert_eq!(starts(sim.trace(), "c"), vec![2.0]);
    assert_eq!(
        pauses(sim.trace()),
        vec!["breakpoint #1: before b {3}", "step"]
    );
    assert!(sim.engine.is_idle());
    assert_checked(sim.trace());
    let controls: Vec<String> = sim
        .trace()
        .iter()
        .filter_map(|e| match &e.kind {
            TraceKind::Control { what, by } if by == "tester" => Some(what.clone()),
            _ => None,
        })
        .collect();
    assert_eq!(
        controls,
        vec![
            "breakpoint before the start of task b (#1)",
            "step",
            "continue"
        ]
    );
}

#[test]
fn step_to_the_next_start_pauses_before_it() {
    let mut sim = Sim::new();
    assert!(sim.engine.pause(Time::ZERO, "tester"));
    three_in_a_row(&mut sim);
    assert!(!sim.engine.pause(Time::ZERO, "tester"), "already paused");
    sim.run();
    assert!(starts(sim.trace(), "g").is_empty(), "nothing starts");
    // To the next start: the goal's turn; a step starts it; its children are then ready.
    sim.engine.step_to_start(Time::ZERO, "tester");
    sim.run();
    assert!(sim.engine.is_paused());
    assert!(starts(sim.trace(), "g").is_empty());
    sim.engine.step(Time::ZERO, "tester");
    sim.run();
    assert_eq!(starts(sim.trace(), "g"), vec![0.0]);
    assert!(starts(sim.trace(), "a").is_empty());
    sim.engine.step(Time::ZERO, "tester");
    sim.run();
    assert_eq!(starts(sim.trace(), "a"), vec![0.0]);
    sim.engine.resume(Time::ZERO, "tester");
    sim.run();
    assert_eq!(starts(sim.trace(), "c"), vec![2.0]);
    assert_checked(sim.trace());
}

/// A simulator with one command `late`, which may start at 5 s, taking a second.
fn late_at_five() -> Sim {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    cmd(
        &mut sim.engine,
        root,
        "late",
        takes(s(1.0)),
        &[not_before(5.0)],
    );
    sim
}

#[test]
fn a_step_with_nothing_ready_fires_the_next_timer() {
    let mut sim = late_at_five();
    sim.engine.pause(Time::ZERO, "tester");
    sim.run();
    // The step fires the timer (the clock moves to it), which makes `late` ready; it waits.
    sim.engine.step(Time::ZERO, "tester");
    assert_eq!(sim.run(), at(5.0));
    assert!(sim.engine.is_paused());
    assert!(starts(sim.trace(), "late").is_empty());
    sim.engine.step(at(5.0), "tester");
    sim.run();
    assert_eq!(starts(sim.trace(), "late"), vec![5.0]);
    sim.engine.resume(at(5.0), "tester");
    sim.run();
    assert_checked(sim.trace());
}

#[test]
fn a_pause_holds_the_timers_and_a_monitors_schedule() {
    let mut sim = late_at_five();
    let mut spec = MonitorSpec::new(factory(|_, _, _, _| Outcome::done()));
    spec.period = Some(s(1.0));
    spec.max_activations = Some(5);
    sim.engine
        .spawn(Time::ZERO, Spawn::monitor(sim.engine.root(), "tick", spec))
        .expect("spawn");
    sim.run_until(at(2.5));
    // Paused from 2.5 s to 5.5 s of the run's clock, as on real time: the pending timers move
    // 3 s later.
    sim.engine.pause(at(2.5), "tester");
    sim.engine.resume(at(5.5), "tester");
    sim.run();
    let activations: Vec<f64> = sim
        .trace()
        .iter()
        .filter(|e| matches!(e.kind, TraceKind::Activated { .. }))
        .map(|e| e.t as f64 / 1e9)
        .collect();
    assert_eq!(activations, vec![0.0, 1.0, 2.0, 6.0, 7.0]);
    assert_eq!(starts(sim.trace(), "late"), vec![8.0]);
    assert!(sim.trace().iter().any(|e| e.kind
        == TraceKind::Resumed {
            held_ns: 3_000_000_000
        }));
    assert_checked(sim.trace());
}

/// A goal `g` with a handler `detour` of `Blocked`, whose body spawns `move` twice in a row.
fn moves_with_detour(sim: &mut Sim, ran: Rc<Cell<u32>>) {
    let root = sim.engine.root();
    let mv = move || -> Body {
        let ran = ran.clone();
        body(move |_, _, _| {
            ran.set(ran.get() + 1);
            Outcome::after(s(1.0))
        })
    };
    let mut sp = Spawn::new(
        root,
        NodeKind::Goal,
        "g",
        spawns(0.0, move |e, me, _| {
            cmd(e, me, "move", mv(), &[]);
            cmd(e, me, "move", mv(), &[AFTER_PREVIOUS]);
        }),
    );
    sp.handlers = vec![HandlerSpec {
        name: "detour".into(),
        exception: "Blocked".into(),
        max_activations: None,
        body: factory(|_, _, _, _| Outcome::after(s(0.5))),
    }];
    sim.engine.spawn(Time::ZERO, sp).expect("spawn");
}

/// The next `move` fails with `Blocked`.
fn next_move_blocked() -> Fault {
    Fault {
        on: Matcher::Task("move".into()),
        times: 1,
        outcome: FaultOutcome::Fail(Failure::new("Blocked", "injected")),
    }
}

#[test]
fn a_fault_fails_the_next_node_of_a_task_without_running_it() {
    let mut sim = Sim::new();
    let ran = Rc::new(Cell::new(0));
    sim.engine.inject(Time::ZERO, next_move_blocked(), "tester");
    moves_with_detour(&mut sim, ran.clone());
    sim.run();
    assert_eq!(
        ran.get(),
        1,
        "the first move's action never ran; the second did"
    );
    let t = sim.trace();
    let names = names(t);
    assert!(t.iter().any(|e| matches!(&e.kind,
        TraceKind::Injected { node, outcome } if names[node] == "move" && outcome == "fail Blocked: injected")));
    assert!(t.iter().any(
        |e| matches!(&e.kind, TraceKind::HandlerChosen { handler, .. } if handler == "detour")
    ));
    assert_eq!(starts(t, "move"), vec![0.0, 0.5]);
    assert_checked(t);
}

#[test]
fn a_never_ending_fault_runs_until_terminated() {
    let mut sim = Sim::new();
    let ran = Rc::new(Cell::new(0));
    let counted = ran.clone();
    let root = sim.engine.root();
    sim.engine.inject(
        Time::ZERO,
        Fault {
            on: Matcher::Path("stuck".into()),
            times: 3,
            outcome: FaultOutcome::Never,
        },
        "tester",
    );
    let b = body(move |_, _, _| {
        counted.set(counted.get() + 1);
        Outcome::after(s(1.0))
    });
    cmd(&mut sim.engine, root, "stuck", b, &[stop_in(4.0)]);
    cmd(
        &mut sim.engine,
        root,
        "after",
        takes(s(1.0)),
        &[AFTER_PREVIOUS],
    );
    sim.run();
    assert_eq!(ran.get(), 0);
    let t = sim.trace();
    assert!(
        t.iter()
            .any(|e| matches!(e.kind, TraceKind::Terminated { node: 1 }) && e.t == 4_000_000_000)
    );
    assert_eq!(starts(t, "after"), vec![4.0]);
    assert_checked(t);
    assert!(sim.engine.is_idle());
}

#[test]
fn breakpoints_after_an_end_on_an_exception_and_on_a_handler() {
    for (at_, on, expect) in [
        (
            BreakAt::End,
            Matcher::Task("move".into()),
            "breakpoint #1: after the end of move {2}",
        ),
        (
            BreakAt::Raised,
            Matcher::Exception("Blocked".into()),
            "breakpoint #1: exception raised by move {2}",
        ),
        (
            BreakAt::Handler,
            Matcher::Task("detour".into()),
            "breakpoint #1: handler chosen: detour {3}",
        ),
    ] {
        let mut sim = Sim::new();
        sim.engine
            .add_breakpoint(Time::ZERO, Breakpoint { at: at_, on }, "tester");
        sim.engine.inject(Time::ZERO, next_move_blocked(), "tester");
        moves_with_detour(&mut sim, Rc::new(Cell::new(0)));
        sim.run();
        assert!(sim.engine.is_paused(), "{expect}");
        assert_eq!(pauses(sim.trace()), vec![expect]);
        sim.engine.resume(sim.now(), "tester");
        sim.run();
        assert!(sim.engine.is_idle() || sim.engine.is_paused());
        assert_checked(sim.trace());
    }
}

/// A command `arm` that takes a second, under an approval rule with `timeout`.
fn arm_needing_approval(timeout: Option<f64>) -> (Sim, NodeId) {
    let mut sim = Sim::new();
    sim.engine.require_approval(
        Time::ZERO,
        Approval {
            on: Matcher::Task("arm".into()),
            timeout: timeout.map(s),
        },
        "tester",
    );
    let root = sim.engine.root();
    let arm = cmd(&mut sim.engine, root, "arm", takes(s(1.0)), &[]);
    sim.run();
    (sim, arm)
}

#[test]
fn an_approved_node_starts_and_a_refused_one_fails() {
    let (mut sim, arm) = arm_needing_approval(None);
    assert_eq!(sim.engine.held(), vec![arm]);
    assert!(starts(sim.trace(), "arm").is_empty());
    assert!(sim.engine.is_idle(), "held, nothing else to do");
    sim.engine.approve(at(0.0), arm, "operator").expect("held");
    assert!(matches!(
        sim.engine.approve(at(0.0), arm, "operator"),
        Err(EngineError::NotHeld(_))
    ));
    sim.run();
    assert_eq!(starts(sim.trace(), "arm"), vec![0.0]);
    assert!(
        sim.trace()
            .iter()
            .any(|e| matches!(&e.kind, TraceKind::Approved { node: 1, by } if by == "operator"))
    );
    assert_checked(sim.trace());

    let (mut sim, arm) = arm_needing_approval(None);
    sim.engine
        .refuse(at(0.0), arm, "operator", "the arm is blocked")
        .expect("held");
    sim.run();
    assert!(starts(sim.trace(), "arm").is_empty());
    assert!(sim.trace().iter().any(|e| matches!(&e.kind,
        TraceKind::Failed { node: 1, exception, message } if exception == "ApprovalRefused" && message == "not approved: the arm is blocked")));
    assert_checked(sim.trace());
}

#[test]
fn a_node_not_approved_in_time_fails() {
    let (sim, _arm) = arm_needing_approval(Some(3.0));
    assert_eq!(sim.now(), at(3.0));
    assert!(sim.engine.held().is_empty());
    let failed = sim.trace().iter().find_map(|e| match &e.kind {
        TraceKind::Failed { message, .. } => Some((e.t, message.clone())),
        _ => None,
    });
    assert_eq!(
        failed,
        Some((3_000_000_000, "not approved: no approval within 3s".into()))
    );
    assert_checked(sim.trace());
}

#[test]
fn release_clears_breakpoints_approves_the_held_and_resumes() {
    let (mut sim, arm) = arm_needing_approval(None);
    let root = sim.engine.root();
    sim.engine.add_breakpoint(
        Time::ZERO,
        Breakpoint {
            at: BreakAt::Start,
            on: Matcher::Any,
        },
        "page",
    );
    cmd(&mut sim.engine, root, "other", never(), &[stop_in(2.0)]);
    sim.run();
    assert!(sim.engine.is_paused());
    sim.engine.release(Time::ZERO, "page");
    assert!(!sim.engine.is_paused());
    sim.run();
    assert_eq!(starts(sim.trace(), "arm"), vec![0.0]);
    assert_eq!(starts(sim.trace(), "other"), vec![0.0]);
    assert!(sim.engine.held().is_empty());
    let _ = arm;
    assert_checked(sim.trace());
}

#[test]
fn a_spawn_asking_for_approval_is_held_without_any_rule() {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    let sp = Spawn::new(root, NodeKind::Command, "grasp", takes(s(1.0)))
        .with(Constraint::Approval(Some(s(2.0))));
    let grasp = sim.engine.spawn(Time::ZERO, sp).expect("spawn");
    let sp = Spawn::new(root, NodeKind::Command, "grasp", takes(s(1.0)))
        .with(Constraint::Approval(None));
    let other = sim.engine.spawn(Time::ZERO, sp).expect("spawn");
    sim.run();
    // The first timed out at 2 s; the other still waits.
    assert_eq!(sim.engine.held(), vec![other]);
    assert!(sim.trace().iter().any(|e| matches!(&e.kind,
        TraceKind::Failed { node: 1, exception, .. } if exception == "ApprovalRefused")
        && e.t == 2_000_000_000));
    sim.engine
        .approve(at(2.0), other, "operator")
        .expect("held");
    sim.run();
    assert_eq!(starts(sim.trace(), "grasp"), vec![2.0]);
    let _ = grasp;
    assert_checked(sim.trace());
}

#[test]
fn a_fault_with_a_value_succeeds_at_once_without_running_the_action() {
    let mut sim = Sim::new();
    let ran = Rc::new(Cell::new(0));
    sim.engine.inject(
        Time::ZERO,
        Fault {
            on: Matcher::Task("move".into()),
            times: 2,
            outcome: FaultOutcome::Succeed(Some(FaultValue::of(7u32))),
        },
        "tester",
    );
    moves_with_detour(&mut sim, ran.clone());
    sim.run();
    assert_eq!(ran.get(), 0, "neither move ran");
    let t = sim.trace();
    let injected = t
        .iter()
        .filter(|e| matches!(&e.kind, TraceKind::Injected { outcome, .. } if outcome == "succeed with 7"))
        .count();
    assert_eq!(injected, 2);
    assert_eq!(starts(t, "move"), vec![0.0, 0.0]);
    assert!(!t.iter().any(|e| matches!(e.kind, TraceKind::Failed { .. })));
    assert_checked(t);
}
