//! Story tests of the engine on virtual time, driven by [`crate::sim::Sim`].
//!
//! Each test builds a small tree with scripted actions, runs it, and asserts on the order of the
//! trace, rendered compactly by [`story`]: one line per transition, `<seconds> <name> <what>`.

use crate::sim::{Body, Outcome, Sim, SimEngine, body, noop, takes};
use crate::*;
use std::time::Duration;
use tcm_trace::{TraceEvent, TraceKind};

fn s(secs: f64) -> Duration {
    Duration::from_secs_f64(secs)
}

/// Renders a trace as lines `"<t> <name> <facet> <state>"` (plus termination, failure and
/// reclamation records), after checking it with the trace checker: every story test thus runs it.
fn story(trace: &[TraceEvent]) -> Vec<String> {
    assert_checked(trace);
    story_unchecked(trace)
}

fn story_unchecked(trace: &[TraceEvent]) -> Vec<String> {
    tcm_trace::story::story(trace)
}

use tcm_trace::story::{assert_order, only};

fn cmd(
    e: &mut SimEngine,
    parent: NodeId,
    name: &'static str,
    b: Body,
    cs: &[Constraint],
) -> NodeId {
    let mut spec = Spawn::new(parent, NodeKind::Command, name, b);
    spec.constraints = cs.to_vec();
    e.spawn(Time::ZERO.max(e.now()), spec).expect("spawn")
}

fn goal(
    e: &mut SimEngine,
    parent: NodeId,
    name: &'static str,
    b: Body,
    cs: &[Constraint],
) -> NodeId {
    let mut spec = Spawn::new(parent, NodeKind::Goal, name, b);
    spec.constraints = cs.to_vec();
    let now = e.now();
    e.spawn(now, spec).expect("spawn")
}

#[test]
fn sequential_execution_previous_chains_commands() {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    let e = &mut sim.engine;
    cmd(e, root, "a", takes(s(1.0)), &[]);
    cmd(
        e,
        root,
        "b",
        takes(s(1.0)),
        &[Constraint::sequential_previous()],
    );
    cmd(
        e,
        root,
        "c",
        takes(s(1.0)),
        &[Constraint::sequential_previous()],
    );
    sim.run();
    let st = only(&story(sim.trace()), &["handling"]);
    assert_eq!(
        st,
        [
            "0 a handling enabled",
            "0 a handling active",
            "1 a handling completed",
            "1 b handling enabled",
            "1 b handling active",
            "2 b handling completed",
            "2 c handling enabled",
            "2 c handling active",
            "3 c handling completed",
        ]
    );
}

#[test]
fn unconstrained_siblings_start_together_in_spawn_order() {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    for name in ["a", "b", "c"] {
        cmd(&mut sim.engine, root, name, takes(s(1.0)), &[]);
    }
    sim.run();
    let st = only(&story(sim.trace()), &["handling active"]);
    assert_eq!(
        st,
        [
            "0 a handling active",
            "0 b handling active",
            "0 c handling active"
        ]
    );
}

#[test]
fn serial_waits_for_whole_subtree_of_previous() {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    let e = &mut sim.engine;
    goal(
        e,
        root,
        "g",
        body(|e, me, _| {
            cmd(e, me, "inner", takes(s(2.0)), &[]);
            Outcome::done()
        }),
        &[],
    );
    cmd(
        e,
        root,
        "after",
        takes(s(1.0)),
        &[Constraint::Serial(NodeRef::Previous)],
    );
    sim.run();
    let st = story(sim.trace());
    assert_order(
        &st,
        &[
            "2 inner handling completed",
            "2 g execution completed",
            "2 after handling active",
        ],
    );
    assert!(!st.iter().any(|l| l.starts_with("0 after handling active")));
}

