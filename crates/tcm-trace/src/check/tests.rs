//! Unit tests for `check.rs`: valid hand-made traces pass, and each rule catches a trace that breaks it.

use super::{Rule, check};
use crate::event::{TraceConstraint, TraceEvent, TraceKind, TraceThen, TraceWhen};
use crate::state::{NodeKind, Point};
use crate::test_util::*;

#[track_caller]
pub(super) fn passes(trace: &[TraceEvent]) -> super::CheckReport {
    match check(trace) {
        Ok(r) => r,
        Err(vs) => {
            let text: Vec<String> = vs.iter().map(|v| v.to_string()).collect();
            panic!("expected no violation, got:\n{}", text.join("\n"))
        }
    }
}

// Goal {1} "a" running with command {2} "c" running under it, both alive.
fn running(b: &mut Tb) {
    b.goal(1, 0, "a").start_goal(1);
    b.command(2, 1, "c");
    b.tr(1, X, D, E).tr(1, H, A, C).tr(1, P, A, C);
    b.start_command(2).tr(1, X, E, A);
}

// Terminates the running tree of `running`.
fn terminate_running(b: &mut Tb) {
    b.push(TraceKind::Terminating { node: 1 });
    b.push(TraceKind::Terminating { node: 2 });
    b.tr(2, H, A, C).tr(2, X, A, C);
    b.push(TraceKind::Terminated { node: 2 });
    b.tr(1, X, A, C);
    b.push(TraceKind::Terminated { node: 1 });
    b.push(TraceKind::Reclaimed { node: 2 });
    b.push(TraceKind::Reclaimed { node: 1 });
}

fn term_at_time(at: u64) -> TraceConstraint {
    TraceConstraint::trigger(TraceWhen::At(at), TraceThen::Terminate)
}

#[test]
fn valid_small_run_passes_and_counts() {
    let r = passes(&small_run());
    assert_eq!((r.n_nodes, r.n_transitions), (2, 15));
    assert_eq!(r.n_records, small_run().len() as u64);
}

#[test]
fn valid_termination_passes() {
    let mut b = Tb::new();
    running(&mut b);
    b.at(2 * S);
    terminate_running(&mut b);
    passes(&b.build());
}

#[test]
fn valid_terminate_at_time_passes_and_late_is_caught() {
    let mut b = Tb::new();
    b.goal(1, 0, "a")
        .constrain(1, term_at_time(2 * S))
        .start_goal(1);
    b.command(2, 1, "c");
    b.tr(1, X, D, E).tr(1, H, A, C).tr(1, P, A, C);
    b.start_command(2).tr(1, X, E, A);
    let mut ok = b.clone_for_test();
    ok.at(2 * S);
    terminate_running(&mut ok);
    let r = passes(&ok.build());
    assert_eq!(r.n_terminations_checked, 1);
    b.at(3 * S);
    terminate_running(&mut b);
    caught(&b.build(), Rule::Terminate);
}

#[test]
fn terminate_at_time_not_owed_by_a_trace_that_ends_before() {
    let mut b = Tb::new();
    b.goal(1, 0, "a")
        .constrain(1, term_at_time(10 * S))
        .start_goal(1);
    b.at(S).push(TraceKind::External { name: "x".into() });
    passes(&b.build());
    // Going past the due time without terminating is caught at the end of the trace.
    b.at(11 * S).push(TraceKind::External { name: "y".into() });
    caught(&b.build(), Rule::Terminate);
}

/// The small run with one more record after it, a second after its end.
fn after_small_run(kind: TraceKind) -> Vec<TraceEvent> {
    let mut t = small_run();
    let seq = t.len() as u64;
    t.push(TraceEvent {
        seq,
        t: 2 * S,
        kind,
    });
    t
}

