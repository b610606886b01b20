//! Property test: random trees with random constraints run on virtual time and always pass the
//! trace checker, and the same program always gives the same trace.
//!
//! Timed and event-driven constraints are generated as the engine sees them, one trigger: a "when"
//! ([`when`]) combined with a "then" ([`then`]), so every combination comes up; with monitors,
//! exception handlers, failures, external events that the program raises itself, and resources
//! (random uses, priorities and refusals to wait, over capacities and a pending limit).

use proptest::prelude::*;
use std::rc::Rc;
use std::time::Duration;
use tcm_core::sim::{Body, Factory, Outcome, Sim, SimEngine, body, factory};
use tcm_core::{
    Constraint, EngineError, Event, ExternalId, Facet, Failure, HandlerSpec, MonitorSpec, NodeId,
    NodeKind, NodeRef, Overrun, Point, Purpose, Spawn, Termination, Then, Time, Uses, When,
};

#[derive(Clone, Debug)]
enum C {
    Sequential(Facet, Target),
    Serial(Target),
    /// Every timed or event-driven constraint: when something happens, do something.
    Trigger(W, T),
    ExpandFirst,
    DelayExpansion,
}

impl C {
    /// The sibling the constraint names, if it names one.
    fn target(&self) -> Option<Target> {
        match self {
            C::Sequential(_, t) | C::Serial(t) => Some(*t),
            C::Trigger(w, _) => w.target(),
            C::ExpandFirst | C::DelayExpansion => None,
        }
    }
}

/// When a trigger fires ([`When`]); times in whole seconds.
#[derive(Clone, Copy, Debug)]
enum W {
    Now,
    At(u8),
    In(u8),
    Event(Target, Facet, Point),
    After(u8, Target, Facet, Point),
    /// External event `x<k>`, raised by the nodes whose plan says so.
    External(u8),
}

impl W {
    fn target(&self) -> Option<Target> {
        match self {
            W::Event(t, ..) | W::After(_, t, ..) => Some(*t),
            _ => None,
        }
    }
}

/// What a trigger does then ([`Then`]).
#[derive(Clone, Copy, Debug)]
enum T {
    Enable(Facet),
    Terminate,
    Activate,
}

/// Which node a constraint names, relative to the node being spawned (its index `i` among siblings).
#[derive(Clone, Copy, Debug)]
enum Target {
    Previous,
    /// Sibling `i - k` (void if there is none).
    Back(u8),
    /// Sibling `i + k`, spawned later: a forward reference (dead if there is none).
    Ahead(u8),
    Parent,
}

#[derive(Clone, Debug)]
struct Plan {
    goal: bool,
    secs: u8,
    fail: bool,
    // Which exception a failure raises: 0 = `A`, 1 = `B` (a kind of `A`).
    exc: u8,
    never: bool,
    /// Raises external event `x<k>` once its action has spawned its children.
    raise: Option<u8>,
    constraints: Vec<C>,
    children: Vec<Plan>,
    monitor: Option<Mon>,
    handlers: Vec<H>,
    /// Resources it uses: (resource `r<k>`, a draw for the amount: 0 asks for more than any
    /// capacity, 1 to 3 for two units of `r1`, else one unit), at a priority, maybe refusing to
    /// wait.
    uses: Vec<(u8, u8)>,
    priority: i8,
    deny: bool,
}

/// A monitor instead of a plain node.
#[derive(Clone, Debug)]
struct Mon {
    period_ms: u16,
    max_activations: u8,
    max_triggers: Option<u8>,
    initial_wait: bool,
    serial: bool,
    child_secs: u8,
    /// The overrun policy: 0 burst, 1 skip, 2 delay (an activation lasts as long as its probe,
    /// up to 2 s, so polls overrun).
    overrun: u8,
}

/// A handler attached to a goal: `what` 0 = recover, 1 = bypass, 2 = fail with `C`.
#[derive(Clone, Debug)]
struct H {
    exc: u8,
    max: Option<u8>,
    what: u8,
}

fn mon() -> impl Strategy<Value = Option<Mon>> {
    prop::option::weighted(
        0.15,
        (
            300u16..2000,
            1u8..5,
            prop::option::of(1u8..3),
            any::<bool>(),
            any::<bool>(),
            0u8..3,
            0u8..3,
        )
            .prop_map(
                |(
                    period_ms,
                    max_activations,
                    max_triggers,
                    initial_wait,
                    serial,
                    child_secs,
                    overrun,
                )| {
                    Mon {
                        period_ms,
                        max_activations,
                        max_triggers,
                        initial_wait,
                        serial,
                        child_secs,
                        overrun,
                    }
                },
            ),
    )
}

