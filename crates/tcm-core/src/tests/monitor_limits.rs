//! Monitor limits changed after the spawn (TDL's `maximum activate`, `maximum trigger` and
//! `period` as constraint statements): before the monitor starts, while it runs, at or past the
//! new maximum, and on nodes where they mean nothing.

use super::{assert_story, check, cmd, idle, monitor_spec, not_before, run, s, spawn_with};
use crate::sim::{Body, Factory, Outcome, SimEngine, body, factory, noop};
use crate::*;
use tcm_trace::TraceKind;
use tcm_trace::story::only;

/// Spawns a monitor under `up`.
fn monitor(e: &mut SimEngine, up: NodeId, spec: MonitorSpec<Factory>) -> NodeId {
    spawn_with(e, Spawn::monitor(up, "watch", spec), &[])
}

/// A command's action that changes `monitor`'s limits with `f` when it starts.
fn change(
    monitor: NodeId,
    f: impl FnOnce(&mut SimEngine, Time, NodeId) -> Result<(), EngineError> + 'static,
) -> Body {
    body(move |e, _, now| {
        f(e, now, monitor).expect("change the monitor's limits");
        Outcome::done()
    })
}

/// The `monitor_params` records of a trace, as (maximum activations, maximum triggers, period in
/// seconds).
fn params(trace: &[tcm_trace::TraceEvent]) -> Vec<(Option<u32>, Option<u32>, Option<f64>)> {
    trace
        .iter()
        .filter_map(|ev| match ev.kind {
            TraceKind::MonitorParams {
                max_activations,
                max_triggers,
                period_ns,
                ..
            } => Some((
                max_activations,
                max_triggers,
                period_ns.map(|ns| ns as f64 / 1e9),
            )),
            _ => None,
        })
        .collect()
}

#[test]
fn lowering_the_maximum_activations_while_polling_stops_at_the_new_maximum() {
    // Polls every second with no maximum; at 2.5 s the maximum becomes 4: activations at 0, 1,
    // 2 and 3, the last of which completes the monitor.
    let r = run(|e, root| {
        let m = monitor(e, root, monitor_spec(idle(), None, Some(1.0)));
        let limit = change(m, |e, now, m| e.set_max_activations(now, m, 4));
        cmd(e, root, "limit", limit, &[not_before(2.5)]);
    });
    assert_story(
        &only(
            &r.story,
            &["ACT-watch handling active", " watch handling completed"],
        ),
        "
        0 ACT-watch handling active
        1 ACT-watch handling active
        2 ACT-watch handling active
        3 watch handling completed
        3 ACT-watch handling active
        ",
    );
    assert_eq!(
        params(r.trace()),
        [(None, None, Some(1.0)), (Some(4), None, Some(1.0))]
    );
}

#[test]
fn a_maximum_already_passed_completes_the_monitor_at_once() {
    // Three activations made by 2 s; a maximum of 2 set at 2.5 s completes the monitor then,
    // with no further activation.
    let r = run(|e, root| {
        let m = monitor(e, root, monitor_spec(idle(), None, Some(1.0)));
        let limit = change(m, |e, now, m| e.set_max_activations(now, m, 2));
        cmd(e, root, "limit", limit, &[not_before(2.5)]);
    });
    assert_story(
        &only(&r.story, &["ACT-watch handling active", " watch "]),
        "
        0 watch execution enabled
        0 watch handling enabled
        0 watch handling active
        0 watch execution active
        0 ACT-watch handling active
        1 ACT-watch handling active
        2 ACT-watch handling active
        2.5 watch handling completed
        2.5 watch execution completed
        ",
    );
}

#[test]
fn reaching_a_new_maximum_of_triggers_completes_the_monitor() {
    // Each activation triggers; the maximum of 10 triggers is lowered to 2 at 2.5 s, when two
    // triggers were already counted (activations at 0 and 1; the one at 2 does not trigger).
    let r = run(|e, root| {
        let body = factory(|e, act, now, p| {
            if matches!(p, Purpose::Activation { number, .. } if *number <= 2) {
                e.trigger(now, act).expect("trigger");
            }
            Outcome::done()
        });
        let mut spec = monitor_spec(body, None, Some(1.0));
        spec.max_triggers = Some(10);
        let m = monitor(e, root, spec);
        let limit = change(m, |e, now, m| e.set_max_triggers(now, m, 2));
        cmd(e, root, "limit", limit, &[not_before(2.5)]);
    });
    assert_story(
        &only(
            &r.story,
            &["ACT-watch handling active", " watch handling completed"],
        ),
        "
        0 ACT-watch handling active
        1 ACT-watch handling active
        2 ACT-watch handling active
        2.5 watch handling completed
        ",
    );
    assert_eq!(
        params(r.trace()),
        [(None, Some(10), Some(1.0)), (None, Some(2), Some(1.0))]
    );
}

