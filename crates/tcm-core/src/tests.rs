//! Story tests of the engine on virtual time, driven by [`crate::sim::Sim`].
//!
//! A test builds a small tree with scripted actions and hands it to [`check`], in the spirit of
//! rust-analyzer's `check(fixture, expect)`: `check` runs the tree to its end, passes the trace
//! through the trace checker ([`tcm_trace::check`]) and compares its whole story
//! ([`tcm_trace::story::story`]: one line per transition, `<seconds> <name> <what>`) with the
//! expected one. What a story does not show (handler choices, errors, the engine afterwards) is
//! asserted on the [`Run`] that `check` and [`run`] return.
//!
//! By subject:
//! - `constraints`: ordering (sequential, serial, disable … until, expand first, cycles);
//! - `triggers`: the one trigger concept, every "when" with every "then";
//! - `conditions`: state variables and every trigger on a condition (enable, terminate, activate,
//!   on change of, skip, invariant, pause);
//! - `termination`: terminate constraints, cascades, on-terminate tasks, suspension;
//! - `references`: reservations, forward and dead references, `previous`, held children;
//! - `resources`: capacity, priority, all or nothing, reserve, lock, pending limit, denial, release, wait cycles;
//! - `monitors`, `monitor_limits` (limits changed after the spawn) and `exceptions` (handlers, retry, wiretaps, unhandled failures);
//! - `inputs`: the inputs recorded for a journal;
//! - `steering`: pausing, stepping, breakpoints, faults and approvals;
//! - `api`: the engine's inputs, outputs and errors without the simulator, and memory.

mod api;
mod canon;
mod conditions;
mod constraints;
mod exceptions;
mod inputs;
mod monitor_limits;
mod monitors;
mod references;
mod resources;
mod steering;
mod tcm_semantics;
mod termination;
mod triggers;

use crate::sim::{Body, Factory, Outcome, Sim, SimEngine, body, factory};
use crate::*;
use std::time::Duration;
use tcm_trace::TraceEvent;
use tcm_trace::story::story;

/// `secs` seconds.
fn s(secs: f64) -> Duration {
    Duration::from_secs_f64(secs)
}

/// `sequential execution previous`.
const AFTER_PREVIOUS: Constraint = Constraint::Sequential(Facet::Execution, NodeRef::Previous);

/// `disable handling for secs`: the node starts `secs` from now at the earliest.
fn not_before(secs: f64) -> Constraint {
    Constraint::disable(Facet::Handling, When::In(s(secs)))
}

/// `terminate in secs`.
fn stop_in(secs: f64) -> Constraint {
    Constraint::terminate(When::In(s(secs)))
}

/// An action that never ends by itself (only termination stops it).
fn never() -> Body {
    body(|_, _, _| Outcome::Never)
}

/// A goal's action: spawns its children with `f` (whatever it returns), then ends after `secs`.
fn spawns<R>(secs: f64, f: impl FnOnce(&mut SimEngine, NodeId, Time) -> R + 'static) -> Body {
    body(move |e, me, now| {
        f(e, me, now);
        Outcome::after(s(secs))
    })
}

/// A factory that ends at once (a monitor body or handler that does nothing).
fn idle() -> Factory {
    factory(|_, _, _, _| Outcome::done())
}

/// A monitor: `body` per activation, at most `max_activations`, polling every `period` seconds.
fn monitor_spec(
    body: Factory,
    max_activations: Option<u32>,
    period: Option<f64>,
) -> MonitorSpec<Factory> {
    let mut spec = MonitorSpec::new(body);
    spec.max_activations = max_activations;
    spec.period = period.map(s);
    spec
}

/// Spawns `spec` with the constraints `cs` at the engine's current time.
fn spawn_with(e: &mut SimEngine, mut spec: Spawn<Body, Factory>, cs: &[Constraint]) -> NodeId {
    spec.constraints.extend_from_slice(cs);
    let now = e.now();
    e.spawn(now, spec).expect("spawn")
}

/// Spawns a command under `up`.
fn cmd(e: &mut SimEngine, up: NodeId, name: &'static str, b: Body, cs: &[Constraint]) -> NodeId {
    spawn_with(e, Spawn::new(up, NodeKind::Command, name, b), cs)
}

/// Spawns a goal under `up`.
fn goal(e: &mut SimEngine, up: NodeId, name: &'static str, b: Body, cs: &[Constraint]) -> NodeId {
    spawn_with(e, Spawn::new(up, NodeKind::Goal, name, b), cs)
}

/// A scenario run to its end: the simulator afterwards, and the story of its checked trace.
struct Run {
    sim: Sim,
    story: Vec<String>,
}

impl Run {
    /// The trace.
    fn trace(&self) -> &[TraceEvent] {
        self.sim.trace()
    }
}

/// Builds a tree with `setup` (given the engine and its root) on a new simulator, runs it until
/// nothing is left to do, and passes the trace through the trace checker.
#[track_caller]
fn run(setup: impl FnOnce(&mut SimEngine, NodeId)) -> Run {
    let mut sim = Sim::new();
    let root = sim.engine.root();
    setup(&mut sim.engine, root);
    sim.run();
    assert_checked(sim.trace());
    let story = story(sim.trace());
    Run { sim, story }
}

/// The story helper: [`run`]s `setup`, then compares the whole story with `expect`.
#[track_caller]
fn check(setup: impl FnOnce(&mut SimEngine, NodeId), expect: &str) -> Run {
    let r = run(setup);
    assert_story(&r.story, expect);
    r
}

/// Compares story lines with `expect`, one line per line (indentation and blank lines ignored).
/// On a difference, prints the actual story ready to paste.
#[track_caller]
fn assert_story(lines: &[String], expect: &str) {
    let expected: Vec<&str> = expect
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect();
    if lines
        .iter()
        .map(String::as_str)
        .eq(expected.iter().copied())
    {
        return;
    }
    let at = lines
        .iter()
        .zip(&expected)
        .position(|(a, b)| a != b)
        .unwrap_or(lines.len().min(expected.len()));
    panic!(
        "the story differs from line {} on: expected {:?}, got {:?}\n\nexpected:\n{}\n\nactual:\n{}\n",
        at + 1,
        expected.get(at),
        lines.get(at),
        expected.join("\n"),
        lines.join("\n"),
    );
}

/// Asserts the trace passes the trace checker, which looked at something.
#[track_caller]
fn assert_checked(trace: &[TraceEvent]) {
    match tcm_trace::check(trace) {
        Ok(r) => assert!(r.n_transitions > 0, "the trace checker saw no transition"),
        Err(v) => {
            let v: Vec<String> = v.iter().map(ToString::to_string).collect();
            panic!(
                "trace checker:\n{}\nstory:\n{}",
                v.join("\n"),
                story(trace).join("\n")
            );
        }
    }
}
