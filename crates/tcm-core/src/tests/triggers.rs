//! The one trigger concept: every "when" ([`When`]) with every "then" ([`Then`]), and external
//! events.

use super::{assert_story, check, cmd, goal, idle, monitor_spec, never, not_before, run, s};
use super::{spawn_with, spawns};
use crate::sim::{Body, Outcome, SimEngine, body, noop, takes};
use crate::*;

/// Spawns `t` under `root` with `Trigger(when, then)`: a command of one second to enable, a command
/// that never ends to terminate, a monitor of one activation to activate.
fn target(e: &mut SimEngine, root: NodeId, when: When, then: Then) -> NodeId {
    let c = [Constraint::Trigger(when, then)];
    match then {
        Then::Enable(_) => cmd(e, root, "t", takes(s(1.0)), &c),
        Then::Terminate => cmd(e, root, "t", never(), &c),
        Then::Activate => {
            let spec = monitor_spec(idle(), Some(1), None);
            spawn_with(e, Spawn::monitor(root, "t", spec), &c)
        }
        Then::Skip | Then::Invariant | Then::Pause => {
            unreachable!("conditions are tested in `conditions`")
        }
        Then::ActivateWith(_) => unreachable!("made by `Engine::activate_when` alone"),
    }
}

/// An action that raises `x`.
fn raises(x: ExternalId) -> Body {
    body(move |e, _, now| {
        e.handle_external(now, x);
        Outcome::done()
    })
}

/// `disable handling until x`.
fn until(x: ExternalId) -> Constraint {
    Constraint::disable(Facet::Handling, When::External(x))
}

/// Builds a "when" from the watched node `a` and the external event `x`.
type MakeWhen<'a> = dyn Fn(NodeId, ExternalId) -> When + 'a;

#[test]
fn every_when_fires_every_then_at_its_time() {
    // `a` runs from 0 to 2 s; `button` raises `x` at 6 s. Each "then" shows in the story when it
    // fires: `t` starts, `t` is terminated, the monitor `t` makes its activation `ACT-t`.
    let a_done = |a| Event::new(a, Point::Completed);
    let whens: [(&str, &MakeWhen<'_>); 6] = [
        ("now", &|_, _| When::Now),
        ("at 4 s", &|_, _| When::At(Time::ZERO + s(4.0))),
        ("in 5 s", &|_, _| When::In(s(5.0))),
        ("a completed", &|a, _| When::Event(a_done(a))),
        ("1 s after a completed", &|a, _| {
            When::After(s(1.0), a_done(a))
        }),
        ("external x", &|_, x| When::External(x)),
    ];
    let thens = [
        (Then::Enable(Facet::Handling), "t handling active"),
        (Then::Terminate, "t terminating"),
        (Then::Activate, "ACT-t handling active"),
    ];
    let mut table = Vec::new();
    for (name, when) in whens {
        let mut row = format!("{name}:");
        for (then, shows) in thens {
            let r = run(|e, root| {
                let x = e.external("x");
                let a = cmd(e, root, "a", takes(s(2.0)), &[]);
                cmd(e, root, "button", raises(x), &[not_before(6.0)]);
                target(e, root, when(a, x), then);
            });
            let fired = r.story.iter().find_map(|l| {
                let (t, what) = l.split_once(' ')?;
                (what == shows).then_some(t)
            });
            row += &format!(" {shows} at {}", fired.unwrap_or("never"));
        }
        table.push(row);
    }
    assert_story(
        &table,
        "
        now: t handling active at 0 t terminating at 0 ACT-t handling active at 0
        at 4 s: t handling active at 4 t terminating at 4 ACT-t handling active at 4
        in 5 s: t handling active at 5 t terminating at 5 ACT-t handling active at 5
        a completed: t handling active at 2 t terminating at 2 ACT-t handling active at 2
        1 s after a completed: t handling active at 3 t terminating at 3 ACT-t handling active at 3
        external x: t handling active at 6 t terminating at 6 ACT-t handling active at 6
        ",
    );
}

#[test]
fn external_events_gate_and_terminate() {
    check(
        |e, root| {
            let door = e.external("door_open");
            let stop = e.external("stop");
            cmd(e, root, "enter", noop(), &[until(door)]);
            let on_stop = Constraint::terminate(When::External(stop));
            cmd(e, root, "patrol", never(), &[on_stop]);
            let button = body(move |e, _, now| {
                e.handle_external(now, door);
                e.handle_external(now, stop);
                Outcome::done()
            });
            cmd(e, root, "button", button, &[not_before(3.0)]);
        },
        "
        0 enter execution enabled
        0 patrol execution enabled
        0 patrol handling enabled
        0 patrol handling active
        0 patrol execution active
        0 button execution enabled
        3 button handling enabled
        3 button handling active
        3 button execution active
        3 enter handling enabled
        3 enter handling active
        3 enter execution active
        3 patrol terminating
        3 patrol handling completed
        3 button handling completed
        3 button execution completed
        3 enter handling completed
        3 enter execution completed
        3 patrol execution completed
        3 patrol terminated
        ",
    );
}

#[test]
fn an_external_event_is_latched_for_enabling_but_activates_only_after() {
    // `x` is raised at 1, 3 and 4 s. At 2 s, `spawner` spawns `late`, disabled until `x`: it was
    // raised already, so `late` starts at once; and the monitor `watch`, activated by `x`: only the
    // raises after that activate it.
    check(
        |e, root| {
            let x = e.external("x");
            for (name, at) in [("raise1", 1.0), ("raise3", 3.0), ("raise4", 4.0)] {
                cmd(e, root, name, raises(x), &[not_before(at)]);
            }
            let spawner = spawns(0.0, move |e, me, _| {
                cmd(e, me, "late", noop(), &[until(x)]);
                let spec = monitor_spec(idle(), Some(2), None);
                let activated = Constraint::activate(When::External(x));
                spawn_with(e, Spawn::monitor(me, "watch", spec), &[activated]);
            });
            goal(e, root, "spawner", spawner, &[not_before(2.0)]);
        },
        "
        0 raise1 execution enabled
        0 raise3 execution enabled
        0 raise4 execution enabled
        0 spawner expansion enabled
        0 spawner execution enabled
        1 raise1 handling enabled
        1 raise1 handling active
        1 raise1 execution active
        1 raise1 handling completed
        1 raise1 execution completed
        2 spawner handling enabled
        2 spawner handling active
        2 spawner expansion active
        2 late execution enabled
        2 late handling enabled
        2 late handling active
        2 late execution active
        2 spawner execution active
        2 watch execution enabled
        2 watch handling enabled
        2 watch handling active
        2 watch execution active
        2 spawner handling completed
        2 spawner expansion completed
        2 late handling completed
        2 late execution completed
        3 raise3 handling enabled
        3 raise3 handling active
        3 raise3 execution active
        3 ACT-watch execution enabled
        3 ACT-watch handling enabled
        3 ACT-watch handling active
        3 ACT-watch execution active
        3 raise3 handling completed
        3 raise3 execution completed
        3 ACT-watch handling completed
        3 ACT-watch execution completed
        4 raise4 handling enabled
        4 raise4 handling active
        4 raise4 execution active
        4 watch handling completed
        4 ACT-watch execution enabled
        4 ACT-watch handling enabled
        4 ACT-watch handling active
        4 ACT-watch execution active
        4 raise4 handling completed
        4 raise4 execution completed
        4 ACT-watch handling completed
        4 ACT-watch execution completed
        4 watch execution completed
        4 spawner execution completed
        ",
    );
}