#[test]
fn limits_set_before_the_monitor_starts_replace_the_spawned_ones() {
    // The monitor waits 1 s to start; by then its limits were changed at 0: it polls every 0.5 s
    // for 3 activations instead of every 10 s for 5.
    check(
        |e, root| {
            let m = spawn_with(
                e,
                Spawn::monitor(root, "watch", monitor_spec(idle(), Some(5), Some(10.0))),
                &[not_before(1.0)],
            );
            let now = e.now();
            e.set_max_activations(now, m, 3).expect("maximum");
            e.set_period(now, m, s(0.5)).expect("period");
        },
        "
        0 watch execution enabled
        1 watch handling enabled
        1 watch handling active
        1 watch execution active
        1 ACT-watch execution enabled
        1 ACT-watch handling enabled
        1 ACT-watch handling active
        1 ACT-watch execution active
        1 ACT-watch handling completed
        1 ACT-watch execution completed
        1.5 ACT-watch execution enabled
        1.5 ACT-watch handling enabled
        1.5 ACT-watch handling active
        1.5 ACT-watch execution active
        1.5 ACT-watch handling completed
        1.5 ACT-watch execution completed
        2 watch handling completed
        2 ACT-watch execution enabled
        2 ACT-watch handling enabled
        2 ACT-watch handling active
        2 ACT-watch execution active
        2 ACT-watch handling completed
        2 ACT-watch execution completed
        2 watch execution completed
        ",
    );
}

#[test]
fn a_new_period_counts_from_the_poll_already_due() {
    // Every 2 s from 0; at 1 s the period becomes 0.5 s: the poll due at 2 keeps its time, then
    // 2.5, 3, 3.5 (the fifth activation is the maximum).
    let r = run(|e, root| {
        let m = monitor(e, root, monitor_spec(idle(), Some(5), Some(2.0)));
        let faster = change(m, |e, now, m| e.set_period(now, m, s(0.5)));
        cmd(e, root, "faster", faster, &[not_before(1.0)]);
    });
    assert_story(
        &only(&r.story, &["ACT-watch handling active"]),
        "
        0 ACT-watch handling active
        2 ACT-watch handling active
        2.5 ACT-watch handling active
        3 ACT-watch handling active
        3.5 ACT-watch handling active
        ",
    );
    assert_eq!(
        params(r.trace()),
        [(Some(5), None, Some(2.0)), (Some(5), None, Some(0.5))]
    );
}

#[test]
fn a_period_given_to_a_running_monitor_polls_one_period_later() {
    // Not polling, activated once by hand at start; from 1 s it polls every 2 s: 3 and 5.
    let r = run(|e, root| {
        let m = spawn_with(
            e,
            Spawn::monitor(root, "watch", monitor_spec(idle(), Some(3), None)),
            &[Constraint::activate(When::Now)],
        );
        let poll = change(m, |e, now, m| e.set_period(now, m, s(2.0)));
        cmd(e, root, "poll", poll, &[not_before(1.0)]);
    });
    assert_story(
        &only(
            &r.story,
            &["ACT-watch handling active", " watch handling completed"],
        ),
        "
        0 ACT-watch handling active
        3 ACT-watch handling active
        5 watch handling completed
        5 ACT-watch handling active
        ",
    );
}

#[test]
fn a_finished_monitor_is_left_alone_and_other_nodes_are_refused() {
    let r = run(|e, root| {
        let m = monitor(e, root, monitor_spec(idle(), Some(1), None));
        let now = e.now();
        e.activate(now, m).expect("activate");
        // Completed at its one activation: nothing changes, nothing is traced.
        e.set_max_activations(now, m, 5).expect("completed monitor");
        let c = cmd(e, root, "plain", noop(), &[]);
        assert_eq!(
            e.set_max_triggers(now, c, 1),
            Err(EngineError::NotAMonitor(3))
        );
    });
    assert_eq!(params(r.trace()), [(Some(1), None, None)]);
}
