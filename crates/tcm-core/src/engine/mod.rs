//! The engine: a sans-IO state machine that owns the task tree, the constraints and the agenda.
//!
//! # Protocol
//!
//! The shell calls `handle_*`-style input methods (`spawn`, `action_finished`, `terminate`,
//! `raise`, `handle_timeout`, …), each with the current virtual time, then drains the outputs:
//! [`Engine::poll_effect`] (start or cancel an action, notify a watcher), [`Engine::poll_trace`]
//! (trace records) and [`Engine::poll_timeout`] (the next timer deadline). Every input settles the
//! engine completely before it returns: all signals it caused are delivered, every node that became
//! ready is started, so the outputs are complete.
//!
//! # How one event flows
//!
//! 1. An input changes a node (an action returned: its handling completes).
//! 2. The change is a *transition*; it is traced and fires the node's *waiters*, registered by the
//!    constraints that name that point ("disable B's execution until A's execution completed").
//! 3. Fired waiters decrement the target's blocking count, or arm a timer, or terminate the target,
//!    and queue a *check* of the target. Completions queue a check of the parent.
//! 4. A check moves a node as far as its constraints allow: facets become enabled, complete, the node
//!    terminates or is reclaimed. A node whose handling becomes enabled joins the ready queue.
//! 5. When no checks are pending, the oldest ready node starts: its action becomes a
//!    [`Effect::Start`]. Starting fires "active" waiters, so the loop repeats until all is quiet.
//!
//! Work is queued, never recursive, so a 10,000-deep tree costs no stack.
//! Aggregates (open children per facet) are counters kept on each parent: a transition costs O(1)
//! plus the waiters it fires.

/// Traces a record, building it only when someone reads the trace (records carry names and
/// messages; building and dropping them would cost every transition when tracing is off).
macro_rules! emit {
    ($engine:expr, $kind:expr $(,)?) => {
        if $engine.tracing {
            let kind = $kind;
            $engine.push_trace(kind);
        }
    };
}

mod exception;
mod monitor;
pub(crate) mod node;
mod report;
mod timers;

use crate::arena::{Arena, Fate, Lookup};
use crate::constraint::{Constraint, Event, NodeRef, TerminateWhen, Until};
use crate::failure::{Failure, FailurePolicy, FatalFailure};
use crate::ids::{ExternalId, NodeId, WatchToken};
use crate::time::Time;
use crate::{Name, NodeKind};
pub use exception::HandlerSpec;
use exception::{HandlerEntry, Wiretap};
use monitor::Monitor;
pub use monitor::{EachActivation, MonitorSpec};
use node::{Link, Node, Payload, WaitKind, Waiter, Waiters};
pub use node::{OnTerminate, Purpose};
pub use report::{Blocked, NodeInfo};
use std::collections::{BTreeMap, VecDeque};
use std::time::Duration;
use tcm_trace::{
    Facet, Point, State, TRACE_FORMAT_VERSION, Termination, TraceConstraint, TraceEvent,
    TraceEventRef, TraceKind,
};
use timers::{TimerKind, Timers};

/// An output of the engine for the shell to carry out.
#[derive(Debug)]
pub enum Effect<A, F = ()> {
    /// Run this node's action.
    Start {
        /// The node.
        node: NodeId,
        /// Its action, handed over once.
        action: A,
    },
    /// Run a factory for `node` (a monitor activation, an exception handler, a retry, a wiretap
    /// check). Report the end with `action_finished` (or, for a wiretap, `tap_finished`).
    Invoke {
        /// The node it runs for.
        node: NodeId,
        /// The factory, given at spawn or registration.
        body: F,
        /// Why it runs, with what it needs to know (boxed: effects stay small).
        purpose: Box<Purpose>,
    },
    /// Stop this node's running action; the engine already counts it as finished.
    Cancel {
        /// The node.
        node: NodeId,
    },
    /// A watched point was reached (see [`Engine::watch`]).
    Notify {
        /// The token given to `watch`.
        token: WatchToken,
        /// How the node got there.
        outcome: WatchOutcome,
    },
}

/// How a watched node reached the watched point.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum WatchOutcome {
    /// Normally; its action succeeded.
    Reached,
    /// Normally, but its own action failed with this failure and no handler took it.
    Failed(Failure),
    /// Its action failed with this failure and a handler took it; the handler's subtree is done.
    Handled(Failure),
    /// It was terminated (the point was passed without the work being done).
    Terminated,
    /// It was a reservation that was never spawned.
    Dead,
}

/// A request to insert a node (see [`Engine::spawn`]).
pub struct Spawn<A, F = ()> {
    /// Where to insert it.
    pub parent: NodeId,
    /// Its kind.
    pub kind: NodeKind,
    /// Its instance name.
    pub name: Name,
    /// Its action (`None` for a monitor, which runs its body per activation).
    pub action: Option<A>,
    /// Constraints applied before insertion (terminate forms right after it).
    pub constraints: Vec<Constraint>,
    /// Keep the node after completion (not reclaimed).
    pub persistent: bool,
    /// Cleanup tasks run if the node is terminated while its action runs.
    pub on_terminate: Vec<OnTerminate<A>>,
    /// A reservation (from [`Engine::reserve`]) this spawn fulfils.
    pub fulfils: Option<NodeId>,
    /// For a monitor: its body and parameters.
    pub monitor: Option<Box<MonitorSpec<F>>>,
    /// Exception handlers attached to the node, in the order they are tried.
    pub handlers: Vec<HandlerSpec<F>>,
    /// A factory that re-runs this task (same arguments), so handlers can retry it.
    pub retry: Option<F>,
}

impl<A, F: Clone> Spawn<A, F> {
    /// A node with no constraints.
    pub fn new(parent: NodeId, kind: NodeKind, name: impl Into<Name>, action: A) -> Spawn<A, F> {
        Spawn {
            parent,
            kind,
            name: name.into(),
            action: Some(action),
            constraints: Vec::new(),
            persistent: false,
            on_terminate: Vec::new(),
            fulfils: None,
            monitor: None,
            handlers: Vec::new(),
            retry: None,
        }
    }

    /// A monitor node.
    pub fn monitor(parent: NodeId, name: impl Into<Name>, spec: MonitorSpec<F>) -> Spawn<A, F> {
        Spawn {
            parent,
            kind: NodeKind::Monitor,
            name: name.into(),
            action: None,
            constraints: Vec::new(),
            persistent: false,
            on_terminate: Vec::new(),
            fulfils: None,
            monitor: Some(Box::new(spec)),
            handlers: Vec::new(),
            retry: None,
        }
    }

    /// Adds a constraint.
    pub fn with(mut self, c: Constraint) -> Spawn<A, F> {
        self.constraints.push(c);
        self
    }
}