#[test]
fn sequential_expansion_and_handling() {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    let e = &mut sim.engine;
    let a = goal(e, root, "a", takes(s(1.0)), &[]);
    goal(
        e,
        root,
        "b",
        takes(s(1.0)),
        &[Constraint::Sequential(Facet::Expansion, a.into())],
    );
    cmd(
        e,
        root,
        "c",
        takes(s(1.0)),
        &[Constraint::Sequential(Facet::Handling, NodeRef::Previous)],
    );
    sim.run();
    let st = story(sim.trace());
    assert_order(
        &st,
        &[
            "1 a expansion completed",
            "1 b expansion enabled",
            "1 b handling active",
            "2 b handling completed",
            "2 c handling active",
        ],
    );
}

#[test]
fn disable_until_time_for_and_for_after() {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    let e = &mut sim.engine;
    let a = cmd(
        e,
        root,
        "a",
        takes(s(2.0)),
        &[Constraint::Disable(
            Facet::Handling,
            Until::Time(Time::ZERO + s(1.0)),
        )],
    );
    cmd(
        e,
        root,
        "b",
        noop(),
        &[Constraint::Disable(Facet::Handling, Until::For(s(0.5)))],
    );
    cmd(
        e,
        root,
        "c",
        noop(),
        &[Constraint::Disable(
            Facet::Execution,
            Until::ForAfter(s(0.25), Event::new(a, Point::Completed)),
        )],
    );
    sim.run();
    let st = only(&story(sim.trace()), &["handling active"]);
    assert_eq!(
        st,
        [
            "0.5 b handling active",
            "1 a handling active",
            "3.25 c handling active"
        ]
    );
}

#[test]
fn disable_until_an_active_event() {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    let e = &mut sim.engine;
    let a = cmd(
        e,
        root,
        "a",
        takes(s(1.0)),
        &[Constraint::Disable(Facet::Handling, Until::For(s(2.0)))],
    );
    cmd(
        e,
        root,
        "b",
        noop(),
        &[Constraint::Disable(
            Facet::Handling,
            Until::Event(Event::new(a, Point::Active)),
        )],
    );
    sim.run();
    assert_order(
        &story(sim.trace()),
        &["2 a handling active", "2 b handling enabled"],
    );
}

#[test]
fn expand_first_executes_only_after_the_whole_expansion() {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    let e = &mut sim.engine;
    goal(
        e,
        root,
        "plan",
        body(|e, me, _| {
            cmd(e, me, "act", takes(s(1.0)), &[]);
            goal(
                e,
                me,
                "subplan",
                body(|e, me, _| {
                    cmd(e, me, "act2", noop(), &[]);
                    Outcome::after(s(3.0))
                }),
                &[],
            );
            Outcome::done()
        }),
        &[Constraint::ExpandFirst],
    );
    sim.run();
    let st = story(sim.trace());
    assert_order(
        &st,
        &[
            "3 subplan handling completed",
            "3 plan expansion completed",
            "3 plan execution enabled",
            "3 act handling active",
        ],
    );
    assert!(!st.iter().any(|l| l.starts_with("0 act handling active")));
}

#[test]
fn delay_expansion_with_sequential_execution_is_fully_serial() {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    let e = &mut sim.engine;
    cmd(e, root, "first", takes(s(1.0)), &[]);
    goal(
        e,
        root,
        "second",
        body(|e, me, _| {
            cmd(e, me, "x", noop(), &[]);
            Outcome::done()
        }),
        &[
            Constraint::sequential_previous(),
            Constraint::DelayExpansion,
        ],
    );
    sim.run();
    let st = story(sim.trace());
    assert_order(
        &st,
        &[
            "1 first execution completed",
            "1 second execution enabled",
            "1 second expansion enabled",
            "1 second handling active",
        ],
    );
}

