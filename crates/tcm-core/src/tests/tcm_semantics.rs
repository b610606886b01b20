//! What a program ported from TCM relies on (issue 11): terminating what is already gone,
//! a body that terminates itself and goes on, the plan's order kept by a node terminated before it
//! started, persistent goals, on-terminate tasks of a body that already ended, and handler search
//! from a failing handler. Each story is numbered as docs/semantics.md, "Termination".

use super::{AFTER_PREVIOUS, check, cmd, goal, never, not_before, run, s, spawns};
use crate::sim::{Outcome, SimEngine, body, factory, noop, takes};
use crate::*;
use std::cell::Cell;
use std::rc::Rc;
use tcm_trace::{TraceEvent, TraceKind};

/// The warnings of a trace, in order.
fn warnings(trace: &[TraceEvent]) -> Vec<String> {
    trace
        .iter()
        .filter_map(|r| match &r.kind {
            TraceKind::Warning { message, .. } => Some(message.clone()),
            _ => None,
        })
        .collect()
}

/// A persistent goal under `up` whose body spawns with `f`, then ends after `secs`.
fn persistent_goal(
    e: &mut SimEngine,
    up: NodeId,
    name: &'static str,
    secs: f64,
    f: impl FnOnce(&mut SimEngine, NodeId, Time) + 'static,
) -> NodeId {
    let mut spec = Spawn::new(up, NodeKind::Goal, name, spawns(secs, f));
    spec.persistent = true;
    let now = e.now();
    e.spawn(now, spec).expect("spawn")
}

#[test]
fn terminating_a_node_already_gone_or_terminating_warns_and_goes_on() {
    let r = check(
        |e, root| {
            let quick = cmd(e, root, "quick", takes(s(1.0)), &[]);
            let slow = cmd(e, root, "slow", never(), &[]);
            let killer = body(move |e, _, now| {
                // Neither is an error: TCM warned and went on.
                e.terminate(now, quick).expect("a reclaimed node");
                e.terminate(now, slow).expect("a running node");
                e.terminate(now, slow).expect("a node already terminating");
                Outcome::done()
            });
            cmd(e, root, "killer", killer, &[not_before(2.0)]);
        },
        "
        0 quick execution enabled
        0 quick handling enabled
        0 quick handling active
        0 quick execution active
        0 slow execution enabled
        0 slow handling enabled
        0 slow handling active
        0 slow execution active
        0 killer execution enabled
        1 quick handling completed
        1 quick execution completed
        2 killer handling enabled
        2 killer handling active
        2 killer execution active
        2 slow terminating
        2 slow handling completed
        2 killer handling completed
        2 killer execution completed
        2 slow execution completed
        2 slow terminated
        ",
    );
    let w = warnings(r.trace());
    assert_eq!(w.len(), 2, "{w:?}");
    assert!(
        w[0].starts_with("Trying to terminate already dead node"),
        "{w:?}"
    );
    assert!(w[0].ends_with("(completed)"), "{w:?}");
    assert!(w[1].contains("slow"), "{w:?}");
}

#[test]
fn a_goal_that_terminates_itself_still_spawns_children_that_wind_down_with_it() {
    let spawned = Rc::new(Cell::new(0));
    let seen = spawned.clone();
    let r = check(
        |e, root| {
            let me_first = body(move |e, me, now| {
                e.terminate(now, me).expect("terminate itself");
                // TCM created these: they are terminated at once, with their parent.
                for name in ["after1", "after2"] {
                    let child = Spawn::new(
                        me,
                        NodeKind::Command,
                        name,
                        body(|_, _, _| panic!("a child of a terminated goal never runs")),
                    );
                    e.spawn(now, child).expect("spawn under a terminating goal");
                    seen.set(seen.get() + 1);
                }
                Outcome::after(s(1.0))
            });
            goal(e, root, "quitter", me_first, &[]);
            cmd(e, root, "next", noop(), &[AFTER_PREVIOUS]);
        },
        "
        0 quitter expansion enabled
        0 quitter execution enabled
        0 quitter handling enabled
        0 quitter handling active
        0 quitter expansion active
        0 quitter terminating
        0 quitter handling completed
        0 after1 terminating
        0 after1 execution enabled
        0 after1 handling enabled
        0 after1 handling completed
        0 after1 execution completed
        0 after1 terminated
        0 after2 terminating
        0 after2 execution enabled
        0 after2 handling enabled
        0 after2 handling completed
        0 after2 execution completed
        0 after2 terminated
        0 quitter expansion completed
        0 quitter execution completed
        0 quitter terminated
        0 next execution enabled
        0 next handling enabled
        0 next handling active
        0 next execution active
        0 next handling completed
        0 next execution completed
        ",
    );
    assert_eq!(spawned.get(), 2);
    assert_eq!(r.sim.engine.stats().live_nodes, 1, "only the root is left");
}

