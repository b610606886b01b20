//! Exception stories: unhandled failures, the paper's navigateToLocn handlers, a bypass chain,
//! subclass matching, re-raise, retry, and a wiretap that vetoes a move.

use super::{AFTER_PREVIOUS, check, cmd, goal, idle, s, spawn_with, spawns};
use crate::sim::{Body, Factory, Outcome, SimEngine, body, factory, noop, takes};
use crate::*;
use std::cell::Cell;
use std::rc::Rc;
use tcm_trace::TraceKind;
use tcm_trace::story::handler_choices;

/// A handler of `exception` (and its subclasses) running `f`, at most `max` times.
fn handler(
    name: &'static str,
    exception: &'static str,
    max: Option<u32>,
    f: Factory,
) -> HandlerSpec<Factory> {
    HandlerSpec {
        name: name.into(),
        exception: exception.into(),
        max_activations: max,
        body: f,
    }
}

/// Spawns a goal with handlers under `up`.
fn goal_with(
    e: &mut SimEngine,
    up: NodeId,
    name: &'static str,
    b: Body,
    hs: Vec<HandlerSpec<Factory>>,
) {
    let mut sp = Spawn::new(up, NodeKind::Goal, name, b);
    sp.handlers = hs;
    spawn_with(e, sp, &[]);
}

/// An action that fails with `exception` after `secs`.
fn fails(secs: f64, exception: &'static str) -> Body {
    body(move |_, _, _| Outcome::fail(s(secs), exception))
}

/// An action that fails after one second with `exception` and `message`.
fn fails_with(exception: &'static str, message: &'static str) -> Body {
    body(move |_, _, _| Outcome::After(s(1.0), Err(Failure::new(exception, message))))
}

#[test]
fn unhandled_failure_completes_the_node_and_siblings_go_on() {
    let r = check(
        |e, root| {
            let bad = fails_with("NoPath", "all routes blocked");
            cmd(e, root, "bad", bad, &[]);
            cmd(e, root, "next", noop(), &[AFTER_PREVIOUS]);
        },
        "
        0 bad execution enabled
        0 bad handling enabled
        0 bad handling active
        0 bad execution active
        1 bad failed NoPath
        1 bad handling completed
        1 bad execution completed
        1 next execution enabled
        1 next handling enabled
        1 next handling active
        1 next execution active
        1 next handling completed
        1 next execution completed
        ",
    );
    assert!(r.sim.engine.fatal().is_none());
}

#[test]
fn fatal_policy_names_the_failing_node_and_its_path() {
    let r = check(
        |e, root| {
            e.set_failure_policy(FailurePolicy::Fatal);
            let deliver = spawns(0.0, |e, me, _| {
                cmd(e, me, "move", fails_with("Blocked", "cart in the way"), &[]);
            });
            goal(e, root, "deliver", deliver, &[]);
        },
        "
        0 deliver expansion enabled
        0 deliver execution enabled
        0 deliver handling enabled
        0 deliver handling active
        0 deliver expansion active
        0 move execution enabled
        0 move handling enabled
        0 move handling active
        0 move execution active
        0 deliver execution active
        0 deliver handling completed
        0 deliver expansion completed
        1 move failed Blocked
        1 move handling completed
        1 move execution completed
        1 deliver execution completed
        ",
    );
    let fatal = r.sim.engine.fatal().expect("fatal failure recorded");
    assert_eq!(fatal.path, "deliver/move");
    assert_eq!(fatal.failure.exception, "Blocked");
    assert_eq!(
        fatal.to_string(),
        "unhandled exception Blocked in deliver/move {2}: cart in the way"
    );
}