#[test]
fn terminate_in_and_at_time_cancel_running_actions() {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    let e = &mut sim.engine;
    cmd(
        e,
        root,
        "slow",
        body(|_, _, _| Outcome::Never),
        &[Constraint::Terminate(TerminateWhen::In(s(30.0)))],
    );
    cmd(
        e,
        root,
        "slow2",
        body(|_, _, _| Outcome::Never),
        &[Constraint::Terminate(TerminateWhen::Time(
            Time::ZERO + s(5.0),
        ))],
    );
    cmd(
        e,
        root,
        "quick",
        takes(s(1.0)),
        &[Constraint::Terminate(TerminateWhen::In(s(30.0)))],
    );
    sim.run();
    let st = story(sim.trace());
    assert_order(
        &st,
        &[
            "5 slow2 terminating",
            "5 slow2 handling completed",
            "5 slow2 terminated",
            "30 slow terminating",
            "30 slow terminated",
        ],
    );
    assert!(
        !st.iter().any(|l| l.contains("quick terminating")),
        "a completed node ignores its timer"
    );
    assert_eq!(sim.now(), Time::ZERO + s(30.0));
}

#[test]
fn terminate_at_event_and_in_after_event() {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    let e = &mut sim.engine;
    let m = cmd(e, root, "monitor", takes(s(4.0)), &[]);
    cmd(
        e,
        root,
        "speak",
        body(|_, _, _| Outcome::Never),
        &[Constraint::Terminate(TerminateWhen::Event(Event::new(
            m,
            Point::Completed,
        )))],
    );
    cmd(
        e,
        root,
        "linger",
        body(|_, _, _| Outcome::Never),
        &[Constraint::Terminate(TerminateWhen::InAfter(
            s(1.0),
            Event::new(m, Point::Active),
        ))],
    );
    sim.run();
    assert_order(
        &story(sim.trace()),
        &[
            "1 linger terminating",
            "4 monitor execution completed",
            "4 speak terminating",
            "4 speak terminated",
        ],
    );
}

#[test]
fn terminate_now_never_starts_the_action() {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    cmd(
        &mut sim.engine,
        root,
        "x",
        body(|_, _, _| panic!("must not run")),
        &[Constraint::Terminate(TerminateWhen::Now)],
    );
    sim.run();
    let st = story(sim.trace());
    assert!(!st.iter().any(|l| l.contains("active")), "{st:?}");
    assert_order(
        &st,
        &[
            "0 x terminating",
            "0 x handling completed",
            "0 x execution completed",
            "0 x terminated",
        ],
    );
}

#[test]
fn termination_of_a_middle_node_spares_siblings_and_releases_waiters() {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    let e = &mut sim.engine;
    let mid = goal(
        e,
        root,
        "mid",
        body(|e, me, _| {
            cmd(e, me, "leaf1", body(|_, _, _| Outcome::Never), &[]);
            cmd(
                e,
                me,
                "leaf2",
                takes(s(9.0)),
                &[Constraint::sequential_previous()],
            );
            Outcome::done()
        }),
        &[Constraint::Terminate(TerminateWhen::In(s(2.0)))],
    );
    cmd(e, root, "sibling", takes(s(5.0)), &[]);
    cmd(
        e,
        root,
        "after_mid",
        noop(),
        &[Constraint::Sequential(Facet::Execution, mid.into())],
    );
    sim.run();
    let st = story(sim.trace());
    assert_order(
        &st,
        &[
            "2 mid terminating",
            "2 leaf1 terminating",
            "2 leaf2 terminating",
            "2 leaf1 terminated",
            "2 leaf2 terminated",
            "2 mid terminated",
            "2 after_mid handling active",
            "5 sibling handling completed",
        ],
    );
    assert!(!st.iter().any(|l| l.contains("leaf2 handling active")));
}

