//! Monitor stories: the paper's Figure 6, maxima, termination mid-activation, activation
//! constraints, initial wait and serial activations.

use super::{assert_story, check, cmd, goal, idle, monitor_spec, never, not_before, run, s};
use super::{spawn_with, spawns, stop_in};
use crate::sim::{Factory, Outcome, SimEngine, factory, takes};
use crate::*;
use std::cell::Cell;
use std::rc::Rc;
use std::time::Duration;
use tcm_trace::TraceKind;
use tcm_trace::story::only;

/// Spawns a monitor under `up`.
fn monitor(
    e: &mut SimEngine,
    up: NodeId,
    name: &'static str,
    spec: MonitorSpec<Factory>,
    cs: &[Constraint],
) -> NodeId {
    spawn_with(e, Spawn::monitor(up, name, spec), cs)
}

#[test]
fn figure_6_monitor_triggers_when_the_mail_is_gone() {
    // Mail is taken at 5 s; the monitor polls every 1.5 s (0, 1.5, 3, 4.5, 6): it triggers at 6 s,
    // spawns speak and notifySender in parallel, completes, and the waiting speak is terminated.
    let r = check(
        |e, root| {
            let deliver_mail = spawns(0.0, |e, me, now| {
                let m = e.reserve(now, me, "monitorPickup").expect("reserve");
                let m_done = When::Event(Event::new(m, Point::Completed));
                cmd(e, me, "speak", never(), &[Constraint::terminate(m_done)]);
                let pickup = factory(|e, act, now, _| {
                    if now >= Time::ZERO + s(5.0) {
                        e.trigger(now, act).expect("trigger");
                        cmd(e, act, "speak", takes(s(1.0)), &[]);
                        cmd(e, act, "notifySender", takes(s(0.5)), &[]);
                    }
                    Outcome::done()
                });
                let mut spec = monitor_spec(pickup, Some(15), Some(1.5));
                spec.max_triggers = Some(1);
                let mut sp = Spawn::monitor(me, "monitorPickup", spec);
                sp.fulfils = Some(m);
                spawn_with(e, sp, &[]);
            });
            goal(e, root, "deliverMail", deliver_mail, &[]);
        },
        "
        0 deliverMail expansion enabled
        0 deliverMail execution enabled
        0 deliverMail handling enabled
        0 deliverMail handling active
        0 deliverMail expansion active
        0 speak execution enabled
        0 speak handling enabled
        0 speak handling active
        0 speak execution active
        0 deliverMail execution active
        0 monitorPickup execution enabled
        0 monitorPickup handling enabled
        0 monitorPickup handling active
        0 monitorPickup execution active
        0 ACT-monitorPickup execution enabled
        0 ACT-monitorPickup handling enabled
        0 ACT-monitorPickup handling active
        0 ACT-monitorPickup execution active
        0 deliverMail handling completed
        0 deliverMail expansion completed
        0 ACT-monitorPickup handling completed
        0 ACT-monitorPickup execution completed
        1.5 ACT-monitorPickup execution enabled
        1.5 ACT-monitorPickup handling enabled
        1.5 ACT-monitorPickup handling active
        1.5 ACT-monitorPickup execution active
        1.5 ACT-monitorPickup handling completed
        1.5 ACT-monitorPickup execution completed
        3 ACT-monitorPickup execution enabled
        3 ACT-monitorPickup handling enabled
        3 ACT-monitorPickup handling active
        3 ACT-monitorPickup execution active
        3 ACT-monitorPickup handling completed
        3 ACT-monitorPickup execution completed
        4.5 ACT-monitorPickup execution enabled
        4.5 ACT-monitorPickup handling enabled
        4.5 ACT-monitorPickup handling active
        4.5 ACT-monitorPickup execution active
        4.5 ACT-monitorPickup handling completed
        4.5 ACT-monitorPickup execution completed
        6 ACT-monitorPickup execution enabled
        6 ACT-monitorPickup handling enabled
        6 ACT-monitorPickup handling active
        6 ACT-monitorPickup execution active
        6 monitorPickup handling completed
        6 speak execution enabled
        6 speak handling enabled
        6 speak handling active
        6 speak execution active
        6 notifySender execution enabled
        6 notifySender handling enabled
        6 notifySender handling active
        6 notifySender execution active
        6 ACT-monitorPickup handling completed
        6.5 notifySender handling completed
        6.5 notifySender execution completed
        7 speak handling completed
        7 speak execution completed
        7 ACT-monitorPickup execution completed
        7 monitorPickup execution completed
        7 speak terminating
        7 speak handling completed
        7 speak execution completed
        7 speak terminated
        7 deliverMail execution completed
        ",
    );
    assert!(
        r.trace()
            .iter()
            .any(|e| matches!(e.kind, TraceKind::Triggered { count: 1, .. }))
    );
}

