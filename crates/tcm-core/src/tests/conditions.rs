//! State variables and triggers on conditions over them (docs/semantics.md, "State and
//! conditions"): each trigger fires at the instant a set makes its condition true, or at once when
//! it already holds; every trace passes the checker, which re-evaluates the conditions from the
//! recorded values.

use super::{AFTER_PREVIOUS, check, cmd, goal, idle, monitor_spec, never, run, s, spawn_with};
use crate::sim::{Outcome, SimEngine, body, noop, takes};
use crate::*;
use tcm_trace::story::only;

/// A command that, `at` seconds after it is spawned, sets `var` to each of `values` in turn (all
/// at one instant), then ends.
fn setter(e: &mut SimEngine, root: NodeId, at: f64, var: StateId, values: Vec<Value>) {
    let b = body(move |e, _, now| {
        for v in values {
            e.set_state(now, var, v).expect("set");
        }
        Outcome::done()
    });
    let wait = Constraint::disable(Facet::Handling, When::In(s(at)));
    cmd(e, root, "sensor", b, &[wait]);
}

fn flag(e: &mut SimEngine, name: &str, initial: bool) -> StateId {
    e.declare_state(name, Type::Bool, Value::Bool(initial))
        .expect("declare")
}

fn cond(e: &mut SimEngine, expr: Expr) -> CondId {
    e.condition(&expr).expect("condition")
}

#[test]
fn disable_until_a_condition_waits_for_the_set_that_makes_it_true() {
    check(
        |e, root| {
            let ok = flag(e, "ok", false);
            let c = cond(e, Expr::var("ok"));
            setter(e, root, 2.0, ok, vec![true.into()]);
            cmd(
                e,
                root,
                "step",
                takes(s(1.0)),
                &[Constraint::disable(Facet::Handling, When::Condition(c))],
            );
        },
        "
        0 sensor execution enabled
        0 step execution enabled
        2 sensor handling enabled
        2 sensor handling active
        2 sensor execution active
        2 set ok = true
        2 step handling enabled
        2 step handling active
        2 step execution active
        2 sensor handling completed
        2 sensor execution completed
        3 step handling completed
        3 step execution completed
        ",
    );
}

#[test]
fn a_condition_that_already_holds_does_not_wait() {
    let r = run(|e, root| {
        flag(e, "ok", true);
        let c = cond(e, Expr::var("ok"));
        let until = Constraint::disable(Facet::Handling, When::Condition(c));
        cmd(e, root, "step", takes(s(1.0)), &[until]);
    });
    assert_eq!(
        only(&r.story, &["step handling active"]),
        ["0 step handling active"]
    );
}

#[test]
fn a_condition_that_flips_in_one_instant_enables_once_and_stays_latched() {
    let r = run(|e, root| {
        let ok = flag(e, "ok", false);
        let c = cond(e, Expr::var("ok"));
        // true, false, true, false at 2 s: the first true enables (each set settles the engine
        // before the next, so `step` starts at once); the wait is over.
        let flips = vec![true.into(), false.into(), true.into(), false.into()];
        setter(e, root, 2.0, ok, flips);
        let until = Constraint::disable(Facet::Handling, When::Condition(c));
        cmd(e, root, "step", takes(s(1.0)), &[until]);
    });
    assert_eq!(
        only(&r.story, &["set ok", "step handling"]),
        [
            "2 set ok = true",
            "2 step handling enabled",
            "2 step handling active",
            "2 set ok = false",
            "2 set ok = true",
            "2 set ok = false",
            "3 step handling completed",
        ]
    );
}

