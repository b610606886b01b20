//! Resource stories (docs/semantics.md, "Resources"): capacity, priority then request order, all
//! or nothing without overtaking, reservation, lock, the pending limit, denial, release on every
//! way a node ends, and a wait cycle over resources named in the stuck report.

use super::{check, goal, never, not_before, run, s, spawn_with, stop_in};
use crate::sim::{Body, Factory, Outcome, SimEngine, body, factory, takes};
use crate::*;
use tcm_trace::story::{handler_choices, only};

/// Spawns command `name` under `up`, using `uses` (amounts of resources), at `priority`.
fn user(
    e: &mut SimEngine,
    up: NodeId,
    name: &'static str,
    b: Body,
    uses: &[(ResourceId, u32)],
    priority: i32,
) -> NodeId {
    let mut sp = Spawn::new(up, NodeKind::Command, name, b);
    sp.uses = Some(Box::new(Uses {
        amounts: uses.to_vec(),
        priority,
        deny_if_busy: false,
    }));
    spawn_with(e, sp, &[])
}

/// A handler of `exception` that does nothing.
fn handler(name: &'static str, exception: &'static str) -> HandlerSpec<Factory> {
    HandlerSpec {
        name: name.into(),
        exception: exception.into(),
        max_activations: None,
        body: factory(|_, _, _, _| Outcome::done()),
    }
}

/// The lines of a story about resources and failures.
fn resource_lines(story: &[String]) -> Vec<String> {
    only(
        story,
        &[
            "requests",
            "granted",
            "released",
            "withdrawn",
            "denied",
            "dropped",
            "reserved",
            "locked",
            "failed",
            "terminat",
        ],
    )
}

#[test]
fn a_third_user_waits_until_one_of_two_ends() {
    check(
        |e, root| {
            let arm = e.declare_resource("arm", 2, None).expect("declare");
            user(e, root, "a", takes(s(3.0)), &[(arm, 1)], 0);
            user(e, root, "b", takes(s(5.0)), &[(arm, 1)], 0);
            user(e, root, "c", takes(s(1.0)), &[(arm, 1)], 0);
        },
        "
        0 a execution enabled
        0 a handling enabled
        0 a requests arm
        0 a granted arm
        0 a handling active
        0 a execution active
        0 b execution enabled
        0 b handling enabled
        0 b requests arm
        0 b granted arm
        0 b handling active
        0 b execution active
        0 c execution enabled
        0 c handling enabled
        0 c requests arm
        3 a released arm
        3 a handling completed
        3 a execution completed
        3 c granted arm
        3 c handling active
        3 c execution active
        4 c released arm
        4 c handling completed
        4 c execution completed
        5 b released arm
        5 b handling completed
        5 b execution completed
        ",
    );
}

#[test]
fn lower_priority_first_then_request_order() {
    let r = run(|e, root| {
        let base = e.declare_resource("base", 1, None).expect("declare");
        user(e, root, "holder", takes(s(2.0)), &[(base, 1)], 0);
        user(e, root, "x", takes(s(1.0)), &[(base, 1)], 5);
        user(e, root, "y", takes(s(1.0)), &[(base, 1)], 1);
        user(e, root, "z", takes(s(1.0)), &[(base, 1)], 1);
    });
    let granted = only(&r.story, &["granted"]);
    assert_eq!(
        granted,
        [
            "0 holder granted base",
            "2 y granted base",
            "3 z granted base",
            "4 x granted base"
        ]
    );
}

#[test]
fn all_or_nothing_and_no_overtaking() {
    // `x` needs the base and the arm while `arm_user` holds the arm: it waits without holding
    // the base, which `urgent` (a better priority) uses meanwhile. `late` needs only the base but
    // asked after `x`: it does not overtake `x`, which would starve it.
    let r = run(|e, root| {
        let base = e.declare_resource("base", 1, None).expect("declare");
        let arm = e.declare_resource("arm", 1, None).expect("declare");
        user(e, root, "arm_user", takes(s(5.0)), &[(arm, 1)], 0);
        user(e, root, "x", takes(s(1.0)), &[(base, 1), (arm, 1)], 0);
        user(e, root, "late", takes(s(1.0)), &[(base, 1)], 0);
        user(e, root, "urgent", takes(s(2.0)), &[(base, 1)], -1);
    });
    assert_eq!(
        resource_lines(&r.story),
        [
            "0 arm_user requests arm",
            "0 arm_user granted arm",
            "0 x requests base, arm",
            "0 late requests base",
            "0 urgent requests base",
            "0 urgent granted base",
            "2 urgent released base",
            "5 arm_user released arm",
            "5 x granted base, arm",
            "6 x released base, arm",
            "6 late granted base",
            "7 late released base",
        ]
    );
}