#[test]
fn shape_rules() {
    let mut t = small_run();
    t.remove(0);
    caught(&t, Rule::RunStarted);
    let mut t = small_run();
    t[3].seq = 7;
    caught(&t, Rule::SeqGap);
    let mut t = small_run();
    t[1].t = 5;
    caught(&t, Rule::TimeBackwards);
    let mut b = Tb::new();
    b.tr(5, H, D, E);
    caught(&b.build(), Rule::BeforeSpawn);
    caught(
        &after_small_run(TraceKind::Suspended { node: 2 }),
        Rule::AfterReclaim,
    );
    let mut b = Tb::new();
    b.goal(1, 0, "a").goal(1, 0, "a");
    caught(&b.build(), Rule::DuplicateNode);
    let mut b = Tb::new();
    b.goal(1, 0, "a").goal(2, 7, "b");
    caught(&b.build(), Rule::UnknownParent);
    let mut b = Tb::new();
    b.tr(0, H, A, C);
    caught(&b.build(), Rule::RootRecord);
    // A `placed` or `log` record names a node in the tree, as every record about a node does.
    let placed = |node| TraceKind::Placed {
        node,
        agent: "arm".into(),
    };
    let log = |node| TraceKind::Log {
        node,
        message: "gripper open".into(),
    };
    for note in [&placed as &dyn Fn(u64) -> TraceKind, &log] {
        let mut b = Tb::new();
        b.push(note(3));
        caught(&b.build(), Rule::BeforeSpawn);
        caught(&after_small_run(note(2)), Rule::AfterReclaim);
        let mut b = Tb::new();
        b.command(1, 0, "grasp")
            .push(note(1))
            .start_command(1)
            .finish_command(1);
        assert_eq!(rules(&b.build()), []);
    }
}

#[test]
fn reservation_rules() {
    let reserve = |b: &mut Tb| {
        b.goal(1, 0, "a");
        b.push(TraceKind::Reserved {
            node: 2,
            parent: 1,
            name: "b".into(),
        });
    };
    let mut b = Tb::new();
    reserve(&mut b);
    b.goal(2, 1, "b");
    passes(&b.build());
    let mut b = Tb::new();
    reserve(&mut b);
    b.push(TraceKind::Dead { node: 2 });
    passes(&b.build());
    // Unresolved while the parent's subtree runs: nothing owed yet (a stuck run may end so, and
    // an on-terminate label lives until the node that took it over completes).
    let mut b = Tb::new();
    reserve(&mut b);
    passes(&b.build());
    b.start_goal(1).tr(1, H, A, C);
    passes(&b.build());
    b.tr(1, P, A, C).tr(1, X, E, C);
    caught(&b.build(), Rule::ReservedUnresolved);
    let mut b = Tb::new();
    reserve(&mut b);
    b.tr(2, P, D, E);
    caught(&b.build(), Rule::BeforeSpawn);
    let mut b = Tb::new();
    reserve(&mut b);
    b.push(TraceKind::Dead { node: 2 });
    b.goal(2, 1, "b");
    caught(&b.build(), Rule::DeadNode);
}

#[test]
fn facet_and_termination_order() {
    let mut b = Tb::new();
    b.goal(1, 0, "a").tr(1, P, E, A);
    caught(&b.build(), Rule::TransitionFrom);
    let mut b = Tb::new();
    b.command(1, 0, "c").tr(1, P, C, E);
    caught(&b.build(), Rule::FacetForward);
    let mut b = Tb::new();
    b.goal(1, 0, "a").push(TraceKind::Terminated { node: 1 });
    caught(&b.build(), Rule::TerminationOrder);
    let mut b = Tb::new();
    b.goal(1, 0, "a")
        .push(TraceKind::Terminating { node: 1 })
        .push(TraceKind::Terminating { node: 1 });
    caught(&b.build(), Rule::TerminationOrder);
}

