//! References: reservations (forward references), dead references, `previous` with nothing
//! before, constraints applied to a reservation, reservations fulfilled by on-terminate tasks,
//! and children held until the body ends.

use super::stop_in;
use super::{AFTER_PREVIOUS, assert_story, check, cmd, goal, never, run, s, spawn_with, spawns};
use crate::sim::{Body, SimEngine, noop, takes};
use crate::*;
use tcm_trace::TraceKind;
use tcm_trace::story::only;

/// Spawns the command `name` under `up`, fulfilling the reservation `reserved`.
fn fulfil(e: &mut SimEngine, up: NodeId, reserved: NodeId, name: &'static str, b: Body) {
    let mut spec = Spawn::new(up, NodeKind::Command, name, b);
    spec.fulfils = Some(reserved);
    spawn_with(e, spec, &[]);
}

/// `sequential execution <node>`.
fn after(node: NodeId) -> Constraint {
    Constraint::Sequential(Facet::Execution, node.into())
}

#[test]
fn forward_reference_to_a_later_spawn() {
    check(
        |e, root| {
            let plan = spawns(0.0, |e, me, now| {
                let later = e.reserve(now, me, "later").expect("reserve");
                cmd(e, me, "first", noop(), &[after(later)]);
                fulfil(e, me, later, "later", takes(s(2.0)));
            });
            goal(e, root, "plan", plan, &[]);
        },
        "
        0 plan expansion enabled
        0 plan execution enabled
        0 plan handling enabled
        0 plan handling active
        0 plan expansion active
        0 later execution enabled
        0 later handling enabled
        0 later handling active
        0 later execution active
        0 plan execution active
        0 plan handling completed
        0 plan expansion completed
        2 later handling completed
        2 later execution completed
        2 first execution enabled
        2 first handling enabled
        2 first handling active
        2 first execution active
        2 first handling completed
        2 first execution completed
        2 plan execution completed
        ",
    );
}

#[test]
fn dead_reference_voids_enablement_and_fires_termination() {
    check(
        |e, root| {
            let errand = spawns(1.0, |e, me, now| {
                let never_spawned = e.reserve(now, me, "never_spawned").expect("reserve");
                cmd(e, me, "waits", noop(), &[after(never_spawned)]);
                let done = When::Event(Event::new(never_spawned, Point::Completed));
                cmd(e, me, "doomed", never(), &[Constraint::terminate(done)]);
            });
            goal(e, root, "errand", errand, &[]);
        },
        "
        0 errand expansion enabled
        0 errand execution enabled
        0 errand handling enabled
        0 errand handling active
        0 errand expansion active
        0 doomed execution enabled
        0 doomed handling enabled
        0 doomed handling active
        0 doomed execution active
        0 errand execution active
        1 errand handling completed
        1 never_spawned dead
        1 waits execution enabled
        1 waits handling enabled
        1 doomed terminating
        1 doomed handling completed
        1 errand expansion completed
        1 waits handling active
        1 waits execution active
        1 doomed execution completed
        1 doomed terminated
        1 waits handling completed
        1 waits execution completed
        1 errand execution completed
        ",
    );
}

#[test]
fn previous_with_nothing_before_is_void() {
    let r = check(
        |e, root| {
            let lone = spawns(0.0, |e, me, _| {
                cmd(e, me, "first", noop(), &[AFTER_PREVIOUS])
            });
            goal(e, root, "lone", lone, &[]);
        },
        "
        0 lone expansion enabled
        0 lone execution enabled
        0 lone handling enabled
        0 lone handling active
        0 lone expansion active
        0 first execution enabled
        0 first handling enabled
        0 first handling active
        0 first execution active
        0 lone execution active
        0 lone handling completed
        0 lone expansion completed
        0 first handling completed
        0 first execution completed
        0 lone execution completed
        ",
    );
    let void = |e: &&tcm_trace::TraceEvent| matches!(e.kind, TraceKind::ConstraintVoid { .. });
    assert_eq!(r.trace().iter().filter(void).count(), 1);
}

#[test]
fn constraints_on_a_reservation_apply_when_it_is_spawned() {
    // See: a constraint statement on a task the body spawns later (`f2 serial f1;` before `spawn f2`).
    check(
        |e, root| {
            let fetch = spawns(0.0, |e, me, now| {
                let f2 = e.reserve(now, me, "f2").expect("reserve");
                let f1 = cmd(e, me, "f1", takes(s(2.0)), &[]);
                let serial = Constraint::Serial(f1.into());
                e.constrain(now, f2, serial)
                    .expect("constrain a reservation");
                e.constrain(now, f2, stop_in(10.0)).expect("constrain");
                fulfil(e, me, f2, "f2", never());
            });
            goal(e, root, "fetch", fetch, &[]);
        },
        "
        0 fetch expansion enabled
        0 fetch execution enabled
        0 fetch handling enabled
        0 fetch handling active
        0 fetch expansion active
        0 f1 execution enabled
        0 f1 handling enabled
        0 f1 handling active
        0 f1 execution active
        0 fetch execution active
        0 fetch handling completed
        0 fetch expansion completed
        2 f1 handling completed
        2 f1 execution completed
        2 f2 execution enabled
        2 f2 handling enabled
        2 f2 handling active
        2 f2 execution active
        10 f2 terminating
        10 f2 handling completed
        10 f2 execution completed
        10 f2 terminated
        10 fetch execution completed
        ",
    );
}