#[test]
fn a_reserved_resource_goes_only_to_the_holders_subtree_until_its_execution_completes() {
    let r = run(|e, root| {
        let base = e.declare_resource("base", 1, None).expect("declare");
        let plan = body(move |e, me, _| {
            user(e, me, "own_move", takes(s(1.0)), &[(base, 1)], 0);
            Outcome::after(s(2.0))
        });
        let plan = goal(e, root, "plan", plan, &[]);
        e.reserve_resource(Time::ZERO, base, plan).expect("reserve");
        user(e, root, "stranger", takes(s(1.0)), &[(base, 1)], 0);
    });
    assert_eq!(
        resource_lines(&r.story),
        [
            "0 base reserved for plan",
            "0 stranger requests base",
            "0 own_move requests base",
            "0 own_move granted base",
            "1 own_move released base",
            "2 base unreserved",
            "2 stranger granted base",
            "3 stranger released base",
        ]
    );
}

#[test]
fn a_locked_resource_is_granted_to_nobody_until_unlocked() {
    let r = run(|e, root| {
        let camera = e.declare_resource("camera", 1, None).expect("declare");
        e.lock_resource(Time::ZERO, camera).expect("lock");
        let unlock = body(move |e, _, now| {
            e.unlock_resource(now, camera).expect("unlock");
            Outcome::done()
        });
        super::cmd(e, root, "calibrated", unlock, &[not_before(3.0)]);
        user(e, root, "snap", takes(s(1.0)), &[(camera, 1)], 0);
    });
    assert_eq!(
        resource_lines(&r.story),
        [
            "0 camera locked",
            "0 snap requests camera",
            "3 camera unlocked",
            "3 snap granted camera",
            "4 snap released camera",
        ]
    );
}

#[test]
fn past_the_pending_limit_the_oldest_request_is_dropped_and_its_failure_handled() {
    let r = run(|e, root| {
        let arm = e.declare_resource("arm", 1, Some(1)).expect("declare");
        user(e, root, "holder", takes(s(5.0)), &[(arm, 1)], 0);
        let mut first = Spawn::new(root, NodeKind::Command, "first", takes(s(1.0)));
        first.uses = Some(Box::new(Uses::default().and(arm, 1)));
        first.handlers = vec![handler("recover_first", "ResourceDropped")];
        spawn_with(e, first, &[]);
        user(e, root, "second", takes(s(1.0)), &[(arm, 1)], 0);
    });
    assert_eq!(
        resource_lines(&r.story),
        [
            "0 holder requests arm",
            "0 holder granted arm",
            "0 first requests arm",
            "0 second requests arm",
            "0 first dropped arm",
            "0 first failed ResourceDropped",
            "5 holder released arm",
            "5 second granted arm",
            "6 second released arm",
        ]
    );
    assert_eq!(
        handler_choices(r.trace()),
        ["recover_first<-ResourceDropped"]
    );
    assert!(r.sim.engine.unhandled().is_empty());
}

#[test]
fn a_request_that_may_not_wait_is_denied_and_its_failure_handled() {
    let r = run(|e, root| {
        let camera = e.declare_resource("camera", 1, None).expect("declare");
        user(e, root, "video", takes(s(5.0)), &[(camera, 1)], 0);
        let mut snap = Spawn::new(root, NodeKind::Command, "snap", takes(s(1.0)));
        snap.uses = Some(Box::new(Uses {
            deny_if_busy: true,
            ..Uses::default().and(camera, 1)
        }));
        snap.handlers = vec![handler("recover_snap", "ResourceDenied")];
        spawn_with(e, snap, &[]);
    });
    assert_eq!(
        resource_lines(&r.story),
        [
            "0 video requests camera",
            "0 video granted camera",
            "0 snap requests camera",
            "0 snap denied camera",
            "0 snap failed ResourceDenied",
            "5 video released camera",
        ]
    );
    assert_eq!(handler_choices(r.trace()), ["recover_snap<-ResourceDenied"]);
    let failed = r.trace().iter().find_map(|ev| match &ev.kind {
        tcm_trace::TraceKind::Failed { message, .. } => Some(message.clone()),
        _ => None,
    });
    assert_eq!(
        failed.as_deref(),
        Some("resource `camera` denied: 1 of 1 of `camera` are held by video {1}")
    );
}

#[test]
fn asking_for_more_than_the_capacity_is_denied_even_when_it_may_wait() {
    let r = run(|e, root| {
        let arm = e.declare_resource("arm", 2, None).expect("declare");
        user(e, root, "lift", takes(s(1.0)), &[(arm, 3)], 0);
    });
    assert_eq!(
        resource_lines(&r.story),
        [
            "0 lift requests arm(3)",
            "0 lift denied arm",
            "0 lift failed ResourceDenied",
        ]
    );
    let unhandled = r.sim.engine.unhandled();
    assert_eq!(unhandled.len(), 1);
    assert_eq!(
        unhandled[0].failure.message,
        "resource `arm` denied: it asks for 3 of `arm`, whose capacity is 2"
    );
    let data = unhandled[0]
        .failure
        .data::<ResourceDenied>()
        .expect("typed");
    assert_eq!(data.resource, "arm");
}

