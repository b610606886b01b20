//! The engine through its API without the simulator: what a shell sees ([`Effect`]s, [`Job`]s),
//! what misuse returns, and memory.

use super::{AFTER_PREVIOUS, assert_checked, cmd, goal, never, run, s, spawns};
use crate::sim::{Sim, noop};
use crate::*;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use tcm_trace::{TraceEvent, TraceKind};

/// An engine whose actions and factories are names.
type Bare = Engine<&'static str, &'static str>;

/// Spawns the node `name` under `up` at time zero; its action is its name.
fn spawn(
    e: &mut Bare,
    up: NodeId,
    kind: NodeKind,
    name: &'static str,
    cs: &[Constraint],
) -> NodeId {
    let mut spec = Spawn::new(up, kind, name, name);
    spec.constraints = cs.iter().copied().collect();
    e.spawn(Time::ZERO, spec).expect("spawn")
}

/// Spawns the command `name` under the root.
fn command(e: &mut Bare, name: &'static str, cs: &[Constraint]) -> NodeId {
    spawn(e, e.root(), NodeKind::Command, name, cs)
}

/// The next effect, which must start `node`.
#[track_caller]
fn started(e: &mut Bare, node: NodeId) {
    match e.poll_effect() {
        Some(Effect::Start { node: n, .. }) if n == node => {}
        other => panic!("expected the start of {node}, got {other:?}"),
    }
}

/// The next effect, which must be an invocation: its job, factory and purpose.
#[track_caller]
fn invoked(e: &mut Bare) -> (Job, &'static str, Purpose) {
    match e.poll_effect() {
        Some(Effect::Invoke { job, body, purpose }) => (job, body, (*purpose).clone()),
        other => panic!("expected an invocation, got {other:?}"),
    }
}

/// The engine's trace so far, which the trace checker passed.
#[track_caller]
fn checked_trace(e: &mut Bare) -> Vec<TraceEvent> {
    let trace: Vec<TraceEvent> = std::iter::from_fn(|| e.poll_trace()).collect();
    assert_checked(&trace);
    trace
}

#[test]
fn a_start_is_withdrawn_when_its_node_is_terminated_before_the_shell_saw_it() {
    let mut e: Bare = Engine::new(1);
    // Started and terminated within one call: `x` is terminated when its handling goes active.
    let this_active = When::Event(Event::new(NodeRef::This, Point::Active));
    command(&mut e, "x", &[Constraint::terminate(this_active)]);
    assert!(e.poll_effect().is_none(), "neither a start nor a cancel");
    // Started by one call, terminated by the next before the shell polled.
    let y = command(&mut e, "y", &[]);
    e.terminate(Time::ZERO, y).expect("terminate");
    assert!(e.poll_effect().is_none(), "neither a start nor a cancel");
    // Once the shell has taken the start, termination cancels.
    let z = command(&mut e, "z", &[]);
    started(&mut e, z);
    e.terminate(Time::ZERO, z).expect("terminate");
    assert!(matches!(e.poll_effect(), Some(Effect::Cancel { node }) if node == z));
    assert!(e.poll_effect().is_none());
    // The cancelled action counts as running, and its node is not terminated, until the shell
    // reports that it stopped.
    assert_eq!(e.stats().running, 1);
    assert!(!e.is_idle());
    e.handle_action_finished(Time::ZERO, z, Ok(()))
        .expect("the stop is reported");
    assert_eq!(e.stats().running, 0);
    assert!(e.is_idle());
    let trace = checked_trace(&mut e);
    let terminated = trace
        .iter()
        .filter(|r| matches!(r.kind, TraceKind::Terminated { .. }));
    assert_eq!(terminated.count(), 3);
}