/// Misuse of the engine API. A failing action is not an error: see [`Failure`].
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum EngineError {
    /// The handle belongs to another run.
    #[error("{node} belongs to run {}, not to this run ({run}); handles cannot cross runs", node.run())]
    ForeignNode {
        /// The handle.
        node: NodeId,
        /// This engine's run.
        run: u32,
    },
    /// The handle names a node that no longer exists.
    #[error("{0} no longer exists (it completed or was terminated and was reclaimed)")]
    Gone(NodeId),
    /// The root cannot be terminated, suspended, or constrained.
    #[error("the root node cannot be {0}")]
    Root(&'static str),
    /// A child cannot be added under a node whose execution already completed.
    #[error("cannot spawn under {name} {{{node}}}: its execution already completed")]
    ParentCompleted {
        /// Display number of the parent.
        node: u64,
        /// Its name.
        name: String,
    },
    /// `fulfils` names no open reservation of this parent.
    #[error("{0} is not an open reservation of this parent")]
    NotReserved(NodeId),
    /// A constraint can no longer apply: its facet has started.
    #[error(
        "cannot apply {constraint} to {name} {{{node}}}: its {facet} already left the disabled state"
    )]
    TooLate {
        /// Display number of the node.
        node: u64,
        /// Its name.
        name: String,
        /// The facet.
        facet: Facet,
        /// The constraint, as written.
        constraint: String,
    },
    /// `expand first` and `delay expansion` together can never be satisfied.
    #[error("`expand first` and `delay expansion` on one node can never both hold")]
    Inconsistent,
    /// `action_finished` for a node whose action is not running.
    #[error("{0} has no running action")]
    NotRunning(NodeId),
    /// A monitor operation on a node that is not a monitor (or a monitor spawned without its body).
    #[error("node {{{0}}} is not a monitor (a monitor is spawned with its body and parameters)")]
    NotAMonitor(u64),
    /// Activation of a monitor whose handling is not active.
    #[error("monitor {{{0}}} is not active: it has not started, has completed, or was terminated")]
    InactiveMonitor(u64),
    /// `watch` needs a node handle; `previous`, `this` and `parent` only mean something in a spawn.
    #[error("a watched event must name a node handle, not `previous`, `this` or `parent`")]
    RelativeRef,
    /// Bypass or retry from a node that is not an exception handler.
    #[error("node {{{0}}} is not an exception handler")]
    NotAHandler(u64),
    /// Retry of a task spawned without a retry factory.
    #[error("node {{{0}}} cannot be retried: it was spawned without a retry factory")]
    NotRetryable(u64),
}

#[derive(Clone, Copy, Debug)]
enum Work {
    Check(NodeId),
    Terminate(NodeId),
}

struct External {
    name: String,
    raised: bool,
    waiters: Vec<WaitKind>,
    // Monitors activated on every raise.
    activators: Vec<NodeId>,
}

/// Counters for benchmarks and tests.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Stats {
    /// Nodes in the arena now (including the root and reservations).
    pub live_nodes: usize,
    /// The most nodes ever in the arena at once.
    pub high_water: usize,
    /// Nodes ever created.
    pub created: u64,
    /// Actions running now.
    pub running: u32,
}

/// The deterministic task-tree engine. `A` is the shell's action type; the engine only stores it and
/// hands it back in [`Effect::Start`].
pub struct Engine<A, F = ()> {
    run: u32,
    now: Time,
    nodes: Arena<A, F>,
    root: NodeId,
    next_display: u64,
    seq: u64,
    tracing: bool,
    trace: VecDeque<TraceEvent>,
    work: VecDeque<Work>,
    ready: VecDeque<NodeId>,
    effects: VecDeque<Effect<A, F>>,
    timers: Timers,
    externals: Vec<External>,
    external_ids: BTreeMap<String, ExternalId>,
    running: u32,
    policy: FailurePolicy,
    fatal: Option<FatalFailure>,
    taps: Vec<Wiretap<F>>,
}

impl<A, F: Clone> Engine<A, F> {
    /// A new run with its root node. `run` numbers the run: handles of other runs are refused.
    pub fn new(run: u32) -> Engine<A, F> {
        let mut nodes = Arena::new(run);
        let mut root = Node::new(0, NodeKind::Root, Name::Borrowed("Root Node"), None);
        root.states = [State::Active, State::Active, State::Active];
        let root_id = nodes.insert(root);
        let mut engine = Engine {
            run,
            now: Time::ZERO,
            nodes,
            root: root_id,
            next_display: 1,
            seq: 0,
            tracing: true,
            trace: VecDeque::new(),
            work: VecDeque::new(),
            ready: VecDeque::new(),
            effects: VecDeque::new(),
            timers: Timers::default(),
            externals: Vec::new(),
            external_ids: BTreeMap::new(),
            running: 0,
            policy: FailurePolicy::Warn,
            fatal: None,
            taps: Vec::new(),
        };
        engine.push_trace(TraceKind::RunStarted {
            version: TRACE_FORMAT_VERSION,
            run,
        });
        engine
    }

    /// Turns trace recording on or off (on by default). Off, [`Engine::poll_trace`] yields nothing.
    pub fn set_tracing(&mut self, on: bool) {
        self.tracing = on;
    }

    /// Chooses what an unhandled failure does.
    pub fn set_failure_policy(&mut self, policy: FailurePolicy) {
        self.policy = policy;
    }

    /// The root node: top-level tasks are its children.
    pub fn root(&self) -> NodeId {
        self.root
    }

    /// The current virtual time (the latest given to an input).
    pub fn now(&self) -> Time {
        self.now
    }

    /// The first unhandled failure, under [`FailurePolicy::Fatal`].
    pub fn fatal(&self) -> Option<&FatalFailure> {
        self.fatal.as_ref()
    }

    /// Counters.
    pub fn stats(&self) -> Stats {
        Stats {
            live_nodes: self.nodes.live(),
            high_water: self.nodes.high_water(),
            created: self.next_display - 1,
            running: self.running,
        }
    }

    // ----------------------------------------------------------------------------------------
    // Inputs.

    /// Reserves a node under `parent` for a later spawn, so constraints can name it before it exists
    /// (a forward reference). If the parent's action ends without spawning it, it is *dead*:
    /// enablement constraints on it are void, `terminate at` it fires at once (catalogue §1.6).
    pub fn reserve(
        &mut self,
        now: Time,
        parent: NodeId,
        name: impl Into<Name>,
    ) -> Result<NodeId, EngineError> {
        self.advance(now);
        let pd = self.live(parent)?;
        if pd.state(Facet::Execution) == State::Completed {
            return Err(EngineError::ParentCompleted {
                node: pd.display,
                name: pd.name.to_string(),
            });
        }
        let display = self.next_display();
        let name = name.into();
        let mut node = Node::new(display, NodeKind::Goal, name.clone(), Some(parent));
        node.reserved = true;
        let id = self.nodes.insert(node);
        let parent_display = self.node(parent).display;
        self.node_mut(parent).cold_mut().reservations.push(id);
        emit!(
            self,
            TraceKind::Reserved {
                node: display,
                parent: parent_display,
                name: name.into_owned(),
            }
        );
        Ok(id)
    }