#[test]
fn termination_constraints_on_a_terminated_reference_do_not_fire() {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    let e = &mut sim.engine;
    let a = cmd(
        e,
        root,
        "a",
        body(|_, _, _| Outcome::Never),
        &[Constraint::Terminate(TerminateWhen::In(s(1.0)))],
    );
    cmd(
        e,
        root,
        "b",
        takes(s(3.0)),
        &[Constraint::Terminate(TerminateWhen::Event(Event::new(
            a,
            Point::Completed,
        )))],
    );
    sim.run();
    let st = story(sim.trace());
    assert!(st.contains(&"1 a terminated".to_string()));
    assert!(!st.iter().any(|l| l.contains("b terminating")), "{st:?}");
    assert!(st.contains(&"3 b execution completed".to_string()));
}

#[test]
fn on_terminate_task_runs_to_completion() {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    let e = &mut sim.engine;
    let mut spec = Spawn::new(
        root,
        NodeKind::Command,
        "grasp",
        body(|_, _, _| Outcome::Never),
    );
    spec.on_terminate.push(OnTerminate {
        kind: NodeKind::Command,
        name: "release-onTerminate".into(),
        action: takes(s(2.0)),
    });
    spec.constraints
        .push(Constraint::Terminate(TerminateWhen::In(s(1.0))));
    e.spawn(Time::ZERO, spec).expect("spawn");
    // A node terminated before it starts runs no cleanup.
    let mut spec = Spawn::new(root, NodeKind::Command, "never", noop());
    spec.on_terminate.push(OnTerminate {
        kind: NodeKind::Command,
        name: "cleanup2".into(),
        action: noop(),
    });
    spec.constraints
        .push(Constraint::Disable(Facet::Handling, Until::For(s(10.0))));
    spec.constraints
        .push(Constraint::Terminate(TerminateWhen::In(s(1.0))));
    e.spawn(Time::ZERO, spec).expect("spawn");
    sim.run();
    let st = story(sim.trace());
    assert_order(
        &st,
        &[
            "1 grasp terminating",
            "1 release-onTerminate handling active",
            "3 release-onTerminate handling completed",
            "3 grasp terminated",
        ],
    );
    assert!(!st.iter().any(|l| l.contains("cleanup2")));
}

#[test]
fn suspension_holds_new_and_queued_work_until_unsuspended() {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    let e = &mut sim.engine;
    let g = goal(
        e,
        root,
        "g",
        body(|e, me, now| {
            e.suspend(now, me).expect("suspend");
            cmd(e, me, "child", noop(), &[]);
            Outcome::after(s(1.0))
        }),
        &[],
    );
    cmd(
        e,
        root,
        "waker",
        body(move |e, _, now| {
            e.unsuspend(now, g).expect("unsuspend");
            Outcome::done()
        }),
        &[Constraint::Disable(Facet::Handling, Until::For(s(5.0)))],
    );
    sim.run();
    let st = story(sim.trace());
    assert_order(
        &st,
        &[
            "0 g suspended",
            "0 child suspended",
            "5 g unsuspended",
            "5 child unsuspended",
            "5 child handling active",
        ],
    );
}

#[test]
fn forward_reference_to_a_later_spawn() {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    let e = &mut sim.engine;
    goal(
        e,
        root,
        "body",
        body(|e, me, now| {
            let later = e.reserve(now, me, "later").expect("reserve");
            cmd(
                e,
                me,
                "first",
                noop(),
                &[Constraint::Sequential(Facet::Execution, later.into())],
            );
            let mut spec = Spawn::new(me, NodeKind::Command, "later", takes(s(2.0)));
            spec.fulfils = Some(later);
            e.spawn(now, spec).expect("fulfil");
            Outcome::done()
        }),
        &[],
    );
    sim.run();
    assert_order(
        &story(sim.trace()),
        &[
            "0 later handling active",
            "2 later execution completed",
            "2 first handling active",
        ],
    );
}