#[test]
fn an_overdue_cancelled_action_is_a_warning_and_its_stop_terminates_the_node() {
    let mut e: Bare = Engine::new(1);
    let z = command(&mut e, "z", &[]);
    started(&mut e, z);
    // Not being stopped: nothing to warn about.
    e.handle_action_overdue(Time::ZERO, z, s(1.0));
    assert_eq!(e.stats().warnings, 0);
    e.terminate(Time::ZERO, z).expect("terminate");
    assert!(matches!(e.poll_effect(), Some(Effect::Cancel { node }) if node == z));
    // The shell's grace period ended with the action still running: it drops it, then reports.
    e.handle_action_overdue(Time::ZERO + s(1.0), z, s(1.0));
    assert_eq!(
        e.stats().running,
        1,
        "still running until the stop is reported"
    );
    e.handle_action_stopped(Time::ZERO + s(1.0), z);
    assert!(e.is_idle());
    let trace = checked_trace(&mut e);
    let warnings: Vec<(u64, &str)> = trace
        .iter()
        .filter_map(|r| match &r.kind {
            TraceKind::Warning { node, message } => Some((node.unwrap_or(0), message.as_str())),
            _ => None,
        })
        .collect();
    assert_eq!(
        warnings,
        [(
            1,
            "Action of z {1} did not stop within its grace period (1s) after termination: dropped"
        )]
    );
    let terminated = trace
        .iter()
        .find(|r| matches!(r.kind, TraceKind::Terminated { node: 1 }));
    assert_eq!(terminated.map(|r| r.t), Some(1_000_000_000));
}

#[test]
fn a_log_line_is_a_record_at_its_time_about_a_live_node_and_kept_with_the_warnings() {
    let mut e: Bare = Engine::new(1);
    let z = command(&mut e, "z", &[]);
    started(&mut e, z);
    e.log(Time::ZERO + s(1.5), z, "half way".into())
        .expect("z is live");
    e.handle_action_finished(Time::ZERO + s(2.0), z, Ok(()))
        .expect("finished");
    // Gone: refused, as every input about a node that left the tree.
    assert!(e.log(Time::ZERO + s(3.0), z, "late".into()).is_err());
    let trace = checked_trace(&mut e);
    let logs: Vec<(u64, u64, &str)> = trace
        .iter()
        .filter_map(|r| match &r.kind {
            TraceKind::Log { node, message } => Some((r.t, *node, message.as_str())),
            _ => None,
        })
        .collect();
    assert_eq!(logs, [(1_500_000_000, 1, "half way")]);
    // Tracing off (after the first record), a shell that logs warnings still gets the lines, and
    // no spawn or transition.
    let mut e: Bare = Engine::new(1);
    e.set_tracing(false);
    e.trace_warnings(true);
    let z = command(&mut e, "z", &[]);
    started(&mut e, z);
    e.log(Time::ZERO, z, "quiet".into()).expect("z is live");
    let kept: Vec<TraceKind> = std::iter::from_fn(|| e.poll_trace())
        .map(|r| r.kind)
        .filter(|k| !matches!(k, TraceKind::RunStarted { .. }))
        .collect();
    assert_eq!(
        kept,
        [TraceKind::Log {
            node: 1,
            message: "quiet".into()
        }]
    );
}

#[test]
fn a_wiretap_check_is_a_job_reported_like_an_action() {
    let mut e: Bare = Engine::new(1);
    e.wiretap("move", TapWhen::Before, "stable?");
    let t = |secs| Time::ZERO + s(secs);
    let m = command(&mut e, "move", &[]);
    let (job, body, purpose) = invoked(&mut e);
    assert_eq!((job.node(), body), (m, "stable?"));
    assert!(!job.cancellable(), "a check runs to its end");
    assert_ne!(job, Job::from(m));
    assert!(matches!(
        purpose,
        Purpose::Tap {
            when: TapWhen::Before,
            ..
        }
    ));
    assert!(e.poll_effect().is_none(), "the action waits for its check");
    // The node's own end cannot be reported while only its check runs.
    let early = e.handle_action_finished(t(1.0), m, Ok(()));
    assert_eq!(early, Err(EngineError::NotRunning(m)));
    e.handle_action_finished(t(1.0), job, Ok(()))
        .expect("the check passed");
    started(&mut e, m);
    e.handle_action_finished(t(2.0), m, Ok(()))
        .expect("the action ended");
    // Reported twice, an action's end is refused.
    let again = e.handle_action_finished(t(3.0), m, Ok(()));
    assert_eq!(again, Err(EngineError::Gone(m)));
    assert!(e.is_idle());
    checked_trace(&mut e);
}

