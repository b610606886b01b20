//! One task-tree node as the engine stores it.

use crate::failure::Failure;
use crate::ids::{NodeId, WatchToken};
use crate::{Name, NodeKind};
use std::time::Duration;
use tcm_trace::{Facet, Point, State, Termination};

/// What happens when a watched point of a node is reached.
#[derive(Clone, Copy, Debug)]
pub(crate) enum WaitKind {
    /// One enablement constraint of `target`'s facet is satisfied.
    Enable { target: NodeId, facet: Facet },
    /// As `Enable`, `delay` after the point.
    EnableAfter {
        target: NodeId,
        facet: Facet,
        delay: Duration,
    },
    /// Terminate `target`.
    Terminate { target: NodeId },
    /// Terminate `target`, `delay` after the point.
    TerminateAfter { target: NodeId, delay: Duration },
    /// Tell the shell.
    Watch { token: WatchToken },
}

impl WaitKind {
    pub(crate) fn is_termination(&self) -> bool {
        matches!(
            self,
            WaitKind::Terminate { .. } | WaitKind::TerminateAfter { .. }
        )
    }
}

/// A request "when my `facet` reaches `point`, do `kind`" registered on the node it watches.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Waiter {
    pub(crate) facet: Facet,
    pub(crate) point: Point,
    pub(crate) kind: WaitKind,
}

/// A task to insert as a child if the node is terminated while its action runs.
pub struct OnTerminate<A> {
    /// Kind of the cleanup node.
    pub kind: NodeKind,
    /// Its instance name.
    pub name: Name,
    /// Its action.
    pub action: A,
}

pub(crate) struct Node<A> {
    pub(crate) display: u64,
    pub(crate) kind: NodeKind,
    pub(crate) name: Name,
    pub(crate) parent: Option<NodeId>,
    // Children in spawn order, as an intrusive doubly-linked list (O(1) unlink on reclaim).
    pub(crate) first_child: Option<NodeId>,
    pub(crate) last_child: Option<NodeId>,
    pub(crate) prev_sibling: Option<NodeId>,
    pub(crate) next_sibling: Option<NodeId>,
    // The child spawned most recently, for `previous`.
    pub(crate) last_spawned: Option<NodeId>,
    pub(crate) states: [State; 3],
    pub(crate) termination: Termination,
    // Invariant: blocks[f] counts the enablement constraints of facet f not yet satisfied.
    pub(crate) blocks: [u32; 3],
    pub(crate) expand_first: bool,
    pub(crate) delay_expansion: bool,
    pub(crate) suspended: bool,
    // Enabled while suspended: waits in no queue until unsuspended.
    pub(crate) parked: bool,
    pub(crate) persistent: bool,
    // Reserved for a later spawn (forward reference): not linked into the parent yet.
    pub(crate) reserved: bool,
    // Delayed termination (on-terminate nodes): a terminating ancestor does not terminate it.
    pub(crate) immune: bool,
    pub(crate) failure: Option<Box<Failure>>,
    // Invariant: the number of linked children whose expansion is not completed.
    pub(crate) open_expansions: u32,
    // Invariant: the number of linked children whose execution is not completed.
    pub(crate) open_executions: u32,
    // Invariant: the number of linked children that are Terminating (not yet Terminated).
    pub(crate) terminating_children: u32,
    // Invariant: the number of linked children not yet reclaimed.
    pub(crate) live_children: u32,
    pub(crate) waiters: Vec<Waiter>,
    pub(crate) action: Option<A>,
    pub(crate) on_terminate: Vec<OnTerminate<A>>,
    pub(crate) reservations: Vec<NodeId>,
}

impl<A> Node<A> {
    pub(crate) fn new(display: u64, kind: NodeKind, name: Name, parent: Option<NodeId>) -> Node<A> {
        let expansion = if kind.expands() {
            State::Disabled
        } else {
            State::Completed
        };
        Node {
            display,
            kind,
            name,
            parent,
            first_child: None,
            last_child: None,
            prev_sibling: None,
            next_sibling: None,
            last_spawned: None,
            states: [State::Disabled, expansion, State::Disabled],
            termination: Termination::Alive,
            blocks: [0; 3],
            expand_first: false,
            delay_expansion: false,
            suspended: false,
            parked: false,
            persistent: false,
            reserved: false,
            immune: false,
            failure: None,
            open_expansions: 0,
            open_executions: 0,
            terminating_children: 0,
            live_children: 0,
            waiters: Vec::new(),
            action: None,
            on_terminate: Vec::new(),
            reservations: Vec::new(),
        }
    }

    pub(crate) fn state(&self, facet: Facet) -> State {
        self.states[facet.index()]
    }

    pub(crate) fn reached(&self, facet: Facet, point: Point) -> bool {
        self.state(facet) >= point.state()
    }

    pub(crate) fn alive(&self) -> bool {
        self.termination == Termination::Alive
    }
}