#[test]
fn navigate_to_locn_sends_each_exception_to_its_handler() {
    // The failing move completes (failed) but its execution waits for the handler's cool-down:
    // the sibling sequential on it starts only then.
    let r = check(
        |e, root| {
            let cool_down = factory(|e, me, _, _| {
                cmd(e, me, "coolDown", takes(s(3.0)), &[]);
                Outcome::done()
            });
            let hs = vec![
                handler("handleOverheating", "Overheating", None, cool_down),
                handler("handlePlannerFailure", "NoPath", None, idle()),
            ];
            let navigate = spawns(0.0, |e, me, _| {
                let mv = cmd(e, me, "move", fails(1.0, "Overheating"), &[]);
                cmd(e, me, "plan", fails(2.0, "NoPath"), &[]);
                let after_move = Constraint::Sequential(Facet::Execution, mv.into());
                cmd(e, me, "afterMove", noop(), &[after_move]);
            });
            goal_with(e, root, "navigateToLocn", navigate, hs);
        },
        "
        0 navigateToLocn expansion enabled
        0 navigateToLocn execution enabled
        0 navigateToLocn handling enabled
        0 navigateToLocn handling active
        0 navigateToLocn expansion active
        0 move execution enabled
        0 move handling enabled
        0 move handling active
        0 move execution active
        0 navigateToLocn execution active
        0 plan execution enabled
        0 plan handling enabled
        0 plan handling active
        0 plan execution active
        0 navigateToLocn handling completed
        0 navigateToLocn expansion completed
        1 move failed Overheating
        1 move handling completed
        1 handleOverheating expansion enabled
        1 handleOverheating execution enabled
        1 handleOverheating handling enabled
        1 handleOverheating handling active
        1 handleOverheating expansion active
        1 coolDown execution enabled
        1 coolDown handling enabled
        1 coolDown handling active
        1 coolDown execution active
        1 handleOverheating execution active
        1 handleOverheating handling completed
        1 handleOverheating expansion completed
        2 plan failed NoPath
        2 plan handling completed
        2 handlePlannerFailure expansion enabled
        2 handlePlannerFailure execution enabled
        2 handlePlannerFailure handling enabled
        2 handlePlannerFailure handling active
        2 handlePlannerFailure expansion active
        2 handlePlannerFailure handling completed
        2 handlePlannerFailure expansion completed
        2 handlePlannerFailure execution completed
        2 plan execution completed
        4 coolDown handling completed
        4 coolDown execution completed
        4 handleOverheating execution completed
        4 move execution completed
        4 afterMove execution enabled
        4 afterMove handling enabled
        4 afterMove handling active
        4 afterMove execution active
        4 afterMove handling completed
        4 afterMove execution completed
        4 navigateToLocn execution completed
        ",
    );
    assert_eq!(
        handler_choices(r.trace()),
        [
            "handleOverheating<-Overheating",
            "handlePlannerFailure<-NoPath"
        ]
    );
}

#[test]
fn a_bypass_chain_over_three_levels_respects_maximum_activations() {
    // top (handler A, max 1) > mid (handler B, bypasses) > leaf fails twice with Blocked.
    // First failure: B (at mid) bypasses -> A (at top). Second: B bypasses -> A is used up -> none.
    let r = check(
        |e, root| {
            let top = spawns(0.0, |e, top, _| {
                let mid = spawns(0.0, |e, mid, _| {
                    cmd(e, mid, "leaf1", fails(1.0, "Blocked"), &[]);
                    cmd(e, mid, "leaf2", fails(3.0, "Blocked"), &[]);
                });
                let bypass = factory(|_, _, _, _| Outcome::Bypass(s(0.5)));
                let b = handler("B", "Blocked", None, bypass);
                goal_with(e, top, "mid", mid, vec![b]);
            });
            let a = handler("A", "Blocked", Some(1), idle());
            goal_with(e, root, "top", top, vec![a]);
        },
        "
        0 top expansion enabled
        0 top execution enabled
        0 top handling enabled
        0 top handling active
        0 top expansion active
        0 mid expansion enabled
        0 mid execution enabled
        0 mid handling enabled
        0 mid handling active
        0 mid expansion active
        0 leaf1 execution enabled
        0 leaf1 handling enabled
        0 leaf1 handling active
        0 leaf1 execution active
        0 mid execution active
        0 top execution active
        0 leaf2 execution enabled
        0 leaf2 handling enabled
        0 leaf2 handling active
        0 leaf2 execution active
        0 top handling completed
        0 mid handling completed
        0 mid expansion completed
        0 top expansion completed
        1 leaf1 failed Blocked
        1 leaf1 handling completed
        1 B expansion enabled
        1 B execution enabled
        1 B handling enabled
        1 B handling active
        1 B expansion active
        1.5 B handling completed
        1.5 A expansion enabled
        1.5 A execution enabled
        1.5 A handling enabled
        1.5 A handling active
        1.5 A expansion active
        1.5 A handling completed
        1.5 A expansion completed
        1.5 A execution completed
        1.5 B expansion completed
        1.5 B execution completed
        1.5 leaf1 execution completed
        3 leaf2 failed Blocked
        3 leaf2 handling completed
        3 B expansion enabled
        3 B execution enabled
        3 B handling enabled
        3 B handling active
        3 B expansion active
        3.5 B handling completed
        3.5 B expansion completed
        3.5 B execution completed
        3.5 leaf2 execution completed
        3.5 mid execution completed
        3.5 top execution completed
        ",
    );
    assert_eq!(
        handler_choices(r.trace()),
        ["B<-Blocked", "bypass", "A<-Blocked", "B<-Blocked", "bypass"]
    );
    assert!(r.trace().iter().any(|e| matches!(
        &e.kind,
        TraceKind::Warning { message, .. } if message.contains("No exception handler found")
    )));
}