#[test]
fn dead_reference_voids_enablement_and_fires_termination() {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    goal(
        &mut sim.engine,
        root,
        "body",
        body(|e, me, now| {
            let never = e.reserve(now, me, "never_spawned").expect("reserve");
            cmd(
                e,
                me,
                "waits",
                noop(),
                &[Constraint::Sequential(Facet::Execution, never.into())],
            );
            cmd(
                e,
                me,
                "doomed",
                body(|_, _, _| Outcome::Never),
                &[Constraint::Terminate(TerminateWhen::Event(Event::new(
                    never,
                    Point::Completed,
                )))],
            );
            Outcome::after(s(1.0))
        }),
        &[],
    );
    sim.run();
    assert_order(
        &story(sim.trace()),
        &[
            "1 body handling completed",
            "1 never_spawned dead",
            "1 doomed terminating",
            "1 waits handling active",
        ],
    );
}

#[test]
fn previous_with_nothing_before_is_void() {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    goal(
        &mut sim.engine,
        root,
        "g",
        body(|e, me, _| {
            cmd(e, me, "first", noop(), &[Constraint::sequential_previous()]);
            Outcome::done()
        }),
        &[],
    );
    sim.run();
    assert!(
        sim.trace()
            .iter()
            .any(|e| matches!(e.kind, TraceKind::ConstraintVoid { .. }))
    );
    assert!(story(sim.trace()).contains(&"0 first handling active".to_string()));
}

#[test]
fn external_events_gate_and_terminate() {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    let door = sim.engine.external("door_open");
    let stop = sim.engine.external("stop");
    let e = &mut sim.engine;
    cmd(
        e,
        root,
        "enter",
        noop(),
        &[Constraint::Disable(Facet::Handling, Until::External(door))],
    );
    cmd(
        e,
        root,
        "patrol",
        body(|_, _, _| Outcome::Never),
        &[Constraint::Terminate(TerminateWhen::External(stop))],
    );
    cmd(
        e,
        root,
        "button",
        body(move |e, _, now| {
            e.raise(now, door);
            e.raise(now, stop);
            Outcome::done()
        }),
        &[Constraint::Disable(Facet::Handling, Until::For(s(3.0)))],
    );
    sim.run();
    assert_order(
        &story(sim.trace()),
        &[
            "3 button handling active",
            "3 enter handling active",
            "3 patrol terminating",
        ],
    );
}

#[test]
fn unhandled_failure_completes_the_node_and_siblings_go_on() {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    let e = &mut sim.engine;
    cmd(
        e,
        root,
        "bad",
        body(|_, _, _| Outcome::After(s(1.0), Err(Failure::new("NoPath", "all routes blocked")))),
        &[],
    );
    cmd(
        e,
        root,
        "next",
        noop(),
        &[Constraint::sequential_previous()],
    );
    sim.run();
    let st = story(sim.trace());
    assert_order(
        &st,
        &[
            "1 bad failed NoPath",
            "1 bad handling completed",
            "1 next handling active",
        ],
    );
    assert!(sim.engine.fatal().is_none());
}

#[test]
fn fatal_policy_names_the_failing_node_and_its_path() {
    let mut sim = Sim::new();
    sim.engine.set_failure_policy(FailurePolicy::Fatal);
    let root = sim.engine.root();
    goal(
        &mut sim.engine,
        root,
        "deliver",
        body(|e, me, _| {
            cmd(
                e,
                me,
                "move",
                body(|_, _, _| {
                    Outcome::After(s(1.0), Err(Failure::new("Blocked", "cart in the way")))
                }),
                &[],
            );
            Outcome::done()
        }),
        &[],
    );
    sim.run();
    let fatal = sim.engine.fatal().expect("fatal failure recorded");
    assert_eq!(fatal.path, "deliver/move");
    assert_eq!(fatal.failure.exception, "Blocked");
    assert_eq!(
        fatal.to_string(),
        "unhandled exception Blocked in deliver/move {2}: cart in the way"
    );
}