#[test]
fn a_wiretap_check_reported_twice_is_refused() {
    let mut e: Bare = Engine::new(1);
    e.wiretap("move", TapWhen::Before, "stable?");
    e.wiretap("move", TapWhen::Before, "charged?");
    let m = command(&mut e, "move", &[]);
    let (stable, _, _) = invoked(&mut e);
    let (charged, _, _) = invoked(&mut e);
    e.handle_action_finished(Time::ZERO, stable, Ok(()))
        .expect("the first check passed");
    let again = e.handle_action_finished(Time::ZERO, stable, Ok(()));
    assert_eq!(again, Err(EngineError::NotRunning(m)));
    assert!(
        e.poll_effect().is_none(),
        "move must not start while charged? runs"
    );
    assert_eq!(e.stats().running, 1, "charged? still runs");
    e.handle_action_finished(Time::ZERO, charged, Ok(()))
        .expect("the second check passed");
    started(&mut e, m);
    e.handle_action_finished(Time::ZERO, m, Ok(()))
        .expect("the action ended");
    assert!(e.is_idle());
    checked_trace(&mut e);
}

#[test]
fn checks_of_a_terminated_node_stop_counting_and_their_reports_are_refused() {
    let mut e: Bare = Engine::new(1);
    e.wiretap("move", TapWhen::Before, "stable?");
    let m = command(&mut e, "move", &[]);
    let (stable, _, _) = invoked(&mut e);
    assert_eq!(e.stats().running, 1, "the check runs");
    e.terminate(Time::ZERO, m).expect("terminate");
    assert_eq!(
        e.stats().running,
        0,
        "a check of a terminated node decides nothing"
    );
    assert!(e.is_idle(), "the run does not wait for it");
    // Its late report changes nothing, whether the node is still there or reclaimed.
    let late = e.handle_action_finished(Time::ZERO, stable, Err(Failure::new("Tilted", "")));
    assert!(
        matches!(late, Ok(()) | Err(EngineError::NotRunning(_))),
        "{late:?}"
    );
    assert_eq!(e.stats().running, 0);
    assert!(e.poll_effect().is_none(), "move never starts");
    checked_trace(&mut e);
}

#[test]
fn a_handler_bypasses_by_request_during_its_body() {
    let mut e: Bare = Engine::new(1);
    let mut top = Spawn::new(e.root(), NodeKind::Goal, "top", "top");
    top.handlers.push(HandlerSpec {
        name: "skip".into(),
        exception: "Blocked".into(),
        max_activations: None,
        body: "skip",
    });
    let top = e.spawn(Time::ZERO, top).expect("spawn");
    started(&mut e, top);
    let leaf = spawn(&mut e, top, NodeKind::Command, "leaf", &[]);
    started(&mut e, leaf);
    e.handle_action_finished(Time::ZERO, top, Ok(()))
        .expect("top's body ended");
    // Only a handler may bypass.
    let not_a_handler = e.request_bypass(Time::ZERO, leaf);
    assert!(matches!(not_a_handler, Err(EngineError::NotAHandler(_))));
    let failure = Failure::new("Blocked", "cart in the way");
    e.handle_action_finished(Time::ZERO, leaf, Err(failure))
        .expect("leaf failed");
    let (job, body, purpose) = invoked(&mut e);
    assert_eq!(body, "skip");
    assert!(matches!(purpose, Purpose::Handler { failing, .. } if failing == leaf));
    e.request_bypass(Time::ZERO, job.node()).expect("bypass");
    e.handle_action_finished(Time::ZERO, job, Ok(()))
        .expect("the handler's body ended");
    assert!(e.is_idle());
    let choices = tcm_trace::story::handler_choices(&checked_trace(&mut e));
    assert_eq!(choices, ["skip<-Blocked", "bypass"]);
}

