//! Cloning an engine and its canonical hash (`engine/canon.rs`): a clone behaves as the original,
//! states reached through different histories hash alike, and states that differ in what decides
//! the future hash apart.

use crate::*;
use std::collections::hash_map::DefaultHasher;
use std::hash::Hasher;
use std::time::Duration;

type E = Engine<u32, u32>;

fn hash<S: Keep<crate::engine::node::Node<u32, u32>>>(e: &Engine<u32, u32, S>) -> u64 {
    let mut h = DefaultHasher::new();
    let _ = e.canonical_hash(&mut h);
    h.finish()
}

fn t(secs: u64) -> Time {
    Time::from_nanos(secs * 1_000_000_000)
}

/// Drains the effects, returning the nodes started.
fn started<S: Keep<crate::engine::node::Node<u32, u32>>>(
    e: &mut Engine<u32, u32, S>,
) -> Vec<NodeId> {
    let mut out = Vec::new();
    while let Some(effect) = e.poll_effect() {
        if let Effect::Start { node, .. } = effect {
            out.push(node);
        }
    }
    out
}

fn records<S: Keep<crate::engine::node::Node<u32, u32>>>(
    e: &mut Engine<u32, u32, S>,
) -> Vec<String> {
    let mut out = Vec::new();
    while let Some(r) = e.poll_trace() {
        out.push(tcm_trace::to_line(&r));
    }
    out
}

#[test]
fn a_clone_runs_as_the_original() {
    let mut a: E = Engine::new(1);
    let root = a.root();
    let x = a
        .spawn(t(0), Spawn::new(root, NodeKind::Command, "x", 1))
        .expect("spawn x");
    let _y = a
        .spawn(
            t(0),
            Spawn::new(root, NodeKind::Command, "y", 2)
                .with(Constraint::sequential_previous())
                .with(Constraint::terminate(When::In(Duration::from_secs(5)))),
        )
        .expect("spawn y");
    let _ = records(&mut a);
    let mut b = a.clone();
    for e in [&mut a, &mut b] {
        assert_eq!(started(e), vec![x]);
        e.handle_action_finished(t(1), x, Ok(())).expect("x ends");
        e.handle_timeout(t(5));
    }
    assert_eq!(records(&mut a), records(&mut b));
    assert_eq!(hash(&a), hash(&b));
}

/// The two-command program of the test above, on an engine keeping its nodes as `S` does.
fn two_commands<S: Keep<crate::engine::node::Node<u32, u32>>>() -> (Engine<u32, u32, S>, NodeId) {
    let mut e: Engine<u32, u32, S> = Engine::new(1);
    let root = e.root();
    let x = e
        .spawn(t(0), Spawn::new(root, NodeKind::Command, "x", 1))
        .expect("spawn x");
    e.spawn(
        t(0),
        Spawn::new(root, NodeKind::Command, "y", 2)
            .with(Constraint::sequential_previous())
            .with(Constraint::terminate(When::In(Duration::from_secs(5)))),
    )
    .expect("spawn y");
    (e, x)
}

#[test]
fn shared_nodes_are_copied_on_write_and_run_as_owned_ones() {
    let (mut owned, x) = two_commands::<Owned>();
    let (mut shared, _) = two_commands::<Shared>();
    assert_eq!(records(&mut owned), records(&mut shared));
    let before = hash(&shared);
    let mut snapshot = shared.clone();
    // The clone moves on: x fails, y is terminated; the original's nodes must not see it.
    assert_eq!(started(&mut shared), vec![x]);
    shared
        .handle_action_finished(t(1), x, Err(Failure::new("Boom", "boom")))
        .expect("x fails");
    shared.handle_timeout(t(5));
    let _ = records(&mut shared);
    assert_ne!(hash(&shared), before, "the clone changed");
    assert_eq!(hash(&snapshot), before, "the original is untouched");
    // The original then runs exactly as an engine owning its nodes.
    for e in [&mut owned as &mut dyn Steps, &mut snapshot] {
        e.steps(x);
    }
    assert_eq!(records(&mut owned), records(&mut snapshot));
    assert_eq!(hash(&owned), hash(&snapshot));
}