#[test]
fn an_enablement_cycle_is_reported_not_hung() {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    goal(
        &mut sim.engine,
        root,
        "g",
        body(|e, me, now| {
            let b = e.reserve(now, me, "b").expect("reserve");
            let a = cmd(
                e,
                me,
                "a",
                noop(),
                &[Constraint::Sequential(Facet::Execution, b.into())],
            );
            let mut spec = Spawn::new(me, NodeKind::Command, "b", noop());
            spec.fulfils = Some(b);
            spec.constraints
                .push(Constraint::Sequential(Facet::Execution, a.into()));
            e.spawn(now, spec).expect("spawn b");
            Outcome::done()
        }),
        &[],
    );
    sim.run();
    assert!(sim.engine.is_idle());
    let blocked: Vec<String> = sim.engine.blocked().iter().map(|b| b.to_string()).collect();
    // `b` was reserved first, so it has the lower number.
    assert_eq!(
        blocked,
        [
            "b {2} execution waits for a {3} execution completed",
            "a {3} execution waits for b {2} execution completed"
        ]
    );
}

#[test]
fn misuse_gets_errors_not_panics() {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    assert_eq!(
        sim.engine.terminate(Time::ZERO, root),
        Err(EngineError::Root("terminated"))
    );
    let mut other: Engine<()> = Engine::new(2);
    let foreign = other
        .spawn(
            Time::ZERO,
            Spawn::new(other.root(), NodeKind::Command, "x", ()),
        )
        .expect("spawn");
    let err = sim.engine.spawn(
        Time::ZERO,
        Spawn::new(root, NodeKind::Command, "y", noop()).with(Constraint::Serial(foreign.into())),
    );
    assert!(
        matches!(err, Err(EngineError::ForeignNode { .. })),
        "{:?}",
        err.err()
    );
    assert!(matches!(
        sim.engine.terminate(Time::ZERO, foreign),
        Err(EngineError::ForeignNode { .. })
    ));
    let err = sim.engine.spawn(
        Time::ZERO,
        Spawn::new(root, NodeKind::Goal, "z", noop())
            .with(Constraint::ExpandFirst)
            .with(Constraint::DelayExpansion),
    );
    assert_eq!(err.err(), Some(EngineError::Inconsistent));
}

#[test]
fn completed_subtrees_are_reclaimed() {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    goal(
        &mut sim.engine,
        root,
        "g",
        body(|e, me, _| {
            for _ in 0..100 {
                cmd(e, me, "c", noop(), &[Constraint::sequential_previous()]);
            }
            Outcome::done()
        }),
        &[],
    );
    sim.run();
    assert_eq!(sim.engine.stats().live_nodes, 1, "only the root is left");
    assert_eq!(sim.engine.stats().created, 101);
}

#[test]
fn a_million_waited_children_keep_the_tree_small() {
    // See: issue 2 (a robot that runs for days must not grow).
    const N: u64 = 1_000_000;
    use std::cell::Cell;
    use std::rc::Rc;
    let done = Rc::new(Cell::new(0u64));
    let d2 = done.clone();
    let mut sim = Sim::new()
        .without_trace()
        .on_notify(move |e, token, _, now| {
            let parent = NodeId {
                run: 1,
                idx: (token.0 >> 32) as u32,
                generation: token.0 as u32,
            };
            d2.set(d2.get() + 1);
            if d2.get() < N {
                let child = e
                    .spawn(now, Spawn::new(parent, NodeKind::Command, "child", noop()))
                    .expect("spawn");
                e.watch(now, Event::new(child, Point::Completed), token)
                    .expect("watch");
            }
        });
    let root = sim.engine.root();
    let g = sim
        .engine
        .spawn(
            Time::ZERO,
            Spawn::new(
                root,
                NodeKind::Goal,
                "spawner",
                body(|_, _, _| Outcome::Never),
            ),
        )
        .expect("spawn");
    let token = WatchToken(((g.idx as u64) << 32) | g.generation as u64);
    let child = sim
        .engine
        .spawn(
            Time::ZERO,
            Spawn::new(g, NodeKind::Command, "child", noop()),
        )
        .expect("spawn");
    sim.engine
        .watch(Time::ZERO, Event::new(child, Point::Completed), token)
        .expect("watch");
    sim.run();
    assert_eq!(done.get(), N);
    let stats = sim.engine.stats();
    assert!(
        stats.high_water < 10,
        "high-water mark {}",
        stats.high_water
    );
    assert_eq!(stats.created, N + 1);
}