#[test]
fn a_node_terminated_before_it_started_completes_in_the_plans_order() {
    // first (2 s), then second, then third: second is terminated at 1 s, before it started. Its
    // completion, which third waits for, still comes after first's: third never overtakes first.
    check(
        |e, root| {
            cmd(e, root, "first", takes(s(2.0)), &[]);
            let second = cmd(
                e,
                root,
                "second",
                body(|_, _, _| panic!("never starts")),
                &[AFTER_PREVIOUS],
            );
            cmd(e, root, "third", takes(s(1.0)), &[AFTER_PREVIOUS]);
            let killer = body(move |e, _, now| {
                e.terminate(now, second).expect("terminate");
                Outcome::done()
            });
            cmd(e, root, "killer", killer, &[not_before(1.0)]);
        },
        "
        0 first execution enabled
        0 first handling enabled
        0 first handling active
        0 first execution active
        0 killer execution enabled
        1 killer handling enabled
        1 killer handling active
        1 killer execution active
        1 second terminating
        1 killer handling completed
        1 killer execution completed
        2 first handling completed
        2 first execution completed
        2 second execution enabled
        2 second handling enabled
        2 second handling completed
        2 second execution completed
        2 second terminated
        2 third execution enabled
        2 third handling enabled
        2 third handling active
        2 third execution active
        3 third handling completed
        3 third execution completed
        ",
    );
}

#[test]
fn a_node_terminated_before_it_started_does_not_wait_for_its_delays() {
    // Its own delay (10 s) and external event are released; its dependant goes on at once.
    check(
        |e, root| {
            let gate = e.external("never-raised");
            let waits = [
                not_before(10.0),
                Constraint::disable(Facet::Handling, When::External(gate)),
            ];
            let late = cmd(
                e,
                root,
                "late",
                body(|_, _, _| panic!("never starts")),
                &waits,
            );
            cmd(e, root, "then", noop(), &[AFTER_PREVIOUS]);
            let killer = body(move |e, _, now| {
                e.terminate(now, late).expect("terminate");
                Outcome::done()
            });
            cmd(e, root, "killer", killer, &[not_before(1.0)]);
        },
        "
        0 late execution enabled
        0 killer execution enabled
        1 killer handling enabled
        1 killer handling active
        1 killer execution active
        1 late terminating
        1 late handling enabled
        1 late handling completed
        1 late execution completed
        1 late terminated
        1 then execution enabled
        1 then handling enabled
        1 then handling active
        1 then execution active
        1 killer handling completed
        1 killer execution completed
        1 then handling completed
        1 then execution completed
        ",
    );
}