    /// Inserts a node (catalogue §3.3 step 1): applies its constraints, links it under its parent,
    /// and settles. Returns its handle.
    pub fn spawn(&mut self, now: Time, spec: Spawn<A, F>) -> Result<NodeId, EngineError> {
        self.advance(now);
        let Spawn {
            parent,
            kind,
            name,
            action,
            constraints,
            persistent,
            on_terminate,
            fulfils,
            monitor,
            handlers,
            retry,
        } = spec;
        let pd = self.live(parent)?;
        if (kind == NodeKind::Monitor) != monitor.is_some() {
            return Err(EngineError::NotAMonitor(self.next_display));
        }
        if pd.state(Facet::Execution) == State::Completed {
            return Err(EngineError::ParentCompleted {
                node: pd.display,
                name: pd.name.to_string(),
            });
        }
        if constraints.len() >= 2
            && constraints.contains(&Constraint::ExpandFirst)
            && constraints.contains(&Constraint::DelayExpansion)
        {
            return Err(EngineError::Inconsistent);
        }
        let previous = pd.last_spawned;
        for c in &constraints {
            self.validate_refs(c)?;
        }
        let id = match fulfils {
            Some(r) => {
                let ok =
                    matches!(self.nodes.get(r), Some(n) if n.reserved && n.parent == Some(parent));
                if !ok {
                    return Err(EngineError::NotReserved(r));
                }
                self.node_mut(parent)
                    .cold_mut()
                    .reservations
                    .retain(|x| *x != r);
                let node = self.node_mut(r);
                node.reserved = false;
                node.kind = kind;
                node.name = name;
                if !kind.expands() {
                    node.states[Facet::Expansion.index()] = State::Completed;
                }
                r
            }
            None => {
                let display = self.next_display();
                self.nodes
                    .insert(Node::new(display, kind, name, Some(parent)))
            }
        };
        {
            let parent_suspended = self.node(parent).suspended;
            let node = self.node_mut(id);
            node.action = action.map(Payload::Action);
            node.persistent = persistent;
            if !on_terminate.is_empty() {
                node.cold_mut().on_terminate = on_terminate;
            }
            node.suspended = parent_suspended;
            if let Some(m) = monitor {
                node.cold_mut().monitor = Some(Monitor::new(*m));
            }
            if !handlers.is_empty() {
                node.cold_mut().handlers = handlers
                    .into_iter()
                    .map(|spec| HandlerEntry { spec, uses: 0 })
                    .collect();
            }
            if retry.is_some() {
                node.cold_mut().retry = retry;
            }
        }
        self.link(parent, id);
        let display = self.emit_spawned(id, parent);
        if let Some(m) = self.node(id).monitor() {
            let record = TraceKind::MonitorParams {
                node: display,
                max_activations: m.spec.max_activations,
                max_triggers: m.spec.max_triggers,
                period_ns: m
                    .spec
                    .period
                    .map(|p| u64::try_from(p.as_nanos()).unwrap_or(u64::MAX)),
                initial_wait: m.spec.initial_wait,
            };
            emit!(self, record);
        }
        if self.node(id).suspended {
            emit!(self, TraceKind::Suspended { node: display });
        }
        let deferred = self.node_mut(id).take_cold(|c| &mut c.deferred);
        let mut later = Vec::new();
        for (c, prev) in deferred {
            if matches!(c, Constraint::Terminate(_) | Constraint::Activate(_)) {
                later.push((c, prev));
            } else {
                self.apply(id, parent, prev, c);
            }
        }
        for c in constraints {
            if matches!(c, Constraint::Terminate(_) | Constraint::Activate(_)) {
                later.push((c, previous));
            } else {
                self.apply(id, parent, previous, c);
            }
        }
        self.node_mut(parent).last_spawned = Some(id);
        for (c, prev) in later {
            self.apply(id, parent, prev, c);
        }
        if !self.node(parent).alive() && !self.node(id).immune {
            self.work.push_back(Work::Terminate(id));
        }
        self.work.push_back(Work::Check(id));
        self.settle();
        Ok(id)
    }

    /// Applies a constraint to a node that already exists. Termination constraints apply at any time
    /// before the node completes; enablement constraints only while their facet is still disabled.
    pub fn constrain(&mut self, now: Time, node: NodeId, c: Constraint) -> Result<(), EngineError> {
        self.advance(now);
        let n = self.live(node)?;
        if n.kind == NodeKind::Root {
            return Err(EngineError::Root("constrained"));
        }
        self.validate_refs(&c)?;
        if n.reserved {
            // A constraint statement on a task spawned later (a forward reference): kept until the
            // spawn, so it is applied with the spawn's own constraints.
            let parent = n.parent.unwrap_or(self.root);
            let previous = self.nodes.get(parent).and_then(|p| p.last_spawned);
            self.node_mut(node).cold_mut().deferred.push((c, previous));
            return Ok(());
        }
        let gated: &[Facet] = match c {
            Constraint::ExpandFirst => &[Facet::Execution],
            Constraint::DelayExpansion => &[Facet::Expansion],
            Constraint::Sequential(f, _) | Constraint::Disable(f, _) => match f {
                Facet::Handling => &[Facet::Handling],
                Facet::Expansion => &[Facet::Expansion],
                Facet::Execution => &[Facet::Execution],
            },
            Constraint::Serial(_) => &[Facet::Expansion, Facet::Execution],
            Constraint::Parallel | Constraint::Terminate(_) | Constraint::Activate(_) => &[],
        };
        for &f in gated {
            if f == Facet::Expansion && !n.kind.expands() {
                continue; // Void for a node that does not expand (see `apply_disable`).
            }
            if n.state(f) != State::Disabled || n.state(Facet::Handling) != State::Disabled {
                return Err(EngineError::TooLate {
                    node: n.display,
                    name: n.name.to_string(),
                    facet: f,
                    constraint: format!("{c:?}"),
                });
            }
        }
        let parent = n.parent.unwrap_or(self.root);
        let previous = self
            .nodes
            .get(parent)
            .and_then(|p| p.last_spawned)
            .filter(|p| *p != node);
        self.apply(node, parent, previous, c);
        self.work.push_back(Work::Check(node));
        self.settle();
        Ok(())
    }

    /// The node's action returned: its handling completes, with a failure if it failed.
    pub fn action_finished(
        &mut self,
        now: Time,
        node: NodeId,
        result: Result<(), Failure>,
    ) -> Result<(), EngineError> {
        self.advance(now);
        let n = self.nodes.get(node).ok_or(EngineError::Gone(node))?;
        if n.state(Facet::Handling) != State::Active
            || !n.alive()
            || n.monitor().is_some()
            || n.taps_pending() > 0
        {
            // A cancelled action may still report; the engine already finished it.
            if n.state(Facet::Handling) == State::Completed && !n.alive() {
                return Ok(());
            }
            return Err(EngineError::NotRunning(node));
        }
        self.running -= 1;
        match result {
            Err(failure) => {
                self.fail(node, failure);
                self.complete_handling(node);
            }
            Ok(()) => {
                // "After" wiretaps decide whether the node succeeded (`tap_finished`).
                if self.start_taps(node, crate::ids::TapWhen::After) == 0 {
                    self.complete_handling(node);
                }
            }
        }
        self.settle();
        Ok(())
    }

    /// Terminates a node and its subtree (catalogue §3.4).
    pub fn terminate(&mut self, now: Time, node: NodeId) -> Result<(), EngineError> {
        self.advance(now);
        let n = self.live(node)?;
        if n.kind == NodeKind::Root {
            return Err(EngineError::Root("terminated"));
        }
        self.work.push_back(Work::Terminate(node));
        self.settle();
        Ok(())
    }

    /// Terminates every child of `node`.
    pub fn terminate_children(&mut self, now: Time, node: NodeId) -> Result<(), EngineError> {
        self.advance(now);
        self.live(node)?;
        let mut c = self.first_child(node);
        while let Some(child) = c {
            self.work.push_back(Work::Terminate(child));
            c = self.next_sibling(child);
        }
        self.settle();
        Ok(())
    }

    /// Terminates every sibling of `node` (not `node` itself).
    pub fn terminate_siblings(&mut self, now: Time, node: NodeId) -> Result<(), EngineError> {
        self.advance(now);
        let parent = self
            .live(node)?
            .parent
            .ok_or(EngineError::Root("given siblings"))?;
        let mut c = self.first_child(parent);
        while let Some(child) = c {
            if child != node {
                self.work.push_back(Work::Terminate(child));
            }
            c = self.next_sibling(child);
        }
        self.settle();
        Ok(())
    }