#[test]
fn misuse_gets_errors_not_panics() {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    let e = &mut sim.engine;
    assert_eq!(
        e.terminate(Time::ZERO, root),
        Err(EngineError::Root("terminated"))
    );
    let mut other: Engine<()> = Engine::new(2);
    let foreign = Spawn::new(other.root(), NodeKind::Command, "x", ());
    let foreign = other.spawn(Time::ZERO, foreign).expect("spawn");
    let serial = Constraint::Serial(foreign.into());
    let err = e.spawn(
        Time::ZERO,
        Spawn::new(root, NodeKind::Command, "y", noop()).with(serial),
    );
    assert!(
        matches!(err, Err(EngineError::ForeignNode { .. })),
        "{:?}",
        err.err()
    );
    let err = e.terminate(Time::ZERO, foreign);
    assert!(matches!(err, Err(EngineError::ForeignNode { .. })));
    let err = e.handle_action_finished(Time::ZERO, foreign, Ok(()));
    assert!(matches!(err, Err(EngineError::ForeignNode { .. })));
    let both = Spawn::new(root, NodeKind::Goal, "z", noop())
        .with(Constraint::ExpandFirst)
        .with(Constraint::DelayExpansion);
    assert_eq!(
        e.spawn(Time::ZERO, both).err(),
        Some(EngineError::Inconsistent)
    );
    // Nothing was applied: the trace is the run's start alone, and it reads.
    sim.run();
    assert_eq!(
        tcm_trace::check(sim.trace()).map(|r| r.n_transitions),
        Ok(0)
    );
}

#[test]
fn watching_a_relative_reference_is_refused() {
    let mut sim = Sim::new();
    let previous = Event::new(NodeRef::Previous, Point::Completed);
    let err = sim.engine.watch(Time::ZERO, previous, WatchToken(1));
    assert_eq!(err, Err(EngineError::RelativeRef));
}

#[test]
fn completed_subtrees_are_reclaimed() {
    let r = run(|e, root| {
        let g = spawns(0.0, |e, me, _| {
            for _ in 0..100 {
                cmd(e, me, "c", noop(), &[AFTER_PREVIOUS]);
            }
        });
        goal(e, root, "g", g, &[]);
    });
    assert_eq!(r.sim.engine.stats().live_nodes, 1, "only the root is left");
    assert_eq!(r.sim.engine.stats().created, 101);
}

#[test]
fn a_million_waited_children_keep_the_tree_small() {
    // See: issue 2 (a robot that runs for days must not grow).
    const N: u64 = 1_000_000;
    use std::cell::Cell;
    use std::rc::Rc;
    let done = Rc::new(Cell::new(0u64));
    let d2 = done.clone();
    let mut sim = Sim::new()
        .without_trace()
        .on_notify(move |e, token, _, now| {
            let parent = NodeId {
                run: 1,
                idx: (token.0 >> 32) as u32,
                generation: token.0 as u32,
            };
            d2.set(d2.get() + 1);
            if d2.get() < N {
                let child = Spawn::new(parent, NodeKind::Command, "child", noop());
                let child = e.spawn(now, child).expect("spawn");
                let done = Event::new(child, Point::Completed);
                e.watch(now, done, token).expect("watch");
            }
        });
    let root = sim.engine.root();
    let g = Spawn::new(root, NodeKind::Goal, "spawner", never());
    let g = sim.engine.spawn(Time::ZERO, g).expect("spawn");
    let token = WatchToken(((g.idx as u64) << 32) | g.generation as u64);
    let child = Spawn::new(g, NodeKind::Command, "child", noop());
    let child = sim.engine.spawn(Time::ZERO, child).expect("spawn");
    let done_event = Event::new(child, Point::Completed);
    sim.engine
        .watch(Time::ZERO, done_event, token)
        .expect("watch");
    sim.run();
    assert_eq!(done.get(), N);
    let stats = sim.engine.stats();
    assert!(
        stats.high_water < 10,
        "high-water mark {}",
        stats.high_water
    );
    assert_eq!(stats.created, N + 1);
}