#[test]
fn a_node_terminated_before_it_started_completes_at_its_turn_after_the_siblings_released_before_it()
{
    // TDL: `spawn watch() with maximum activate 1; x: spawn x() with terminate; watch activate at
    // x handling completed;`. The body ends at 0.5 s and releases both: `watch`, released first,
    // starts first, and `x` completes at its own turn on the agenda, after that start. So the
    // activation finds `watch` active (no "Trying to activate an inactive monitor"), its one
    // activation completes it, and the run ends instead of waiting forever.
    let r = check(
        |e, root| {
            let tdl_body = spawns(0.5, |e, me, now| {
                e.hold_children(now, me, true).expect("hold");
                let spec = super::monitor_spec(super::idle(), Some(1), None);
                let watch = super::spawn_with(e, Spawn::monitor(me, "watch", spec), &[]);
                let never_starts = body(|_, _, _| panic!("never starts"));
                let x = cmd(
                    e,
                    me,
                    "x",
                    never_starts,
                    &[Constraint::terminate(When::Now)],
                );
                let x_handled = Event::on(x, Facet::Handling, Point::Completed);
                e.constrain(now, watch, Constraint::activate(When::Event(x_handled)))
                    .expect("watch has not completed");
            });
            goal(e, root, "body", tdl_body, &[]);
        },
        "
        0 body expansion enabled
        0 body execution enabled
        0 body handling enabled
        0 body handling active
        0 body expansion active
        0 x terminating
        0.5 body handling completed
        0.5 watch execution enabled
        0.5 watch handling enabled
        0.5 x execution enabled
        0.5 x handling enabled
        0.5 body expansion completed
        0.5 watch handling active
        0.5 watch execution active
        0.5 body execution active
        0.5 x handling completed
        0.5 watch handling completed
        0.5 ACT-watch execution enabled
        0.5 ACT-watch handling enabled
        0.5 x execution completed
        0.5 x terminated
        0.5 ACT-watch handling active
        0.5 ACT-watch execution active
        0.5 ACT-watch handling completed
        0.5 ACT-watch execution completed
        0.5 watch execution completed
        0.5 body execution completed
        ",
    );
    assert_eq!(warnings(r.trace()), Vec::<String>::new());
    let activations = r
        .story
        .iter()
        .filter(|l| l.ends_with("ACT-watch handling active"));
    assert_eq!(activations.count(), 1, "{:#?}", r.story);
    assert!(
        r.sim.engine.blocked().is_empty(),
        "{:?}",
        r.sim.engine.blocked()
    );
    assert_eq!(r.sim.engine.stats().live_nodes, 1, "only the root is left");
}

#[test]
fn terminating_a_completed_persistent_goal_terminates_and_reclaims_its_subtree() {
    let r = check(
        |e, root| {
            let keeper = persistent_goal(e, root, "keeper", 0.0, |e, me, now| {
                let mut child = Spawn::new(me, NodeKind::Goal, "kept", noop());
                child.persistent = true;
                e.spawn(now, child).expect("spawn");
            });
            let killer = body(move |e, _, now| {
                e.terminate(now, keeper)
                    .expect("terminate a completed persistent goal");
                Outcome::done()
            });
            cmd(e, root, "killer", killer, &[not_before(5.0)]);
        },
        "
        0 keeper expansion enabled
        0 keeper execution enabled
        0 keeper handling enabled
        0 keeper handling active
        0 keeper expansion active
        0 killer execution enabled
        0 kept expansion enabled
        0 kept execution enabled
        0 kept handling enabled
        0 kept handling active
        0 kept expansion active
        0 keeper handling completed
        0 kept handling completed
        0 kept expansion completed
        0 kept execution completed
        0 keeper expansion completed
        0 keeper execution completed
        5 killer handling enabled
        5 killer handling active
        5 killer execution active
        5 keeper terminating
        5 kept terminating
        5 kept terminated
        5 keeper terminated
        5 killer handling completed
        5 killer execution completed
        ",
    );
    assert_eq!(r.sim.engine.stats().live_nodes, 1, "only the root is left");
}