    /// Holds (or releases) the start of the children a running action spawns: while held, they are
    /// inserted and constrained but their handling is not enabled. TDL's semantics, where a task's
    /// body always ends before any child it spawned runs (unless it waits), so constraint statements
    /// after a spawn still apply. The hold ends by itself when the action returns.
    /// Returns whether it was holding before.
    pub fn hold_children(
        &mut self,
        now: Time,
        node: NodeId,
        on: bool,
    ) -> Result<bool, EngineError> {
        self.advance(now);
        let n = self.live(node)?;
        if n.kind == NodeKind::Root {
            return Err(EngineError::Root("held"));
        }
        let was = std::mem::replace(&mut self.node_mut(node).holding, on);
        if was && !on {
            self.check_children(node);
            self.settle();
        }
        Ok(was)
    }

    /// Suspends a node and its subtree: no action in it starts until it is unsuspended. Running
    /// actions go on. Children spawned under a suspended node start suspended.
    pub fn suspend(&mut self, now: Time, node: NodeId) -> Result<(), EngineError> {
        self.set_suspended(now, node, true)
    }

    /// Undoes [`Engine::suspend`] for the node and its subtree.
    pub fn unsuspend(&mut self, now: Time, node: NodeId) -> Result<(), EngineError> {
        self.set_suspended(now, node, false)
    }

    /// Interns a named external event (or manual signal gate).
    pub fn external(&mut self, name: &str) -> ExternalId {
        if let Some(id) = self.external_ids.get(name) {
            return *id;
        }
        let id = ExternalId(self.externals.len() as u32);
        self.externals.push(External {
            name: name.to_string(),
            raised: false,
            waiters: Vec::new(),
            activators: Vec::new(),
        });
        self.external_ids.insert(name.to_string(), id);
        id
    }

    /// Raises a named external event. It is latched: constraints applied later find it raised.
    pub fn raise(&mut self, now: Time, event: ExternalId) {
        self.advance(now);
        let Some(ext) = self.externals.get_mut(event.0 as usize) else {
            return;
        };
        let first = !ext.raised;
        ext.raised = true;
        let name = ext.name.clone();
        let waiters = std::mem::take(&mut ext.waiters);
        let activators = ext.activators.clone();
        emit!(self, TraceKind::External { name });
        if first {
            for w in waiters {
                self.fire(w, false);
            }
        }
        for monitor in activators {
            self.activation_due(monitor);
        }
        self.settle();
    }

    /// Asks to be told (by [`Effect::Notify`] with `token`) when `event` happens. If it already
    /// happened, the notification is queued at once.
    pub fn watch(&mut self, now: Time, event: Event, token: WatchToken) -> Result<(), EngineError> {
        self.advance(now);
        let NodeRef::Node(node) = event.node else {
            return Err(EngineError::RelativeRef);
        };
        self.check_run(node)?;
        match self.nodes.lookup(node) {
            Lookup::Gone(fate) => {
                let outcome = match fate {
                    Fate::Completed => WatchOutcome::Reached,
                    Fate::Terminated => WatchOutcome::Terminated,
                    Fate::Dead => WatchOutcome::Dead,
                };
                self.effects.push_back(Effect::Notify { token, outcome });
            }
            Lookup::Live => {
                let waiter = Waiter {
                    facet: event.facet,
                    point: event.point,
                    kind: WaitKind::Watch { token },
                };
                if self.node(node).reached(event.facet, event.point) {
                    self.fire_now(node, waiter.kind);
                } else {
                    self.node_mut(node).waiters.push(waiter);
                }
            }
        }
        self.settle();
        Ok(())
    }

    /// Fires every timer due at or before `now`.
    pub fn handle_timeout(&mut self, now: Time) {
        self.advance(now);
        self.fire_timers(now, true);
    }

    /// Fires the live timers due before `now` (or at `now` too, if `inclusive`), in deadline order,
    /// each at its own time.
    fn fire_timers(&mut self, now: Time, inclusive: bool) {
        loop {
            let nodes = &self.nodes;
            let Some((at, entry)) = self
                .timers
                .pop_due(now, inclusive, |k| timer_is_live(nodes, k))
            else {
                break;
            };
            if at > self.now {
                self.now = at;
            }
            match entry {
                TimerKind::Enable { target, facet } => self.satisfy(target, facet),
                TimerKind::Terminate { target } => self.work.push_back(Work::Terminate(target)),
                TimerKind::Poll { monitor, k } => self.poll(monitor, k),
                TimerKind::ActivateOnce { monitor } => self.activation_due(monitor),
            }
            self.settle();
        }
    }

    // ----------------------------------------------------------------------------------------
    // Outputs.

    /// The next effect to carry out.
    pub fn poll_effect(&mut self) -> Option<Effect<A, F>> {
        self.effects.pop_front()
    }

    /// The next trace record.
    pub fn poll_trace(&mut self) -> Option<TraceEvent> {
        self.trace.pop_front()
    }

    /// Whether trace records wait to be polled.
    pub fn has_trace(&self) -> bool {
        !self.trace.is_empty()
    }

    /// The earliest pending timer that still matters.
    pub fn poll_timeout(&mut self) -> Option<Time> {
        let nodes = &self.nodes;
        self.timers.next_deadline(|k| timer_is_live(nodes, k))
    }

    /// Whether nothing can happen without a new input: no action runs, no timer is pending, nothing
    /// is ready. A run that is idle before its task completed is stuck (see [`Engine::blocked`]).
    pub fn is_idle(&mut self) -> bool {
        self.running == 0
            && self.ready.is_empty()
            && self.work.is_empty()
            && self.poll_timeout().is_none()
    }

    // ----------------------------------------------------------------------------------------
    // Internals: lookups.

    /// Moves the engine's clock to `now`. It never skips a deadline: timers due before `now` fire
    /// first, each at its own time, so an input that arrives late (on real time the shell wakes a
    /// little after a deadline) never overtakes a timer that was due before it.
    fn advance(&mut self, now: Time) {
        self.fire_timers(now, false);
        if now > self.now {
            self.now = now;
        }
    }

    fn next_display(&mut self) -> u64 {
        let d = self.next_display;
        self.next_display += 1;
        d
    }

    fn check_run(&self, id: NodeId) -> Result<(), EngineError> {
        if id.run != self.run {
            return Err(EngineError::ForeignNode {
                node: id,
                run: self.run,
            });
        }
        Ok(())
    }

    fn live(&self, id: NodeId) -> Result<&Node<A, F>, EngineError> {
        self.check_run(id)?;
        self.nodes.get(id).ok_or(EngineError::Gone(id))
    }

    fn validate_refs(&self, c: &Constraint) -> Result<(), EngineError> {
        let ev = match c {
            Constraint::Sequential(_, r) | Constraint::Serial(r) => Some(*r),
            Constraint::Disable(_, Until::Event(e) | Until::ForAfter(_, e)) => Some(e.node),
            Constraint::Terminate(TerminateWhen::Event(e) | TerminateWhen::InAfter(_, e)) => {
                Some(e.node)
            }
            _ => None,
        };
        if let Some(NodeRef::Node(id)) = ev {
            self.check_run(id)?;
        }
        Ok(())
    }

    pub(crate) fn node(&self, id: NodeId) -> &Node<A, F> {
        self.nodes.get(id).expect("engine invariant: node exists")
    }

    fn node_mut(&mut self, id: NodeId) -> &mut Node<A, F> {
        self.nodes
            .get_mut(id)
            .expect("engine invariant: node exists")
    }

