//! What happened to each node, and when: the part of a [`Replay`] that readers of a whole run
//! (the viewer, the demo's summary, `tdl trace`) read instead of folding the records themselves.
//!
//! Each node has a [`Row`] whose *marks* are the moments (record number and time) at which it was
//! reserved, spawned, each facet reached each point, it began terminating, terminated, was
//! reclaimed, found dead, first failed. The state of a node at a record `s` is then the last point
//! of each facet whose mark is at most `s`: a reader scrubs through a run without replaying it.
//! Beside the rows: every exception raised with what followed ([`ExceptionStory`]), external
//! events, and the reservations and locks of resources ([`Restriction`]).
//!
//! The history is kept only by a replay made with [`Replay::with_history`]; the checker and the
//! text log, which read the tree's state alone, do without it.
//!
//! After each record, [`Replay::changed_rows`] names the rows that record changed, so a reader
//! that follows a run as it goes (the viewer's live page) takes the rows from here, record by
//! record, instead of folding the records again.
//!
//! Only the point a transition reaches is marked (a facet that skips a point leaves its mark
//! unset); [`ReplayNode::reached_at`](super::ReplayNode::reached_at) gives the skipped points too.

use super::Replay;
use crate::event::{ResourceUse, TraceConstraint, TraceKind};
use crate::state::{Facet, NodeKind, Point, State};
use serde::Serialize;

/// Index of the spawn mark in a row's marks.
pub const M_SPAWNED: usize = 0;
/// Index of the mark where `facet` reached `point`: 1 + 3 × facet + point (enabled 0, active 1,
/// completed 2).
pub fn m_point(facet: Facet, point: Point) -> usize {
    1 + 3 * facet.index() + super::point_index(point)
}
/// Index of the mark where the node began terminating.
pub const M_TERMINATING: usize = 10;
/// Index of the mark where the node was terminated.
pub const M_TERMINATED: usize = 11;
/// Index of the mark where the node was reclaimed.
pub const M_RECLAIMED: usize = 12;
/// Index of the mark where the reserved node was found dead.
pub const M_DEAD: usize = 13;
/// Index of the mark where the node's number was reserved.
pub const M_RESERVED: usize = 14;
/// Index of the mark of the node's first failure.
pub const M_FAILED: usize = 15;
/// Index of the mark where the node was skipped.
pub const M_SKIPPED: usize = 16;
/// Marks per row.
pub const MARKS: usize = 17;

/// A node number further past the last one allocated than this is taken as a damaged trace: its
/// history is not kept (each `reserved` or `spawned` record allocates one number).
pub const NUMBER_SLACK: u64 = 1 << 16;

/// A moment of the run: a record's number and its time.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Mark {
    /// The record's `seq`.
    pub seq: u64,
    /// The record's time, ns.
    pub t: u64,
}

/// One failure of a node.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Failure {
    /// When.
    pub at: Mark,
    /// The exception's type.
    pub exception: String,
    /// For people.
    pub message: String,
}

/// What happened to one node, and when (see the module's documentation).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Row {
    /// Display number.
    pub number: u64,
    /// Parent's number (none for the root, and for a number no record allocated).
    pub parent: Option<u64>,
    /// Kind, once spawned (the root's is `Root`).
    pub kind: Option<NodeKind>,
    /// Name.
    pub name: String,
    /// Children, in spawn (or reservation) order.
    pub children: Vec<u64>,
    /// See the module's documentation.
    pub marks: [Option<Mark>; MARKS],
    /// Constraints applied to it, with when.
    pub constraints: Vec<(Mark, TraceConstraint)>,
    /// Failures, in order.
    pub failures: Vec<Failure>,
    /// Suspensions: from, and until (if resumed).
    pub suspensions: Vec<(Mark, Option<Mark>)>,
    /// A monitor's activations so far.
    pub activations: u32,
    /// A monitor's triggers so far.
    pub triggers: u32,
    /// For an activation: its monitor.
    pub activation_of: Option<u64>,
    /// For a handler node: the node whose failure it handles, and the handler's name.
    pub handles: Option<(u64, String)>,
    /// For a retry: the node it runs again.
    pub retry_of: Option<u64>,
    /// Its request for resources, if it made one: when, and what.
    pub request: Option<(Mark, Vec<ResourceUse>)>,
    /// When the request was granted.
    pub granted: Option<Mark>,
    /// When it gave the resources back.
    pub released: Option<Mark>,
    /// When the request ended without a grant (withdrawn, denied, dropped), and how.
    pub refused: Option<(Mark, &'static str)>,
    /// The agent its action runs on, for a node placed on one (a `placed` record).
    pub agent: Option<String>,
    /// The lines its body wrote to the run's log (`log` records), with when.
    pub logs: Vec<(Mark, String)>,
    /// The arguments its task was given, as its `spawned` record tells them.
    pub args: Option<String>,
}