#[test]
fn held_children_start_when_the_body_ends() {
    // TDL: the body finishes before its children run, so a constraint statement after a spawn applies.
    check(
        |e, root| {
            let tdl_body = spawns(0.5, |e, me, now| {
                e.hold_children(now, me, true).expect("hold");
                let a = cmd(e, me, "a", takes(s(1.0)), &[]);
                let b = cmd(e, me, "b", takes(s(1.0)), &[]);
                let serial = Constraint::Serial(a.into());
                e.constrain(now, b, serial).expect("b has not started yet");
            });
            goal(e, root, "body", tdl_body, &[]);
        },
        "
        0 body expansion enabled
        0 body execution enabled
        0 body handling enabled
        0 body handling active
        0 body expansion active
        0.5 body handling completed
        0.5 a execution enabled
        0.5 a handling enabled
        0.5 body expansion completed
        0.5 a handling active
        0.5 a execution active
        0.5 body execution active
        1.5 a handling completed
        1.5 a execution completed
        1.5 b execution enabled
        1.5 b handling enabled
        1.5 b handling active
        1.5 b execution active
        2.5 b handling completed
        2.5 b execution completed
        2.5 body execution completed
        ",
    );
}

/// An on-terminate task of kind command, fulfilling `label`.
fn cleanup(name: &'static str, b: Body, label: NodeId) -> OnTerminate<Body> {
    OnTerminate {
        kind: NodeKind::Command,
        name: name.into(),
        action: b,
        fulfils: Some(label),
    }
}

#[test]
fn a_labelled_on_terminate_task_fulfils_its_reservation_or_it_dies_with_its_node() {
    // TDL: `grasp` with `on terminate one: spawn release(), on terminate two: spawn stow()`,
    // `two serial one`, and `report` after `one`; `hold` completes normally, so its label `drop`
    // is dead when its execution completes and `after_drop` goes on then. The body ends at 0, yet
    // the labels live on with the nodes that took them over.
    let r = run(|e, root| {
        let plan = spawns(0.0, |e, me, now| {
            let one = e.reserve(now, me, "release").expect("reserve");
            let two = e.reserve(now, me, "stow").expect("reserve");
            let drop = e.reserve(now, me, "drop").expect("reserve");
            e.constrain(now, two, Constraint::Serial(one.into()))
                .expect("constrain a label");
            cmd(e, me, "report", noop(), &[after(one)]);
            let mut grasp = Spawn::new(me, NodeKind::Command, "grasp", never());
            grasp.on_terminate = vec![
                cleanup("release", takes(s(1.0)), one),
                cleanup("stow", takes(s(1.0)), two),
            ];
            spawn_with(e, grasp, &[stop_in(2.0)]);
            let mut hold = Spawn::new(me, NodeKind::Command, "hold", takes(s(1.0)));
            hold.on_terminate = vec![cleanup("drop", noop(), drop)];
            spawn_with(e, hold, &[]);
            cmd(e, me, "after_drop", noop(), &[after(drop)]);
        });
        goal(e, root, "plan", plan, &[]);
    });
    assert_story(
        &only(
            &r.story,
            &[
                "handling active",
                "grasp terminat",
                "hold handling completed",
                "execution completed",
                " dead",
            ],
        ),
        "
        0 plan handling active
        0 grasp handling active
        0 hold handling active
        1 hold handling completed
        1 hold execution completed
        1 drop dead
        1 after_drop handling active
        1 after_drop execution completed
        2 grasp terminating
        2 release handling active
        3 release execution completed
        3 report handling active
        3 stow handling active
        3 report execution completed
        4 stow execution completed
        4 grasp execution completed
        4 grasp terminated
        4 plan execution completed
        ",
    );
    // Each label names the node inserted for it: spawned under `grasp` with the number reserved.
    let spawned: Vec<(u64, u64, String)> = r
        .trace()
        .iter()
        .filter_map(|ev| match &ev.kind {
            TraceKind::Spawned {
                node, parent, name, ..
            } if name == "release" || name == "stow" => Some((*node, *parent, name.clone())),
            _ => None,
        })
        .collect();
    assert_eq!(
        spawned,
        [(2, 6, "release".to_owned()), (3, 6, "stow".to_owned())]
    );
}