    /// Appends a record; use `emit!`, which builds the record only when tracing is on.
    fn push_trace(&mut self, kind: TraceKind) {
        let seq = self.seq;
        self.seq += 1;
        self.trace.push_back(TraceEvent {
            seq,
            t: self.now.as_nanos(),
            kind,
        });
    }

    fn event_ref(&self, node: NodeId, facet: Facet, point: Point) -> TraceEventRef {
        TraceEventRef {
            node: self.nodes.get(node).map_or(0, |n| n.display),
            facet,
            point,
        }
    }

    fn link(&mut self, parent: NodeId, child: NodeId) {
        let last = self.node(parent).last_child;
        {
            let c = self.node_mut(child);
            c.prev_sibling = last;
            c.next_sibling = Link::NONE;
        }
        if let Some(l) = self.nodes.id_at(last) {
            self.node_mut(l).next_sibling = Link::to(child);
        }
        let child_expands = self.node(child).state(Facet::Expansion) != State::Completed;
        let p = self.node_mut(parent);
        if p.first_child == Link::NONE {
            p.first_child = Link::to(child);
        }
        p.last_child = Link::to(child);
        p.live_children += 1;
        p.open_executions += 1;
        if child_expands {
            p.open_expansions += 1;
        }
    }

    /// The first linked child of a live node.
    pub(crate) fn first_child(&self, id: NodeId) -> Option<NodeId> {
        self.nodes
            .get(id)
            .and_then(|n| self.nodes.id_at(n.first_child))
    }

    /// The next linked sibling of a live node.
    pub(crate) fn next_sibling(&self, id: NodeId) -> Option<NodeId> {
        self.nodes
            .get(id)
            .and_then(|n| self.nodes.id_at(n.next_sibling))
    }

    /// Allocates, links and traces a new node under `parent` with the given payload (activations,
    /// handler nodes, retries, on-terminate tasks). The caller queues its check.
    pub(crate) fn insert(
        &mut self,
        parent: NodeId,
        kind: NodeKind,
        name: Name,
        payload: Payload<A, F>,
    ) -> NodeId {
        let display = self.next_display();
        let mut node = Node::new(display, kind, name, Some(parent));
        node.action = Some(payload);
        node.suspended = self.node(parent).suspended;
        let id = self.nodes.insert(node);
        self.link(parent, id);
        self.emit_spawned(id, parent);
        if self.node(id).suspended {
            emit!(self, TraceKind::Suspended { node: display });
        }
        if !self.node(parent).alive() {
            self.work.push_back(Work::Terminate(id));
        }
        id
    }

    /// Traces a node's insertion under `parent`; returns its display number.
    fn emit_spawned(&mut self, id: NodeId, parent: NodeId) -> u64 {
        let (display, kind) = (self.node(id).display, self.node(id).kind);
        let parent = self.node(parent).display;
        // The name is only copied when someone reads the trace.
        let name = if self.tracing {
            self.node(id).name.to_string()
        } else {
            String::new()
        };
        emit!(
            self,
            TraceKind::Spawned {
                node: display,
                parent,
                kind,
                name,
            }
        );
        display
    }

    fn unlink(&mut self, child: NodeId) {
        let (parent, prev, next) = {
            let c = self.node(child);
            (c.parent, c.prev_sibling, c.next_sibling)
        };
        let Some(parent) = parent else { return };
        match self.nodes.id_at(prev) {
            Some(p) => self.node_mut(p).next_sibling = next,
            None => self.node_mut(parent).first_child = next,
        }
        match self.nodes.id_at(next) {
            Some(n) => self.node_mut(n).prev_sibling = prev,
            None => self.node_mut(parent).last_child = prev,
        }
        self.node_mut(parent).live_children -= 1;
    }

    // ----------------------------------------------------------------------------------------
    // Internals: constraints.

    fn resolve(
        &self,
        r: NodeRef,
        this: NodeId,
        parent: NodeId,
        previous: Option<NodeId>,
    ) -> Option<NodeId> {
        match r {
            NodeRef::Node(id) => Some(id),
            NodeRef::Previous => previous,
            NodeRef::This => Some(this),
            NodeRef::Parent => Some(parent),
        }
    }

    /// Traces a constraint that was dropped; the reason is only built when someone reads the trace.
    fn void(&mut self, node: NodeId, reason: impl FnOnce() -> String) {
        if !self.tracing {
            return;
        }
        let display = self.node(node).display;
        emit!(
            self,
            TraceKind::ConstraintVoid {
                node: display,
                reason: reason(),
            }
        );
    }

    /// Applies one constraint to `node` (already in the arena).
    fn apply(&mut self, node: NodeId, parent: NodeId, previous: Option<NodeId>, c: Constraint) {
        let display = self.node(node).display;
        match c {
            Constraint::Parallel => {}
            Constraint::ExpandFirst => {
                self.node_mut(node).expand_first = true;
                emit!(
                    self,
                    TraceKind::Constrained {
                        node: display,
                        constraint: TraceConstraint::ExpandFirst,
                    }
                );
            }
            Constraint::DelayExpansion => {
                self.node_mut(node).delay_expansion = true;
                emit!(
                    self,
                    TraceKind::Constrained {
                        node: display,
                        constraint: TraceConstraint::DelayExpansion,
                    }
                );
            }
            Constraint::Sequential(facet, r) => {
                let point_facet = facet;
                self.apply_disable(
                    node,
                    parent,
                    previous,
                    facet,
                    Until::Event(Event::on(r, point_facet, Point::Completed)),
                );
            }
            Constraint::Serial(r) => {
                let ev = Until::Event(Event::on(r, Facet::Execution, Point::Completed));
                self.apply_disable(node, parent, previous, Facet::Expansion, ev);
                self.apply_disable(node, parent, previous, Facet::Execution, ev);
            }
            Constraint::Disable(facet, until) => {
                self.apply_disable(node, parent, previous, facet, until)
            }
            Constraint::Terminate(when) => self.apply_terminate(node, parent, previous, when),
            Constraint::Activate(when) => self.apply_activate(node, parent, previous, when),
        }
    }

