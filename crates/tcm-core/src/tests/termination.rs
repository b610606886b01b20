//! Termination: `terminate` constraints (in, at, at an event, after an event, now), the cascade
//! through a subtree, withdrawn starts, on-terminate tasks, and suspension.

use super::{AFTER_PREVIOUS, check, cmd, goal, never, not_before, s, spawn_with, spawns, stop_in};
use crate::sim::{Body, Outcome, body, noop, takes};
use crate::*;

/// `terminate when <node> reaches <point>`.
fn stop_when(node: impl Into<NodeRef>, point: Point) -> Constraint {
    Constraint::terminate(When::Event(Event::new(node, point)))
}

/// An action that must never run.
fn must_not_run() -> Body {
    body(|_, _, _| panic!("must not run"))
}

#[test]
fn terminate_in_and_at_time_cancel_running_actions() {
    let r = check(
        |e, root| {
            cmd(e, root, "slow", never(), &[stop_in(30.0)]);
            let at_5 = Constraint::terminate(When::At(Time::ZERO + s(5.0)));
            cmd(e, root, "slow2", never(), &[at_5]);
            // A completed node ignores its timer.
            cmd(e, root, "quick", takes(s(1.0)), &[stop_in(30.0)]);
        },
        "
        0 slow execution enabled
        0 slow handling enabled
        0 slow handling active
        0 slow execution active
        0 slow2 execution enabled
        0 slow2 handling enabled
        0 slow2 handling active
        0 slow2 execution active
        0 quick execution enabled
        0 quick handling enabled
        0 quick handling active
        0 quick execution active
        1 quick handling completed
        1 quick execution completed
        5 slow2 terminating
        5 slow2 handling completed
        5 slow2 execution completed
        5 slow2 terminated
        30 slow terminating
        30 slow handling completed
        30 slow execution completed
        30 slow terminated
        ",
    );
    assert_eq!(r.sim.now(), Time::ZERO + s(30.0));
}

#[test]
fn terminate_at_event_and_in_after_event() {
    check(
        |e, root| {
            let m = cmd(e, root, "monitor", takes(s(4.0)), &[]);
            cmd(e, root, "speak", never(), &[stop_when(m, Point::Completed)]);
            let after_m_active = When::After(s(1.0), Event::new(m, Point::Active));
            let linger = Constraint::terminate(after_m_active);
            cmd(e, root, "linger", never(), &[linger]);
        },
        "
        0 monitor execution enabled
        0 monitor handling enabled
        0 monitor handling active
        0 monitor execution active
        0 speak execution enabled
        0 speak handling enabled
        0 speak handling active
        0 speak execution active
        0 linger execution enabled
        0 linger handling enabled
        0 linger handling active
        0 linger execution active
        1 linger terminating
        1 linger handling completed
        1 linger execution completed
        1 linger terminated
        4 monitor handling completed
        4 monitor execution completed
        4 speak terminating
        4 speak handling completed
        4 speak execution completed
        4 speak terminated
        ",
    );
}

#[test]
fn terminate_now_never_starts_the_action() {
    check(
        |e, root| {
            let now = Constraint::terminate(When::Now);
            cmd(e, root, "x", must_not_run(), &[now]);
        },
        "
        0 x terminating
        0 x execution enabled
        0 x handling enabled
        0 x handling completed
        0 x execution completed
        0 x terminated
        ",
    );
}

#[test]
fn a_node_started_and_terminated_in_one_call_never_runs() {
    // `x` is terminated as soon as its handling is active: the engine withdraws its queued start,
    // so the simulator never runs the action. `y`, spawned and terminated by its parent's body,
    // likewise: its start was still queued.
    check(
        |e, root| {
            let when_started = stop_when(NodeRef::This, Point::Active);
            cmd(e, root, "x", must_not_run(), &[when_started]);
            let parent = spawns(0.0, |e, me, now| {
                let y = cmd(e, me, "y", must_not_run(), &[]);
                e.terminate(now, y).expect("terminate");
            });
            goal(e, root, "parent", parent, &[]);
        },
        "
        0 x execution enabled
        0 x handling enabled
        0 x handling active
        0 x execution active
        0 x terminating
        0 x handling completed
        0 x execution completed
        0 x terminated
        0 parent expansion enabled
        0 parent execution enabled
        0 parent handling enabled
        0 parent handling active
        0 parent expansion active
        0 y execution enabled
        0 y handling enabled
        0 y handling active
        0 y execution active
        0 parent execution active
        0 y terminating
        0 y handling completed
        0 y execution completed
        0 y terminated
        0 parent handling completed
        0 parent expansion completed
        0 parent execution completed
        ",
    );
}