impl Row {
    fn new(number: u64) -> Row {
        Row {
            number,
            parent: None,
            kind: None,
            name: String::new(),
            children: Vec::new(),
            marks: [None; MARKS],
            constraints: Vec::new(),
            failures: Vec::new(),
            suspensions: Vec::new(),
            activations: 0,
            triggers: 0,
            activation_of: None,
            handles: None,
            retry_of: None,
            agent: None,
            logs: Vec::new(),
            args: None,
            request: None,
            granted: None,
            released: None,
            refused: None,
        }
    }

    /// The root's row: spawned, its three facets enabled and active, at the first record.
    pub(super) fn root() -> Row {
        let mut root = Row::new(0);
        root.kind = Some(NodeKind::Root);
        root.name = "root".to_string();
        let origin = Some(Mark { seq: 0, t: 0 });
        root.marks[M_SPAWNED] = origin;
        for f in Facet::ALL {
            for p in [Point::Enabled, Point::Active] {
                root.marks[m_point(f, p)] = origin;
            }
        }
        root
    }

    /// The point `facet` had reached by record `seq`, if any.
    pub fn point_at(&self, facet: Facet, seq: u64) -> Option<Point> {
        [Point::Completed, Point::Active, Point::Enabled]
            .into_iter()
            .find(|p| self.reached(m_point(facet, *p), seq))
    }

    /// Whether the mark `m` is set at or before record `seq`.
    pub fn reached(&self, m: usize, seq: u64) -> bool {
        self.marks[m].is_some_and(|mark| mark.seq <= seq)
    }

    /// Whether the node is goal-like (its handling belongs to its expansion).
    pub fn goal_like(&self) -> bool {
        matches!(
            self.kind,
            Some(NodeKind::Goal | NodeKind::Handler | NodeKind::Root)
        )
    }

    /// Whether it held a grant of `resource` at record `seq`.
    pub fn holds_at(&self, resource: &str, seq: u64) -> bool {
        self.granted.is_some_and(|g| g.seq <= seq)
            && self.released.is_none_or(|rel| rel.seq > seq)
            && self
                .request
                .as_ref()
                .is_some_and(|(_, us)| us.iter().any(|x| x.resource == resource))
    }
}

/// How one exception went: where it was raised, the handlers chosen in order, bypasses, retries.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct ExceptionStory {
    /// The failing node.
    pub node: u64,
    /// Its path.
    pub path: String,
    /// The exception's type.
    pub exception: String,
    /// For people.
    pub message: String,
    /// When it was raised.
    pub at: Mark,
    /// What happened next, in order.
    pub steps: Vec<Step>,
}

/// One step of an exception's story.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Step {
    /// `chosen`, `bypassed`, `retried`, `unhandled` or `warning`.
    pub what: &'static str,
    /// The node concerned (the handler node, the retry), if any.
    pub node: Option<u64>,
    /// For people: the handler's name, the warning.
    pub detail: String,
    /// When.
    pub at: Mark,
    /// For a handler chosen: the node it was attached to.
    #[serde(skip)]
    pub attached: Option<u64>,
}

/// A reservation (for a holder's subtree) or a lock (against all) of a resource.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Restriction {
    /// The resource.
    pub resource: String,
    /// The node whose subtree may still be granted it; `None` for a lock.
    pub holder: Option<u64>,
    /// When it began.
    pub from: Mark,
    /// When it ended, if it did.
    pub until: Option<Mark>,
}

impl Restriction {
    /// Whether it held at record `seq`.
    pub fn holds_at(&self, seq: u64) -> bool {
        self.from.seq <= seq && self.until.is_none_or(|until| until.seq > seq)
    }
}