#[test]
fn a_node_stays_small() {
    // Nodes are the engine's bulk: a million alive at once must fit in a few hundred megabytes.
    // See: issue 6 (1M-node W1 within 250 MB).
    let size =
        std::mem::size_of::<crate::engine::node::Node<crate::sim::Body, crate::sim::Factory>>();
    assert!(size <= 208, "a node takes {size} bytes");
}

#[test]
fn timer_callbacks_notify_their_token_and_a_timed_one_is_a_pending_timer() {
    let mut e: Bare = Engine::new(1);
    let a = command(&mut e, "a", &[]);
    started(&mut e, a);
    let at = Time::ZERO + s(2.0);
    e.invoke_at(Time::ZERO, at, WatchToken(7), "later", Some(a))
        .expect("invoke_at");
    e.invoke_when(
        Time::ZERO,
        Event::on(a, Facet::Execution, Point::Completed),
        WatchToken(8),
        "after a",
        None,
    )
    .expect("invoke_when");
    // The timed one is a deadline: the engine is not settled while it is pending.
    assert_eq!(e.poll_timeout(), Some(at));
    assert!(!e.is_settled());
    assert!(e.poll_effect().is_none());
    e.handle_action_finished(Time::ZERO + s(1.0), a, Ok(()))
        .expect("finished");
    assert!(matches!(
        e.poll_effect(),
        Some(Effect::Notify {
            token: WatchToken(8),
            outcome,
        }) if *outcome == WatchOutcome::Reached
    ));
    e.handle_timeout(at);
    assert!(matches!(
        e.poll_effect(),
        Some(Effect::Notify {
            token: WatchToken(7),
            outcome,
        }) if *outcome == WatchOutcome::Reached
    ));
    e.callback_ran(WatchToken(7), "later");
    assert!(e.is_settled() && e.is_idle());
    let trace = checked_trace(&mut e);
    let callbacks: Vec<&TraceKind> = trace
        .iter()
        .map(|ev| &ev.kind)
        .filter(|k| {
            matches!(
                k,
                TraceKind::CallbackSet { .. } | TraceKind::CallbackRan { .. }
            )
        })
        .collect();
    assert!(matches!(
        callbacks[..],
        [
            TraceKind::CallbackSet {
                callback: 7,
                node: Some(1),
                ..
            },
            TraceKind::CallbackSet {
                callback: 8,
                node: None,
                ..
            },
            TraceKind::CallbackRan { callback: 7, .. },
        ]
    ));
}

#[test]
fn the_stuck_report_names_parked_actions_and_their_waiting_children() {
    let mut e: Bare = Engine::new(1);
    let root = e.root();
    // `plan` expands first; its action waits for `measure`, whose execution waits for `plan`'s.
    let plan = spawn(
        &mut e,
        root,
        NodeKind::Goal,
        "plan",
        &[Constraint::ExpandFirst],
    );
    started(&mut e, plan);
    let measure = spawn(&mut e, plan, NodeKind::Command, "measure", &[]);
    let awaited = Event::on(measure, Facet::Execution, Point::Completed);
    e.watch(Time::ZERO, awaited, WatchToken(1)).expect("watch");
    assert!(
        e.is_settled() && !e.is_idle(),
        "only the parked action runs"
    );
    let text = |b: Vec<Blocked>| b.iter().map(ToString::to_string).collect::<Vec<_>>();
    assert_eq!(
        text(e.blocked_awaiting(&[(plan, awaited)])),
        [
            "plan {1} handling is active and waits for its action, which awaits measure {2} \
             execution completed",
            "plan {1} execution waits for its own expansion (expand first)",
            "measure {2} execution waits for its parent plan {1} execution enabled",
        ]
    );
    // Without the parked action, the engine alone still names both nodes.
    assert_eq!(text(e.blocked()).len(), 2);
    let info = e.info(plan).expect("plan");
    assert!(info.reached(Facet::Handling, Point::Active) && !info.is_terminating());
    checked_trace(&mut e);
}