#[test]
fn constraint_records_rules() {
    // An enablement of a facet already enabled comes too late.
    let mut b = Tb::new();
    b.goal(1, 0, "a").tr(1, P, D, E);
    b.constrain(
        1,
        TraceConstraint::trigger(TraceWhen::At(S), TraceThen::Enable(P)),
    );
    caught(&b.build(), Rule::LateConstraint);
    // One of a facet still disabled (a constraint statement after the spawn, its node held by
    // its parent's body) can still take effect.
    let mut b = Tb::new();
    b.goal(1, 0, "a").tr(1, P, D, E);
    b.constrain(
        1,
        TraceConstraint::trigger(TraceWhen::At(S), TraceThen::Enable(H)),
    );
    assert!(crate::check(&b.build()).is_ok());
    // Terminate forms may come later.
    let mut b = Tb::new();
    b.goal(1, 0, "a")
        .tr(1, P, D, E)
        .constrain(1, term_at_time(S));
    passes(&b.build());
    let mut b = Tb::new();
    b.goal(1, 0, "a");
    b.constrain(
        1,
        TraceConstraint::trigger(
            TraceWhen::Event(ev_ref(9, X, Point::Completed)),
            TraceThen::Enable(H),
        ),
    );
    caught(&b.build(), Rule::UnknownReference);
}

#[test]
fn enablement_structure_rules() {
    let mut b = Tb::new();
    b.goal(1, 0, "a").tr(1, H, D, E);
    caught(&b.build(), Rule::HandlingEnable);
    let mut b = Tb::new();
    b.command(1, 0, "c").tr(1, H, D, E);
    caught(&b.build(), Rule::HandlingEnable);
    let mut b = Tb::new();
    b.goal(1, 0, "a").goal(2, 1, "b").tr(2, P, D, E);
    caught(&b.build(), Rule::ExpansionEnable);
    let mut b = Tb::new();
    b.goal(1, 0, "a").command(2, 1, "c").tr(2, X, D, E);
    caught(&b.build(), Rule::ExecutionEnable);
}

#[test]
fn activation_rules() {
    let mut b = Tb::new();
    b.goal(1, 0, "a").tr(1, P, D, E).tr(1, H, D, A);
    caught(&b.build(), Rule::HandlingSkipsEnabled);
    let mut b = Tb::new();
    b.goal(1, 0, "a").tr(1, P, D, E).tr(1, H, D, E);
    b.push(TraceKind::Terminating { node: 1 }).tr(1, H, E, A);
    caught(&b.build(), Rule::ActiveWhileTerminating);
    let mut b = Tb::new();
    b.goal(1, 0, "a")
        .push(TraceKind::Suspended { node: 1 })
        .tr(1, P, D, E)
        .tr(1, H, D, E)
        .tr(1, H, E, A);
    caught(&b.build(), Rule::ActiveWhileSuspended);
    let mut b = Tb::new();
    b.goal(1, 0, "a")
        .push(TraceKind::Suspended { node: 1 })
        .tr(1, P, D, E)
        .tr(1, H, D, E);
    b.push(TraceKind::Unsuspended { node: 1 }).tr(1, H, E, A);
    passes(&b.build());
    let mut b = Tb::new();
    b.goal(1, 0, "a").tr(1, P, D, E).tr(1, P, E, A);
    caught(&b.build(), Rule::ExpansionActive);
    let mut b = Tb::new();
    b.goal(1, 0, "a")
        .start_goal(1)
        .tr(1, X, D, E)
        .tr(1, X, E, A);
    caught(&b.build(), Rule::ExecutionActive);
}

#[test]
fn completion_rules() {
    // A goal child not handled yet keeps the parent's expansion open.
    let mut b = Tb::new();
    b.goal(1, 0, "a")
        .start_goal(1)
        .goal(2, 1, "b")
        .tr(1, H, A, C)
        .tr(1, P, A, C);
    caught(&b.build(), Rule::ExpansionComplete);
    let mut b = Tb::new();
    b.goal(1, 0, "a").start_goal(1).tr(1, P, A, C);
    caught(&b.build(), Rule::ExpansionComplete);
    // Deep: a grandchild goal not handled keeps the grandparent's expansion open.
    let mut b = Tb::new();
    b.goal(1, 0, "a")
        .start_goal(1)
        .goal(2, 1, "b")
        .start_goal(2)
        .goal(3, 2, "c");
    b.tr(2, H, A, C).tr(1, H, A, C).tr(1, P, A, C);
    caught(&b.build(), Rule::ExpansionComplete);
    let mut b = Tb::new();
    running(&mut b);
    b.tr(1, X, A, C);
    caught(&b.build(), Rule::ExecutionComplete);
    let mut b = Tb::new();
    running(&mut b);
    b.push(TraceKind::Terminating { node: 1 })
        .push(TraceKind::Terminated { node: 1 });
    caught(&b.build(), Rule::TerminatedEarly);
    let mut b = Tb::new();
    running(&mut b);
    b.finish_command(2)
        .tr(1, X, A, C)
        .push(TraceKind::Reclaimed { node: 1 });
    caught(&b.build(), Rule::ReclaimEarly);
    let mut b = Tb::new();
    running(&mut b);
    b.push(TraceKind::Reclaimed { node: 2 });
    caught(&b.build(), Rule::ReclaimEarly);
}