    fn apply_disable(
        &mut self,
        node: NodeId,
        parent: NodeId,
        previous: Option<NodeId>,
        facet: Facet,
        until: Until,
    ) {
        let display = self.node(node).display;
        if facet == Facet::Expansion && !self.node(node).kind.expands() {
            // A command's expansion is complete from the start (paper, footnote 1).
            self.void(node, || {
                format!("{facet} of a node that does not expand is always completed")
            });
            return;
        }
        match until {
            Until::Time(at) => {
                emit!(
                    self,
                    TraceKind::Constrained {
                        node: display,
                        constraint: TraceConstraint::DisableUntilTime {
                            facet,
                            at: at.as_nanos(),
                        },
                    }
                );
                if at > self.now {
                    self.node_mut(node).blocks[facet.index()] += 1;
                    self.timers.push(
                        at,
                        TimerKind::Enable {
                            target: node,
                            facet,
                        },
                    );
                }
            }
            Until::For(d) => {
                self.apply_disable(node, parent, previous, facet, Until::Time(self.now + d))
            }
            Until::External(x) => {
                let Some(ext) = self.externals.get(x.0 as usize) else {
                    self.void(node, || "unknown external event".into());
                    return;
                };
                let (name, raised) = (ext.name.clone(), ext.raised);
                emit!(
                    self,
                    TraceKind::Constrained {
                        node: display,
                        constraint: TraceConstraint::DisableUntilExternal { facet, name },
                    }
                );
                if !raised {
                    self.node_mut(node).blocks[facet.index()] += 1;
                    self.externals[x.0 as usize].waiters.push(WaitKind::Enable {
                        target: node,
                        facet,
                    });
                }
            }
            Until::Event(ev) | Until::ForAfter(_, ev) => {
                let delay = match until {
                    Until::ForAfter(d, _) => Some(d),
                    _ => None,
                };
                let Some(r) = self.resolve(ev.node, node, parent, previous) else {
                    self.void(node, || {
                        format!(
                            "{facet} constraint names `previous`, but nothing was spawned before"
                        )
                    });
                    return;
                };
                let event = self.event_ref(r, ev.facet, ev.point);
                let constraint = match delay {
                    Some(d) => TraceConstraint::DisableForAfter {
                        facet,
                        delay_ns: u64::try_from(d.as_nanos()).unwrap_or(u64::MAX),
                        event,
                    },
                    None => TraceConstraint::DisableUntilEvent { facet, event },
                };
                let passed = match self.nodes.lookup(r) {
                    Lookup::Gone(_) => true,
                    Lookup::Live => self.node(r).reached(ev.facet, ev.point),
                };
                if let Lookup::Gone(_) = self.nodes.lookup(r) {
                    self.void(node, || {
                        "the referenced node is already gone; its events have passed".into()
                    });
                    return;
                }
                emit!(
                    self,
                    TraceKind::Constrained {
                        node: display,
                        constraint,
                    }
                );
                match (passed, delay) {
                    (true, None) => {}
                    (true, Some(d)) => {
                        self.node_mut(node).blocks[facet.index()] += 1;
                        self.timers.push(
                            self.now + d,
                            TimerKind::Enable {
                                target: node,
                                facet,
                            },
                        );
                    }
                    (false, _) => {
                        self.node_mut(node).blocks[facet.index()] += 1;
                        let kind = match delay {
                            Some(delay) => WaitKind::EnableAfter {
                                target: node,
                                facet,
                                delay,
                            },
                            None => WaitKind::Enable {
                                target: node,
                                facet,
                            },
                        };
                        self.node_mut(r).waiters.push(Waiter {
                            facet: ev.facet,
                            point: ev.point,
                            kind,
                        });
                    }
                }
            }
        }
    }

    fn apply_terminate(
        &mut self,
        node: NodeId,
        parent: NodeId,
        previous: Option<NodeId>,
        when: TerminateWhen,
    ) {
        let display = self.node(node).display;
        match when {
            TerminateWhen::Now => {
                emit!(
                    self,
                    TraceKind::Constrained {
                        node: display,
                        constraint: TraceConstraint::TerminateNow,
                    }
                );
                self.work.push_back(Work::Terminate(node));
            }
            TerminateWhen::Time(at) => {
                emit!(
                    self,
                    TraceKind::Constrained {
                        node: display,
                        constraint: TraceConstraint::TerminateAtTime { at: at.as_nanos() },
                    }
                );
                if at <= self.now {
                    self.work.push_back(Work::Terminate(node));
                } else {
                    self.timers.push(at, TimerKind::Terminate { target: node });
                }
            }
            TerminateWhen::In(d) => {
                self.apply_terminate(node, parent, previous, TerminateWhen::Time(self.now + d))
            }
            TerminateWhen::External(x) => {
                let Some(ext) = self.externals.get(x.0 as usize) else {
                    self.void(node, || "unknown external event".into());
                    return;
                };
                let (name, raised) = (ext.name.clone(), ext.raised);
                emit!(
                    self,
                    TraceKind::Constrained {
                        node: display,
                        constraint: TraceConstraint::TerminateAtExternal { name },
                    }
                );
                if raised {
                    self.work.push_back(Work::Terminate(node));
                } else {
                    self.externals[x.0 as usize]
                        .waiters
                        .push(WaitKind::Terminate { target: node });
                }
            }
            TerminateWhen::Event(ev) | TerminateWhen::InAfter(_, ev) => {
                let delay = match when {
                    TerminateWhen::InAfter(d, _) => Some(d),
                    _ => None,
                };
                let Some(r) = self.resolve(ev.node, node, parent, previous) else {
                    self.void(node, || {
                        "terminate constraint names `previous`, but nothing was spawned before"
                            .into()
                    });
                    return;
                };
                let event = self.event_ref(r, ev.facet, ev.point);
                let constraint = match delay {
                    Some(d) => TraceConstraint::TerminateInAfter {
                        delay_ns: u64::try_from(d.as_nanos()).unwrap_or(u64::MAX),
                        event,
                    },
                    None => TraceConstraint::TerminateAtEvent { event },
                };
                match self.nodes.lookup(r) {
                    Lookup::Gone(Fate::Terminated) => {
                        self.void(node, || "the referenced node was terminated; its termination constraints never fire".into());
                    }
                    Lookup::Gone(Fate::Dead) => {
                        emit!(
                            self,
                            TraceKind::Constrained {
                                node: display,
                                constraint,
                            }
                        );
                        self.fire_termination(node, delay);
                    }
                    Lookup::Gone(Fate::Completed) => {
                        emit!(
                            self,
                            TraceKind::Constrained {
                                node: display,
                                constraint,
                            }
                        );
                        self.fire_termination(node, delay);
                    }
                    Lookup::Live => {
                        emit!(
                            self,
                            TraceKind::Constrained {
                                node: display,
                                constraint,
                            }
                        );
                        let rn = self.node(r);
                        if !rn.alive() {
                            // Its points are reached by termination only: the constraint never fires.
                        } else if rn.reached(ev.facet, ev.point) {
                            self.fire_termination(node, delay);
                        } else {
                            let kind = match delay {
                                Some(delay) => WaitKind::TerminateAfter {
                                    target: node,
                                    delay,
                                },
                                None => WaitKind::Terminate { target: node },
                            };
                            self.node_mut(r).waiters.push(Waiter {
                                facet: ev.facet,
                                point: ev.point,
                                kind,
                            });
                        }
                    }
                }
            }
        }
    }

    fn fire_termination(&mut self, target: NodeId, delay: Option<Duration>) {
        match delay {
            None => self.work.push_back(Work::Terminate(target)),
            Some(d) => self
                .timers
                .push(self.now + d, TimerKind::Terminate { target }),
        }
    }

    /// One enablement constraint of `target`'s `facet` is satisfied.
    fn satisfy(&mut self, target: NodeId, facet: Facet) {
        let Some(n) = self.nodes.get_mut(target) else {
            return;
        };
        let b = &mut n.blocks[facet.index()];
        if *b > 0 {
            *b -= 1;
        }
        self.work.push_back(Work::Check(target));
    }

    /// Carries out a waiter whose point was reached. `by_termination`: the watched node reached it
    /// only because it is terminating (termination constraints do not fire then).
    fn fire(&mut self, kind: WaitKind, by_termination: bool) {
        match kind {
            WaitKind::Enable { target, facet } => self.satisfy(target, facet),
            WaitKind::EnableAfter {
                target,
                facet,
                delay,
            } => {
                self.timers
                    .push(self.now + delay, TimerKind::Enable { target, facet });
            }
            WaitKind::Terminate { target } => {
                if !by_termination {
                    self.work.push_back(Work::Terminate(target));
                }
            }
            WaitKind::TerminateAfter { target, delay } => {
                if !by_termination {
                    self.timers
                        .push(self.now + delay, TimerKind::Terminate { target });
                }
            }
            WaitKind::Watch { token } => {
                // Only reached through `fire_now`/`transition`, which supply the outcome.
                let _ = token;
            }
            // Activation constraints fire even on a forced completion (catalogue §3.4).
            WaitKind::Activate { monitor } => self.activation_due(monitor),
            WaitKind::ActivateAfter { monitor, delay } => {
                self.timers
                    .push(self.now + delay, TimerKind::ActivateOnce { monitor });
            }
        }
    }