#[test]
fn a_handler_for_an_ancestor_type_catches_the_subclass() {
    let r = check(
        |e, root| {
            let fly = spawns(0.0, |e, me, _| {
                let on_fire = body(|_, _, _| {
                    let f = Failure::new("EngineOnFire", "smoke")
                        .with_ancestry(vec!["EngineFailure".into(), "HardwareFailure".into()]);
                    Outcome::After(s(1.0), Err(f))
                });
                cmd(e, me, "engine", on_fire, &[]);
            });
            let hardware_fix = factory(|_, _, _, p| {
                let on_fire = |f: &Failure| f.exception == "EngineOnFire";
                assert!(matches!(p, Purpose::Handler { failure, .. } if on_fire(failure)));
                Outcome::done()
            });
            let hs = vec![
                handler("softwareFix", "SoftwareFailure", None, idle()),
                handler("hardwareFix", "HardwareFailure", None, hardware_fix),
            ];
            goal_with(e, root, "fly", fly, hs);
        },
        "
        0 fly expansion enabled
        0 fly execution enabled
        0 fly handling enabled
        0 fly handling active
        0 fly expansion active
        0 engine execution enabled
        0 engine handling enabled
        0 engine handling active
        0 engine execution active
        0 fly execution active
        0 fly handling completed
        0 fly expansion completed
        1 engine failed EngineOnFire
        1 engine handling completed
        1 hardwareFix expansion enabled
        1 hardwareFix execution enabled
        1 hardwareFix handling enabled
        1 hardwareFix handling active
        1 hardwareFix expansion active
        1 hardwareFix handling completed
        1 hardwareFix expansion completed
        1 hardwareFix execution completed
        1 engine execution completed
        1 fly execution completed
        ",
    );
    assert_eq!(handler_choices(r.trace()), ["hardwareFix<-EngineOnFire"]);
}

#[test]
fn a_handler_that_re_raises_goes_to_the_enclosing_handler() {
    // `regrasp`'s own failure searches above `inner`, where it was attached: `reportFailure` takes
    // `GiveUp` (and `loop` at `outer` is never asked about `Slipped` again).
    let r = check(
        |e, root| {
            let outer = spawns(0.0, |e, outer, _| {
                let inner = spawns(0.0, |e, me, _| {
                    cmd(e, me, "grasp", fails(1.0, "Slipped"), &[])
                });
                let give_up = factory(|_, _, _, _| Outcome::fail(s(1.0), "GiveUp"));
                let regrasp = handler("regrasp", "Slipped", None, give_up);
                goal_with(e, outer, "inner", inner, vec![regrasp]);
            });
            let hs = vec![
                handler("reportFailure", "GiveUp", None, idle()),
                handler("loop", "Slipped", None, idle()),
            ];
            goal_with(e, root, "outer", outer, hs);
        },
        "
        0 outer expansion enabled
        0 outer execution enabled
        0 outer handling enabled
        0 outer handling active
        0 outer expansion active
        0 inner expansion enabled
        0 inner execution enabled
        0 inner handling enabled
        0 inner handling active
        0 inner expansion active
        0 grasp execution enabled
        0 grasp handling enabled
        0 grasp handling active
        0 grasp execution active
        0 inner execution active
        0 outer execution active
        0 outer handling completed
        0 inner handling completed
        0 inner expansion completed
        0 outer expansion completed
        1 grasp failed Slipped
        1 grasp handling completed
        1 regrasp expansion enabled
        1 regrasp execution enabled
        1 regrasp handling enabled
        1 regrasp handling active
        1 regrasp expansion active
        2 regrasp failed GiveUp
        2 regrasp handling completed
        2 reportFailure expansion enabled
        2 reportFailure execution enabled
        2 reportFailure handling enabled
        2 reportFailure handling active
        2 reportFailure expansion active
        2 reportFailure handling completed
        2 reportFailure expansion completed
        2 reportFailure execution completed
        2 regrasp expansion completed
        2 regrasp execution completed
        2 grasp execution completed
        2 inner execution completed
        2 outer execution completed
        ",
    );
    assert_eq!(
        handler_choices(r.trace()),
        ["regrasp<-Slipped", "reportFailure<-GiveUp"]
    );
}