/// Goals whose executions completed wait, unreclaimed, for a persistent grandchild; once it is
/// terminated and reclaimed, its parent goes, and then that goal's parent: a reclaim is what
/// lets the next one up go.
#[test]
fn completed_goals_are_reclaimed_once_their_terminated_persistent_grandchild_is() {
    let r = check(
        |e, root| {
            let holder = goal(
                e,
                root,
                "holder",
                spawns(0.0, |e, me, now| {
                    let mid = Spawn::new(
                        me,
                        NodeKind::Goal,
                        "mid",
                        spawns(0.0, |e, me, now| {
                            let mut kept = Spawn::new(me, NodeKind::Command, "kept", noop());
                            kept.persistent = true;
                            e.spawn(now, kept).expect("spawn")
                        }),
                    );
                    e.spawn(now, mid).expect("spawn")
                }),
                &[],
            );
            let killer = body(move |e, _, now| {
                let mid = e.children(holder).first().copied().expect("mid is alive");
                let kept = e.children(mid).first().copied().expect("kept is alive");
                e.terminate(now, kept)
                    .expect("terminate a completed persistent command");
                Outcome::done()
            });
            cmd(e, root, "killer", killer, &[not_before(5.0)]);
        },
        "
        0 holder expansion enabled
        0 holder execution enabled
        0 holder handling enabled
        0 holder handling active
        0 holder expansion active
        0 killer execution enabled
        0 mid expansion enabled
        0 mid execution enabled
        0 mid handling enabled
        0 mid handling active
        0 mid expansion active
        0 kept execution enabled
        0 kept handling enabled
        0 kept handling active
        0 kept execution active
        0 mid execution active
        0 holder execution active
        0 holder handling completed
        0 mid handling completed
        0 mid expansion completed
        0 holder expansion completed
        0 kept handling completed
        0 kept execution completed
        0 mid execution completed
        0 holder execution completed
        5 killer handling enabled
        5 killer handling active
        5 killer execution active
        5 kept terminating
        5 kept terminated
        5 killer handling completed
        5 killer execution completed
        ",
    );
    let reclaimed: Vec<u64> = r
        .trace()
        .iter()
        .filter_map(|t| match t.kind {
            TraceKind::Reclaimed { node } => Some(node),
            _ => None,
        })
        .collect();
    // holder {1}, killer {2}, mid {3}, kept {4}: kept goes first, then mid, then holder.
    assert!(
        reclaimed.windows(3).any(|w| w == [4, 3, 1]),
        "kept, mid and holder reclaimed in turn: {reclaimed:?}"
    );
    assert_eq!(r.sim.engine.stats().live_nodes, 1, "only the root is left");
}

#[test]
fn a_child_spawned_under_a_completed_persistent_goal_runs_with_a_warning() {
    let r = check(
        |e, root| {
            let keeper = persistent_goal(e, root, "keeper", 0.0, |_, _, _| {});
            let late = body(move |e, _, now| {
                let child = Spawn::new(keeper, NodeKind::Command, "late-child", takes(s(1.0)));
                e.spawn(now, child)
                    .expect("spawn under a completed persistent goal");
                Outcome::done()
            });
            cmd(e, root, "adder", late, &[not_before(3.0)]);
        },
        "
        0 keeper expansion enabled
        0 keeper execution enabled
        0 keeper handling enabled
        0 keeper handling active
        0 keeper expansion active
        0 adder execution enabled
        0 keeper handling completed
        0 keeper expansion completed
        0 keeper execution completed
        3 adder handling enabled
        3 adder handling active
        3 adder execution active
        3 late-child execution enabled
        3 late-child handling enabled
        3 late-child handling active
        3 late-child execution active
        3 adder handling completed
        3 adder execution completed
        4 late-child handling completed
        4 late-child execution completed
        ",
    );
    let w = warnings(r.trace());
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(
        w[0].starts_with("Adding a child to completed persistent node keeper"),
        "{w:?}"
    );
}

