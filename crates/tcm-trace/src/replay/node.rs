//! One node of a [`Replay`](super::Replay) as its records rebuilt it: its kind, place, states,
//! constraints, monitor counts, resources and agent, with the aggregates the checker reads.

use super::ROOT_NAME;
use crate::event::{ResourceUse, TraceConstraint};
use crate::state::{Facet, NodeKind, Outcome, Point, State, Termination};

/// One node of a [`Replay`].
#[derive(Clone, Debug)]
pub struct ReplayNode {
    pub(super) number: u64,
    // Invariant: `None` exactly while the node is reserved and not spawned (or dead).
    pub(super) kind: Option<NodeKind>,
    pub(super) name: String,
    pub(super) parent: Option<u64>,
    pub(super) children: Vec<u64>,
    pub(super) facets: [State; 3],
    pub(super) termination: Termination,
    pub(super) suspended: bool,
    pub(super) failed: bool,
    pub(super) skipped: bool,
    pub(super) reclaimed: bool,
    pub(super) reserved: bool,
    pub(super) dead: bool,
    pub(super) constraints: Vec<TraceConstraint>,
    pub(super) spawned_t: Option<u64>,
    pub(super) dead_t: Option<u64>,
    // Time each (facet, point) was first reached; index [facet][point].
    pub(super) reached_t: [[Option<u64>; 3]; 3],
    // Whether the node was no longer alive when it reached (facet, point).
    pub(super) reached_terminating: [[bool; 3]; 3],
    // Aggregates, maintained by `Replay::apply`.
    // Invariant: children whose execution is not completed.
    pub(crate) n_children_exec_open: usize,
    // Invariant: children neither terminated nor execution-completed.
    pub(crate) n_children_unsettled: usize,
    // Invariant: spawned children not yet reclaimed.
    pub(crate) n_children_live: usize,
    // Invariant: children whose subtree still has a goal-like node with handling not completed.
    pub(crate) n_children_goals_open: usize,
    // Invariant: some goal-like node of the subtree has handling >= active.
    pub(crate) goal_started_below: bool,
    // Invariant: some command-like node of the subtree has handling >= active.
    pub(crate) command_started_below: bool,
    pub(super) monitor: Option<MonitorInfo>,
    pub(super) activation_of: Option<u64>,
    pub(super) handler_for: Option<u64>,
    // For a retry: the first run of its task (a `retried` record's `of`, or that node's own first
    // run).
    pub(super) retry_of: Option<u64>,
    // A retry of this failed node completed its execution without failing or being terminated.
    pub(super) recovered: bool,
    // Resources: the request waiting to be granted, the grant held, and whether it ever asked.
    pub(super) request: Option<Vec<ResourceUse>>,
    pub(super) grant: Option<Vec<ResourceUse>>,
    pub(super) requested: bool,
    // The agent its action runs on (a `placed` record), if it runs on one.
    pub(super) agent: Option<String>,
}

/// What the trace says of a monitor: its parameters and counts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MonitorInfo {
    /// Maximum activations, if any.
    pub max_activations: Option<u32>,
    /// Maximum triggers, if any.
    pub max_triggers: Option<u32>,
    /// Polling period (ns), if polling.
    pub period_ns: Option<u64>,
    /// Activations so far.
    pub activations: u32,
    /// Triggers so far.
    pub triggers: u32,
}

pub(super) fn point_index(point: Point) -> usize {
    match point {
        Point::Enabled => 0,
        Point::Active => 1,
        Point::Completed => 2,
    }
}

pub(super) const POINTS: [Point; 3] = [Point::Enabled, Point::Active, Point::Completed];

impl ReplayNode {
    pub(super) fn new(number: u64, name: String, parent: Option<u64>) -> ReplayNode {
        ReplayNode {
            number,
            kind: None,
            name,
            parent,
            children: Vec::new(),
            facets: [State::Disabled; 3],
            termination: Termination::Alive,
            suspended: false,
            failed: false,
            skipped: false,
            reclaimed: false,
            reserved: false,
            dead: false,
            constraints: Vec::new(),
            spawned_t: None,
            dead_t: None,
            reached_t: [[None; 3]; 3],
            reached_terminating: [[false; 3]; 3],
            n_children_exec_open: 0,
            n_children_unsettled: 0,
            n_children_live: 0,
            n_children_goals_open: 0,
            goal_started_below: false,
            command_started_below: false,
            monitor: None,
            activation_of: None,
            handler_for: None,
            retry_of: None,
            recovered: false,
            request: None,
            grant: None,
            requested: false,
            agent: None,
        }
    }

    pub(super) fn root() -> ReplayNode {
        let mut it = ReplayNode::new(0, ROOT_NAME.to_string(), None);
        it.kind = Some(NodeKind::Root);
        it.facets = [State::Active; 3];
        it.spawned_t = Some(0);
        for f in 0..3 {
            it.reached_t[f] = [Some(0), Some(0), None];
        }
        it
    }

