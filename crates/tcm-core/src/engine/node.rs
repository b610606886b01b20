//! One task-tree node as the engine stores it.

use super::exception::{HandlerCtx, HandlerEntry};
use super::monitor::Monitor;
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
    /// Activate the monitor (fires even when the watched node reached the point by termination).
    Activate { monitor: NodeId },
    /// Activate the monitor `delay` after the point.
    ActivateAfter { monitor: NodeId, delay: Duration },
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

/// A link between linked (hence live) nodes: the slot index alone, `NONE` for no node.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Link(pub(crate) u32);

impl Link {
    pub(crate) const NONE: Link = Link(u32::MAX);

    pub(crate) fn to(id: NodeId) -> Link {
        Link(id.idx)
    }
}

/// A list that is almost always empty: one pointer while empty, instead of a `Vec`'s three words.
/// Nodes are the engine's bulk, so their rarely used lists stay small.
// A boxed `Vec` on purpose: one word while empty, which is nearly always.
#[allow(clippy::box_collection)]
pub(crate) struct Sparse<T>(Option<Box<Vec<T>>>);

impl<T> Default for Sparse<T> {
    fn default() -> Self {
        Sparse(None)
    }
}

impl<T> Sparse<T> {
    pub(crate) fn push(&mut self, it: T) {
        self.0.get_or_insert_with(Box::default).push(it);
    }

    pub(crate) fn take(&mut self) -> Vec<T> {
        self.0.take().map(|b| *b).unwrap_or_default()
    }

    pub(crate) fn set(&mut self, v: Vec<T>) {
        self.0 = if v.is_empty() {
            None
        } else {
            Some(Box::new(v))
        };
    }

    pub(crate) fn as_slice(&self) -> &[T] {
        self.0.as_deref().map_or(&[], Vec::as_slice)
    }

    pub(crate) fn get_mut(&mut self, i: usize) -> Option<&mut T> {
        self.0.as_deref_mut().and_then(|v| v.get_mut(i))
    }

    pub(crate) fn retain(&mut self, f: impl FnMut(&T) -> bool) {
        if let Some(v) = self.0.as_deref_mut() {
            v.retain(f);
        }
    }
}

/// Why the shell is asked to run a factory (see `Effect::Invoke`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Purpose {
    /// One activation of a monitor: `node` is the activation node, a child of the monitor.
    Activation {
        /// The monitor.
        monitor: NodeId,
        /// This activation's number, from 1 (activations are counted when created).
        number: u32,
        /// Triggers counted so far.
        triggers: u32,
    },
    /// An exception handler: `node` is the new handler node.
    Handler {
        /// The failure being handled.
        failure: Failure,
        /// The node whose action failed.
        failing: NodeId,
        /// The node the handler was attached to.
        attached: NodeId,
    },
    /// A fresh run of a failed task, asked for by a handler: `node` is the new node.
    Retry {
        /// The node that failed.
        of: NodeId,
    },
    /// A wiretap check on `node` (no new node): report with `Engine::tap_finished`.
    Tap {
        /// Which wiretap.
        tap: crate::ids::WiretapId,
        /// Before the node's action starts, or after it returned successfully.
        when: crate::ids::TapWhen,
    },
}

/// What a node runs when it starts.
pub(crate) enum Payload<A, F> {
    /// The shell's one-shot action.
    Action(A),
    /// A factory to invoke, and why (boxed: rare, and large next to an action).
    Invoke(Box<(F, Purpose)>),
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

pub(crate) struct Node<A, F> {
    pub(crate) display: u64,
    pub(crate) kind: NodeKind,
    pub(crate) name: Name,
    pub(crate) parent: Option<NodeId>,
    // Children in spawn order, as an intrusive doubly-linked list (O(1) unlink on reclaim).
    // Links hold slot indices only: a linked node is alive, so its slot's generation is current.
    pub(crate) first_child: Link,
    pub(crate) last_child: Link,
    pub(crate) prev_sibling: Link,
    pub(crate) next_sibling: Link,
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
    pub(crate) action: Option<Payload<A, F>>,
    pub(crate) on_terminate: Sparse<OnTerminate<A>>,
    pub(crate) reservations: Sparse<NodeId>,
    // Monitor state, for monitor nodes.
    pub(crate) monitor: Option<Box<Monitor<F>>>,
    // For activation nodes: their monitor.
    pub(crate) activation_of: Option<NodeId>,
    // Exception handlers attached to this node, in the order they are tried.
    pub(crate) handlers: Sparse<HandlerEntry<F>>,
    // For handler nodes: what they handle.
    pub(crate) handling: Option<Box<HandlerCtx>>,
    // A factory that re-runs this task, for retries.
    pub(crate) retry: Option<F>,
    // A handler took this node's failure.
    pub(crate) handled: bool,
    // Wiretap checks running on this node, and whether the "before" checks already ran.
    pub(crate) taps_pending: u32,
    pub(crate) tapped_before: bool,
    pub(crate) tap_failure: Option<Box<Failure>>,
    // Constraints applied to a reservation before its spawn, with the `previous` of that moment;
    // applied when the spawn fulfils it.
    pub(crate) deferred: Sparse<(crate::constraint::Constraint, Option<NodeId>)>,
    // While the action runs, its new children do not start (TDL: a body ends before its children run).
    pub(crate) holding: bool,
}

impl<A, F> Node<A, F> {
    pub(crate) fn new(
        display: u64,
        kind: NodeKind,
        name: Name,
        parent: Option<NodeId>,
    ) -> Node<A, F> {
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
            first_child: Link::NONE,
            last_child: Link::NONE,
            prev_sibling: Link::NONE,
            next_sibling: Link::NONE,
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
            on_terminate: Sparse::default(),
            reservations: Sparse::default(),
            monitor: None,
            activation_of: None,
            handlers: Sparse::default(),
            handling: None,
            retry: None,
            handled: false,
            taps_pending: 0,
            tapped_before: false,
            tap_failure: None,
            deferred: Sparse::default(),
            holding: false,
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
