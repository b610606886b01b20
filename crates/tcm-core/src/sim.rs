//! A deterministic driver for the engine without async: scripted actions on virtual time.
//!
//! Each action is a [`Body`]: a closure called when the node starts, with the engine (to spawn
//! children, add constraints, terminate nodes) and the node, returning when and how the action
//! ends. Monitor bodies, exception handlers, retries and wiretaps are [`Factory`]s, called once per
//! use. [`Sim::run`] then plays the agenda: it starts actions, finishes them at their time, fires
//! timers, and collects the trace. Used by this crate's tests, property tests and benchmarks; the
//! tokio shell in `tcm` does the same with real async actions.

use crate::{Effect, Engine, Failure, NodeId, Purpose, Time, WatchOutcome, WatchToken, WiretapId};
use std::collections::BTreeMap;
use std::rc::Rc;
use std::time::Duration;
use tcm_trace::TraceEvent;

/// How a scripted action ends.
pub enum Outcome {
    /// It ends after this long, with this result.
    After(Duration, Result<(), Failure>),
    /// A handler passes its exception on after this long.
    Bypass(Duration),
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

    /// Fails after `d` with an exception of type `exception`.
    pub fn fail(d: Duration, exception: &'static str) -> Outcome {
        Outcome::After(d, Err(Failure::new(exception, "scripted failure")))
    }
}

/// The engine as the simulator drives it.
pub type SimEngine = Engine<Body, Factory>;

/// The closure of a scripted action.
type BodyFn = dyn FnOnce(&mut SimEngine, NodeId, Time) -> Outcome;

/// A scripted action.
pub struct Body(Box<BodyFn>);

/// The closure of a factory: called with the node it runs for and why.
type FactoryFn = dyn Fn(&mut SimEngine, NodeId, Time, &Purpose) -> Outcome;

/// A reusable scripted action: a monitor body, a handler, a retry, a wiretap check.
#[derive(Clone)]
pub struct Factory(Rc<FactoryFn>);

impl Factory {
    /// Calls the factory, as the simulator does for an invocation.
    pub fn call(&self, e: &mut SimEngine, node: NodeId, now: Time, purpose: &Purpose) -> Outcome {
        (self.0)(e, node, now, purpose)
    }
}

/// Wraps a closure as a [`Body`].
pub fn body(f: impl FnOnce(&mut SimEngine, NodeId, Time) -> Outcome + 'static) -> Body {
    Body(Box::new(f))
}

/// Wraps a closure as a [`Factory`].
pub fn factory(f: impl Fn(&mut SimEngine, NodeId, Time, &Purpose) -> Outcome + 'static) -> Factory {
    Factory(Rc::new(f))
}

/// An action that succeeds after `d`.
pub fn takes(d: Duration) -> Body {
    body(move |_, _, _| Outcome::after(d))
}

/// An action that succeeds at once.
pub fn noop() -> Body {
    body(|_, _, _| Outcome::done())
}

enum Finish {
    Action(NodeId, Result<(), Failure>),
    Bypass(NodeId),
    Tap(NodeId, WiretapId, Result<(), Failure>),
}

/// Called for each watch notification, with the engine, so a "waiting" body can continue.
pub type NotifyHook = Box<dyn FnMut(&mut SimEngine, WatchToken, &WatchOutcome, Time)>;

/// The driver.
pub struct Sim {
    /// The engine under test.
    pub engine: SimEngine,
    now: Time,
    pending: BTreeMap<(Time, u64), Finish>,
    by_node: BTreeMap<NodeId, (Time, u64)>,
    seq: u64,
    trace: Vec<TraceEvent>,
    notes: Vec<(WatchToken, WatchOutcome)>,
    keep_trace: bool,
    on_notify: Option<NotifyHook>,
}

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
        hook: impl FnMut(&mut SimEngine, WatchToken, &WatchOutcome, Time) + 'static,
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

    fn schedule(&mut self, d: Duration, finish: Finish, cancellable: Option<NodeId>) {
        let key = (self.now + d, self.seq);
        self.seq += 1;
        self.pending.insert(key, finish);
        if let Some(node) = cancellable {
            self.by_node.insert(node, key);
        }
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

    fn apply(&mut self, effect: Effect<Body, Factory>, cancelled: &[NodeId]) {
        match effect {
            Effect::Start { node, .. } | Effect::Invoke { node, .. }
                if cancelled.contains(&node) => {}
            Effect::Start { node, action } => {
                let outcome = (action.0)(&mut self.engine, node, self.now);
                self.outcome(node, outcome, None);
            }
            Effect::Invoke {
                node,
                body,
                purpose,
            } => {
                let outcome = (body.0)(&mut self.engine, node, self.now, &purpose);
                let tap = match *purpose {
                    Purpose::Tap { tap, .. } => Some(tap),
                    _ => None,
                };
                self.outcome(node, outcome, tap);
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

    fn outcome(&mut self, node: NodeId, outcome: Outcome, tap: Option<WiretapId>) {
        match (outcome, tap) {
            (Outcome::Never, _) => {}
            (Outcome::After(d, res), Some(tap)) => {
                self.schedule(d, Finish::Tap(node, tap, res), None);
            }
            (Outcome::Bypass(_), Some(tap)) => {
                self.schedule(Duration::ZERO, Finish::Tap(node, tap, Ok(())), None)
            }
            (Outcome::After(d, res), None) => {
                self.schedule(d, Finish::Action(node, res), Some(node))
            }
            (Outcome::Bypass(d), None) => self.schedule(d, Finish::Bypass(node), Some(node)),
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
                if let Some((_, finish)) = self.pending.pop_first() {
                    // The node may have been terminated meanwhile; the engine ignores it then.
                    let _ = match finish {
                        Finish::Action(node, res) => {
                            self.by_node.remove(&node);
                            self.engine.action_finished(self.now, node, res)
                        }
                        Finish::Bypass(node) => {
                            self.by_node.remove(&node);
                            self.engine.bypass(self.now, node)
                        }
                        Finish::Tap(node, tap, res) => {
                            self.engine.tap_finished(self.now, node, tap, res)
                        }
                    };
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