#[test]
fn monitor_info_answers_for_the_monitor_and_its_activations() {
    let mut e: Bare = Engine::new(1);
    let mut spec = MonitorSpec::new("body");
    spec.max_activations = Some(4);
    spec.period = Some(s(1.5));
    spec.each.serial = true;
    spec.each.delay_expansion = true;
    spec.overrun = crate::Overrun::Skip;
    let m = e
        .spawn(Time::ZERO, Spawn::monitor(e.root(), "m", spec))
        .expect("spawn");
    let (job, _, _) = invoked(&mut e);
    let from_activation = e.monitor_info(job.node()).expect("an activation");
    let info = e.monitor_info(m).expect("a monitor");
    assert_eq!(info, from_activation);
    assert_eq!(info.monitor, m);
    assert_eq!((info.activations, info.triggers), (1, 0));
    assert_eq!(info.max_activations, Some(4));
    assert_eq!(info.period, Some(s(1.5)));
    assert!(!info.initial_wait);
    // The per-activation constraints and the overrun policy, as given.
    assert!(info.each.serial && info.each.delay_expansion);
    assert!(!info.each.sequential_execution && !info.each.expand_first);
    assert_eq!(info.overrun, crate::Overrun::Skip);
    assert_eq!(e.monitor_info(e.root()), None);
    checked_trace(&mut e);
}

/// A trigger with data (`Engine::activate_when`) hands its data to the activation it makes, and
/// the activation alone; `Then::ActivateWith` written by hand, naming data the monitor does not
/// keep, is void, as is data on an activation by an external event.
#[test]
fn an_activation_trigger_with_data_hands_it_to_its_activation() {
    let mut e: Bare = Engine::new(1);
    let m = e
        .spawn(
            Time::ZERO,
            Spawn::monitor(e.root(), "m", MonitorSpec::new("body")),
        )
        .expect("spawn");
    e.activate_when(Time::ZERO, m, When::In(s(1.0)), std::sync::Arc::new(7u32))
        .expect("a trigger with data");
    e.constrain(
        Time::ZERO,
        m,
        Constraint::Trigger(When::Now, Then::ActivateWith(3)),
    )
    .expect("void, not refused");
    let x = e.external("x");
    assert!(matches!(
        e.activate_when(Time::ZERO, m, When::External(x), std::sync::Arc::new(8u32)),
        Err(EngineError::ActivationData(_))
    ));
    assert!(e.poll_effect().is_none());
    e.handle_timeout(Time::ZERO + s(1.0));
    let (job, _, _) = invoked(&mut e);
    let data = e.activation_data(job.node()).expect("data");
    assert_eq!(data.downcast_ref::<u32>(), Some(&7));
    assert!(e.activation_data(m).is_none());
    let trace = checked_trace(&mut e);
    let voids: Vec<_> = trace
        .iter()
        .filter_map(|t| match &t.kind {
            TraceKind::ConstraintVoid { reason, .. } => Some(reason.as_str()),
            _ => None,
        })
        .collect();
    assert_eq!(
        voids,
        ["an activation carries data only at an event or a time, through `Engine::activate_when`"]
    );
}

/// A clock for `Engine::with_clock` that reads `at` (in ms) and counts its readings.
fn counting_clock(e: &mut Bare) -> (Arc<AtomicU64>, Arc<AtomicU64>) {
    let (at, reads) = (Arc::new(AtomicU64::new(0)), Arc::new(AtomicU64::new(0)));
    let (a, r) = (at.clone(), reads.clone());
    e.set_clock(Arc::new(move |_| {
        r.fetch_add(1, Ordering::Relaxed);
        Time::ZERO + s(a.load(Ordering::Relaxed) as f64 / 1000.0)
    }));
    (at, reads)
}