    /// Display number.
    pub fn number(&self) -> u64 {
        self.number
    }
    /// Kind, once spawned (`None` while only reserved, or dead).
    pub fn kind(&self) -> Option<NodeKind> {
        self.kind
    }
    /// Instance name (the reservation's name until spawned).
    pub fn name(&self) -> &str {
        &self.name
    }
    /// Parent's display number (`None` for the root).
    pub fn parent(&self) -> Option<u64> {
        self.parent
    }
    /// The agent its action runs on, for a node placed on one (a `placed` record).
    pub fn agent(&self) -> Option<&str> {
        self.agent.as_deref()
    }
    /// Children, in spawn order (reclaimed ones included).
    pub fn children(&self) -> &[u64] {
        &self.children
    }
    /// State of one facet.
    pub fn state(&self, facet: Facet) -> State {
        self.facets[facet.index()]
    }
    /// How the node ended, as far as the records so far tell (meaningful once its execution
    /// completed): terminated if it was asked to terminate, failed if its action failed and no
    /// retry of it ended well, else succeeded.
    pub fn outcome(&self) -> Outcome {
        if self.termination != Termination::Alive {
            Outcome::Terminated
        } else if self.failed && !self.recovered {
            Outcome::Failed
        } else if self.skipped {
            Outcome::Skipped
        } else {
            Outcome::Succeeded
        }
    }

    /// Whether it was skipped (a `skipped` record).
    pub fn is_skipped(&self) -> bool {
        self.skipped
    }

    /// Termination state.
    pub fn termination(&self) -> Termination {
        self.termination
    }
    /// Whether the node is suspended (between `suspended` and `unsuspended`).
    pub fn is_suspended(&self) -> bool {
        self.suspended
    }
    /// For a monitor: its parameters and counts so far.
    pub fn monitor(&self) -> Option<&MonitorInfo> {
        self.monitor.as_ref()
    }
    /// For an activation node: its monitor.
    pub fn activation_of(&self) -> Option<u64> {
        self.activation_of
    }
    /// For a handler node: the node whose failure it handles.
    pub fn handler_for(&self) -> Option<u64> {
        self.handler_for
    }
    /// Whether a `failed` record was seen for the node.
    pub fn is_failed(&self) -> bool {
        self.failed
    }
    /// Whether the node was reclaimed.
    pub fn is_reclaimed(&self) -> bool {
        self.reclaimed
    }
    /// Whether the node is reserved and neither spawned nor dead yet.
    pub fn is_reserved(&self) -> bool {
        self.reserved && self.kind.is_none() && !self.dead
    }
    /// Whether the node was reserved before it was spawned (a forward reference).
    pub fn was_reserved(&self) -> bool {
        self.reserved
    }
    /// Whether the node is spawned (false while reserved, or dead; true for the root).
    pub fn is_spawned(&self) -> bool {
        self.kind.is_some()
    }
    /// Whether the reservation died: the node will never be spawned.
    pub fn is_dead(&self) -> bool {
        self.dead
    }
    /// Constraints applied to the node, in order.
    pub fn constraints(&self) -> &[TraceConstraint] {
        &self.constraints
    }
    /// Time the node was spawned.
    pub fn spawned_at(&self) -> Option<u64> {
        self.spawned_t
    }
    /// Time the reservation was found dead.
    pub fn dead_at(&self) -> Option<u64> {
        self.dead_t
    }
    /// Time `facet` first reached `point` (a facet that skips states reaches the skipped points too).
    pub fn reached_at(&self, facet: Facet, point: Point) -> Option<u64> {
        self.reached_t[facet.index()][point_index(point)]
    }
    /// Whether `facet` reached `point` while the node was terminating or terminated.
    pub fn reached_while_terminating(&self, facet: Facet, point: Point) -> bool {
        self.reached_terminating[facet.index()][point_index(point)]
    }
    /// Its request for resources still waiting to be granted (docs/semantics.md, "Resources").
    pub fn request(&self) -> Option<&[ResourceUse]> {
        self.request.as_deref()
    }
    /// The resources it holds.
    pub fn grant(&self) -> Option<&[ResourceUse]> {
        self.grant.as_deref()
    }
    /// Whether it ever asked for resources (a `requested` record).
    pub fn has_requested(&self) -> bool {
        self.requested
    }
    /// Whether the node is goal-like (its handling belongs to its expansion).
    pub fn expands(&self) -> bool {
        self.kind.is_some_and(NodeKind::expands)
    }

    // Whether every goal-like node of the subtree, reached through goal-like nodes, has completed
    // handling. A command-like node's expansion is complete from the start (paper, footnote 1): the
    // handler goals that may appear under a failing command belong to its execution, not to the
    // expansion of its ancestors.
    pub(crate) fn goals_done(&self) -> bool {
        !self.expands() || (self.facets[0] == State::Completed && self.n_children_goals_open == 0)
    }
}