#[test]
fn termination_of_a_middle_node_spares_siblings_and_releases_waiters() {
    check(
        |e, root| {
            let mid = spawns(0.0, |e, me, _| {
                cmd(e, me, "leaf1", never(), &[]);
                cmd(e, me, "leaf2", takes(s(9.0)), &[AFTER_PREVIOUS]);
            });
            let mid = goal(e, root, "mid", mid, &[stop_in(2.0)]);
            cmd(e, root, "sibling", takes(s(5.0)), &[]);
            let after_mid = Constraint::Sequential(Facet::Execution, mid.into());
            cmd(e, root, "after_mid", noop(), &[after_mid]);
        },
        "
        0 mid expansion enabled
        0 mid execution enabled
        0 mid handling enabled
        0 mid handling active
        0 mid expansion active
        0 sibling execution enabled
        0 sibling handling enabled
        0 sibling handling active
        0 sibling execution active
        0 leaf1 execution enabled
        0 leaf1 handling enabled
        0 leaf1 handling active
        0 leaf1 execution active
        0 mid execution active
        0 mid handling completed
        0 mid expansion completed
        2 mid terminating
        2 leaf1 terminating
        2 leaf1 handling completed
        2 leaf2 terminating
        2 leaf1 execution completed
        2 leaf1 terminated
        2 leaf2 execution enabled
        2 leaf2 handling enabled
        2 leaf2 handling completed
        2 leaf2 execution completed
        2 leaf2 terminated
        2 mid execution completed
        2 mid terminated
        2 after_mid execution enabled
        2 after_mid handling enabled
        2 after_mid handling active
        2 after_mid execution active
        2 after_mid handling completed
        2 after_mid execution completed
        5 sibling handling completed
        5 sibling execution completed
        ",
    );
}

#[test]
fn termination_constraints_on_a_terminated_reference_do_not_fire() {
    check(
        |e, root| {
            let a = cmd(e, root, "a", never(), &[stop_in(1.0)]);
            let when_a_done = stop_when(a, Point::Completed);
            cmd(e, root, "b", takes(s(3.0)), &[when_a_done]);
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
        1 a terminating
        1 a handling completed
        1 a execution completed
        1 a terminated
        3 b handling completed
        3 b execution completed
        ",
    );
}

#[test]
fn on_terminate_task_runs_to_completion() {
    check(
        |e, root| {
            let on_terminate = |name: &'static str, action| OnTerminate {
                kind: NodeKind::Command,
                name: name.into(),
                action,
                fulfils: None,
            };
            let mut grasp = Spawn::new(root, NodeKind::Command, "grasp", never());
            grasp
                .on_terminate
                .push(on_terminate("release-onTerminate", takes(s(2.0))));
            spawn_with(e, grasp, &[stop_in(1.0)]);
            // A node terminated before it starts runs no cleanup.
            let mut never_starts = Spawn::new(root, NodeKind::Command, "never", noop());
            never_starts
                .on_terminate
                .push(on_terminate("cleanup2", noop()));
            spawn_with(e, never_starts, &[not_before(10.0), stop_in(1.0)]);
        },
        "
        0 grasp execution enabled
        0 grasp handling enabled
        0 grasp handling active
        0 grasp execution active
        0 never execution enabled
        1 grasp terminating
        1 grasp handling completed
        1 release-onTerminate execution enabled
        1 release-onTerminate handling enabled
        1 release-onTerminate handling active
        1 release-onTerminate execution active
        1 never terminating
        1 never handling enabled
        1 never handling completed
        1 never execution completed
        1 never terminated
        3 release-onTerminate handling completed
        3 release-onTerminate execution completed
        3 grasp execution completed
        3 grasp terminated
        ",
    );
}

#[test]
fn suspension_holds_new_and_queued_work_until_unsuspended() {
    check(
        |e, root| {
            let g = spawns(1.0, |e, me, now| {
                e.suspend(now, me).expect("suspend");
                cmd(e, me, "child", noop(), &[]);
            });
            let g = goal(e, root, "g", g, &[]);
            let waker = body(move |e, _, now| {
                e.unsuspend(now, g).expect("unsuspend");
                Outcome::done()
            });
            cmd(e, root, "waker", waker, &[not_before(5.0)]);
        },
        "
        0 g expansion enabled
        0 g execution enabled
        0 g handling enabled
        0 g handling active
        0 g expansion active
        0 waker execution enabled
        0 g suspended
        0 child suspended
        0 child execution enabled
        0 child handling enabled
        1 g handling completed
        1 g expansion completed
        5 waker handling enabled
        5 waker handling active
        5 waker execution active
        5 g unsuspended
        5 child unsuspended
        5 child handling active
        5 child execution active
        5 g execution active
        5 waker handling completed
        5 waker execution completed
        5 child handling completed
        5 child execution completed
        5 g execution completed
        ",
    );
}