// Two sibling commands under the root, {1} and {2}; {2} carries `c`; {1} runs to completion at 1 s,
// then {2} is enabled at `t2`.
fn two_commands(c: Option<TraceConstraint>, t2: u64) -> Tb {
    let mut b = Tb::new();
    b.command(1, 0, "one").command(2, 0, "two");
    if let Some(c) = c {
        b.constrain(2, c);
    }
    b.start_command(1).at(S).finish_command(1);
    b.at(t2).start_command(2);
    b
}

#[test]
fn disable_until_event() {
    let c = TraceConstraint::trigger(
        TraceWhen::Event(ev_ref(1, X, Point::Completed)),
        TraceThen::Enable(X),
    );
    let r = passes(&two_commands(Some(c.clone()), S).build());
    assert!(r.n_enablement_checks >= 1);
    let mut b = Tb::new();
    b.command(1, 0, "one").command(2, 0, "two").constrain(2, c);
    b.start_command(2);
    caught(&b.build(), Rule::Disable);
    // A dead reference satisfies it.
    let mut b = Tb::new();
    b.goal(1, 0, "a").start_goal(1);
    b.push(TraceKind::Reserved {
        node: 2,
        parent: 1,
        name: "b".into(),
    });
    b.command(3, 1, "c");
    b.constrain(
        3,
        TraceConstraint::trigger(
            TraceWhen::Event(ev_ref(2, X, Point::Completed)),
            TraceThen::Enable(X),
        ),
    );
    b.push(TraceKind::Dead { node: 2 });
    b.tr(1, X, D, E).start_command(3);
    passes(&b.build());
}

/// An outcome event (`one failed`): a command that succeeded does not satisfy it, so a node
/// waiting for it must not start; one that failed does.
#[test]
fn disable_until_an_outcome_event() {
    let mut failed = ev_ref(1, X, Point::Completed);
    failed.outcome = Some(crate::state::Outcome::Failed);
    let c = TraceConstraint::trigger(TraceWhen::Event(failed), TraceThen::Enable(X));
    // `one` succeeded and `two` starts anyway.
    caught(&two_commands(Some(c.clone()), S).build(), Rule::Disable);
    // `one` failed: `two` may start.
    let mut b = Tb::new();
    b.command(1, 0, "one").command(2, 0, "two").constrain(2, c);
    b.start_command(1).at(S);
    b.push(TraceKind::Failed {
        node: 1,
        exception: "Blocked".into(),
        message: "blocked".into(),
    });
    b.finish_command(1);
    b.at(S).start_command(2);
    passes(&b.build());
}

#[test]
fn disable_until_time_and_for_after() {
    let c = TraceConstraint::trigger(TraceWhen::At(2 * S), TraceThen::Enable(X));
    passes(&two_commands(Some(c.clone()), 2 * S).build());
    caught(&two_commands(Some(c), S).build(), Rule::Disable);
    let c = TraceConstraint::trigger(
        TraceWhen::After {
            delay_ns: S,
            event: ev_ref(1, H, Point::Completed),
        },
        TraceThen::Enable(X),
    );
    passes(&two_commands(Some(c.clone()), 2 * S).build());
    caught(&two_commands(Some(c), S + S / 2).build(), Rule::Disable);
}