fn handlers() -> impl Strategy<Value = Vec<H>> {
    prop::collection::vec(
        (0u8..3, prop::option::of(1u8..3), 0u8..3).prop_map(|(exc, max, what)| H {
            exc,
            max,
            what,
        }),
        0..3,
    )
}

fn facet() -> impl Strategy<Value = Facet> {
    prop_oneof![
        Just(Facet::Handling),
        Just(Facet::Expansion),
        Just(Facet::Execution)
    ]
}

fn point() -> impl Strategy<Value = Point> {
    prop_oneof![
        Just(Point::Enabled),
        Just(Point::Active),
        Just(Point::Completed)
    ]
}

fn target() -> impl Strategy<Value = Target> {
    prop_oneof![
        3 => Just(Target::Previous),
        2 => (1u8..3).prop_map(Target::Back),
        2 => (1u8..3).prop_map(Target::Ahead),
        1 => Just(Target::Parent),
    ]
}

/// One generator for "when", whatever the trigger does.
fn when() -> impl Strategy<Value = W> {
    prop_oneof![
        1 => Just(W::Now),
        2 => (0u8..12).prop_map(W::At),
        3 => (0u8..10).prop_map(W::In),
        4 => (target(), facet(), point()).prop_map(|(t, f, p)| W::Event(t, f, p)),
        2 => (0u8..4, target(), facet(), point()).prop_map(|(s, t, f, p)| W::After(s, t, f, p)),
        1 => (0u8..2).prop_map(W::External),
    ]
}

/// One generator for "then", whatever triggers it (`activate` on a node that is not a monitor is
/// void, which the trace shows and the checker reads).
fn then() -> impl Strategy<Value = T> {
    prop_oneof![
        4 => facet().prop_map(T::Enable),
        3 => Just(T::Terminate),
        2 => Just(T::Activate),
    ]
}

fn constraint() -> impl Strategy<Value = C> {
    prop_oneof![
        4 => (facet(), target()).prop_map(|(f, t)| C::Sequential(f, t)),
        2 => target().prop_map(C::Serial),
        8 => (when(), then()).prop_map(|(w, t)| C::Trigger(w, t)),
        1 => Just(C::ExpandFirst),
        1 => Just(C::DelayExpansion),
    ]
}

fn leaf() -> impl Strategy<Value = Plan> {
    (
        (any::<bool>(), 0u8..4, prop::bool::weighted(0.15), 0u8..2),
        (
            prop::bool::weighted(0.05),
            prop::option::weighted(0.1, 0u8..2),
        ),
        prop::collection::vec(constraint(), 0..3),
        mon(),
        handlers(),
        (
            prop::collection::vec((0u8..3, 0u8..10), 0..3),
            -1i8..2,
            prop::bool::weighted(0.1),
        ),
    )
        .prop_map(
            |(
                (goal, secs, fail, exc),
                (never, raise),
                constraints,
                monitor,
                handlers,
                (uses, priority, deny),
            )| Plan {
                goal,
                secs,
                fail,
                exc,
                never,
                raise,
                constraints,
                children: vec![],
                monitor,
                handlers,
                uses,
                priority,
                deny,
            },
        )
}

fn plan() -> impl Strategy<Value = Plan> {
    leaf().prop_recursive(3, 40, 5, |inner| {
        (leaf(), prop::collection::vec(inner, 1..5)).prop_map(|(mut p, children)| {
            p.goal = true;
            p.children = children;
            p
        })
    })
}

fn lower(
    c: &C,
    resolve: &dyn Fn(Target) -> Option<NodeRef>,
    externals: &[ExternalId; 2],
) -> Option<Constraint> {
    let s = |n: u8| Duration::from_secs(u64::from(n));
    Some(match c {
        C::Sequential(f, t) => Constraint::Sequential(*f, resolve(*t)?),
        C::Serial(t) => Constraint::Serial(resolve(*t)?),
        C::Trigger(w, t) => {
            let when = match *w {
                W::Now => When::Now,
                W::At(n) => When::At(Time::ZERO + s(n)),
                W::In(n) => When::In(s(n)),
                W::Event(t, f, p) => When::Event(Event::on(resolve(t)?, f, p)),
                W::After(n, t, f, p) => When::After(s(n), Event::on(resolve(t)?, f, p)),
                W::External(k) => When::External(externals[usize::from(k)]),
            };
            let then = match *t {
                T::Enable(f) => Then::Enable(f),
                T::Terminate => Then::Terminate,
                T::Activate => Then::Activate,
            };
            Constraint::Trigger(when, then)
        }
        C::ExpandFirst => Constraint::ExpandFirst,
        C::DelayExpansion => Constraint::DelayExpansion,
    })
}

