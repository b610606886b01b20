//! A deterministic driver for the engine without async: scripted actions on virtual time.
//!
//! Each action is a [`Body`]: a closure called when the node starts, with the engine (to spawn
//! children, add constraints, terminate nodes) and the node, returning when and how the action
//! ends. [`Sim::run`] then plays the agenda: it starts actions, finishes them at their time, fires
//! timers, and collects the trace. Used by this crate's tests, property tests and benchmarks; the
//! tokio shell in `tcm` does the same with real async actions.

use crate::{Effect, Engine, Failure, NodeId, Time, WatchOutcome, WatchToken};
use std::collections::BTreeMap;
use std::time::Duration;
use tcm_trace::TraceEvent;

/// How a scripted action ends.
pub enum Outcome {
    /// It ends after this long, with this result.
    After(Duration, Result<(), Failure>),
    /// It never ends by itself (only termination stops it).
    Never,
}

impl Outcome {
    /// Succeeds at once.
    pub fn done() -> Outcome {
        Outcome::After(Duration::ZERO, Ok(()))
    }

    /// Succeeds after `d`.
    pub fn after(d: Duration) -> Outcome {
        Outcome::After(d, Ok(()))
    }
}

/// The closure of a scripted action.
type BodyFn = dyn FnOnce(&mut Engine<Body>, NodeId, Time) -> Outcome;

/// A scripted action.
pub struct Body(Box<BodyFn>);

/// Wraps a closure as a [`Body`].
pub fn body(f: impl FnOnce(&mut Engine<Body>, NodeId, Time) -> Outcome + 'static) -> Body {
    Body(Box::new(f))
}

/// An action that succeeds after `d`.
pub fn takes(d: Duration) -> Body {
    body(move |_, _, _| Outcome::after(d))
}

/// An action that succeeds at once.
pub fn noop() -> Body {
    body(|_, _, _| Outcome::done())
}

/// The driver.
pub struct Sim {
    /// The engine under test.
    pub engine: Engine<Body>,
    now: Time,
    pending: BTreeMap<(Time, u64), (NodeId, Result<(), Failure>)>,
    by_node: BTreeMap<NodeId, (Time, u64)>,
    seq: u64,
    trace: Vec<TraceEvent>,
    notes: Vec<(WatchToken, WatchOutcome)>,
    keep_trace: bool,
    on_notify: Option<NotifyHook>,
}

/// Called for each watch notification, with the engine, so a "waiting" body can continue.
pub type NotifyHook = Box<dyn FnMut(&mut Engine<Body>, WatchToken, &WatchOutcome, Time)>;

impl Default for Sim {
    fn default() -> Self {
        Sim::new()
    }
}

impl Sim {
    /// A new run (number 1) at time zero.
    pub fn new() -> Sim {
        Sim {
            engine: Engine::new(1),
            now: Time::ZERO,
            pending: BTreeMap::new(),
            by_node: BTreeMap::new(),
            seq: 0,
            trace: Vec::new(),
            notes: Vec::new(),
            keep_trace: true,
            on_notify: None,
        }
    }

    /// Drops trace records instead of keeping them (for runs of millions of nodes).
    pub fn without_trace(mut self) -> Sim {
        self.keep_trace = false;
        self.engine.set_tracing(false);
        self
    }

    /// Calls `hook` on every watch notification (the continuation of a waiting body).
    pub fn on_notify(
        mut self,
        hook: impl FnMut(&mut Engine<Body>, WatchToken, &WatchOutcome, Time) + 'static,
    ) -> Sim {
        self.on_notify = Some(Box::new(hook));
        self
    }

    /// The current virtual time.
    pub fn now(&self) -> Time {
        self.now
    }

    /// The trace so far.
    pub fn trace(&self) -> &[TraceEvent] {
        &self.trace
    }

    /// Watch notifications received so far.
    pub fn notes(&self) -> &[(WatchToken, WatchOutcome)] {
        &self.notes
    }

    fn drain(&mut self) {
        while let Some(first) = self.engine.poll_effect() {
            // A node may be started and terminated in one settle: then it must not run at all.
            let mut batch = vec![first];
            while let Some(e) = self.engine.poll_effect() {
                batch.push(e);
            }
            let cancelled: Vec<NodeId> = batch
                .iter()
                .filter_map(|e| match e {
                    Effect::Cancel { node } => Some(*node),
                    _ => None,
                })
                .collect();
            for effect in batch {
                self.apply(effect, &cancelled);
            }
        }
        if self.keep_trace {
            while let Some(ev) = self.engine.poll_trace() {
                self.trace.push(ev);
            }
        }
    }

    fn apply(&mut self, effect: Effect<Body>, cancelled: &[NodeId]) {
        {
            match effect {
                Effect::Start { node, .. } if cancelled.contains(&node) => {}
                Effect::Start { node, action } => {
                    match (action.0)(&mut self.engine, node, self.now) {
                        Outcome::After(d, res) => {
                            let key = (self.now + d, self.seq);
                            self.seq += 1;
                            self.pending.insert(key, (node, res));
                            self.by_node.insert(node, key);
                        }
                        Outcome::Never => {}
                    }
                }
                Effect::Cancel { node } => {
                    if let Some(key) = self.by_node.remove(&node) {
                        self.pending.remove(&key);
                    }
                }
                Effect::Notify { token, outcome } => {
                    if let Some(hook) = self.on_notify.as_mut() {
                        hook(&mut self.engine, token, &outcome, self.now);
                    }
                    if self.keep_trace {
                        self.notes.push((token, outcome));
                    }
                }
            }
        }
    }

    /// Runs until nothing is left to do or virtual time passes `limit`. Returns the end time.
    pub fn run_until(&mut self, limit: Time) -> Time {
        loop {
            self.drain();
            let next_action = self.pending.keys().next().map(|k| k.0);
            let next_timer = self.engine.poll_timeout();
            let next = match (next_action, next_timer) {
                (Some(a), Some(t)) => a.min(t),
                (Some(a), None) => a,
                (None, Some(t)) => t,
                (None, None) => return self.now,
            };
            if next > limit {
                self.now = limit;
                return self.now;
            }
            self.now = next;
            if next_action == Some(next) {
                if let Some(((_, _), (node, res))) = self.pending.pop_first() {
                    self.by_node.remove(&node);
                    // The node may have been terminated meanwhile; the engine ignores it then.
                    let _ = self.engine.action_finished(self.now, node, res);
                }
            } else {
                self.engine.handle_timeout(self.now);
            }
        }
    }

    /// Runs until nothing is left to do.
    pub fn run(&mut self) -> Time {
        self.run_until(Time::NEVER)
    }
}