#[test]
fn disable_until_external() {
    let c = TraceConstraint::trigger(TraceWhen::External("go".into()), TraceThen::Enable(H));
    caught(&two_commands(Some(c.clone()), S).build(), Rule::Disable);
    let mut b = Tb::new();
    b.command(1, 0, "one")
        .constrain(1, c)
        .push(TraceKind::External { name: "go".into() });
    b.start_command(1);
    passes(&b.build());
}

#[test]
fn expand_first_and_delay_expansion() {
    let mut b = Tb::new();
    b.goal(1, 0, "a")
        .constrain(1, TraceConstraint::ExpandFirst)
        .start_goal(1)
        .tr(1, X, D, E);
    caught(&b.build(), Rule::ExpandFirst);
    let mut b = Tb::new();
    b.goal(1, 0, "a")
        .constrain(1, TraceConstraint::ExpandFirst)
        .start_goal(1);
    b.tr(1, H, A, C).tr(1, P, A, C).tr(1, X, D, E);
    passes(&b.build());
    let mut b = Tb::new();
    b.goal(1, 0, "a")
        .constrain(1, TraceConstraint::DelayExpansion)
        .start_goal(1);
    caught(&b.build(), Rule::DelayExpansion);
    let mut b = Tb::new();
    b.goal(1, 0, "a")
        .constrain(1, TraceConstraint::DelayExpansion)
        .tr(1, X, D, E)
        .start_goal(1);
    passes(&b.build());
}

#[test]
fn terminate_now() {
    let mut b = Tb::new();
    running(&mut b);
    b.at(S).constrain(
        1,
        TraceConstraint::trigger(TraceWhen::Now, TraceThen::Terminate),
    );
    let mut ok = b.clone_for_test();
    terminate_running(&mut ok);
    passes(&ok.build());
    b.at(2 * S);
    terminate_running(&mut b);
    caught(&b.build(), Rule::Terminate);
}

// {1} "a" running with command {2}; command {3} "m" under the root, constrained by `c`; {3} runs and
// completes at 1 s; {1} is terminated at `tt`.
fn watcher(c: TraceConstraint, tt: u64) -> Vec<TraceEvent> {
    let mut b = Tb::new();
    running(&mut b);
    b.command(3, 0, "m").start_command(3);
    b.constrain(1, c);
    b.at(S).finish_command(3);
    b.at(tt);
    terminate_running(&mut b);
    b.build()
}

#[test]
fn terminate_at_event() {
    let c = TraceConstraint::trigger(
        TraceWhen::Event(ev_ref(3, X, Point::Completed)),
        TraceThen::Terminate,
    );
    passes(&watcher(c.clone(), S));
    caught(&watcher(c, 2 * S), Rule::Terminate);
    // An event reached because its node was terminating does not fire the constraint.
    let mut b = Tb::new();
    running(&mut b);
    b.command(3, 0, "m").start_command(3);
    b.constrain(
        1,
        TraceConstraint::trigger(
            TraceWhen::Event(ev_ref(3, X, Point::Completed)),
            TraceThen::Terminate,
        ),
    );
    b.at(S)
        .push(TraceKind::Terminating { node: 3 })
        .finish_command(3);
    b.push(TraceKind::Terminated { node: 3 });
    b.at(2 * S).push(TraceKind::External {
        name: "later".into(),
    });
    passes(&b.build());
}

#[test]
fn terminate_in_after() {
    let c = TraceConstraint::trigger(
        TraceWhen::After {
            delay_ns: S,
            event: ev_ref(3, X, Point::Completed),
        },
        TraceThen::Terminate,
    );
    passes(&watcher(c.clone(), 2 * S));
    caught(&watcher(c, 3 * S), Rule::Terminate);
}

#[test]
fn terminate_at_external() {
    let mut b = Tb::new();
    running(&mut b);
    b.constrain(
        1,
        TraceConstraint::trigger(TraceWhen::External("stop".into()), TraceThen::Terminate),
    );
    b.at(S).push(TraceKind::External {
        name: "stop".into(),
    });
    let mut ok = b.clone_for_test();
    terminate_running(&mut ok);
    passes(&ok.build());
    b.at(2 * S);
    terminate_running(&mut b);
    caught(&b.build(), Rule::Terminate);
}