mod exceptions;
mod monitors;

/// Asserts the trace passes the trace checker, which looked at something.
#[track_caller]
fn assert_checked(trace: &[TraceEvent]) {
    match tcm_trace::check(trace) {
        Ok(r) => assert!(r.n_transitions > 0),
        Err(v) => {
            let v: Vec<String> = v.iter().map(ToString::to_string).collect();
            panic!(
                "trace checker:\n{}\nstory:\n{}",
                v.join("\n"),
                story_unchecked(trace).join("\n")
            );
        }
    }
}

#[test]
fn constraints_on_a_reservation_apply_when_it_is_spawned() {
    // See: a constraint statement on a task the body spawns later (`f2 serial f1;` before `spawn f2`).
    let mut sim = Sim::new();
    let root = sim.engine.root();
    goal(
        &mut sim.engine,
        root,
        "body",
        body(|e, me, now| {
            let f2 = e.reserve(now, me, "f2").expect("reserve");
            let f1 = cmd(e, me, "f1", takes(s(2.0)), &[]);
            e.constrain(now, f2, Constraint::Serial(f1.into()))
                .expect("constrain a reservation");
            e.constrain(now, f2, Constraint::Terminate(TerminateWhen::In(s(10.0))))
                .expect("constrain");
            let mut spec = Spawn::new(me, NodeKind::Command, "f2", body(|_, _, _| Outcome::Never));
            spec.fulfils = Some(f2);
            e.spawn(now, spec).expect("fulfil");
            Outcome::done()
        }),
        &[],
    );
    sim.run();
    assert_order(
        &story(sim.trace()),
        &[
            "2 f1 execution completed",
            "2 f2 handling active",
            "10 f2 terminating",
        ],
    );
    assert_checked(sim.trace());
}

#[test]
fn held_children_start_when_the_body_ends() {
    // TDL: the body finishes before its children run, so a constraint statement after a spawn applies.
    let mut sim = Sim::new();
    let root = sim.engine.root();
    goal(
        &mut sim.engine,
        root,
        "body",
        body(|e, me, now| {
            e.hold_children(now, me, true).expect("hold");
            let a = cmd(e, me, "a", takes(s(1.0)), &[]);
            let b = cmd(e, me, "b", takes(s(1.0)), &[]);
            e.constrain(now, b, Constraint::Serial(a.into()))
                .expect("b has not started yet");
            Outcome::after(s(0.5))
        }),
        &[],
    );
    sim.run();
    assert_eq!(
        only(&story(sim.trace()), &["handling active"]),
        [
            "0 body handling active",
            "0.5 a handling active",
            "1.5 b handling active"
        ]
    );
    assert_checked(sim.trace());
}

#[test]
fn a_node_stays_small() {
    // Nodes are the engine's bulk: a million alive at once must fit in a few hundred megabytes.
    // See: issue 6 (1M-node W1 within 250 MB).
    let size =
        std::mem::size_of::<crate::engine::node::Node<crate::sim::Body, crate::sim::Factory>>();
    assert!(size <= 208, "a node takes {size} bytes");
}

#[test]
fn watching_a_relative_reference_is_refused() {
    let mut sim = Sim::new();
    let err = sim.engine.watch(
        Time::ZERO,
        Event::new(NodeRef::Previous, Point::Completed),
        WatchToken(1),
    );
    assert_eq!(err, Err(EngineError::RelativeRef));
}
