//! The driver: the one loop that carries the engine's outputs out and feeds its inputs back, shared
//! by every shell (the tokio runtime in `tcm`, the simulator in [`crate::sim`]).
//!
//! A shell implements [`Shell`]: how it starts an action, runs an invocation, cancels, answers a
//! watcher and keeps a trace record. It then calls the driver's steps, in this order, each turn:
//!
//! 1. [`Driver::time`]: the clock moved to `now`; every timer due by then fires.
//! 2. [`Driver::effects`]: every queued [`Effect`] is handed to the shell, in order. A shell that
//!    runs an action at once (the simulator) may call the engine from inside; what that queues is
//!    carried out in the same step.
//! 3. [`Driver::trace`]: every trace record is handed to the shell.
//! 4. [`Driver::next`]: what the shell waits for before the next turn ([`Next`]): the next
//!    deadline, whether the engine is idle (then a run whose task has not ended is stuck), and
//!    whether it is settled (only running actions can change it).
//!
//! [`Driver::turn`] runs the four steps. An input (an action finished, an external event) goes to
//! the engine's `handle_*` methods between turns, with the time of the same clock the shell gives
//! to step 1: one source of time per shell.

use crate::engine::{Effect, Engine, Job, Purpose, WatchOutcome};
use crate::ids::{NodeId, WatchToken};
use crate::time::Time;
use tcm_trace::TraceEvent;

/// What a shell does with the engine's outputs. `A` is its action type, `F` its factory type.
pub trait Shell<A, F> {
    /// Runs a node's action; its end goes to [`Engine::handle_action_finished`] with `node`.
    fn start(&mut self, engine: &mut Engine<A, F>, node: NodeId, action: A);
    /// Runs a factory for `job` (a monitor activation, a handler, a retry, a wiretap check); its
    /// end goes to [`Engine::handle_action_finished`] with `job`.
    fn invoke(
        &mut self,
        engine: &mut Engine<A, F>,
        job: Job,
        body: F,
        purpose: std::sync::Arc<Purpose>,
    );
    /// Stops a running action; report to [`Engine::handle_action_stopped`] once it stopped.
    fn cancel(&mut self, node: NodeId);
    /// A watched point was reached.
    fn notify(&mut self, engine: &mut Engine<A, F>, token: WatchToken, outcome: WatchOutcome);
    /// A fault stands for `node`'s action and succeeds with `value`: keep it as the node's value
    /// (the default drops it).
    fn value(&mut self, node: NodeId, value: crate::FaultValue) {
        let _ = (node, value);
    }
    /// Keeps one trace record (the default drops it).
    fn trace(&mut self, record: TraceEvent) {
        let _ = record;
    }
}

/// What the shell waits for after a turn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[must_use]
pub struct Next {
    /// The earliest pending timer: call [`Driver::time`] (or [`Driver::turn`]) then.
    pub deadline: Option<Time>,
    /// Nothing can happen without a new input (no action runs, no timer is pending).
    pub idle: bool,
    /// Only the running actions (or a new input) can change anything: nothing is ready and no timer
    /// is pending ([`Engine::is_settled`]). A shell whose running actions all await the engine
    /// itself is stuck then (docs/semantics.md, "Run outcome").
    pub settled: bool,
    /// The run is paused ([`Engine::is_paused`]): it is settled, but not stuck; it waits for
    /// whoever steers it.
    pub paused: bool,
}

/// The driver's steps (see the module documentation).
pub struct Driver;

impl Driver {
    /// Step 1: the time is `now`; fires every timer due by then.
    pub fn time<A, F: Clone>(engine: &mut Engine<A, F>, now: Time) {
        engine.handle_timeout(now);
    }

    /// Step 2: hands every queued effect to the shell.
    pub fn effects<A, F: Clone>(engine: &mut Engine<A, F>, shell: &mut impl Shell<A, F>) {
        while let Some(effect) = engine.poll_effect() {
            Driver::effect(engine, shell, effect);
        }
    }

    /// Hands one effect, already polled, to the shell (what step 2 does with each).
    #[inline]
    pub fn effect<A, F: Clone>(
        engine: &mut Engine<A, F>,
        shell: &mut impl Shell<A, F>,
        effect: Effect<A, F>,
    ) {
        match effect {
            Effect::Start { node, action } => shell.start(engine, node, action),
            Effect::Invoke { job, body, purpose } => shell.invoke(engine, job, body, purpose),
            Effect::Cancel { node } => shell.cancel(node),
            Effect::Notify { token, outcome } => shell.notify(engine, token, *outcome),
            Effect::Value { node, value } => shell.value(node, *value),
        }
    }

    /// Step 3: hands every trace record to the shell.
    pub fn trace<A, F: Clone>(engine: &mut Engine<A, F>, shell: &mut impl Shell<A, F>) {
        while let Some(record) = engine.poll_trace() {
            shell.trace(record);
        }
    }

    /// Step 4: what to wait for.
    pub fn next<A, F: Clone>(engine: &mut Engine<A, F>) -> Next {
        let settled = engine.is_settled();
        Next {
            deadline: engine.poll_timeout(),
            idle: settled && engine.stats().running == 0,
            settled,
            paused: engine.is_paused(),
        }
    }

    /// One turn: the four steps in order.
    pub fn turn<A, F: Clone>(
        engine: &mut Engine<A, F>,
        shell: &mut impl Shell<A, F>,
        now: Time,
    ) -> Next {
        Driver::time(engine, now);
        Driver::effects(engine, shell);
        Driver::trace(engine, shell);
        Driver::next(engine)
    }
}