#[test]
fn a_monitor_completes_at_its_maximum_activations_without_triggering() {
    let count = Rc::new(Cell::new(0));
    let c = count.clone();
    let r = run(|e, root| {
        let watch = factory(move |_, _, _, p| {
            if let Purpose::Activation { number, .. } = p {
                c.set(*number);
            }
            Outcome::after(s(0.1))
        });
        let spec = monitor_spec(watch, Some(15), Some(1.5));
        monitor(e, root, "watch", spec, &[]);
    });
    assert_eq!(count.get(), 15);
    assert_story(
        &only(&r.story, &["ACT-watch handling active", " watch "]),
        "
        0 watch execution enabled
        0 watch handling enabled
        0 watch handling active
        0 watch execution active
        0 ACT-watch handling active
        1.5 ACT-watch handling active
        3 ACT-watch handling active
        4.5 ACT-watch handling active
        6 ACT-watch handling active
        7.5 ACT-watch handling active
        9 ACT-watch handling active
        10.5 ACT-watch handling active
        12 ACT-watch handling active
        13.5 ACT-watch handling active
        15 ACT-watch handling active
        16.5 ACT-watch handling active
        18 ACT-watch handling active
        19.5 ACT-watch handling active
        21 watch handling completed
        21 ACT-watch handling active
        21.1 watch execution completed
        ",
    );
}

#[test]
fn terminating_a_monitor_mid_activation_terminates_the_activation() {
    // The second scan, from 10 s, is cut at 12 s, not finished at 15 s.
    check(
        |e, root| {
            let scan = factory(|e, act, _, _| {
                cmd(e, act, "scan", takes(s(5.0)), &[]);
                Outcome::done()
            });
            let spec = monitor_spec(scan, None, Some(10.0));
            monitor(e, root, "watch", spec, &[stop_in(12.0)]);
        },
        "
        0 watch execution enabled
        0 watch handling enabled
        0 watch handling active
        0 watch execution active
        0 ACT-watch execution enabled
        0 ACT-watch handling enabled
        0 ACT-watch handling active
        0 ACT-watch execution active
        0 scan execution enabled
        0 scan handling enabled
        0 scan handling active
        0 scan execution active
        0 ACT-watch handling completed
        5 scan handling completed
        5 scan execution completed
        5 ACT-watch execution completed
        10 ACT-watch execution enabled
        10 ACT-watch handling enabled
        10 ACT-watch handling active
        10 ACT-watch execution active
        10 scan execution enabled
        10 scan handling enabled
        10 scan handling active
        10 scan execution active
        10 ACT-watch handling completed
        12 watch terminating
        12 watch handling completed
        12 ACT-watch terminating
        12 scan terminating
        12 scan handling completed
        12 scan execution completed
        12 scan terminated
        12 ACT-watch execution completed
        12 ACT-watch terminated
        12 watch execution completed
        12 watch terminated
        ",
    );
}

#[test]
fn activate_at_an_event_and_in_after_an_event() {
    check(
        |e, root| {
            let door = cmd(e, root, "openDoor", takes(s(2.0)), &[]);
            let cs = [
                Constraint::activate(When::Event(Event::new(door, Point::Completed))),
                Constraint::activate(When::After(s(3.0), Event::new(door, Point::Active))),
            ];
            monitor(e, root, "check", monitor_spec(idle(), Some(2), None), &cs);
        },
        "
        0 openDoor execution enabled
        0 openDoor handling enabled
        0 openDoor handling active
        0 openDoor execution active
        0 check execution enabled
        0 check handling enabled
        0 check handling active
        0 check execution active
        2 openDoor handling completed
        2 openDoor execution completed
        2 ACT-check execution enabled
        2 ACT-check handling enabled
        2 ACT-check handling active
        2 ACT-check execution active
        2 ACT-check handling completed
        2 ACT-check execution completed
        3 check handling completed
        3 ACT-check execution enabled
        3 ACT-check handling enabled
        3 ACT-check handling active
        3 ACT-check execution active
        3 ACT-check handling completed
        3 ACT-check execution completed
        3 check execution completed
        ",
    );
}