/// The same steps on an owned or a shared engine.
trait Steps {
    fn steps(&mut self, x: NodeId);
}

impl<S: Keep<crate::engine::node::Node<u32, u32>>> Steps for Engine<u32, u32, S> {
    fn steps(&mut self, x: NodeId) {
        assert_eq!(started(self), vec![x]);
        self.handle_action_finished(t(1), x, Ok(()))
            .expect("x ends");
        self.handle_timeout(t(5));
    }
}

#[test]
fn equal_states_reached_at_other_times_and_numbers_hash_alike() {
    // One run has a node come and go first (so its numbers differ) and does everything 7 s later.
    let run = |shift: u64, reserve_first: bool| {
        let mut e: E = Engine::new(1);
        let root = e.root();
        if reserve_first {
            let z = e
                .spawn(t(shift), Spawn::new(root, NodeKind::Command, "z", 4))
                .expect("spawn z");
            let _ = started(&mut e);
            e.handle_action_finished(t(shift), z, Ok(()))
                .expect("z ends");
        }
        let a = e
            .spawn(t(shift), Spawn::new(root, NodeKind::Command, "a", 1))
            .expect("spawn a");
        let _b = e
            .spawn(
                t(shift),
                Spawn::new(root, NodeKind::Command, "b", 2)
                    .with(Constraint::terminate(When::In(Duration::from_secs(30)))),
            )
            .expect("spawn b");
        let _ = started(&mut e);
        e.handle_action_finished(t(shift + 2), a, Ok(()))
            .expect("a ends");
        e
    };
    let one = run(0, false);
    let other = run(7, true);
    assert_ne!(one.now(), other.now());
    assert_eq!(hash(&one), hash(&other));
    // The same tree with the timer 1 s nearer is another state.
    let mut nearer = run(0, false);
    nearer.handle_timeout(t(3));
    assert_ne!(hash(&one), hash(&nearer));
}

#[test]
fn handler_uses_are_part_of_the_state() {
    let run = |uses: u32| {
        let mut e: E = Engine::new(1);
        let root = e.root();
        let mut spec = Spawn::new(root, NodeKind::Goal, "g", 1);
        spec.handlers.push(HandlerSpec {
            name: "h".into(),
            exception: "Oops".into(),
            max_activations: Some(3),
            body: 9,
        });
        let g = e.spawn(t(0), spec).expect("spawn g");
        let _ = started(&mut e);
        for i in 0..uses {
            let c = e
                .spawn(t(0), Spawn::new(g, NodeKind::Command, "c", 3))
                .expect("spawn c");
            let _ = started(&mut e);
            e.handle_action_finished(t(0), c, Err(Failure::new("Oops", "scripted")))
                .expect("c fails");
            // Each handler node ends at once.
            while let Some(effect) = e.poll_effect() {
                if let Effect::Invoke { job, .. } = effect {
                    e.handle_action_finished(t(0), job, Ok(()))
                        .expect("handler ends");
                }
            }
            let _ = i;
        }
        e
    };
    assert_ne!(hash(&run(1)), hash(&run(2)));
}

#[test]
fn a_monitor_polling_forever_comes_back_to_the_same_state() {
    let mut e: E = Engine::new(1);
    let root = e.root();
    let mut spec = MonitorSpec::new(7);
    spec.period = Some(Duration::from_secs(1));
    let _m = e
        .spawn(t(0), Spawn::monitor(root, "watch", spec))
        .expect("spawn the monitor");
    // Each activation ends at once; the hash after each poll is the same (counts no maximum
    // limits are not part of the state, times are relative).
    let mut hashes = Vec::new();
    for k in 0..4 {
        e.handle_timeout(t(k));
        while let Some(effect) = e.poll_effect() {
            if let Effect::Invoke { job, .. } = effect {
                e.handle_action_finished(t(k), job, Ok(()))
                    .expect("the activation ends");
            }
        }
        hashes.push(hash(&e));
    }
    assert_eq!(hashes[1], hashes[2]);
    assert_eq!(hashes[2], hashes[3]);
    // With a maximum, the count matters.
    let mut f: E = Engine::new(1);
    let root = f.root();
    let mut spec = MonitorSpec::new(7);
    spec.period = Some(Duration::from_secs(1));
    spec.max_activations = Some(10);
    f.spawn(t(0), Spawn::monitor(root, "watch", spec))
        .expect("spawn the monitor");
    let mut limited = Vec::new();
    for k in 0..3 {
        f.handle_timeout(t(k));
        while let Some(effect) = f.poll_effect() {
            if let Effect::Invoke { job, .. } = effect {
                f.handle_action_finished(t(k), job, Ok(()))
                    .expect("the activation ends");
            }
        }
        limited.push(hash(&f));
    }
    assert_ne!(limited[1], limited[2]);
}

