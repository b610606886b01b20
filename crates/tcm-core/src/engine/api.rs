//! The engine's API types: what goes in ([`Spawn`], [`Job`]), what comes out ([`Effect`],
//! [`WatchOutcome`], [`Stats`]) and what misuse returns ([`EngineError`]).

use super::exception::HandlerSpec;
use super::monitor::MonitorSpec;
use super::node::{OnTerminate, Purpose};
use super::resource::Uses;
use crate::constraint::{Constraint, Constraints};
use crate::failure::Failure;
use crate::ids::{NodeId, WatchToken, WiretapId};
use crate::{Name, NodeKind};
use std::sync::Arc;
use tcm_trace::Facet;

/// An output of the engine for the shell to carry out.
#[derive(Clone, Debug)]
pub enum Effect<A, F = ()> {
    /// Run this node's action. Report its end with [`Engine::handle_action_finished`].
    Start {
        /// The node.
        node: NodeId,
        /// Its action, handed over once.
        action: A,
    },
    /// Run a factory (a monitor activation, an exception handler, a retry, a wiretap check).
    /// Report its end with [`Engine::handle_action_finished`], giving back `job`.
    Invoke {
        /// What to report the end of; `job.node()` is the node it runs for.
        job: Job,
        /// The factory, given at spawn or registration.
        body: F,
        /// Why it runs, with what it needs to know (shared: effects stay small, and the shell
        /// keeps it for the invocation's whole run without copying it).
        purpose: Arc<Purpose>,
    },
    /// Stop this node's running action, then report that it stopped: to
    /// [`Engine::handle_action_stopped`] (or, if it ended first, to
    /// [`Engine::handle_action_finished`]). Until then it counts as running and its node, already
    /// terminating, is not terminated.
    Cancel {
        /// The node.
        node: NodeId,
    },
    /// A fault stands for this node's action and succeeds with `value` (docs/semantics.md,
    /// "Steering a run", rule 4): keep it as the node's value, for whoever waits for it. Comes
    /// before the node's completion is notified.
    Value {
        /// The node.
        node: NodeId,
        /// What stands for its action's value (boxed: effects are queued by the thousand, and
        /// this one is rare).
        value: Box<super::FaultValue>,
    },
    /// A watched point was reached (see [`Engine::watch`]).
    Notify {
        /// The token given to `watch`.
        token: WatchToken,
        /// How the node got there (boxed: a failure is large, and effects are queued by the
        /// thousand when a goal releases its children).
        outcome: Box<WatchOutcome>,
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
    /// Its action failed with this failure, and a retry of it, `by` (the last of a chain of
    /// retries), succeeded: the node's outcome is `by`'s, its value `by`'s value.
    Recovered {
        /// The first run's failure.
        failure: Failure,
        /// The retry that succeeded.
        by: NodeId,
    },
    /// It was terminated (the point was passed without the work being done).
    Terminated,
    /// It was skipped: its `skip if` condition held when its turn came, and it completed without
    /// running (docs/semantics.md, "State and conditions").
    Skipped,
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
    /// The name of the task it is an instance of, when it differs from its instance name (`None`:
    /// the same). Wiretaps and handlers attached to a task match it (docs/semantics.md,
    /// "Wiretaps").
    pub task: Option<Name>,
    /// Its action (`None` for a monitor, which runs its body per activation).
    pub action: Option<A>,
    /// Constraints applied before insertion (terminate forms right after it).
    pub constraints: Constraints,
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
    /// The resources it uses, granted before it starts (docs/semantics.md, "Resources").
    pub uses: Option<Box<Uses>>,
    /// The version of the program that defines its task, when the program was loaded under one
    /// (a serving executive's content hash): its `spawned` record names it.
    pub version: Option<std::sync::Arc<str>>,
    /// The arguments its task was given, as text (`name = value, …`), for its `spawned` record;
    /// a shell describes them only when the engine traces (`Engine::traces`).
    pub args: Option<Box<str>>,
}

impl<A, F: Clone> Spawn<A, F> {
    /// A node with no constraints.
    pub fn new(parent: NodeId, kind: NodeKind, name: impl Into<Name>, action: A) -> Spawn<A, F> {
        Spawn {
            parent,
            kind,
            name: name.into(),
            task: None,
            action: Some(action),
            constraints: Constraints::new(),
            persistent: false,
            on_terminate: Vec::new(),
            fulfils: None,
            monitor: None,
            handlers: Vec::new(),
            retry: None,
            uses: None,
            version: None,
            args: None,
        }
    }

    /// A monitor node.
    pub fn monitor(parent: NodeId, name: impl Into<Name>, spec: MonitorSpec<F>) -> Spawn<A, F> {
        Spawn {
            parent,
            kind: NodeKind::Monitor,
            name: name.into(),
            task: None,
            action: None,
            constraints: Constraints::new(),
            persistent: false,
            on_terminate: Vec::new(),
            fulfils: None,
            monitor: Some(Box::new(spec)),
            handlers: Vec::new(),
            retry: None,
            uses: None,
            version: None,
            args: None,
        }
    }