#[test]
fn only_terminate_at_time_checked_at_end_when_due_in_trace() {
    // A record past the due time is needed before a timer-based termination is owed.
    let mut b = Tb::new();
    running(&mut b);
    b.constrain(1, term_at_time(5 * S));
    b.at(5 * S).push(TraceKind::External {
        name: "tick".into(),
    });
    passes(&b.build());
    assert!(rules(&b.build()).is_empty());
}

#[test]
fn monitor_and_handler_kinds() {
    let mut b = Tb::new();
    b.spawn(1, 0, NodeKind::Monitor, "mon")
        .start_command(1)
        .finish_command(1);
    b.spawn(2, 0, NodeKind::Handler, "h")
        .start_goal(2)
        .tr(2, H, A, C)
        .tr(2, P, A, C);
    passes(&b.build());
}

#[test]
fn monitor_params_changed_after_the_spawn_keep_the_counts() {
    // A monitor without maximum makes two activations; a second `monitor_params` record sets its
    // maximum to 2, which its handling then completes at. Without that record, completing is a
    // violation.
    let params = |max_activations| TraceKind::MonitorParams {
        node: 1,
        max_activations,
        max_triggers: None,
        period_ns: None,
        initial_wait: false,
    };
    let mut b = Tb::new();
    b.spawn(1, 0, NodeKind::Monitor, "mon")
        .push(params(None))
        .start_command(1);
    for (node, number) in [(2, 1), (3, 2)] {
        b.command(node, 1, "ACT-mon").push(TraceKind::Activated {
            monitor: 1,
            node,
            number,
        });
        b.start_command(node).finish_command(node);
    }
    let mut unchanged = b.clone_for_test();
    b.push(params(Some(2))).tr(1, H, A, C).tr(1, X, A, C);
    passes(&b.build());
    unchanged.tr(1, H, A, C).tr(1, X, A, C);
    caught(&unchanged.build(), Rule::MonitorComplete);
}

#[test]
fn long_chain_checks_quickly() {
    // 20,000 commands, each `disable execution until previous execution completed`, then a 2,000-deep
    // recursion of goals: checks in linear time (a quadratic checker would take minutes in debug).
    let mut b = Tb::new();
    let n = 20_000u64;
    for i in 1..=n {
        b.command(i, 0, "c");
        if i > 1 {
            b.constrain(
                i,
                TraceConstraint::trigger(
                    TraceWhen::Event(ev_ref(i - 1, X, Point::Completed)),
                    TraceThen::Enable(X),
                ),
            );
        }
        b.start_command(i).finish_command(i);
        if i > 1 {
            b.push(TraceKind::Reclaimed { node: i - 1 });
        }
    }
    let depth = 2_000u64;
    for d in 0..depth {
        let node = n + 1 + d;
        let parent = if d == 0 { 0 } else { node - 1 };
        b.goal(node, parent, "rec")
            .start_goal(node)
            .tr(node, X, D, E);
    }
    for d in (0..depth).rev() {
        let node = n + 1 + d;
        b.tr(node, H, A, C).tr(node, P, A, C);
    }
    let r = passes(&b.build());
    assert_eq!(r.n_nodes, n + depth);
}

#[test]
fn million_records() {
    // Slow in debug builds: run with RUN_SLOW_TESTS=1 (about a second in release).
    if std::env::var_os("RUN_SLOW_TESTS").is_none() {
        return;
    }
    let mut b = Tb::new();
    let n = 110_000u64;
    for i in 1..=n {
        b.command(i, 0, "c");
        if i > 1 {
            b.constrain(
                i,
                TraceConstraint::trigger(
                    TraceWhen::Event(ev_ref(i - 1, X, Point::Completed)),
                    TraceThen::Enable(X),
                ),
            );
        }
        b.start_command(i).finish_command(i);
        if i > 1 {
            b.push(TraceKind::Reclaimed { node: i - 1 });
        }
    }
    let depth = 10_000u64;
    for d in 0..depth {
        let node = n + 1 + d;
        let parent = if d == 0 { 0 } else { node - 1 };
        b.goal(node, parent, "rec")
            .start_goal(node)
            .tr(node, X, D, E);
    }
    let leaf = n + depth + 1;
    b.command(leaf, leaf - 1, "move").start_command(leaf);
    for d in (0..depth).rev() {
        let node = n + 1 + d;
        b.tr(node, X, E, A);
    }
    b.finish_command(leaf);
    for d in (0..depth).rev() {
        let node = n + 1 + d;
        b.tr(node, H, A, C).tr(node, P, A, C).tr(node, X, A, C);
    }
    let trace = b.build();
    assert!(trace.len() >= 1_000_000, "{}", trace.len());
    let started = std::time::Instant::now();
    let r = passes(&trace);
    eprintln!("checked {} records in {:?}", trace.len(), started.elapsed());
    assert_eq!(r.n_nodes, n + depth + 1);
}