#[test]
fn with_the_clock_an_untraced_input_that_needs_no_time_reads_no_clock() {
    let mut e: Bare = Engine::new(1);
    e.set_tracing(false);
    let (at, reads) = counting_clock(&mut e);
    at.store(5, Ordering::Relaxed);
    let root = e.root();
    let spec = Spawn::new(root, NodeKind::Command, "a", "a");
    let a = e.with_clock(|e, now| e.spawn(now, spec)).expect("spawn");
    started(&mut e, a);
    e.with_clock(|e, now| e.handle_action_finished(now, a, Ok(())))
        .expect("end");
    assert_eq!(reads.load(Ordering::Relaxed), 0, "nothing needed the time");
    assert!(e.info(a).is_none(), "a ran and was reclaimed");
    // A timer started by an input needs the time: the clock is read then, once.
    let spec =
        Spawn::new(root, NodeKind::Command, "b", "b").with(Constraint::terminate(When::In(s(1.0))));
    let b = e.with_clock(|e, now| e.spawn(now, spec)).expect("spawn");
    assert_eq!(reads.load(Ordering::Relaxed), 1);
    assert_eq!(e.now(), Time::ZERO + s(0.005));
    assert_eq!(
        e.poll_timeout(),
        Some(Time::ZERO + s(1.005)),
        "counted from the reading"
    );
    started(&mut e, b);
}

#[test]
fn with_the_clock_a_traced_input_is_dated_by_one_reading_and_due_timers_fire_at_their_own_time() {
    let mut e: Bare = Engine::new(1);
    let (at, reads) = counting_clock(&mut e);
    let root = e.root();
    at.store(1_000, Ordering::Relaxed);
    let spec =
        Spawn::new(root, NodeKind::Command, "a", "a").with(Constraint::terminate(When::In(s(1.0))));
    let a = e.with_clock(|e, now| e.spawn(now, spec)).expect("spawn");
    assert_eq!(
        reads.load(Ordering::Relaxed),
        1,
        "one reading dates the whole input"
    );
    started(&mut e, a);
    // The next input comes late, after `a`'s deadline (2 s) passed unnoticed: `a` is
    // terminated at its deadline, and the new node is spawned at the reading, 3 s.
    at.store(3_000, Ordering::Relaxed);
    let spec = Spawn::new(root, NodeKind::Command, "b", "b");
    let b = e.with_clock(|e, now| e.spawn(now, spec)).expect("spawn");
    assert_eq!(reads.load(Ordering::Relaxed), 2);
    let trace = checked_trace(&mut e);
    let when = |pred: &dyn Fn(&TraceKind) -> bool| {
        trace
            .iter()
            .find(|r| pred(&r.kind))
            .map(|r| r.t)
            .expect("record")
    };
    let (a_disp, b_disp) = (e.info(a).expect("a").display, e.info(b).expect("b").display);
    assert_eq!(
        when(&|k| matches!(k, TraceKind::Spawned { node, .. } if *node == a_disp)),
        1_000_000_000
    );
    assert_eq!(
        when(&|k| matches!(k, TraceKind::Terminating { node } if *node == a_disp)),
        2_000_000_000,
        "the timer fired at its own time"
    );
    assert_eq!(
        when(&|k| matches!(k, TraceKind::Spawned { node, .. } if *node == b_disp)),
        3_000_000_000
    );
}

#[test]
fn without_a_clock_with_clock_gives_the_latest_time_known() {
    let mut e: Bare = Engine::new(1);
    let root = e.root();
    let a = spawn(&mut e, root, NodeKind::Command, "a", &[]);
    started(&mut e, a);
    e.handle_action_finished(Time::ZERO + s(2.0), a, Ok(()))
        .expect("end");
    let spec = Spawn::new(root, NodeKind::Command, "b", "b");
    let b = e.with_clock(|e, now| e.spawn(now, spec)).expect("spawn");
    let trace = checked_trace(&mut e);
    let b_disp = e.info(b).expect("b").display;
    let spawned = trace
        .iter()
        .find(|r| matches!(r.kind, TraceKind::Spawned { node, .. } if node == b_disp))
        .expect("spawned");
    assert_eq!(spawned.t, 2_000_000_000);
}
