//! Monitor stories: the paper's Figure 6, maxima, termination mid-activation, activation
//! constraints, initial wait and serial activations.

use super::{assert_order, cmd, goal, only, s, story};
use crate::sim::{Outcome, Sim, SimEngine, body, factory, noop, takes};
use crate::*;
use std::cell::Cell;
use std::rc::Rc;

fn monitor(
    e: &mut SimEngine,
    parent: NodeId,
    name: &'static str,
    spec: MonitorSpec<crate::sim::Factory>,
    cs: &[Constraint],
) -> NodeId {
    let mut sp = Spawn::monitor(parent, name, spec);
    sp.constraints = cs.to_vec();
    let now = e.now();
    e.spawn(now, sp).expect("spawn monitor")
}

#[test]
fn figure_6_monitor_triggers_when_the_mail_is_gone() {
    // Mail is taken at 5 s; the monitor polls every 1.5 s (0, 1.5, 3, 4.5, 6): it triggers at 6 s,
    // spawns speak and notifySender in parallel, completes, and the waiting speak is terminated.
    let mut sim = Sim::new();
    let root = sim.engine.root();
    goal(
        &mut sim.engine,
        root,
        "deliverMail",
        body(|e, me, _| {
            let m = e.reserve(e.now(), me, "monitorPickup").expect("reserve");
            cmd(
                e,
                me,
                "speak",
                body(|_, _, _| Outcome::Never),
                &[Constraint::Terminate(TerminateWhen::Event(Event::new(
                    m,
                    Point::Completed,
                )))],
            );
            let mut spec = MonitorSpec::new(factory(|e, act, now, _| {
                if now >= Time::ZERO + s(5.0) {
                    e.trigger(now, act).expect("trigger");
                    cmd(e, act, "speak", takes(s(1.0)), &[]);
                    cmd(e, act, "notifySender", takes(s(0.5)), &[]);
                }
                Outcome::done()
            }));
            spec.max_triggers = Some(1);
            spec.max_activations = Some(15);
            spec.period = Some(s(1.5));
            let mut sp = Spawn::monitor(me, "monitorPickup", spec);
            sp.fulfils = Some(m);
            e.spawn(e.now(), sp).expect("spawn");
            Outcome::done()
        }),
        &[],
    );
    sim.run();
    let st = story(sim.trace());
    let acts = only(&st, &["ACT-monitorPickup handling active"]);
    assert_eq!(
        acts,
        [
            "0 ACT-monitorPickup handling active",
            "1.5 ACT-monitorPickup handling active",
            "3 ACT-monitorPickup handling active",
            "4.5 ACT-monitorPickup handling active",
            "6 ACT-monitorPickup handling active"
        ]
    );
    assert_order(
        &st,
        &[
            "6 monitorPickup handling completed",
            "6 speak handling active",
            "6 notifySender handling active",
            "7 monitorPickup execution completed",
            "7 speak terminating",
            "7 deliverMail execution completed",
        ],
    );
    assert!(
        sim.trace()
            .iter()
            .any(|e| matches!(e.kind, tcm_trace::TraceKind::Triggered { count: 1, .. }))
    );
    super::assert_checked(sim.trace());
}

#[test]
fn a_monitor_completes_at_its_maximum_activations_without_triggering() {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    let count = Rc::new(Cell::new(0));
    let c = count.clone();
    let mut spec = MonitorSpec::new(factory(move |_, _, _, p| {
        if let Purpose::Activation { number, .. } = p {
            c.set(*number);
        }
        Outcome::after(s(0.1))
    }));
    spec.max_activations = Some(15);
    spec.period = Some(s(1.5));
    monitor(&mut sim.engine, root, "watch", spec, &[]);
    sim.run();
    assert_eq!(count.get(), 15);
    let st = story(sim.trace());
    assert_order(
        &st,
        &[
            "21 watch handling completed",
            "21 ACT-watch handling active",
            "21.1 watch execution completed",
        ],
    );
    super::assert_checked(sim.trace());
}