/// The run-wide part of the history.
#[derive(Clone, Debug, Default)]
pub(super) struct History {
    // Whether records are recorded here (`Replay::with_history`).
    kept: bool,
    pub(super) rows: Vec<Row>,
    pub(super) externals: Vec<(Mark, String)>,
    // Each state variable's values: its declaration, then every set, with when.
    pub(super) states: Vec<(Mark, String, tcm_expr::Value)>,
    pub(super) exceptions: Vec<ExceptionStory>,
    pub(super) restrictions: Vec<Restriction>,
    // The rows the last record applied changed, by number, each once, in the order first changed.
    pub(super) changed: Vec<u64>,
}

impl History {
    /// A history that records (`kept`), or stays as it is: the root's row alone.
    pub(super) fn new(kept: bool) -> History {
        History {
            kept,
            rows: vec![Row::root()],
            ..History::default()
        }
    }
}

impl Replay {
    /// The rows, indexed by node number (numbers never allocated are empty rows).
    pub fn rows(&self) -> &[Row] {
        &self.history.rows
    }

    /// The row of node `n`, if a record allocated its number (the root's always).
    pub fn row(&self, n: u64) -> Option<&Row> {
        self.history
            .rows
            .get(n as usize)
            .filter(|r| r.number == 0 || r.parent.is_some())
    }

    /// The rows the last record applied changed, by node number, each once, in the order first
    /// changed: exactly the rows that differ from what they were before that record (a number the
    /// record allocated counts from an empty row). Empty after a record that changed no row (an
    /// external event, a warning), after a refused record, and in a replay that keeps no history.
    pub fn changed_rows(&self) -> &[u64] {
        &self.history.changed
    }

    /// Each external event raised, with when.
    pub fn externals(&self) -> &[(Mark, String)] {
        &self.history.externals
    }

    /// Every value of every state variable, in order: its declared value, then each set (also a
    /// set to the value it had), with when.
    pub fn state_values(&self) -> &[(Mark, String, tcm_expr::Value)] {
        &self.history.states
    }

    /// Every exception raised, in order, each with what followed.
    pub fn exceptions(&self) -> &[ExceptionStory] {
        &self.history.exceptions
    }

    /// The reservations and locks of the run, in order.
    pub fn restrictions(&self) -> &[Restriction] {
        &self.history.restrictions
    }

