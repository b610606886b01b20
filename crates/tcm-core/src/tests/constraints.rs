//! Ordering constraints: `sequential`, `serial`, `disable … until`, `expand first`, `delay
//! expansion`, and an enablement cycle.

use super::{AFTER_PREVIOUS, check, cmd, goal, not_before, s, spawn_with, spawns};
use crate::sim::{noop, takes};
use crate::*;

#[test]
fn sequential_execution_previous_chains_commands() {
    check(
        |e, root| {
            cmd(e, root, "a", takes(s(1.0)), &[]);
            cmd(e, root, "b", takes(s(1.0)), &[AFTER_PREVIOUS]);
            cmd(e, root, "c", takes(s(1.0)), &[AFTER_PREVIOUS]);
        },
        "
        0 a execution enabled
        0 a handling enabled
        0 a handling active
        0 a execution active
        1 a handling completed
        1 a execution completed
        1 b execution enabled
        1 b handling enabled
        1 b handling active
        1 b execution active
        2 b handling completed
        2 b execution completed
        2 c execution enabled
        2 c handling enabled
        2 c handling active
        2 c execution active
        3 c handling completed
        3 c execution completed
        ",
    );
}

#[test]
fn unconstrained_siblings_start_together_in_spawn_order() {
    check(
        |e, root| {
            for name in ["a", "b", "c"] {
                cmd(e, root, name, takes(s(1.0)), &[]);
            }
        },
        "
        0 a execution enabled
        0 a handling enabled
        0 a handling active
        0 a execution active
        0 b execution enabled
        0 b handling enabled
        0 b handling active
        0 b execution active
        0 c execution enabled
        0 c handling enabled
        0 c handling active
        0 c execution active
        1 a handling completed
        1 a execution completed
        1 b handling completed
        1 b execution completed
        1 c handling completed
        1 c execution completed
        ",
    );
}

#[test]
fn serial_waits_for_whole_subtree_of_previous() {
    check(
        |e, root| {
            let g = spawns(0.0, |e, me, _| cmd(e, me, "inner", takes(s(2.0)), &[]));
            goal(e, root, "g", g, &[]);
            let serial = Constraint::Serial(NodeRef::Previous);
            cmd(e, root, "after", takes(s(1.0)), &[serial]);
        },
        "
        0 g expansion enabled
        0 g execution enabled
        0 g handling enabled
        0 g handling active
        0 g expansion active
        0 inner execution enabled
        0 inner handling enabled
        0 inner handling active
        0 inner execution active
        0 g execution active
        0 g handling completed
        0 g expansion completed
        2 inner handling completed
        2 inner execution completed
        2 g execution completed
        2 after execution enabled
        2 after handling enabled
        2 after handling active
        2 after execution active
        3 after handling completed
        3 after execution completed
        ",
    );
}

#[test]
fn sequential_expansion_and_handling() {
    check(
        |e, root| {
            let a = goal(e, root, "a", takes(s(1.0)), &[]);
            let after_a = Constraint::Sequential(Facet::Expansion, a.into());
            goal(e, root, "b", takes(s(1.0)), &[after_a]);
            let after_b = Constraint::Sequential(Facet::Handling, NodeRef::Previous);
            cmd(e, root, "c", takes(s(1.0)), &[after_b]);
        },
        "
        0 a expansion enabled
        0 a execution enabled
        0 a handling enabled
        0 a handling active
        0 a expansion active
        0 b execution enabled
        0 c execution enabled
        1 a handling completed
        1 a expansion completed
        1 a execution completed
        1 b expansion enabled
        1 b handling enabled
        1 b handling active
        1 b expansion active
        2 b handling completed
        2 c handling enabled
        2 b expansion completed
        2 b execution completed
        2 c handling active
        2 c execution active
        3 c handling completed
        3 c execution completed
        ",
    );
}

#[test]
fn disable_until_time_for_and_for_after() {
    check(
        |e, root| {
            let at_1 = Constraint::disable(Facet::Handling, When::At(Time::ZERO + s(1.0)));
            let a = cmd(e, root, "a", takes(s(2.0)), &[at_1]);
            cmd(e, root, "b", noop(), &[not_before(0.5)]);
            let a_done = Event::new(a, Point::Completed);
            let after = Constraint::disable(Facet::Execution, When::After(s(0.25), a_done));
            cmd(e, root, "c", noop(), &[after]);
        },
        "
        0 a execution enabled
        0 b execution enabled
        0.5 b handling enabled
        0.5 b handling active
        0.5 b execution active
        0.5 b handling completed
        0.5 b execution completed
        1 a handling enabled
        1 a handling active
        1 a execution active
        3 a handling completed
        3 a execution completed
        3.25 c execution enabled
        3.25 c handling enabled
        3.25 c handling active
        3.25 c execution active
        3.25 c handling completed
        3.25 c execution completed
        ",
    );
}