#[test]
fn retry_succeeds_on_the_second_attempt() {
    let attempts = Rc::new(Cell::new(0));
    let a = attempts.clone();
    let try_move = factory(move |_, _, _, _| {
        a.set(a.get() + 1);
        if a.get() < 2 {
            Outcome::fail(s(1.0), "Blocked")
        } else {
            Outcome::after(s(1.0))
        }
    });
    let r = check(
        |e, root| {
            let first = try_move.clone();
            let deliver = spawns(0.0, move |e, me, _| {
                let first_try = body(move |e, n, t| first.call(e, n, t, &Purpose::Retry { of: n }));
                let mut sp = Spawn::new(me, NodeKind::Command, "move", first_try);
                sp.retry = Some(try_move);
                spawn_with(e, sp, &[]);
                cmd(e, me, "speak", noop(), &[AFTER_PREVIOUS]);
            });
            let retry = factory(|e, me, now, _| {
                e.retry(now, me).expect("retry");
                Outcome::done()
            });
            let retry_move = handler("retryMove", "Blocked", Some(3), retry);
            goal_with(e, root, "deliver", deliver, vec![retry_move]);
        },
        "
        0 deliver expansion enabled
        0 deliver execution enabled
        0 deliver handling enabled
        0 deliver handling active
        0 deliver expansion active
        0 move execution enabled
        0 move handling enabled
        0 move handling active
        0 move execution active
        0 deliver execution active
        0 deliver handling completed
        0 deliver expansion completed
        1 move failed Blocked
        1 move handling completed
        1 retryMove expansion enabled
        1 retryMove execution enabled
        1 retryMove handling enabled
        1 retryMove handling active
        1 retryMove expansion active
        1 move execution enabled
        1 move handling enabled
        1 move handling active
        1 move execution active
        1 retryMove execution active
        1 retryMove handling completed
        1 retryMove expansion completed
        2 move handling completed
        2 move execution completed
        2 retryMove execution completed
        2 move execution completed
        2 speak execution enabled
        2 speak handling enabled
        2 speak handling active
        2 speak execution active
        2 speak handling completed
        2 speak execution completed
        2 deliver execution completed
        ",
    );
    assert_eq!(attempts.get(), 2);
    assert!(
        r.trace()
            .iter()
            .any(|e| matches!(e.kind, TraceKind::Retried { .. }))
    );
}

#[test]
fn a_wiretap_vetoes_one_of_five_moves() {
    // A stability check before every move, without touching `move`: the third is vetoed, so four
    // moves run.
    let n = Rc::new(Cell::new(0));
    let n2 = n.clone();
    check(
        |e, root| {
            let stable = factory(move |_, _, _, _| {
                n2.set(n2.get() + 1);
                if n2.get() == 3 {
                    Outcome::fail(s(0.1), "Unstable")
                } else {
                    Outcome::after(s(0.1))
                }
            });
            e.wiretap("move", TapWhen::Before, stable);
            let walk = spawns(0.0, |e, me, _| {
                for _ in 0..5 {
                    cmd(e, me, "move", takes(s(1.0)), &[AFTER_PREVIOUS]);
                }
            });
            goal(e, root, "walk", walk, &[]);
        },
        "
        0 walk expansion enabled
        0 walk execution enabled
        0 walk handling enabled
        0 walk handling active
        0 walk expansion active
        0 move execution enabled
        0 move handling enabled
        0 walk handling completed
        0 walk expansion completed
        0.1 move handling active
        0.1 move execution active
        0.1 walk execution active
        1.1 move handling completed
        1.1 move execution completed
        1.1 move execution enabled
        1.1 move handling enabled
        1.2 move handling active
        1.2 move execution active
        2.2 move handling completed
        2.2 move execution completed
        2.2 move execution enabled
        2.2 move handling enabled
        2.3 move failed Unstable
        2.3 move handling completed
        2.3 move execution completed
        2.3 move execution enabled
        2.3 move handling enabled
        2.4 move handling active
        2.4 move execution active
        3.4 move handling completed
        3.4 move execution completed
        3.4 move execution enabled
        3.4 move handling enabled
        3.5 move handling active
        3.5 move execution active
        4.5 move handling completed
        4.5 move execution completed
        4.5 walk execution completed
        ",
    );
    assert_eq!(n.get(), 5);
}
