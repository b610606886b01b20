//! Exception stories: the paper's navigateToLocn handlers, a bypass chain, subclass matching,
//! re-raise, retry, and a wiretap that vetoes a move.

use super::{assert_checked, assert_order, cmd, goal, s, story};
use crate::sim::{Factory, Outcome, Sim, SimEngine, body, factory, noop, takes};
use crate::*;
use std::cell::Cell;
use std::rc::Rc;

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

fn goal_with_handlers(
    e: &mut SimEngine,
    parent: NodeId,
    name: &'static str,
    b: crate::sim::Body,
    hs: Vec<HandlerSpec<Factory>>,
) -> NodeId {
    let mut sp = Spawn::new(parent, NodeKind::Goal, name, b);
    sp.handlers = hs;
    let now = e.now();
    e.spawn(now, sp).expect("spawn")
}

fn handlers_of(trace: &[tcm_trace::TraceEvent]) -> Vec<String> {
    trace
        .iter()
        .filter_map(|e| match &e.kind {
            tcm_trace::TraceKind::HandlerChosen {
                handler, exception, ..
            } => Some(format!("{handler}<-{exception}")),
            tcm_trace::TraceKind::Bypassed { .. } => Some("bypass".into()),
            _ => None,
        })
        .collect()
}

#[test]
fn navigate_to_locn_sends_each_exception_to_its_handler() {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    let hs = vec![
        handler(
            "handleOverheating",
            "Overheating",
            None,
            factory(|e, me, _, _| {
                cmd(e, me, "coolDown", takes(s(3.0)), &[]);
                Outcome::done()
            }),
        ),
        handler(
            "handlePlannerFailure",
            "NoPath",
            None,
            factory(|_, _, _, _| Outcome::done()),
        ),
    ];
    goal_with_handlers(
        &mut sim.engine,
        root,
        "navigateToLocn",
        body(|e, me, _| {
            cmd(
                e,
                me,
                "move",
                body(|_, _, _| Outcome::fail(s(1.0), "Overheating")),
                &[],
            );
            cmd(
                e,
                me,
                "plan",
                body(|_, _, _| Outcome::fail(s(2.0), "NoPath")),
                &[],
            );
            cmd(
                e,
                me,
                "afterMove",
                noop(),
                &[Constraint::Sequential(
                    Facet::Execution,
                    NodeRef::Node(e.children(me)[0]),
                )],
            );
            Outcome::done()
        }),
        hs,
    );
    sim.run();
    assert_eq!(
        handlers_of(sim.trace()),
        [
            "handleOverheating<-Overheating",
            "handlePlannerFailure<-NoPath"
        ]
    );
    let st = story(sim.trace());
    // The failing move completes (failed) but its execution waits for the handler's cool-down:
    // the sibling sequential on it starts only then.
    assert_order(
        &st,
        &[
            "1 move failed Overheating",
            "1 move handling completed",
            "1 handleOverheating handling active",
            "4 coolDown handling completed",
            "4 move execution completed",
            "4 afterMove handling active",
        ],
    );
    assert_checked(sim.trace());
}

#[test]
fn a_bypass_chain_over_three_levels_respects_maximum_activations() {
    // top (handler A, max 1) > mid (handler B, bypasses) > leaf fails twice with Blocked.
    // First failure: B (at mid) bypasses -> A (at top). Second: B bypasses -> A is used up -> none.
    let mut sim = Sim::new();
    let root = sim.engine.root();
    let a = handler(
        "A",
        "Blocked",
        Some(1),
        factory(|_, _, _, _| Outcome::done()),
    );
    goal_with_handlers(
        &mut sim.engine,
        root,
        "top",
        body(|e, top, _| {
            let b = handler(
                "B",
                "Blocked",
                None,
                factory(|_, _, _, _| Outcome::Bypass(s(0.5))),
            );
            goal_with_handlers(
                e,
                top,
                "mid",
                body(|e, mid, _| {
                    cmd(
                        e,
                        mid,
                        "leaf1",
                        body(|_, _, _| Outcome::fail(s(1.0), "Blocked")),
                        &[],
                    );
                    cmd(
                        e,
                        mid,
                        "leaf2",
                        body(|_, _, _| Outcome::fail(s(3.0), "Blocked")),
                        &[],
                    );
                    Outcome::done()
                }),
                vec![b],
            );
            Outcome::done()
        }),
        vec![a],
    );
    sim.run();
    assert_eq!(
        handlers_of(sim.trace()),
        ["B<-Blocked", "bypass", "A<-Blocked", "B<-Blocked", "bypass"]
    );
    assert!(sim.trace().iter().any(|e| matches!(&e.kind, tcm_trace::TraceKind::Warning { message, .. } if message.contains("No exception handler found"))));
    assert_checked(sim.trace());
}