#[test]
fn on_terminate_tasks_run_when_the_body_ended_but_the_subtree_still_runs() {
    // outer's body ended at 1 s; its child inner's body ended too; a grandchild still runs. At 3 s
    // outer is terminated: both outer's and inner's on-terminate tasks run, outer's first.
    let cleanup = |name: &'static str| OnTerminate {
        kind: NodeKind::Command,
        name: Name::Borrowed(name),
        action: takes(s(1.0)),
        fulfils: None,
    };
    check(
        |e, root| {
            let mut outer = Spawn::new(
                root,
                NodeKind::Goal,
                "outer",
                spawns(1.0, move |e, me, now| {
                    let mut inner = Spawn::new(
                        me,
                        NodeKind::Goal,
                        "inner",
                        spawns(0.5, |e, me, now| {
                            let leaf = Spawn::new(me, NodeKind::Command, "leaf", never());
                            e.spawn(now, leaf).expect("spawn");
                        }),
                    );
                    inner.on_terminate.push(cleanup("inner-cleanup"));
                    e.spawn(now, inner).expect("spawn");
                }),
            );
            outer.on_terminate.push(cleanup("outer-cleanup"));
            outer
                .constraints
                .push(Constraint::terminate(When::In(s(3.0))));
            e.spawn(Time::ZERO, outer).expect("spawn");
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
        0 leaf execution enabled
        0 leaf handling enabled
        0 leaf handling active
        0 leaf execution active
        0 inner execution active
        0 outer execution active
        0.5 inner handling completed
        0.5 inner expansion completed
        1 outer handling completed
        1 outer expansion completed
        3 outer terminating
        3 inner terminating
        3 leaf terminating
        3 leaf handling completed
        3 outer-cleanup execution enabled
        3 outer-cleanup handling enabled
        3 inner-cleanup execution enabled
        3 inner-cleanup handling enabled
        3 outer-cleanup handling active
        3 outer-cleanup execution active
        3 inner-cleanup handling active
        3 inner-cleanup execution active
        3 leaf execution completed
        3 leaf terminated
        4 outer-cleanup handling completed
        4 outer-cleanup execution completed
        4 inner-cleanup handling completed
        4 inner-cleanup execution completed
        4 inner execution completed
        4 inner terminated
        4 outer execution completed
        4 outer terminated
        ",
    );
}

#[test]
fn a_failing_handler_is_searched_above_its_attachment_and_the_skipped_handlers_are_named() {
    // `task` fails with Fault; its own handler `fix` takes it and fails with Fault again. The
    // search goes on above `task` (to `mission`'s handler `last`), not back to `fix`, which had
    // uses left: the trace names it as skipped.
    let r = run(|e, root| {
        let mut mission = Spawn::new(
            root,
            NodeKind::Goal,
            "mission",
            spawns(0.0, |e, me, now| {
                let mut task = Spawn::new(
                    me,
                    NodeKind::Command,
                    "task",
                    body(|_, _, _| Outcome::fail(s(1.0), "Fault")),
                );
                task.handlers.push(HandlerSpec {
                    name: Name::Borrowed("fix"),
                    exception: Name::Borrowed("Fault"),
                    max_activations: Some(3),
                    body: factory(|_, _, _, _| Outcome::fail(s(1.0), "Fault")),
                });
                e.spawn(now, task).expect("spawn");
            }),
        );
        mission.handlers.push(HandlerSpec {
            name: Name::Borrowed("last"),
            exception: Name::Borrowed("Fault"),
            max_activations: None,
            body: factory(|_, _, _, _| Outcome::done()),
        });
        e.spawn(Time::ZERO, mission).expect("spawn");
    });
    assert_eq!(
        tcm_trace::story::handler_choices(r.trace()),
        ["fix<-Fault", "last<-Fault"]
    );
    let w = warnings(r.trace());
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(w[0].contains("fix"), "{w:?}");
}

#[test]
fn activate_at_completed_fires_when_the_node_was_terminated() {
    // `watch` is activated when `a` completes and when `b` completes: `a` is terminated while it
    // runs, `b` before it started; terminated counts as completed for activations.
    let r = run(|e, root| {
        let a = cmd(e, root, "a", never(), &[super::stop_in(1.0)]);
        let b = cmd(
            e,
            root,
            "b",
            never(),
            &[not_before(5.0), super::stop_in(2.0)],
        );
        let mut spec = MonitorSpec::new(factory(|_, _, _, _| Outcome::done()));
        spec.max_activations = Some(2);
        let on = |n: NodeId| Constraint::activate(When::Event(Event::new(n, Point::Completed)));
        super::spawn_with(e, Spawn::monitor(root, "watch", spec), &[on(a), on(b)]);
    });
    let activations: Vec<&String> = r
        .story
        .iter()
        .filter(|l| l.contains("ACT-watch handling active"))
        .collect();
    assert_eq!(
        activations,
        ["1 ACT-watch handling active", "2 ACT-watch handling active"]
    );
}