    /// The nodes holding a grant of `resource` at record `seq`, by number.
    pub fn holders_at(&self, resource: &str, seq: u64) -> impl Iterator<Item = u64> + '_ {
        let resource = resource.to_string();
        self.history
            .rows
            .iter()
            .filter(move |r| r.holds_at(&resource, seq))
            .map(|r| r.number)
    }

    /// The names from the root's child down to `n`, joined by `/`.
    pub fn path(&self, n: u64) -> String {
        let rows = &self.history.rows;
        let mut names = Vec::new();
        let mut at = Some(n);
        while let Some(i) = at {
            if i == 0 {
                break;
            }
            match rows.get(i as usize) {
                Some(r) => {
                    names.push(r.name.as_str());
                    at = r.parent;
                }
                None => break,
            }
            if names.len() > rows.len() {
                break;
            }
        }
        names.reverse();
        names.join("/")
    }

    /// `name {n}` for people.
    pub fn label(&self, n: u64) -> String {
        match self.history.rows.get(n as usize) {
            Some(r) if n == 0 => format!("{} {{0}}", r.name),
            Some(r) => format!("{} {{{n}}}", r.name),
            None => format!("{{{n}}}"),
        }
    }

    fn row_mut(&mut self, n: u64) -> Option<&mut Row> {
        let rows = &mut self.history.rows;
        let i = usize::try_from(n).ok()?;
        if i >= rows.len() {
            if n > rows.len() as u64 + NUMBER_SLACK {
                return None;
            }
            let start = rows.len() as u64;
            rows.extend((start..=n).map(Row::new));
        }
        rows.get_mut(i)
    }

    /// Changes node `n`'s row with `f`, which says whether it changed anything; a change is
    /// reported by [`Replay::changed_rows`].
    fn edit(&mut self, n: u64, f: impl FnOnce(&mut Row) -> bool) {
        if self.row_mut(n).is_some_and(f) && !self.history.changed.contains(&n) {
            self.history.changed.push(n);
        }
    }

    fn link(&mut self, node: u64, parent: u64) {
        if self
            .history
            .rows
            .get(node as usize)
            .is_some_and(|r| r.parent == Some(parent))
        {
            return;
        }
        if self.row_mut(parent).is_none() {
            return;
        }
        self.edit(node, |row| assign(&mut row.parent, Some(parent)));
        self.edit(parent, |p| {
            p.children.push(node);
            true
        });
    }

    /// Sets mark `m` of node `n`, unless it is set.
    fn set(&mut self, n: u64, m: usize, at: Mark) {
        self.edit(n, |row| {
            let unset = row.marks[m].is_none();
            if unset {
                row.marks[m] = Some(at);
            }
            unset
        });
    }

    /// Records what an applied record says happened, and when.
    pub(super) fn record_history(&mut self, at: Mark, kind: &TraceKind) {
        use TraceKind as K;
        if !self.history.kept {
            return;
        }
        match kind {
            K::Reserved { node, parent, name } => {
                self.link(*node, *parent);
                self.edit(*node, |row| assign(&mut row.name, name.clone()));
                self.set(*node, M_RESERVED, at);
            }
            K::Spawned {
                node,
                parent,
                kind,
                name,
                args,
                ..
            } => {
                self.link(*node, *parent);
                self.edit(*node, |row| {
                    assign(&mut row.name, name.clone())
                        | assign(&mut row.kind, Some(*kind))
                        | assign(&mut row.args, args.clone())
                });
                self.set(*node, M_SPAWNED, at);
                if !kind.expands() {
                    self.set(*node, m_point(Facet::Expansion, Point::Completed), at);
                }
            }
            K::Constrained { node, constraint } => self.edit(*node, |row| {
                row.constraints.push((at, constraint.clone()));
                true
            }),
            K::Transition {
                node, facet, to, ..
            } => {
                let point = match to {
                    State::Enabled => Some(Point::Enabled),
                    State::Active => Some(Point::Active),
                    State::Completed => Some(Point::Completed),
                    State::Disabled => None,
                };
                if let Some(p) = point {
                    self.set(*node, m_point(*facet, p), at);
                }
            }
            K::Terminating { node } => self.set(*node, M_TERMINATING, at),
            K::Terminated { node } => self.set(*node, M_TERMINATED, at),
            K::Reclaimed { node } => self.set(*node, M_RECLAIMED, at),
            K::Dead { node } => self.set(*node, M_DEAD, at),
            K::Suspended { node } => self.edit(*node, |row| {
                row.suspensions.push((at, None));
                true
            }),
            K::Unsuspended { node } => self.edit(*node, |row| {
                match row.suspensions.iter_mut().rev().find(|s| s.1.is_none()) {
                    Some(open) => {
                        open.1 = Some(at);
                        true
                    }
                    None => false,
                }
            }),
            K::Failed {
                node,
                exception,
                message,
            } => {
                self.set(*node, M_FAILED, at);
                self.edit(*node, |row| {
                    row.failures.push(Failure {
                        at,
                        exception: exception.clone(),
                        message: message.clone(),
                    });
                    true
                });
                let path = self.path(*node);
                self.history.exceptions.push(ExceptionStory {
                    node: *node,
                    path,
                    exception: exception.clone(),
                    message: message.clone(),
                    at,
                    steps: Vec::new(),
                });
            }
            K::External { name } => self.history.externals.push((at, name.clone())),
            K::StateDeclared { var, value, .. } | K::StateSet { var, value } => {
                self.history.states.push((at, var.clone(), value.clone()));
            }
            K::Skipped { node } => self.set(*node, M_SKIPPED, at),
            K::Activated {
                monitor,
                node,
                number,
            } => {
                self.edit(*monitor, |row| assign(&mut row.activations, *number));
                self.edit(*node, |row| assign(&mut row.activation_of, Some(*monitor)));
            }
            K::Triggered { monitor, count } => {
                self.edit(*monitor, |row| assign(&mut row.triggers, *count));
            }
            K::HandlerChosen {
                node,
                failing,
                attached,
                handler,
                ..
            } => {
                self.edit(*node, |row| {
                    assign(&mut row.handles, Some((*failing, handler.clone())))
                });
                let step = Step {
                    what: "chosen",
                    node: Some(*node),
                    detail: handler.clone(),
                    at,
                    attached: Some(*attached),
                };
                self.step_for(*failing, step);
            }
            K::Bypassed { node, exception } => {
                let failing = self
                    .history
                    .rows
                    .get(*node as usize)
                    .and_then(|r| r.handles.as_ref().map(|h| h.0));
                if let Some(failing) = failing {
                    let detail = format!("passed {exception} on");
                    self.step_for(failing, Step::new("bypassed", Some(*node), detail, at));
                }
            }
            K::Retried { node, of } => {
                self.edit(*node, |row| assign(&mut row.retry_of, Some(*of)));
                self.step_for(*of, Step::new("retried", Some(*node), String::new(), at));
            }
            K::Requested { node, uses, .. } => self.edit(*node, |row| {
                assign(&mut row.request, Some((at, uses.clone())))
                    | assign(&mut row.granted, None)
                    | assign(&mut row.released, None)
                    | assign(&mut row.refused, None)
            }),
            K::Granted { node, .. } => self.edit(*node, |row| assign(&mut row.granted, Some(at))),
            K::Released { node, .. } => {
                self.edit(*node, |row| assign(&mut row.released, Some(at)));
            }
            K::Withdrawn { node } => self.refuse(*node, at, "withdrawn"),
            K::Denied { node, .. } => self.refuse(*node, at, "denied"),
            K::Dropped { node, .. } => self.refuse(*node, at, "dropped"),
            K::ResourceReserved { resource, holder } => {
                self.history.restrictions.push(Restriction {
                    resource: resource.clone(),
                    holder: Some(*holder),
                    from: at,
                    until: None,
                });
            }
            K::ResourceLocked { resource } => self.history.restrictions.push(Restriction {
                resource: resource.clone(),
                holder: None,
                from: at,
                until: None,
            }),
            K::ResourceUnreserved { resource } | K::ResourceUnlocked { resource } => {
                let lock = matches!(kind, K::ResourceUnlocked { .. });
                if let Some(r) = self.history.restrictions.iter_mut().rev().find(|r| {
                    &r.resource == resource && r.until.is_none() && r.holder.is_none() == lock
                }) {
                    r.until = Some(at);
                }
            }
            K::Placed { node, agent } => {
                self.edit(*node, |row| assign(&mut row.agent, Some(agent.clone())));
            }
            K::Log { node, message } => {
                self.edit(*node, |row| {
                    row.logs.push((at, message.clone()));
                    true
                });
            }
            K::Warning {
                node: Some(node),
                message,
            } => {
                let what = if message.starts_with("No exception handler found") {
                    "unhandled"
                } else {
                    "warning"
                };
                self.step_for(*node, Step::new(what, None, message.clone(), at));
            }
            // What these records say is in the replayed state, or in the record alone.
            K::RunStarted { .. }
            | K::ConstraintVoid { .. }
            | K::MonitorParams { .. }
            | K::Tapped { .. }
            | K::CallbackSet { .. }
            | K::CallbackRan { .. }
            | K::Resource { .. }
            | K::HandlerAttached { .. }
            | K::HandlerDetached { .. }
            | K::TapAdded { .. }
            | K::TapRemoved { .. }
            | K::Control { .. }
            | K::Paused { .. }
            | K::Resumed { .. }
            | K::Injected { .. }
            | K::Held { .. }
            | K::Approved { .. }
            | K::Warning { node: None, .. } => {}
        }
    }

    fn refuse(&mut self, node: u64, at: Mark, how: &'static str) {
        self.edit(node, |row| assign(&mut row.refused, Some((at, how))));
    }

    /// Adds a step to the last exception raised by `failing`, if it has one.
    fn step_for(&mut self, failing: u64, step: Step) {
        if let Some(story) = self
            .history
            .exceptions
            .iter_mut()
            .rev()
            .find(|s| s.node == failing)
        {
            story.steps.push(step);
        }
    }
}

/// Sets `slot` to `value`; whether that changed it.
fn assign<T: PartialEq>(slot: &mut T, value: T) -> bool {
    let changed = *slot != value;
    if changed {
        *slot = value;
    }
    changed
}

impl Step {
    fn new(what: &'static str, node: Option<u64>, detail: String, at: Mark) -> Step {
        Step {
            what,
            node,
            detail,
            at,
            attached: None,
        }
    }
}

#[cfg(test)]
mod tests;