fn action(plan: Rc<Plan>) -> Body {
    body(move |e: &mut SimEngine, me: NodeId, now: Time| {
        let externals = [e.external("x0"), e.external("x1")];
        let n = plan.children.len();
        // Reserve every child named by an earlier sibling's forward reference, plus one extra
        // reservation per forward reference past the end (a dead reference).
        let mut ids: Vec<Option<NodeId>> = vec![None; n];
        let mut dead: Option<NodeId> = None;
        for (i, child) in plan.children.iter().enumerate() {
            for c in &child.constraints {
                if let Some(Target::Ahead(k)) = c.target() {
                    let j = i + usize::from(k);
                    if j < n {
                        if ids[j].is_none() {
                            ids[j] = Some(e.reserve(now, me, "reserved").expect("reserve"));
                        }
                    } else if dead.is_none() {
                        dead = Some(e.reserve(now, me, "never").expect("reserve"));
                    }
                }
            }
        }
        for (i, child) in plan.children.iter().enumerate() {
            let resolve = |t: Target| -> Option<NodeRef> {
                match t {
                    Target::Previous => Some(NodeRef::Previous),
                    Target::Parent => Some(NodeRef::Parent),
                    Target::Back(k) => i
                        .checked_sub(usize::from(k))
                        .and_then(|j| ids[j])
                        .map(NodeRef::Node),
                    Target::Ahead(k) => ids
                        .get(i + usize::from(k))
                        .copied()
                        .flatten()
                        .or(dead)
                        .map(NodeRef::Node),
                }
            };
            let kind = if child.goal {
                NodeKind::Goal
            } else {
                NodeKind::Command
            };
            let mut spec = match &child.monitor {
                Some(m) => Spawn::monitor(me, "m", monitor_spec(m)),
                None => Spawn::new(
                    me,
                    kind,
                    if child.goal { "g" } else { "c" },
                    action(Rc::new(child.clone())),
                ),
            };
            if child.goal && child.monitor.is_none() {
                spec.handlers = child.handlers.iter().map(handler).collect();
            }
            if !child.uses.is_empty() {
                let amounts = child
                    .uses
                    .iter()
                    .filter_map(|(r, draw)| {
                        let amount = match (*r, *draw) {
                            (_, 0) => 3,
                            (1, 1..=3) => 2,
                            _ => 1,
                        };
                        Some((e.resource_id(&format!("r{r}"))?, amount))
                    })
                    .collect();
                spec.uses = Some(Box::new(Uses {
                    amounts,
                    priority: i32::from(child.priority),
                    deny_if_busy: child.deny,
                }));
            }
            let mut has_first = false;
            for c in &child.constraints {
                if let Some(lc) = lower(c, &resolve, &externals) {
                    // `expand first` with `delay expansion` is refused by the engine; keep one.
                    match lc {
                        Constraint::ExpandFirst => has_first = true,
                        Constraint::DelayExpansion if has_first => continue,
                        _ => {}
                    }
                    if lc == Constraint::DelayExpansion
                        && child
                            .constraints
                            .iter()
                            .any(|c| matches!(c, C::ExpandFirst))
                    {
                        continue;
                    }
                    spec.constraints.push(lc);
                }
            }
            spec.fulfils = ids[i];
            ids[i] = match e.spawn(now, spec) {
                Ok(id) => Some(id),
                // A child's constraint may terminate this node at once (`terminate when parent
                // execution active`, fired by the first command below it): then the rest of the
                // body is refused, as a `tcm` action's would be, and its end does not matter.
                Err(EngineError::Gone(n)) if n == me => return Outcome::done(),
                // Likewise a reservation this node made died when it was terminated: fulfilling
                // it is refused (`dead` was traced for it), as a `tcm` action's spawn would be.
                Err(EngineError::NotReserved(r))
                    if Some(r) == ids[i]
                        && e.info(me)
                            .is_some_and(|n| n.termination != Termination::Alive) =>
                {
                    return Outcome::done();
                }
                Err(err) => panic!("spawn: {err}"),
            };
        }
        // Raised after the spawns: it may terminate this very node.
        if let Some(k) = plan.raise {
            e.handle_external(now, externals[usize::from(k)]);
        }
        if plan.never {
            return Outcome::Never;
        }
        let res = if plan.fail {
            Err(exception(plan.exc))
        } else {
            Ok(())
        };
        Outcome::After(Duration::from_secs(u64::from(plan.secs)), res)
    })
}