    /// Adds a constraint.
    pub fn with(mut self, c: Constraint) -> Spawn<A, F> {
        self.constraints.push(c);
        self
    }

    /// Uses `amount` of `resource` (docs/semantics.md, "Resources").
    pub fn using(mut self, resource: crate::ResourceId, amount: u32) -> Spawn<A, F> {
        self.uses
            .get_or_insert_with(Box::default)
            .amounts
            .push((resource, amount));
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
    /// The node is not held for approval (docs/semantics.md, "Steering a run").
    #[error("{0} is not held for approval")]
    NotHeld(NodeId),
    /// No live node has this display number (an operation given again by a replay).
    #[error("no live node is numbered {0}")]
    NoNodeNumbered(u64),
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
    /// `Engine::trigger_group` asked to enable a facet.
    #[error(
        "an enablement constraint on a group is given to each member at the spawn (it waits for every one); \
         a group trigger only terminates or activates"
    )]
    GroupEnable,
    /// `expand first` and `delay expansion` together can never be satisfied.
    #[error("`expand first` and `delay expansion` on one node can never both hold")]
    Inconsistent,
    /// `action_finished` for a node whose action is not running.
    #[error("{0} has no running action")]
    NotRunning(NodeId),
    /// A monitor operation on a node that is not a monitor (or a monitor spawned without its body).
    #[error("node {{{0}}} is not a monitor (a monitor is spawned with its body and parameters)")]
    NotAMonitor(u64),
    /// An activation trigger with data on something that carries none of its own
    /// ([`Engine::activate_when`]).
    #[error("{0}")]
    ActivationData(&'static str),
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
    /// A resource of this name was already declared.
    #[error("resource `{0}` is already declared")]
    DuplicateResource(String),
    /// A resource needs a capacity of at least 1.
    #[error("resource `{0}` needs a capacity of at least 1")]
    ZeroCapacity(String),
    /// A spawn uses none of a resource.
    #[error("a spawn uses 0 of resource `{0}`: an amount is at least 1")]
    ZeroAmount(String),
    /// The resource handle belongs to another run (or to no resource).
    #[error("the resource belongs to another run than this one ({run})")]
    ForeignResource {
        /// This engine's run.
        run: u32,
    },
    /// No resource is declared under this name.
    #[error("no resource `{0}` is declared")]
    UnknownResource(String),
    /// No state variable is declared under this name.
    #[error("no state variable `{0}` is declared")]
    UnknownState(String),
    /// A state variable declared again with another type.
    #[error("state variable `{var}` is declared as `{was}`, not `{now}`")]
    StateRedeclared {
        /// The variable.
        var: String,
        /// Its type.
        was: tcm_expr::Type,
        /// The type asked for now.
        now: tcm_expr::Type,
    },
    /// A value of the wrong type for a state variable.
    #[error("state variable `{0}`: {1}")]
    StateType(String, tcm_expr::TypeMismatch),
    /// A condition that cannot be evaluated (a type error, an undeclared variable).
    #[error("condition `{condition}`: {error}")]
    BadCondition {
        /// The condition, as TDL writes it.
        condition: String,
        /// What is wrong.
        error: tcm_expr::ExprError,
    },
    /// A condition that is not a `bool`.
    #[error("condition `{condition}` is a `{ty}`, not a `bool`")]
    NotACondition {
        /// The condition.
        condition: String,
        /// Its type.
        ty: tcm_expr::Type,
    },
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
    /// Nodes that failed so far (each `failed` record), handled or not.
    pub failures: u64,
    /// Warnings so far (each `warning` record, traced or not).
    pub warnings: u64,
}

/// A piece of work the shell runs for the engine: a node's action or invocation, or one wiretap
/// check on a node. The shell hands it back, unopened, when the work ends
/// ([`Engine::handle_action_finished`]); the engine alone decides what the end means.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Job {
    node: NodeId,
    tap: Option<WiretapId>,
}

impl Job {
    /// A wiretap check on `node`.
    pub(crate) fn check(node: NodeId, tap: WiretapId) -> Job {
        Job {
            node,
            tap: Some(tap),
        }
    }

    /// The node the work runs for.
    pub fn node(&self) -> NodeId {
        self.node
    }

    /// The wiretap, for a wiretap check.
    pub fn tap(&self) -> Option<WiretapId> {
        self.tap
    }

    /// Whether it is stopped with its node ([`Effect::Cancel`]): a wiretap check is not, it runs
    /// to its end.
    pub fn cancellable(&self) -> bool {
        self.tap.is_none()
    }
}

impl From<NodeId> for Job {
    /// A node's own action or invocation.
    fn from(node: NodeId) -> Job {
        Job { node, tap: None }
    }
}