#[test]
fn disable_until_an_active_event() {
    check(
        |e, root| {
            let a = cmd(e, root, "a", takes(s(1.0)), &[not_before(2.0)]);
            let a_active = When::Event(Event::new(a, Point::Active));
            let until_a_active = Constraint::disable(Facet::Handling, a_active);
            cmd(e, root, "b", noop(), &[until_a_active]);
        },
        "
        0 a execution enabled
        0 b execution enabled
        2 a handling enabled
        2 a handling active
        2 a execution active
        2 b handling enabled
        2 b handling active
        2 b execution active
        2 b handling completed
        2 b execution completed
        3 a handling completed
        3 a execution completed
        ",
    );
}

#[test]
fn expand_first_executes_only_after_the_whole_expansion() {
    check(
        |e, root| {
            let plan = spawns(0.0, |e, me, _| {
                cmd(e, me, "act", takes(s(1.0)), &[]);
                let subplan = spawns(3.0, |e, me, _| cmd(e, me, "act2", noop(), &[]));
                goal(e, me, "subplan", subplan, &[]);
            });
            goal(e, root, "plan", plan, &[Constraint::ExpandFirst]);
        },
        "
        0 plan expansion enabled
        0 plan handling enabled
        0 plan handling active
        0 plan expansion active
        0 subplan expansion enabled
        0 subplan handling enabled
        0 subplan handling active
        0 subplan expansion active
        0 plan handling completed
        3 subplan handling completed
        3 subplan expansion completed
        3 plan expansion completed
        3 plan execution enabled
        3 act execution enabled
        3 act handling enabled
        3 subplan execution enabled
        3 act2 execution enabled
        3 act2 handling enabled
        3 act handling active
        3 act execution active
        3 plan execution active
        3 act2 handling active
        3 act2 execution active
        3 subplan execution active
        3 act2 handling completed
        3 act2 execution completed
        3 subplan execution completed
        4 act handling completed
        4 act execution completed
        4 plan execution completed
        ",
    );
}

#[test]
fn delay_expansion_with_sequential_execution_is_fully_serial() {
    check(
        |e, root| {
            cmd(e, root, "first", takes(s(1.0)), &[]);
            let second = spawns(0.0, |e, me, _| cmd(e, me, "x", noop(), &[]));
            let cs = [AFTER_PREVIOUS, Constraint::DelayExpansion];
            goal(e, root, "second", second, &cs);
        },
        "
        0 first execution enabled
        0 first handling enabled
        0 first handling active
        0 first execution active
        1 first handling completed
        1 first execution completed
        1 second execution enabled
        1 second expansion enabled
        1 second handling enabled
        1 second handling active
        1 second expansion active
        1 x execution enabled
        1 x handling enabled
        1 x handling active
        1 x execution active
        1 second execution active
        1 second handling completed
        1 second expansion completed
        1 x handling completed
        1 x execution completed
        1 second execution completed
        ",
    );
}

#[test]
fn an_enablement_cycle_is_reported_not_hung() {
    let mut r = check(
        |e, root| {
            let g = spawns(0.0, |e, me, now| {
                let b = e.reserve(now, me, "b").expect("reserve");
                let after_b = Constraint::Sequential(Facet::Execution, b.into());
                let a = cmd(e, me, "a", noop(), &[after_b]);
                let mut spec = Spawn::new(me, NodeKind::Command, "b", noop());
                spec.fulfils = Some(b);
                spawn_with(
                    e,
                    spec,
                    &[Constraint::Sequential(Facet::Execution, a.into())],
                );
            });
            goal(e, root, "cycle", g, &[]);
        },
        "
        0 cycle expansion enabled
        0 cycle execution enabled
        0 cycle handling enabled
        0 cycle handling active
        0 cycle expansion active
        0 cycle handling completed
        0 cycle expansion completed
        ",
    );
    assert!(r.sim.engine.is_idle());
    let blocked: Vec<String> = r
        .sim
        .engine
        .blocked()
        .iter()
        .map(ToString::to_string)
        .collect();
    // `b` was reserved first, so it has the lower number.
    assert_eq!(
        blocked,
        [
            "b {2} execution waits for a {3} execution completed",
            "a {3} execution waits for b {2} execution completed"
        ]
    );
}