#[test]
fn a_handler_for_an_ancestor_type_catches_the_subclass() {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    goal_with_handlers(
        &mut sim.engine,
        root,
        "fly",
        body(|e, me, _| {
            cmd(
                e,
                me,
                "engine",
                body(|_, _, _| {
                    let f = Failure::new("EngineOnFire", "smoke")
                        .with_ancestry(vec!["EngineFailure".into(), "HardwareFailure".into()]);
                    Outcome::After(s(1.0), Err(f))
                }),
                &[],
            );
            Outcome::done()
        }),
        vec![
            handler(
                "softwareFix",
                "SoftwareFailure",
                None,
                factory(|_, _, _, _| Outcome::done()),
            ),
            handler(
                "hardwareFix",
                "HardwareFailure",
                None,
                factory(|_, _, _, p| {
                    assert!(
                        matches!(p, Purpose::Handler { failure, .. } if failure.exception == "EngineOnFire")
                    );
                    Outcome::done()
                }),
            ),
        ],
    );
    sim.run();
    assert_eq!(handlers_of(sim.trace()), ["hardwareFix<-EngineOnFire"]);
}

#[test]
fn a_handler_that_re_raises_goes_to_the_enclosing_handler() {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    goal_with_handlers(
        &mut sim.engine,
        root,
        "outer",
        body(|e, outer, _| {
            goal_with_handlers(
                e,
                outer,
                "inner",
                body(|e, me, _| {
                    cmd(
                        e,
                        me,
                        "grasp",
                        body(|_, _, _| Outcome::fail(s(1.0), "Slipped")),
                        &[],
                    );
                    Outcome::done()
                }),
                vec![handler(
                    "regrasp",
                    "Slipped",
                    None,
                    factory(|_, _, _, _| Outcome::fail(s(1.0), "GiveUp")),
                )],
            );
            Outcome::done()
        }),
        vec![
            handler(
                "reportFailure",
                "GiveUp",
                None,
                factory(|_, _, _, _| Outcome::done()),
            ),
            handler(
                "loop",
                "Slipped",
                None,
                factory(|_, _, _, _| Outcome::done()),
            ),
        ],
    );
    sim.run();
    // `regrasp`'s own failure searches above `inner`, where it was attached: `reportFailure` takes
    // `GiveUp` (and `loop` at `outer` is never asked about `Slipped` again).
    assert_eq!(
        handlers_of(sim.trace()),
        ["regrasp<-Slipped", "reportFailure<-GiveUp"]
    );
    assert_checked(sim.trace());
}

#[test]
fn retry_succeeds_on_the_second_attempt() {
    let mut sim = Sim::new();
    let root = sim.engine.root();
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
    let first = try_move.clone();
    goal_with_handlers(
        &mut sim.engine,
        root,
        "deliver",
        body(move |e, me, now| {
            let mut sp = Spawn::new(
                me,
                NodeKind::Command,
                "move",
                body(move |e, n, t| first.call(e, n, t, &Purpose::Retry { of: n })),
            );
            sp.retry = Some(try_move.clone());
            e.spawn(now, sp).expect("spawn");
            cmd(e, me, "speak", noop(), &[Constraint::sequential_previous()]);
            Outcome::done()
        }),
        vec![handler(
            "retryMove",
            "Blocked",
            Some(3),
            factory(|e, me, now, _| {
                e.retry(now, me).expect("retry");
                Outcome::done()
            }),
        )],
    );
    sim.run();
    assert_eq!(attempts.get(), 2);
    let st = story(sim.trace());
    assert_order(
        &st,
        &[
            "1 move failed Blocked",
            "1 retryMove handling active",
            "1 move handling active",
            "2 move handling completed",
            "2 speak handling active",
        ],
    );
    assert!(
        sim.trace()
            .iter()
            .any(|e| matches!(e.kind, tcm_trace::TraceKind::Retried { .. }))
    );
    assert_checked(sim.trace());
}

#[test]
fn a_wiretap_vetoes_one_of_five_moves() {
    // A stability check before every move, without touching `move`: the third is vetoed.
    let mut sim = Sim::new();
    let n = Rc::new(Cell::new(0));
    let n2 = n.clone();
    sim.engine.wiretap(
        "move",
        TapWhen::Before,
        factory(move |_, _, _, _| {
            n2.set(n2.get() + 1);
            if n2.get() == 3 {
                Outcome::fail(s(0.1), "Unstable")
            } else {
                Outcome::after(s(0.1))
            }
        }),
    );
    let root = sim.engine.root();
    goal(
        &mut sim.engine,
        root,
        "walk",
        body(|e, me, _| {
            for _ in 0..5 {
                cmd(
                    e,
                    me,
                    "move",
                    takes(s(1.0)),
                    &[Constraint::sequential_previous()],
                );
            }
            Outcome::done()
        }),
        &[],
    );
    sim.run();
    assert_eq!(n.get(), 5);
    let st = story(sim.trace());
    let runs: Vec<&String> = st
        .iter()
        .filter(|l| l.ends_with("move handling active"))
        .collect();
    assert_eq!(
        runs.len(),
        4,
        "four moves ran, one was vetoed:\n{}",
        st.join("\n")
    );
    assert!(st.iter().any(|l| l.ends_with("move failed Unstable")));
    assert_checked(sim.trace());
}
