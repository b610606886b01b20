//! A deterministic driver for the engine without async: scripted actions on virtual time.
//!
//! Each action is a [`Body`]: a closure called when the node starts, with the engine (to spawn
//! children, add constraints, terminate nodes) and the node, returning when and how the action
//! ends. Monitor bodies, exception handlers, retries and wiretaps are [`Factory`]s, called once per
//! use. [`Sim::run`] then plays the agenda: it starts actions, finishes them at their time, fires
//! timers, and collects the trace, through the same [`Driver`] steps as the tokio shell in `tcm`. Used by this crate's tests, property tests and benchmarks; the
//! tokio shell in `tcm` does the same with real async actions.

use crate::driver::{Driver, Shell};
use crate::{Engine, Failure, Job, NodeId, Purpose, Time, WatchOutcome, WatchToken};
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

/// An end the simulator will report: a job's result (or a handler's bypass) at its time.
enum Finish {
    Done(Job, Result<(), Failure>),
    Bypass(NodeId),
    Stopped(NodeId),
}

/// Called for each watch notification, with the engine, so a "waiting" body can continue.
pub type NotifyHook = Box<dyn FnMut(&mut SimEngine, WatchToken, &WatchOutcome, Time)>;

/// The driver.
pub struct Sim {
    /// The engine under test.
    pub engine: SimEngine,
    shell: SimShell,
}

/// The simulator's side of the [`Driver`]: scripted actions, their ends on virtual time, the trace.
struct SimShell {
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
            shell: SimShell {
                now: Time::ZERO,
                pending: BTreeMap::new(),
                by_node: BTreeMap::new(),
                seq: 0,
                trace: Vec::new(),
                notes: Vec::new(),
                keep_trace: true,
                on_notify: None,
            },
        }
    }

    /// Drops trace records instead of keeping them (for runs of millions of nodes).
    pub fn without_trace(mut self) -> Sim {
        self.shell.keep_trace = false;
        self.engine.set_tracing(false);
        self
    }

    /// Calls `hook` on every watch notification (the continuation of a waiting body).
    pub fn on_notify(
        mut self,
        hook: impl FnMut(&mut SimEngine, WatchToken, &WatchOutcome, Time) + 'static,
    ) -> Sim {
        self.shell.on_notify = Some(Box::new(hook));
        self
    }

    /// The current virtual time.
    pub fn now(&self) -> Time {
        self.shell.now
    }

    /// The trace so far.
    pub fn trace(&self) -> &[TraceEvent] {
        &self.shell.trace
    }

    /// Watch notifications received so far.
    pub fn notes(&self) -> &[(WatchToken, WatchOutcome)] {
        &self.shell.notes
    }

    /// Runs until nothing is left to do, virtual time passes `limit`, or the run is paused.
    /// Returns the end time.
    pub fn run_until(&mut self, limit: Time) -> Time {
        let sh = &mut self.shell;
        loop {
            let next = Driver::turn(&mut self.engine, sh, sh.now);
            if next.paused {
                // On virtual time a paused run's clock stops (docs/semantics.md, "Steering a
                // run"): the caller steps or resumes it, then runs on.
                return sh.now;
            }
            let next_end = sh.pending.keys().next().map(|k| k.0);
            let Some(at) = [next_end, next.deadline].into_iter().flatten().min() else {
                return sh.now;
            };
            if at > limit {
                sh.now = limit;
                return sh.now;
            }
            sh.now = at;
            if next_end != Some(at) {
                continue; // A timer: the next turn fires it.
            }
            let Some((_, finish)) = sh.pending.pop_first() else {
                continue;
            };
            // The node may have been terminated meanwhile; the engine ignores the end then.
            let _ = match finish {
                Finish::Done(job, res) => {
                    sh.by_node.remove(&job.node());
                    self.engine.handle_action_finished(sh.now, job, res)
                }
                Finish::Stopped(node) => {
                    sh.by_node.remove(&node);
                    self.engine.handle_action_stopped(sh.now, node);
                    Ok(())
                }
                Finish::Bypass(node) => {
                    sh.by_node.remove(&node);
                    let _ = self.engine.request_bypass(sh.now, node);
                    self.engine.handle_action_finished(sh.now, node, Ok(()))
                }
            };
        }
    }

    /// Runs until nothing is left to do.
    pub fn run(&mut self) -> Time {
        self.run_until(Time::NEVER)
    }
}

impl SimShell {
    fn schedule(&mut self, d: Duration, finish: Finish, job: Job) {
        let key = (self.now + d, self.seq);
        self.seq += 1;
        self.pending.insert(key, finish);
        if job.cancellable() {
            self.by_node.insert(job.node(), key);
        }
    }

    fn outcome(&mut self, job: Job, outcome: Outcome) {
        match outcome {
            Outcome::Never => {}
            Outcome::After(d, res) => self.schedule(d, Finish::Done(job, res), job),
            // A wiretap check cannot bypass: it passes.
            Outcome::Bypass(_) if !job.cancellable() => {
                self.schedule(Duration::ZERO, Finish::Done(job, Ok(())), job)
            }
            Outcome::Bypass(d) => self.schedule(d, Finish::Bypass(job.node()), job),
        }
    }
}

impl Shell<Body, Factory> for SimShell {
    fn start(&mut self, engine: &mut SimEngine, node: NodeId, action: Body) {
        let outcome = (action.0)(engine, node, self.now);
        self.outcome(Job::from(node), outcome);
    }

    fn invoke(
        &mut self,
        engine: &mut SimEngine,
        job: Job,
        body: Factory,
        purpose: std::sync::Arc<Purpose>,
    ) {
        let outcome = (body.0)(engine, job.node(), self.now, &purpose);
        self.outcome(job, outcome);
    }

    /// The action stops at once; the stop is reported at the same time.
    fn cancel(&mut self, node: NodeId) {
        if let Some(key) = self.by_node.remove(&node) {
            self.pending.remove(&key);
        }
        self.schedule(Duration::ZERO, Finish::Stopped(node), Job::from(node));
    }

    fn notify(&mut self, engine: &mut SimEngine, token: WatchToken, outcome: WatchOutcome) {
        if let Some(hook) = self.on_notify.as_mut() {
            hook(engine, token, &outcome, self.now);
        }
        if self.keep_trace {
            self.notes.push((token, outcome));
        }
    }

    fn trace(&mut self, record: TraceEvent) {
        if self.keep_trace {
            self.trace.push(record);
        }
    }
}