#[test]
fn released_on_success_failure_termination_while_active_and_while_waiting() {
    let r = run(|e, root| {
        let base = e.declare_resource("base", 1, None).expect("declare");
        let fails = body(|_, _, _| Outcome::fail(s(1.0), "Stalled"));
        user(e, root, "fails", fails, &[(base, 1)], 0);
        user(e, root, "succeeds", takes(s(1.0)), &[(base, 1)], 0);
        let stopped = user(e, root, "stopped", never(), &[(base, 1)], 0);
        e.constrain(e.now(), stopped, stop_in(3.0))
            .expect("terminate in");
        let cancelled = user(e, root, "cancelled", never(), &[(base, 1)], 0);
        e.constrain(e.now(), cancelled, stop_in(2.5))
            .expect("terminate in");
        user(e, root, "last", takes(s(1.0)), &[(base, 1)], 0);
    });
    assert_eq!(
        resource_lines(&r.story),
        [
            "0 fails requests base",
            "0 fails granted base",
            "0 succeeds requests base",
            "0 stopped requests base",
            "0 cancelled requests base",
            "0 last requests base",
            "1 fails failed Stalled",
            "1 fails released base",
            "1 succeeds granted base",
            "2 succeeds released base",
            "2 stopped granted base",
            "2.5 cancelled terminating",
            "2.5 cancelled withdrawn",
            "2.5 cancelled terminated",
            "3 stopped terminating",
            "3 stopped released base",
            "3 stopped terminated",
            "3 last granted base",
            "4 last released base",
        ]
    );
    let base = r.sim.engine.resource_id("base").expect("declared");
    let info = r.sim.engine.resource_info(base).expect("info");
    assert_eq!(
        (info.in_use, info.holders.len(), info.waiting.len()),
        (0, 0, 0)
    );
}

#[test]
fn a_suspended_request_waits_and_lets_others_go_first() {
    let r = run(|e, root| {
        let base = e.declare_resource("base", 1, None).expect("declare");
        user(e, root, "holder", takes(s(1.0)), &[(base, 1)], 0);
        let first = user(e, root, "first", takes(s(1.0)), &[(base, 1)], 0);
        user(e, root, "second", takes(s(1.0)), &[(base, 1)], 0);
        e.suspend(e.now(), first).expect("suspend");
        let resume = body(move |e, _, now| {
            e.unsuspend(now, first).expect("unsuspend");
            Outcome::done()
        });
        super::cmd(e, root, "resume", resume, &[not_before(5.0)]);
    });
    assert_eq!(
        only(&r.story, &["granted"]),
        [
            "0 holder granted base",
            "1 second granted base",
            "5 first granted base"
        ]
    );
}

#[test]
fn a_retry_asks_again_for_the_resources_of_the_run_it_repeats() {
    let r = run(|e, root| {
        let arm = e.declare_resource("arm", 1, None).expect("declare");
        let mut grasp = Spawn::new(
            root,
            NodeKind::Command,
            "grasp",
            body(|_, _, _| Outcome::fail(s(1.0), "Slipped")),
        );
        grasp.uses = Some(Box::new(Uses::default().and(arm, 1)));
        grasp.retry = Some(factory(|_, _, _, _| Outcome::after(s(1.0))));
        grasp.handlers = vec![HandlerSpec {
            name: "again".into(),
            exception: "Slipped".into(),
            max_activations: Some(1),
            body: factory(|e, me, now, _| {
                e.retry(now, me).expect("retry");
                Outcome::done()
            }),
        }];
        spawn_with(e, grasp, &[]);
    });
    assert_eq!(
        resource_lines(&r.story),
        [
            "0 grasp requests arm",
            "0 grasp granted arm",
            "1 grasp failed Slipped",
            "1 grasp released arm",
            "1 grasp requests arm",
            "1 grasp granted arm",
            "2 grasp released arm",
        ]
    );
}