    /// Fires a waiter of `watched` whose point has been reached.
    fn fire_now(&mut self, watched: NodeId, kind: WaitKind) {
        let n = self.node(watched);
        let terminating = !n.alive();
        if let WaitKind::Watch { token } = kind {
            let outcome = if terminating {
                WatchOutcome::Terminated
            } else if let Some(f) = n.failure() {
                if n.handled() {
                    WatchOutcome::Handled(f.clone())
                } else {
                    WatchOutcome::Failed(f.clone())
                }
            } else {
                WatchOutcome::Reached
            };
            self.effects.push_back(Effect::Notify { token, outcome });
        } else {
            self.fire(kind, terminating);
        }
    }

    // ----------------------------------------------------------------------------------------
    // Internals: transitions.

    /// Moves `facet` of `id` to `to`, traces it and fires the waiters whose point is now reached.
    fn transition(&mut self, id: NodeId, facet: Facet, to: State) {
        let n = self.node_mut(id);
        let from = n.states[facet.index()];
        debug_assert!(from < to, "facets only move forward");
        n.states[facet.index()] = to;
        let display = n.display;
        // Usually none or one fires: `Waiters` keeps one inline, so no allocation.
        let fired = if n.waiters.is_empty() {
            Waiters::None
        } else {
            let mut fired = Waiters::None;
            n.waiters.retain(|w| {
                if w.facet == facet && w.point.state() <= to {
                    fired.push(*w);
                    false
                } else {
                    true
                }
            });
            fired
        };
        emit!(
            self,
            TraceKind::Transition {
                node: display,
                facet,
                from,
                to,
            }
        );
        if !fired.is_empty() {
            for w in fired {
                self.fire_now(id, w.kind);
            }
        }
    }

    fn parent_allows(&self, n: &Node<A, F>, facet: Facet) -> bool {
        match n.parent {
            None => true,
            Some(p) => self
                .nodes
                .get(p)
                .is_none_or(|p| p.state(facet) >= State::Enabled),
        }
    }

    fn check_children(&mut self, id: NodeId) {
        let mut c = self.first_child(id);
        while let Some(child) = c {
            self.work.push_back(Work::Check(child));
            c = self.next_sibling(child);
        }
    }

    /// Moves a node as far as its constraints allow (see the module documentation).
    fn check(&mut self, id: NodeId) {
        loop {
            let Some(n) = self.nodes.get(id) else { return };
            if n.reserved || n.kind == NodeKind::Root {
                return;
            }
            let alive = n.alive();
            let h = n.state(Facet::Handling);
            let x = n.state(Facet::Expansion);
            let e = n.state(Facet::Execution);
            // Children of a holding action are not enabled at all until it releases them (only
            // looked up while something is left to enable).
            let can_enable = alive
                && (h == State::Disabled || x == State::Disabled || e == State::Disabled)
                && !n
                    .parent
                    .and_then(|p| self.nodes.get(p))
                    .is_some_and(|p| p.holding && p.state(Facet::Handling) == State::Active);
            if can_enable
                && x == State::Disabled
                && n.blocks[Facet::Expansion.index()] == 0
                && self.parent_allows(n, Facet::Expansion)
                && (!n.delay_expansion || e >= State::Enabled)
            {
                self.transition(id, Facet::Expansion, State::Enabled);
                self.check_children(id);
                continue;
            }
            if can_enable
                && e == State::Disabled
                && n.blocks[Facet::Execution.index()] == 0
                && self.parent_allows(n, Facet::Execution)
                && (!n.expand_first || x == State::Completed)
            {
                self.transition(id, Facet::Execution, State::Enabled);
                self.check_children(id);
                continue;
            }
            let gate = if n.kind.expands() { x } else { e };
            if can_enable
                && h == State::Disabled
                && n.blocks[Facet::Handling.index()] == 0
                && gate >= State::Enabled
            {
                self.transition(id, Facet::Handling, State::Enabled);
                self.ready.push_back(id);
                continue;
            }
            if x != State::Completed
                && h == State::Completed
                && n.open_expansions == 0
                && (x >= State::Enabled || !alive)
            {
                self.transition(id, Facet::Expansion, State::Completed);
                if let Some(p) = self.node(id).parent {
                    if let Some(p) = self.nodes.get_mut(p) {
                        p.open_expansions -= 1;
                    }
                    self.work.push_back(Work::Check(p));
                }
                continue;
            }
            if e != State::Completed
                && h == State::Completed
                && x == State::Completed
                && n.open_executions == 0
                && (e >= State::Enabled || !alive)
            {
                self.transition(id, Facet::Execution, State::Completed);
                if let Some(p) = self.node(id).parent {
                    if let Some(p) = self.nodes.get_mut(p) {
                        p.open_executions -= 1;
                    }
                    self.work.push_back(Work::Check(p));
                }
                continue;
            }
            if n.termination == Termination::Terminating
                && e == State::Completed
                && n.open_executions == 0
                && n.terminating_children == 0
            {
                self.node_mut(id).termination = Termination::Terminated;
                let display = self.node(id).display;
                emit!(self, TraceKind::Terminated { node: display });
                if let Some(p) = self.node(id).parent {
                    if let Some(pn) = self.nodes.get_mut(p) {
                        pn.terminating_children -= 1;
                    }
                    self.work.push_back(Work::Check(p));
                }
                continue;
            }
            if e == State::Completed
                && n.termination != Termination::Terminating
                && n.live_children == 0
                && !n.persistent
            {
                self.reclaim(id);
            }
            return;
        }
    }

    fn reclaim(&mut self, id: NodeId) {
        let fate = if self.node(id).termination == Termination::Terminated {
            Fate::Terminated
        } else {
            Fate::Completed
        };
        let parent = self.node(id).parent;
        self.unlink(id);
        let display = self.node(id).display;
        self.nodes.discard(id, fate);
        emit!(self, TraceKind::Reclaimed { node: display });
        if let Some(p) = parent {
            self.work.push_back(Work::Check(p));
        }
    }

    fn start(&mut self, id: NodeId) {
        let Some(n) = self.nodes.get_mut(id) else {
            return;
        };
        if n.state(Facet::Handling) != State::Enabled || !n.alive() {
            return;
        }
        if n.suspended {
            n.parked = true;
            return;
        }
        let is_monitor = n.monitor().is_some();
        let tapped = n.tapped_before();
        if !is_monitor && !tapped && !self.taps.is_empty() {
            n.cold_mut().tapped_before = true;
            if self.start_taps(id, crate::ids::TapWhen::Before) > 0 {
                // Stays enabled until its checks report (`tap_finished`).
                return;
            }
        }
        let Some(n) = self.nodes.get_mut(id) else {
            return;
        };
        let payload = n.action.take();
        if payload.is_none() && !is_monitor {
            return;
        }
        let expands = n.kind.expands();
        if !is_monitor {
            self.running += 1;
        }
        self.transition(id, Facet::Handling, State::Active);
        // Figure 3: the expansion (goals) or execution (commands) of the node and of every ancestor
        // is active once some node of the right kind in the subtree is active.
        let facet = if expands {
            Facet::Expansion
        } else {
            Facet::Execution
        };
        let mut cur = Some(id);
        while let Some(c) = cur {
            let n = self.node(c);
            if n.kind == NodeKind::Root || n.state(facet) != State::Enabled {
                break;
            }
            let parent = n.parent;
            self.transition(c, facet, State::Active);
            cur = parent;
        }
        match payload {
            Some(Payload::Action(action)) => {
                self.effects.push_back(Effect::Start { node: id, action })
            }
            Some(Payload::Invoke(body, purpose)) => {
                self.effects.push_back(Effect::Invoke {
                    node: id,
                    body,
                    purpose,
                });
            }
            None => self.monitor_started(id),
        }
    }