#[test]
fn initial_wait_skips_the_first_polling_activation() {
    check(
        |e, root| {
            let mut spec = monitor_spec(idle(), Some(3), Some(1.0));
            spec.initial_wait = true;
            monitor(e, root, "poll", spec, &[]);
        },
        "
        0 poll execution enabled
        0 poll handling enabled
        0 poll handling active
        0 poll execution active
        1 ACT-poll execution enabled
        1 ACT-poll handling enabled
        1 ACT-poll handling active
        1 ACT-poll execution active
        1 ACT-poll handling completed
        1 ACT-poll execution completed
        2 ACT-poll execution enabled
        2 ACT-poll handling enabled
        2 ACT-poll handling active
        2 ACT-poll execution active
        2 ACT-poll handling completed
        2 ACT-poll execution completed
        3 poll handling completed
        3 ACT-poll execution enabled
        3 ACT-poll handling enabled
        3 ACT-poll handling active
        3 ACT-poll execution active
        3 ACT-poll handling completed
        3 ACT-poll execution completed
        3 poll execution completed
        ",
    );
}

#[test]
fn serial_activations_wait_for_the_previous_one() {
    // Period 1 s but each activation takes 2.5 s: with `serial`, each starts only after the previous
    // one's execution completed, so activations created at 0, 1, 2 run at 0, 2.5, 5.
    check(
        |e, root| {
            let slow = factory(|_, _, _, _| Outcome::after(s(2.5)));
            let mut spec = monitor_spec(slow, Some(3), Some(1.0));
            spec.each.serial = true;
            monitor(e, root, "slow", spec, &[]);
        },
        "
        0 slow execution enabled
        0 slow handling enabled
        0 slow handling active
        0 slow execution active
        0 ACT-slow execution enabled
        0 ACT-slow handling enabled
        0 ACT-slow handling active
        0 ACT-slow execution active
        2 slow handling completed
        2.5 ACT-slow handling completed
        2.5 ACT-slow execution completed
        2.5 ACT-slow execution enabled
        2.5 ACT-slow handling enabled
        2.5 ACT-slow handling active
        2.5 ACT-slow execution active
        5 ACT-slow handling completed
        5 ACT-slow execution completed
        5 ACT-slow execution enabled
        5 ACT-slow handling enabled
        5 ACT-slow handling active
        5 ACT-slow execution active
        7.5 ACT-slow handling completed
        7.5 ACT-slow execution completed
        7.5 slow execution completed
        ",
    );
}

#[test]
fn activating_an_inactive_monitor_is_an_error_the_trace_shows() {
    let r = check(
        |e, root| {
            let spec = monitor_spec(idle(), None, None);
            let m = monitor(e, root, "late", spec, &[not_before(5.0)]);
            let err = e.activate(Time::ZERO, m);
            assert!(
                matches!(err, Err(EngineError::InactiveMonitor(_))),
                "{err:?}"
            );
        },
        "
        0 late execution enabled
        5 late handling enabled
        5 late handling active
        5 late execution active
        ",
    );
    assert!(r.trace().iter().any(|e| matches!(
        &e.kind,
        TraceKind::Warning { message, .. }
            if message.starts_with("Trying to activate an inactive monitor late")
    )));
}

/// A monitor polling every 100 ms from 100 ms (`initial wait`), at most 5 activations, whose
/// first activation takes 350 ms and the others none, under `overrun`: the instants its
/// activations start, from its checked trace.
fn overrun_starts(overrun: Overrun, serial: bool) -> Vec<String> {
    overrun_starts_after(overrun, serial, s(0.35))
}

/// [`overrun_starts`] with a first activation that takes `first`.
fn overrun_starts_after(overrun: Overrun, serial: bool, first: Duration) -> Vec<String> {
    let r = run(|e, root| {
        let body = factory(move |_, _, _, p| match p {
            Purpose::Activation { number: 1, .. } => Outcome::after(first),
            _ => Outcome::done(),
        });
        let mut spec = monitor_spec(body, Some(5), Some(0.1));
        spec.initial_wait = true;
        spec.each.serial = serial;
        spec.overrun = overrun;
        monitor(e, root, "tick", spec, &[]);
    });
    only(&r.story, &["ACT-tick handling active"])
}