#[test]
fn terminate_when_a_comparison_becomes_true() {
    let r = run(|e, root| {
        let t = e
            .declare_state("temperature", Type::Float, Value::Float(40.0))
            .expect("declare");
        let hot = cond(
            e,
            Expr::bin(BinOp::Gt, Expr::var("temperature"), Expr::lit(62.0)),
        );
        // 55 is not hot; an integer 70 is taken as 70.0, which is.
        setter(e, root, 1.0, t, vec![Value::Float(55.0)]);
        setter(e, root, 3.0, t, vec![Value::Int(70)]);
        cmd(
            e,
            root,
            "drive",
            never(),
            &[Constraint::terminate(When::Condition(hot))],
        );
    });
    assert_eq!(
        only(&r.story, &["set temperature", "drive terminat"]),
        [
            "1 set temperature = 55.0",
            "3 set temperature = 70.0",
            "3 drive terminating",
            "3 drive terminated",
        ]
    );
}

#[test]
fn activate_when_fires_on_each_rising_edge_and_on_change_of_on_each_change() {
    let r = run(|e, root| {
        let fault = flag(e, "fault", false);
        let c = cond(e, Expr::var("fault"));
        // Rises at 1, set again to true at 2 (no change), falls at 3, rises at 4.
        setter(e, root, 1.0, fault, vec![true.into()]);
        setter(e, root, 2.0, fault, vec![true.into()]);
        setter(e, root, 3.0, fault, vec![false.into()]);
        setter(e, root, 4.0, fault, vec![true.into()]);
        let when = monitor_spec(idle(), Some(2), None);
        spawn_with(
            e,
            Spawn::monitor(root, "on_fault", when),
            &[Constraint::activate(When::Condition(c))],
        );
        let each = monitor_spec(idle(), Some(3), None);
        spawn_with(
            e,
            Spawn::monitor(root, "on_change", each),
            &[Constraint::activate(When::Changed(fault))],
        );
    });
    assert_eq!(
        only(&r.story, &["ACT-on_fault handling active"]),
        [
            "1 ACT-on_fault handling active",
            "4 ACT-on_fault handling active"
        ]
    );
    assert_eq!(
        only(&r.story, &["ACT-on_change handling active"]),
        [
            "1 ACT-on_change handling active",
            "3 ACT-on_change handling active",
            "4 ACT-on_change handling active"
        ]
    );
}