#[test]
fn a_group_trigger_fires_when_every_member_reached_the_event_or_at_once_when_empty() {
    // `stop` is terminated when both `a` (1 s) and `b` (3 s) completed: at 3 s, not at 1 s.
    // `empty` waits on a group with no member: it is terminated at once. `spared` waits on a
    // group whose member `c` is terminated: it never fires.
    let r = run(|e, root| {
        let a = cmd(e, root, "a", takes(s(1.0)), &[]);
        let b = cmd(e, root, "b", takes(s(3.0)), &[]);
        let c = cmd(e, root, "c", never(), &[super::stop_in(2.0)]);
        let stop = cmd(e, root, "stop", never(), &[]);
        let empty = cmd(e, root, "empty", never(), &[]);
        let spared = cmd(e, root, "spared", takes(s(5.0)), &[]);
        let (x, done) = (Facet::Execution, Point::Completed);
        let now = e.now();
        e.trigger_group(now, stop, &[a, b], x, done, None, Then::Terminate)
            .expect("group trigger");
        e.trigger_group(now, empty, &[], x, done, None, Then::Terminate)
            .expect("empty group trigger");
        e.trigger_group(now, spared, &[a, c], x, done, None, Then::Terminate)
            .expect("group trigger");
    });
    let ends: Vec<&String> = r
        .story
        .iter()
        .filter(|l| l.ends_with("terminating") || l.ends_with("execution completed"))
        .collect();
    assert_eq!(
        ends,
        [
            "0 empty terminating",
            "0 empty execution completed",
            "1 a execution completed",
            "2 c terminating",
            "2 c execution completed",
            "3 b execution completed",
            "3 stop terminating",
            "3 stop execution completed",
            "5 spared execution completed",
        ]
    );
}

#[test]
fn a_group_enablement_is_refused_it_is_given_to_each_member() {
    let mut e = SimEngine::new(1);
    let root = e.root();
    let a = cmd(&mut e, root, "a", noop(), &[]);
    let late = cmd(&mut e, root, "late", noop(), &[]);
    let (x, done, h) = (Facet::Execution, Point::Completed, Facet::Handling);
    let res = e.trigger_group(Time::ZERO, late, &[a], x, done, None, Then::Enable(h));
    assert!(matches!(res, Err(EngineError::GroupEnable)), "{res:?}");
}

#[test]
fn a_delay_after_a_missing_previous_keeps_its_delay() {
    // The first spawn has no `previous`: `disable for 2 s after previous completed` is `disable
    // for 2 s`, and `terminate in 3 s after previous completed` is `terminate in 3 s`.
    let after_previous =
        |d: f64| When::After(s(d), Event::new(NodeRef::Previous, Point::Completed));
    check(
        |e, root| {
            let cs = [
                Constraint::disable(Facet::Handling, after_previous(2.0)),
                Constraint::terminate(after_previous(3.0)),
            ];
            cmd(e, root, "first", never(), &cs);
        },
        "
        0 first execution enabled
        2 first handling enabled
        2 first handling active
        2 first execution active
        3 first terminating
        3 first handling completed
        3 first execution completed
        3 first terminated
        ",
    );
}

#[test]
fn a_group_trigger_on_a_reservation_is_armed_at_its_spawn() {
    // `x terminate at g completed;` before `x` is spawned: kept on the reservation, armed when the
    // spawn fulfils it, then fired when both members completed (at 2 s).
    let r = run(|e, root| {
        let body = spawns(0.0, |e, me, now| {
            let a = cmd(e, me, "a", takes(s(1.0)), &[]);
            let b = cmd(e, me, "b", takes(s(2.0)), &[]);
            let x = e.reserve(now, me, "x").expect("reserve");
            let (ex, done) = (Facet::Execution, Point::Completed);
            e.trigger_group(now, x, &[a, b], ex, done, None, Then::Terminate)
                .expect("group trigger on a reservation");
            let mut spec = Spawn::new(me, NodeKind::Command, "x", never());
            spec.fulfils = Some(x);
            e.spawn(now, spec).expect("spawn");
        });
        goal(e, root, "g", body, &[]);
    });
    assert!(
        r.story.contains(&"2 x terminating".to_string()),
        "{:#?}",
        r.story
    );
}