#[test]
fn a_burst_catches_up_the_polls_an_overrun_missed_at_one_instant() {
    // The default: polls at 200, 300 and 400 ms make their activations, which wait for the first
    // and then run back to back at 450 ms.
    assert_story(
        &overrun_starts(Overrun::default(), true),
        "
        0.1 ACT-tick handling active
        0.45 ACT-tick handling active
        0.45 ACT-tick handling active
        0.45 ACT-tick handling active
        0.5 ACT-tick handling active
        ",
    );
    // Without `serial`, they run beside the first.
    assert_story(
        &overrun_starts(Overrun::Burst, false),
        "
        0.1 ACT-tick handling active
        0.2 ACT-tick handling active
        0.3 ACT-tick handling active
        0.4 ACT-tick handling active
        0.5 ACT-tick handling active
        ",
    );
}

#[test]
fn skip_drops_the_polls_an_overrun_missed_and_keeps_the_schedule() {
    // Polls at 200, 300 and 400 ms fall due while the first activation runs: none activates; the
    // next is the poll at 500 ms, on the schedule. `serial` or not, nothing overlaps.
    for serial in [true, false] {
        assert_story(
            &overrun_starts(Overrun::Skip, serial),
            "
            0.1 ACT-tick handling active
            0.5 ACT-tick handling active
            0.6 ACT-tick handling active
            0.7 ACT-tick handling active
            0.8 ACT-tick handling active
            ",
        );
    }
}

#[test]
fn delay_makes_one_activation_when_an_overrun_ends_and_restarts_the_schedule() {
    // The poll due at 200 ms waits for the first activation (300 and 400 ms make no other) and
    // activates at 450 ms; the next polls come every 100 ms from there.
    for serial in [true, false] {
        assert_story(
            &overrun_starts(Overrun::Delay, serial),
            "
            0.1 ACT-tick handling active
            0.45 ACT-tick handling active
            0.55 ACT-tick handling active
            0.65 ACT-tick handling active
            0.75 ACT-tick handling active
            ",
        );
    }
}

#[test]
fn an_activation_that_ends_as_a_poll_falls_due_is_done_for_that_poll() {
    // The first activation's end is an input at 400 ms, the instant poll 4 falls due: the timer
    // fires after the input, so the poll finds no activation running, under either policy.
    for overrun in [Overrun::Skip, Overrun::Delay] {
        assert_story(
            &overrun_starts_after(overrun, true, 3 * s(0.1)),
            "
            0.1 ACT-tick handling active
            0.4 ACT-tick handling active
            0.5 ACT-tick handling active
            0.6 ACT-tick handling active
            0.7 ACT-tick handling active
            ",
        );
    }
}

#[test]
fn a_held_poll_waits_for_the_last_activation_whatever_made_it() {
    // Delay: the poll due at 1 s waits for the first activation (0 to 1.5 s); at 1.2 s an
    // explicit call makes another, which runs to 2 s; the held poll activates when that one
    // completes, and the schedule goes on from there (3 s). Terminated at 3.5 s.
    let r = run(|e, root| {
        let body = factory(|_, _, _, p| match p {
            Purpose::Activation { number: 1, .. } => Outcome::after(s(1.5)),
            Purpose::Activation { number: 2, .. } => Outcome::after(s(0.8)),
            _ => Outcome::done(),
        });
        let mut spec = monitor_spec(body, None, Some(1.0));
        spec.overrun = Overrun::Delay;
        let m = monitor(e, root, "tick", spec, &[stop_in(3.5)]);
        let poke = crate::sim::body(move |e, _, now| {
            e.activate(now, m).expect("activate");
            Outcome::done()
        });
        cmd(e, root, "poke", poke, &[not_before(1.2)]);
    });
    assert_story(
        &only(&r.story, &["ACT-tick handling active", "tick terminated"]),
        "
        0 ACT-tick handling active
        1.2 ACT-tick handling active
        2 ACT-tick handling active
        3 ACT-tick handling active
        3.5 tick terminated
        ",
    );
}