    fn complete_handling(&mut self, id: NodeId) {
        self.transition(id, Facet::Handling, State::Completed);
        if std::mem::replace(&mut self.node_mut(id).holding, false) {
            self.check_children(id);
        }
        self.bury_reservations(id);
        self.work.push_back(Work::Check(id));
    }

    /// The body of `id` ended: reservations it never spawned are dead (catalogue §1.6).
    fn bury_reservations(&mut self, id: NodeId) {
        let reservations = self.node_mut(id).take_cold(|c| &mut c.reservations);
        for r in reservations {
            let Some(node) = self.nodes.remove(r, Fate::Dead) else {
                continue;
            };
            emit!(self, TraceKind::Dead { node: node.display });
            for w in node.waiters {
                match w.kind {
                    WaitKind::Watch { token } => self.effects.push_back(Effect::Notify {
                        token,
                        outcome: WatchOutcome::Dead,
                    }),
                    // A dead event fires termination at once and drops the `after` part's event.
                    other => self.fire(other, false),
                }
            }
        }
    }

    /// Instance names from the top-level task down to `id`, joined by `/`.
    pub fn path(&self, id: NodeId) -> String {
        let mut names = Vec::new();
        let mut cur = Some(id);
        while let Some(c) = cur {
            let Some(n) = self.nodes.get(c) else { break };
            if n.kind == NodeKind::Root {
                break;
            }
            names.push(n.name.to_string());
            cur = n.parent;
        }
        names.reverse();
        names.join("/")
    }

    /// Terminates `id` and its subtree (catalogue §3.4, numbered as there):
    /// 1. each alive node goes Terminating (a node with delayed termination, an on-terminate task,
    ///    is skipped, so it runs to completion);
    /// 2. its termination waiters are dropped (they never fire), it is unsuspended;
    /// 3. a running action is cancelled and its on-terminate tasks inserted as children; an action
    ///    not yet started never starts; either way the handling completes at once;
    /// 4. its reservations are dead; its children are terminated the same way;
    /// 5. checks then complete expansion and execution bottom-up, so constraints waiting on these
    ///    nodes are released, and each node is Terminated once its children are.
    fn do_terminate(&mut self, id: NodeId) {
        let Some(n) = self.nodes.get(id) else { return };
        // The root never terminates; an on-terminate task runs to completion whatever happens.
        if n.kind == NodeKind::Root || n.immune {
            return;
        }
        let display = n.display;
        if !n.alive() {
            emit!(
                self,
                TraceKind::Warning {
                    node: Some(display),
                    message: format!(
                        "Trying to terminate already dead node {} {{{}}}",
                        n.name, display
                    ),
                }
            );
            return;
        }
        if n.state(Facet::Execution) == State::Completed {
            return;
        }
        let mut queue = VecDeque::from([id]);
        while let Some(c) = queue.pop_front() {
            let Some(n) = self.nodes.get_mut(c) else {
                continue;
            };
            if !n.alive() || (c != id && n.immune) || n.state(Facet::Execution) == State::Completed
            {
                continue;
            }
            n.termination = Termination::Terminating;
            n.waiters.retain(|w| !w.kind.is_termination());
            let was_suspended = std::mem::replace(&mut n.suspended, false);
            n.parked = false;
            let h = n.state(Facet::Handling);
            let display = n.display;
            let parent = n.parent;
            if let Some(p) = parent.and_then(|p| self.nodes.get_mut(p)) {
                p.terminating_children += 1;
            }
            emit!(self, TraceKind::Terminating { node: display });
            if was_suspended {
                emit!(self, TraceKind::Unsuspended { node: display });
            }
            let action_running = h == State::Active
                && self.node(c).monitor().is_none()
                && self.node(c).taps_pending() == 0;
            if h == State::Active {
                if action_running {
                    self.running -= 1;
                    self.effects.push_back(Effect::Cancel { node: c });
                }
                let cleanups = self.node_mut(c).take_cold(|c| &mut c.on_terminate);
                for ot in cleanups {
                    self.spawn_cleanup(c, ot);
                }
            }
            if h != State::Completed {
                self.transition(c, Facet::Handling, State::Completed);
                self.bury_reservations(c);
            }
            let mut child = self.first_child(c);
            while let Some(ch) = child {
                queue.push_back(ch);
                child = self.next_sibling(ch);
            }
            self.work.push_back(Work::Check(c));
        }
    }

    fn spawn_cleanup(&mut self, parent: NodeId, ot: OnTerminate<A>) {
        let id = self.insert(parent, ot.kind, ot.name, Payload::Action(ot.action));
        // Delayed termination: the terminating parent does not take it down (see `do_terminate`).
        self.node_mut(id).immune = true;
        self.node_mut(parent).last_spawned = Some(id);
        self.work.push_back(Work::Check(id));
    }

    fn set_suspended(&mut self, now: Time, id: NodeId, on: bool) -> Result<(), EngineError> {
        self.advance(now);
        let n = self.live(id)?;
        if n.kind == NodeKind::Root {
            return Err(EngineError::Root(if on {
                "suspended"
            } else {
                "unsuspended"
            }));
        }
        let mut queue = VecDeque::from([id]);
        while let Some(c) = queue.pop_front() {
            let Some(n) = self.nodes.get_mut(c) else {
                continue;
            };
            if n.suspended != on && n.alive() {
                n.suspended = on;
                let display = n.display;
                let resume = !on && std::mem::replace(&mut n.parked, false);
                emit!(
                    self,
                    if on {
                        TraceKind::Suspended { node: display }
                    } else {
                        TraceKind::Unsuspended { node: display }
                    }
                );
                if resume {
                    self.ready.push_back(c);
                }
            }
            let mut child = self.first_child(c);
            while let Some(ch) = child {
                queue.push_back(ch);
                child = self.next_sibling(ch);
            }
        }
        self.settle();
        Ok(())
    }

    /// Delivers all queued work, then starts ready nodes one at a time, until nothing is left.
    fn settle(&mut self) {
        loop {
            while let Some(w) = self.work.pop_front() {
                match w {
                    Work::Check(id) => self.check(id),
                    Work::Terminate(id) => self.do_terminate(id),
                }
            }
            match self.ready.pop_front() {
                Some(id) => self.start(id),
                None => break,
            }
        }
    }
}

fn timer_is_live<A, F>(nodes: &Arena<A, F>, kind: &TimerKind) -> bool {
    match *kind {
        TimerKind::Enable { target, facet } => nodes
            .get(target)
            .is_some_and(|n| n.alive() && n.state(facet) == State::Disabled),
        TimerKind::Poll { monitor, .. } => nodes
            .get(monitor)
            .is_some_and(|n| n.alive() && n.state(Facet::Handling) == State::Active),
        TimerKind::ActivateOnce { monitor } => nodes
            .get(monitor)
            .is_some_and(|n| n.alive() && n.state(Facet::Handling) != State::Completed),
        TimerKind::Terminate { target } => nodes
            .get(target)
            .is_some_and(|n| n.alive() && n.state(Facet::Execution) != State::Completed),
    }
}