#[test]
fn spawn_errors_name_the_resource() {
    let mut e: SimEngine = Engine::new(1);
    let root = e.root();
    let arm = e.declare_resource("arm", 2, None).expect("declare");
    assert_eq!(
        e.declare_resource("arm", 1, None),
        Err(EngineError::DuplicateResource("arm".into()))
    );
    assert_eq!(
        e.declare_resource("cpu", 0, None),
        Err(EngineError::ZeroCapacity("cpu".into()))
    );
    let zero = Spawn::new(root, NodeKind::Command, "z", takes(s(1.0))).using(arm, 0);
    assert_eq!(
        e.spawn(Time::ZERO, zero).err(),
        Some(EngineError::ZeroAmount("arm".into()))
    );
    let mut other: SimEngine = Engine::new(2);
    let foreign = other.declare_resource("arm", 2, None).expect("declare");
    let bad = Spawn::new(root, NodeKind::Command, "f", takes(s(1.0))).using(foreign, 1);
    assert!(matches!(
        e.spawn(Time::ZERO, bad),
        Err(EngineError::ForeignResource { .. })
    ));
    assert_eq!(e.resource_id("arm"), Some(arm));
    assert_eq!(e.resource_id("gripper"), None);
}

/// A goal holding `base` whose child needs `base`, and whose action awaits that child: the child
/// waits for the parent, the parent for the child.
#[test]
fn a_wait_cycle_over_a_resource_is_reported_with_the_cycle_named() {
    let r = run(|e, root| {
        let base = e.declare_resource("base", 1, None).expect("declare");
        let plan = body(move |e, me, _| {
            user(e, me, "drive", takes(s(1.0)), &[(base, 1)], 0);
            Outcome::Never
        });
        let mut sp = Spawn::new(root, NodeKind::Goal, "plan", plan);
        sp.uses = Some(Box::new(Uses::default().and(base, 1)));
        spawn_with(e, sp, &[]);
    });
    let e = &r.sim.engine;
    let plan = e.children(e.root())[0];
    let drive = e.children(plan)[0];
    let awaited = Event::on(drive, Facet::Execution, Point::Completed);
    let report: Vec<String> = e
        .blocked_awaiting(&[(plan, awaited)])
        .iter()
        .map(ToString::to_string)
        .collect();
    assert_eq!(
        report,
        [
            "plan {1} handling is active and waits for its action, which awaits drive {2} \
             execution completed",
            "drive {2} handling is enabled and waits for resource `base`, held by plan {1} \
             (1 of 1), in the wait cycle: drive {2} needs `base`, held by plan {1}; plan {1}'s \
             action awaits drive {2}",
        ]
    );
}

/// Two goals each holding one resource, whose children each need the other's: the cycle goes
/// through all four.
#[test]
fn a_wait_cycle_through_two_holders_is_named() {
    let r = run(|e, root| {
        let base = e.declare_resource("base", 1, None).expect("declare");
        let arm = e.declare_resource("arm", 1, None).expect("declare");
        for (name, child, own, other) in [
            ("navigate", "reach", base, arm),
            ("manipulate", "roll", arm, base),
        ] {
            let b = body(move |e, me, _| {
                user(e, me, child, takes(s(1.0)), &[(other, 1)], 0);
                Outcome::Never
            });
            let mut sp = Spawn::new(root, NodeKind::Goal, name, b);
            sp.uses = Some(Box::new(Uses::default().and(own, 1)));
            spawn_with(e, sp, &[]);
        }
    });
    let e = &r.sim.engine;
    let goals = e.children(e.root());
    let awaits: Vec<(NodeId, Event)> = goals
        .iter()
        .map(|g| {
            let child = e.children(*g)[0];
            (*g, Event::on(child, Facet::Execution, Point::Completed))
        })
        .collect();
    let report = e.blocked_awaiting(&awaits);
    let cycles: Vec<&String> = report
        .iter()
        .flat_map(|b| &b.waits_for)
        .filter(|w| w.starts_with("in the wait cycle"))
        .collect();
    assert_eq!(
        cycles,
        [
            "in the wait cycle: reach {3} needs `arm`, held by manipulate {2}; manipulate {2}'s \
             action awaits roll {4}; roll {4} needs `base`, held by navigate {1}; navigate {1}'s \
             action awaits reach {3}"
        ]
    );
}

/// A wait that is no cycle (the holder runs and will end) is reported with its holder and no
/// cycle.
#[test]
fn a_plain_wait_names_the_holder_and_no_cycle() {
    let mut sim = crate::sim::Sim::new();
    let root = sim.engine.root();
    let base = sim
        .engine
        .declare_resource("base", 1, None)
        .expect("declare");
    user(&mut sim.engine, root, "long", never(), &[(base, 1)], 0);
    user(
        &mut sim.engine,
        root,
        "next",
        takes(s(1.0)),
        &[(base, 1)],
        0,
    );
    sim.run_until(Time::ZERO + s(1.0));
    let report: Vec<String> = sim
        .engine
        .blocked()
        .iter()
        .map(ToString::to_string)
        .collect();
    assert_eq!(
        report,
        ["next {2} handling is enabled and waits for resource `base`, held by long {1} (1 of 1)"]
    );
}