#[test]
fn terminating_a_monitor_mid_activation_terminates_the_activation() {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    let mut spec = MonitorSpec::new(factory(|e, act, _, _| {
        cmd(e, act, "scan", takes(s(5.0)), &[]);
        Outcome::done()
    }));
    spec.period = Some(s(10.0));
    monitor(
        &mut sim.engine,
        root,
        "watch",
        spec,
        &[Constraint::Terminate(TerminateWhen::In(s(12.0)))],
    );
    sim.run();
    let st = story(sim.trace());
    assert_order(
        &st,
        &[
            "10 ACT-watch handling active",
            "10 scan handling active",
            "12 watch terminating",
            "12 ACT-watch terminating",
            "12 scan terminating",
            "12 watch terminated",
        ],
    );
    assert!(
        !st.iter().any(|l| l.contains("15 scan")),
        "the scan was cut, not finished"
    );
    super::assert_checked(sim.trace());
}

#[test]
fn activate_at_an_event_and_in_after_an_event() {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    let e = &mut sim.engine;
    let door = cmd(e, root, "openDoor", takes(s(2.0)), &[]);
    let mut spec = MonitorSpec::new(factory(|_, _, _, _| Outcome::done()));
    spec.max_activations = Some(2);
    monitor(
        e,
        root,
        "check",
        spec,
        &[
            Constraint::Activate(ActivateWhen::Event(Event::new(door, Point::Completed))),
            Constraint::Activate(ActivateWhen::InAfter(
                s(3.0),
                Event::new(door, Point::Active),
            )),
        ],
    );
    sim.run();
    let acts = only(&story(sim.trace()), &["ACT-check handling active"]);
    assert_eq!(
        acts,
        ["2 ACT-check handling active", "3 ACT-check handling active"]
    );
    super::assert_checked(sim.trace());
}

#[test]
fn initial_wait_skips_the_first_polling_activation() {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    let mut spec = MonitorSpec::new(factory(|_, _, _, _| Outcome::done()));
    spec.max_activations = Some(3);
    spec.period = Some(s(1.0));
    spec.initial_wait = true;
    monitor(&mut sim.engine, root, "poll", spec, &[]);
    sim.run();
    let acts = only(&story(sim.trace()), &["ACT-poll handling active"]);
    assert_eq!(
        acts,
        [
            "1 ACT-poll handling active",
            "2 ACT-poll handling active",
            "3 ACT-poll handling active"
        ]
    );
}

#[test]
fn serial_activations_wait_for_the_previous_one() {
    // Period 1 s but each activation takes 2.5 s: with `serial`, each starts only after the previous
    // one's execution completed, so activations created at 0, 1, 2 run at 0, 2.5, 5.
    let mut sim = Sim::new();
    let root = sim.engine.root();
    let mut spec = MonitorSpec::new(factory(|_, _, _, _| Outcome::after(s(2.5))));
    spec.max_activations = Some(3);
    spec.period = Some(s(1.0));
    spec.each.serial = true;
    monitor(&mut sim.engine, root, "slow", spec, &[]);
    sim.run();
    let acts = only(&story(sim.trace()), &["ACT-slow handling active"]);
    assert_eq!(
        acts,
        [
            "0 ACT-slow handling active",
            "2.5 ACT-slow handling active",
            "5 ACT-slow handling active"
        ]
    );
    super::assert_checked(sim.trace());
}

#[test]
fn activating_an_inactive_monitor_is_an_error_the_trace_shows() {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    let spec = MonitorSpec::new(factory(|_, _, _, _| Outcome::done()));
    let m = monitor(
        &mut sim.engine,
        root,
        "late",
        spec,
        &[Constraint::Disable(Facet::Handling, Until::For(s(5.0)))],
    );
    let err = sim.engine.activate(Time::ZERO, m);
    assert!(
        matches!(err, Err(EngineError::InactiveMonitor(_))),
        "{err:?}"
    );
    assert!(sim.engine.poll_trace().into_iter().chain(std::iter::from_fn(|| sim.engine.poll_trace())).any(|e| matches!(
        &e.kind,
        tcm_trace::TraceKind::Warning { message, .. } if message.starts_with("Trying to activate an inactive monitor late")
    )));
    let _ = noop();
}