#[test]
fn a_monitor_s_overrun_policy_and_its_held_poll_are_part_of_the_state() {
    // A monitor polling every second whose first activation never ends: at 1 s, the poll is
    // made (burst), dropped (skip) or held (delay); three different states, and the policy
    // alone already tells them apart at the start.
    let at = |overrun: Overrun, secs: u64| {
        let mut e: E = Engine::new(1);
        let root = e.root();
        let mut spec = MonitorSpec::new(7);
        spec.period = Some(Duration::from_secs(1));
        spec.overrun = overrun;
        e.spawn(t(0), Spawn::monitor(root, "watch", spec))
            .expect("spawn the monitor");
        for k in 0..=secs {
            e.handle_timeout(t(k));
            while e.poll_effect().is_some() {}
        }
        hash(&e)
    };
    let policies = [Overrun::Burst, Overrun::Skip, Overrun::Delay];
    for secs in [0, 1] {
        let hashes: Vec<u64> = policies.iter().map(|&o| at(o, secs)).collect();
        assert_ne!(hashes[0], hashes[1], "{secs}");
        assert_ne!(hashes[1], hashes[2], "{secs}");
        assert_ne!(hashes[0], hashes[2], "{secs}");
    }
    // A held poll waits, whatever the time: 1 s and 3 s later, the same state; skipped polls
    // keep the schedule, so the same state too.
    assert_eq!(at(Overrun::Delay, 1), at(Overrun::Delay, 3));
    assert_eq!(at(Overrun::Skip, 1), at(Overrun::Skip, 3));
}

#[test]
fn resource_tables_are_part_of_the_state() {
    // Two commands use one base: the second waits for it. Then it is locked, and reserved.
    let mut e: E = Engine::new(1);
    let base = e.declare_resource("base", 1, None).expect("declared");
    let root = e.root();
    let a = e
        .spawn(
            t(0),
            Spawn::new(root, NodeKind::Command, "a", 1).using(base, 1),
        )
        .expect("spawn a");
    let only_a = hash(&e);
    let _b = e
        .spawn(
            t(0),
            Spawn::new(root, NodeKind::Command, "b", 1).using(base, 1),
        )
        .expect("spawn b");
    assert_eq!(started(&mut e), vec![a]);
    let waiting = hash(&e);
    assert_ne!(only_a, waiting);
    let mut locked = e.clone();
    locked.lock_resource(t(0), base).expect("locks");
    assert_ne!(hash(&locked), waiting, "a lock");
    let mut reserved = e.clone();
    reserved.reserve_resource(t(0), base, a).expect("reserves");
    assert_ne!(hash(&reserved), waiting, "a reservation");
    // The same request order reached through another history hashes alike.
    let mut again: E = Engine::new(1);
    let base2 = again.declare_resource("base", 1, None).expect("declared");
    let root2 = again.root();
    let a2 = again
        .spawn(
            t(3),
            Spawn::new(root2, NodeKind::Command, "a", 1).using(base2, 1),
        )
        .expect("spawn a");
    let _ = again
        .spawn(
            t(3),
            Spawn::new(root2, NodeKind::Command, "b", 1).using(base2, 1),
        )
        .expect("spawn b");
    assert_eq!(started(&mut again), vec![a2]);
    assert_eq!(hash(&again), waiting);
}