#[test]
fn skip_if_is_read_when_the_turn_comes_and_the_sequence_goes_on() {
    let r = check(
        |e, root| {
            e.declare_state("position", Type::Float, Value::Unknown)
                .expect("declare");
            let unknown = cond(e, Expr::not(Expr::known(Expr::var("position"))));
            cmd(e, root, "a", takes(s(1.0)), &[]);
            cmd(
                e,
                root,
                "b",
                takes(s(1.0)),
                &[AFTER_PREVIOUS, Constraint::skip_if(unknown)],
            );
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
        1 b skipped
        1 b handling completed
        1 b execution completed
        1 c execution enabled
        1 c handling enabled
        1 c handling active
        1 c execution active
        2 c handling completed
        2 c execution completed
        ",
    );
    let _ = r;
}

#[test]
fn a_skipped_node_ends_skipped_so_an_outcome_wait_on_success_never_comes() {
    let r = run(|e, root| {
        flag(e, "skip", true);
        let c = cond(e, Expr::var("skip"));
        cmd(e, root, "a", takes(s(1.0)), &[]);
        let b = cmd(
            e,
            root,
            "b",
            takes(s(1.0)),
            &[AFTER_PREVIOUS, Constraint::skip_if(c)],
        );
        let ok = When::Event(Event::ended(b, tcm_trace::Outcome::Succeeded));
        let skipped = When::Event(Event::ended(b, tcm_trace::Outcome::Skipped));
        cmd(
            e,
            root,
            "after_success",
            noop(),
            &[Constraint::disable(Facet::Handling, ok)],
        );
        cmd(
            e,
            root,
            "after_skip",
            noop(),
            &[Constraint::disable(Facet::Handling, skipped)],
        );
    });
    assert_eq!(
        only(
            &r.story,
            &["after_success handling active", "after_success terminated"]
        ),
        ["1 after_success terminated"]
    );
    assert_eq!(
        only(&r.story, &["after_skip handling active"]),
        ["1 after_skip handling active"]
    );
}

#[test]
fn a_node_whose_skip_condition_does_not_hold_runs() {
    let r = run(|e, root| {
        flag(e, "skip", false);
        let c = cond(e, Expr::var("skip"));
        cmd(e, root, "b", takes(s(1.0)), &[Constraint::skip_if(c)]);
    });
    assert!(r.story.iter().any(|l| l == "0 b handling active"));
    assert!(!r.story.iter().any(|l| l.contains("skipped")));
}

#[test]
fn an_invariant_that_turns_false_fails_the_running_node_and_its_subtree() {
    let r = run(|e, root| {
        let healthy = flag(e, "healthy", true);
        let c = cond(e, Expr::var("healthy"));
        setter(e, root, 2.0, healthy, vec![false.into()]);
        let body = body(|e, me, _| {
            cmd(e, me, "inner", never(), &[]);
            Outcome::Never
        });
        goal(e, root, "step", body, &[Constraint::invariant(c)]);
    });
    assert_eq!(
        only(&r.story, &["set healthy", "step failed", "inner terminat"]),
        [
            "2 set healthy = false",
            "2 step failed InvariantFailed",
            "2 inner terminating",
            "2 inner terminated",
        ]
    );
    let failed = r.trace().iter().find_map(|ev| match &ev.kind {
        tcm_trace::TraceKind::Failed { message, .. } => Some(message.clone()),
        _ => None,
    });
    assert_eq!(
        failed.as_deref(),
        Some("invariant `healthy` no longer holds (healthy = false)")
    );
}

#[test]
fn an_invariant_already_false_fails_the_node_as_it_starts() {
    let r = run(|e, root| {
        flag(e, "healthy", false);
        let c = cond(e, Expr::var("healthy"));
        cmd(e, root, "step", never(), &[Constraint::invariant(c)]);
    });
    assert_eq!(
        only(&r.story, &["step"]),
        [
            "0 step execution enabled",
            "0 step handling enabled",
            "0 step handling active",
            "0 step execution active",
            "0 step failed InvariantFailed",
            "0 step handling completed",
            "0 step execution completed",
        ]
    );
}

#[test]
fn pause_while_holds_back_new_starts_and_resumes_when_it_stops_holding() {
    let r = run(|e, root| {
        let healthy = flag(e, "healthy", true);
        let unhealthy = cond(e, Expr::not(Expr::var("healthy")));
        setter(e, root, 1.5, healthy, vec![false.into()]);
        setter(e, root, 4.0, healthy, vec![true.into()]);
        let steps = body(|e, me, _| {
            cmd(e, me, "one", takes(s(2.0)), &[]);
            cmd(e, me, "two", takes(s(1.0)), &[AFTER_PREVIOUS]);
            Outcome::done()
        });
        goal(
            e,
            root,
            "mission",
            steps,
            &[Constraint::pause_while(unhealthy)],
        );
    });
    // `one` goes on while paused; `two`, due at 2, starts only at 4.
    let lines: Vec<String> = only(
        &r.story,
        &["suspended", "handling active", "one handling completed"],
    )
    .into_iter()
    .filter(|l| !l.contains("sensor"))
    .collect();
    assert_eq!(
        lines,
        [
            "0 mission handling active",
            "0 one handling active",
            "1.5 mission suspended",
            "1.5 one suspended",
            "1.5 two suspended",
            "2 one handling completed",
            "4 mission unsuspended",
            "4 two unsuspended",
            "4 two handling active",
        ]
    );
}

#[test]
fn bad_conditions_and_values_are_errors() {
    let mut e: SimEngine = Engine::new(0);
    e.declare_state("n", Type::Int, Value::Int(1))
        .expect("declare");
    let err = e
        .condition(&Expr::var("nope"))
        .expect_err("an undeclared variable");
    assert_eq!(
        err.to_string(),
        "condition `nope`: no state variable `nope` is declared"
    );
    let err = e.condition(&Expr::var("n")).expect_err("not a bool");
    assert_eq!(err.to_string(), "condition `n` is a `int`, not a `bool`");
    let n = e.state_id("n").expect("declared");
    let err = e
        .set_state(Time::ZERO, n, Value::Str("x".into()))
        .expect_err("a string");
    assert_eq!(
        err.to_string(),
        "state variable `n`: expected a value of type `int`, found `\"x\"` of type `string`"
    );
    let err = e
        .declare_state("n", Type::Bool, Value::Bool(true))
        .expect_err("another type");
    assert_eq!(
        err.to_string(),
        "state variable `n` is declared as `int`, not `bool`"
    );
    // Declared again with its type: the same variable, its value kept.
    e.set_state(Time::ZERO, n, Value::Int(5)).expect("set");
    assert_eq!(e.declare_state("n", Type::Int, Value::Int(1)), Ok(n));
    assert_eq!(e.state(n).map(|s| s.2.clone()), Some(Value::Int(5)));
}

#[test]
fn the_checker_refuses_a_trace_whose_values_do_not_explain_its_transitions() {
    let r = run(|e, root| {
        let ok = flag(e, "ok", false);
        let c = cond(e, Expr::var("ok"));
        setter(e, root, 2.0, ok, vec![true.into()]);
        let until = Constraint::disable(Facet::Handling, When::Condition(c));
        cmd(e, root, "step", takes(s(1.0)), &[until]);
        flag(e, "skip", true);
        let skip = cond(e, Expr::var("skip"));
        cmd(e, root, "b", takes(s(1.0)), &[Constraint::skip_if(skip)]);
    });
    // Without the set, `step` starts while `ok` is false.
    let tampered: Vec<tcm_trace::TraceEvent> = r
        .trace()
        .iter()
        .filter(|ev| !matches!(ev.kind, tcm_trace::TraceKind::StateSet { .. }))
        .cloned()
        .enumerate()
        .map(|(i, mut ev)| {
            ev.seq = i as u64;
            ev
        })
        .collect();
    let v = tcm_trace::check(&tampered).expect_err("a violation");
    assert!(
        v.iter().any(|v| v.rule == tcm_trace::Rule::Disable
            && v.message.contains("it waits for `ok`, which has not held")),
        "{v:?}"
    );
    // With `skip` declared false, `b` is skipped for no reason.
    let tampered: Vec<tcm_trace::TraceEvent> = r
        .trace()
        .iter()
        .cloned()
        .map(|mut ev| {
            if let tcm_trace::TraceKind::StateDeclared { var, value, .. } = &mut ev.kind {
                if var == "skip" {
                    *value = Value::Bool(false);
                }
            }
            ev
        })
        .collect();
    let v = tcm_trace::check(&tampered).expect_err("a violation");
    assert!(
        v.iter().any(|v| v.rule == tcm_trace::Rule::Condition
            && v.message.contains("none of its skip conditions holds")),
        "{v:?}"
    );
}

#[test]
fn a_goal_that_may_be_skipped_is_not_expanded_ahead_of_its_turn() {
    // `g` follows `a` (execution); a goal would expand at once, but one with `skip if` waits for
    // its execution's turn, when the condition is read: `flag` is set true at 0.5, before it.
    let r = run(|e, root| {
        let flag = super::conditions::flag(e, "flag", false);
        let c = cond(e, Expr::var("flag"));
        setter(e, root, 0.5, flag, vec![true.into()]);
        cmd(e, root, "a", takes(s(1.0)), &[]);
        let body = body(|e, me, _| {
            cmd(e, me, "inner", takes(s(1.0)), &[]);
            Outcome::done()
        });
        goal(
            e,
            root,
            "g",
            body,
            &[AFTER_PREVIOUS, Constraint::skip_if(c)],
        );
    });
    assert_eq!(
        only(
            &r.story,
            &[
                "g skipped",
                "g handling active",
                "g expansion enabled",
                "inner"
            ]
        ),
        ["1 g expansion enabled", "1 g skipped"]
    );
}