#[test]
fn callbacks_run_once_after_they_are_set_and_not_before_their_event_or_time() {
    let set = |callback: u64, when: TraceWhen| TraceKind::CallbackSet {
        callback,
        name: format!("cb{callback}"),
        node: Some(1),
        when,
    };
    let ran = |callback: u64| TraceKind::CallbackRan {
        callback,
        name: format!("cb{callback}"),
    };
    let mut b = Tb::new();
    running(&mut b);
    b.push(set(1, TraceWhen::At(2 * S)))
        .push(set(2, TraceWhen::Event(ev_ref(2, X, Point::Completed))));
    // Set, not run: passes.
    passes(&b.build());
    let mut early = b.clone_for_test();
    early.at(S).push(ran(1));
    caught(&early.build(), Rule::Callback);
    let mut before_event = b.clone_for_test();
    before_event.at(3 * S).push(ran(2));
    caught(&before_event.build(), Rule::Callback);
    let mut twice = b.clone_for_test();
    twice.at(2 * S).push(ran(1)).push(ran(1));
    caught(&twice.build(), Rule::Callback);
    let mut unset = b.clone_for_test();
    unset.push(ran(9));
    caught(&unset.build(), Rule::Callback);
    let mut again = b.clone_for_test();
    again.push(set(1, TraceWhen::Now));
    caught(&again.build(), Rule::Callback);
    // On time, and after the event: passes.
    b.at(2 * S).push(ran(1));
    b.at(3 * S).finish_command(2).push(ran(2));
    passes(&b.build());
}

#[test]
fn a_prefix_owes_nothing_at_its_cut_but_breaks_no_rule_before_it() {
    use super::check_prefix;
    // Cut right after `terminate now` was applied: the terminations it causes were cut off.
    let mut b = Tb::new();
    running(&mut b);
    b.at(S).constrain(
        1,
        TraceConstraint::trigger(TraceWhen::Now, TraceThen::Terminate),
    );
    let cut = b.build();
    caught(&cut, Rule::Terminate);
    assert!(check_prefix(&cut).is_ok(), "{:?}", check_prefix(&cut).err());
    // Cut after a body ended with a reservation unresolved.
    let mut b = Tb::new();
    b.goal(1, 0, "a");
    b.push(TraceKind::Reserved {
        node: 2,
        parent: 1,
        name: "b".into(),
    });
    b.start_goal(1).tr(1, X, D, E).tr(1, H, A, C).tr(1, P, A, C);
    b.tr(1, X, E, C);
    let cut = b.build();
    caught(&cut, Rule::ReservedUnresolved);
    assert!(check_prefix(&cut).is_ok(), "{:?}", check_prefix(&cut).err());
    // A violation inside the prefix is still one: the termination came a second too late.
    let mut b = Tb::new();
    running(&mut b);
    b.at(S).constrain(
        1,
        TraceConstraint::trigger(TraceWhen::Now, TraceThen::Terminate),
    );
    b.at(2 * S);
    terminate_running(&mut b);
    let rules: Vec<Rule> = match check_prefix(&b.build()) {
        Ok(_) => Vec::new(),
        Err(vs) => vs.iter().map(|v| v.rule).collect(),
    };
    assert!(rules.contains(&Rule::Terminate), "{rules:?}");
}

mod steering;