/// `A`, or `B` which is a kind of `A`, or `C`.
fn exception(which: u8) -> Failure {
    match which {
        0 => Failure::new("A", "planned failure"),
        1 => Failure::new("B", "planned failure").with_ancestry(vec!["A".into()]),
        _ => Failure::new("C", "raised by a handler"),
    }
}

fn handler(h: &H) -> HandlerSpec<Factory> {
    let what = h.what;
    HandlerSpec {
        name: "h".into(),
        exception: ["A", "B", "C"][usize::from(h.exc.min(2))].into(),
        max_activations: h.max.map(u32::from),
        body: factory(move |e, me, now, _| match what {
            0 => {
                let spec = Spawn::new(
                    me,
                    NodeKind::Command,
                    "recover",
                    body(|_, _, _| Outcome::after(Duration::from_secs(1))),
                );
                e.spawn(now, spec).expect("spawn recovery");
                Outcome::done()
            }
            1 => Outcome::Bypass(Duration::from_millis(500)),
            _ => Outcome::After(Duration::from_millis(200), Err(exception(2))),
        }),
    }
}

fn monitor_spec(m: &Mon) -> MonitorSpec<Factory> {
    let child_secs = m.child_secs;
    let mut spec = MonitorSpec::new(factory(move |e, act, now, p| {
        if let Purpose::Activation { number, .. } = p {
            if number % 2 == 0 {
                e.trigger(now, act).expect("trigger");
            }
        }
        let leaf = Spawn::new(
            act,
            NodeKind::Command,
            "probe",
            body(move |_, _, _| Outcome::after(Duration::from_secs(u64::from(child_secs)))),
        );
        // The trigger may have completed the monitor and so released a constraint that terminated
        // it, this activation with it: spawning under a gone node is then refused, not a bug.
        let _ = e.spawn(now, leaf);
        Outcome::done()
    }));
    spec.period = Some(Duration::from_millis(u64::from(m.period_ms)));
    spec.max_activations = Some(u32::from(m.max_activations));
    spec.max_triggers = m.max_triggers.map(u32::from);
    spec.initial_wait = m.initial_wait;
    spec.each.serial = m.serial;
    spec.overrun = [Overrun::Burst, Overrun::Skip, Overrun::Delay][usize::from(m.overrun % 3)];
    spec
}

fn run(plan: &Plan) -> Vec<tcm_trace::TraceEvent> {
    run_with(plan, None)
}

/// `runs_from`: from how many children the engine queues a parent's children as one run.
fn run_with(plan: &Plan, runs_from: Option<u32>) -> Vec<tcm_trace::TraceEvent> {
    let mut sim = Sim::new();
    if let Some(n) = runs_from {
        sim.engine.set_child_runs_from(n);
    }
    let root = sim.engine.root();
    // Resources the nodes use: one unit, two units with at most one request waiting, one unit.
    for (name, capacity, pending) in [("r0", 1, None), ("r1", 2, Some(1)), ("r2", 1, None)] {
        sim.engine
            .declare_resource(name, capacity, pending)
            .expect("declare");
    }
    let spec = Spawn::new(root, NodeKind::Goal, "top", action(Rc::new(plan.clone())));
    sim.engine.spawn(Time::ZERO, spec).expect("spawn top");
    sim.run_until(Time::ZERO + Duration::from_secs(600));
    sim.trace().to_vec()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 1024, ..ProptestConfig::default() })]

    #[test]
    fn random_programs_pass_the_trace_checker(plan in plan()) {
        let trace = run(&plan);
        if let Err(violations) = tcm_trace::check(&trace) {
            let lines: Vec<String> = trace.iter().map(tcm_trace::to_line).collect();
            let v: Vec<String> = violations.iter().map(ToString::to_string).collect();
            prop_assert!(false, "violations:\n{}\n\ntrace:\n{}", v.join("\n"), lines.join("\n"));
        }
        prop_assert_eq!(run(&plan), trace, "same program, same trace");
    }

    // Queuing a parent's children as one run (`Work::Children`) is only a cheaper queue: with
    // runs for every parent with a child and with none, every program gives the same trace.
    #[test]
    fn children_queued_as_one_run_give_the_same_trace(plan in plan()) {
        let one_each = run_with(&plan, Some(u32::MAX));
        let runs = run_with(&plan, Some(1));
        if runs != one_each {
            let a: Vec<String> = one_each.iter().map(tcm_trace::to_line).collect();
            let b: Vec<String> = runs.iter().map(tcm_trace::to_line).collect();
            prop_assert!(false, "one entry each:\n{}\n\nruns:\n{}", a.join("\n"), b.join("\n"));
        }
    }
}
