//! One task-tree node as the engine stores it.

use super::exception::{HandlerCtx, HandlerEntry};
use super::monitor::Monitor;
use crate::constraint::Then;
use crate::failure::Failure;
use crate::ids::{NodeId, WatchToken};
use crate::{Name, NodeKind};
use std::sync::Arc;
use std::time::Duration;
use tcm_trace::{Facet, Point, State, Termination};
use thin_vec::ThinVec;

/// What happens when a watched point of a node is reached.
#[derive(Clone, Copy, Debug)]
pub(crate) enum WaitKind {
    /// A trigger of `target` fires (after `delay`, if any): see `engine/arm.rs`.
    Trigger {
        target: NodeId,
        then: Then,
        delay: Delay,
    },
    /// Tell the shell.
    Watch { token: WatchToken },
    /// One member of a group trigger reached its event (see `engine/arm.rs`, `trigger_group`).
    Join { join: u32, then: Then },
}

impl WaitKind {
    pub(crate) fn is_termination(&self) -> bool {
        matches!(
            self,
            WaitKind::Trigger {
                then: Then::Terminate,
                ..
            } | WaitKind::Join {
                then: Then::Terminate,
                ..
            }
        )
    }
}

/// An optional delay in 8 bytes (an `Option<Duration>` takes 16), so a waiter, which every node
/// keeps one of inline, stays small. A delay beyond `u64::MAX - 1` nanoseconds (584 years) is
/// kept as that.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) struct Delay(u64);

impl Delay {
    pub(crate) const NONE: Delay = Delay(u64::MAX);

    #[inline]
    pub(crate) fn of(d: Option<Duration>) -> Delay {
        match d {
            None => Delay::NONE,
            Some(d) => {
                Delay(u64::try_from(d.as_nanos()).map_or(u64::MAX - 1, |n| n.min(u64::MAX - 1)))
            }
        }
    }

    #[inline]
    pub(crate) fn get(self) -> Option<Duration> {
        (self != Delay::NONE).then(|| Duration::from_nanos(self.0))
    }
}

/// A request "when my `facet` reaches `point`, do `kind`" registered on the node it watches.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Waiter {
    pub(crate) facet: Facet,
    pub(crate) point: Point,
    pub(crate) kind: WaitKind,
    // An outcome event: the point counts only with this outcome.
    pub(crate) outcome: Option<tcm_trace::Outcome>,
}

impl Waiter {
    /// Whether its point is reached when its node's `facet` moves to `to`.
    #[inline]
    pub(crate) fn fires_at(&self, facet: Facet, to: State) -> bool {
        self.facet == facet && self.point.state() <= to
    }
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
    /// A wiretap check on `node` (no new node): report its end, with its `Job`, to
    /// `Engine::handle_action_finished`.
    Tap {
        /// Which wiretap.
        tap: crate::ids::WiretapId,
        /// Before the node's action starts, or after it returned successfully.
        when: crate::ids::TapWhen,
    },
}

/// What a node runs when it starts.
#[derive(Clone)]
pub(crate) enum Payload<A, F> {
    /// The shell's one-shot action.
    Action(A),
    /// A factory to invoke, and why (shared: rare, large next to an action, and kept by the
    /// shell for the invocation's whole run).
    Invoke(F, Arc<Purpose>),
}

/// The waiters of one node: most nodes have none or one (the next sibling's `sequential`), so one
/// is kept inline and only more allocate. Its length is a plain field, so the check every
/// transition makes ("does anything wait here?") is one comparison.
pub(crate) type Waiters = smallvec::SmallVec<[Waiter; 1]>;

/// A task to insert as a child if the node is terminated while its action runs.
#[derive(Clone)]
pub struct OnTerminate<A> {
    /// Kind of the cleanup node.
    pub kind: NodeKind,
    /// Its instance name.
    pub name: Name,
    /// Its action.
    pub action: A,
    /// A reservation its node fulfils when it is inserted (a TDL label on the on-terminate task);
    /// the node that carries this task takes the reservation over at its spawn, so it dies when that
    /// node's handling completes without termination.
    pub fulfils: Option<NodeId>,
}

#[derive(Clone)]
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
    // Terminated while its action ran: the shell was asked to stop it and has not yet reported
    // that it did. The node is not terminated (nor reclaimed) before: its body may still spawn.
    pub(crate) stopping: bool,
    // Invariant: the number of linked children whose expansion is not completed.
    pub(crate) open_expansions: u32,
    // Invariant: the number of linked children whose execution is not completed.
    pub(crate) open_executions: u32,
    // Invariant: the number of linked children that are Terminating (not yet Terminated).
    pub(crate) terminating_children: u32,
    // Invariant: the number of linked children not yet reclaimed.
    pub(crate) live_children: u32,
    pub(crate) waiters: Waiters,
    pub(crate) action: Option<Payload<A, F>>,
    // While the action runs, its new children do not start (TDL: a body ends before its children run).
    pub(crate) holding: bool,
    // Everything most nodes never use, in one box: nodes are the engine's bulk.
    pub(crate) cold: Option<Box<Cold<A, F>>>,
}

/// The rarely used part of a node.
#[derive(Clone)]
pub(crate) struct Cold<A, F> {
    pub(crate) failure: Option<Failure>,
    pub(crate) on_terminate: ThinVec<OnTerminate<A>>,
    // Reserved children not spawned yet.
    pub(crate) reservations: ThinVec<NodeId>,
    // Monitor state, for monitor nodes.
    pub(crate) monitor: Option<Box<Monitor<F>>>,
    // For activation nodes: their monitor.
    pub(crate) activation_of: Option<NodeId>,
    // Exception handlers attached to this node, in the order they are tried.
    pub(crate) handlers: ThinVec<HandlerEntry<F>>,
    // For handler nodes: what they handle.
    pub(crate) handler: Option<Box<HandlerCtx>>,
    // A factory that re-runs this task, for retries.
    pub(crate) retry: Option<F>,
    // A handler took this node's failure.
    pub(crate) handled: bool,
    // Wiretap checks running on this node, and whether the "before" checks already ran.
    pub(crate) taps_open: ThinVec<crate::ids::WiretapId>,
    pub(crate) tapped_before: bool,
    pub(crate) tap_failure: Option<Box<Failure>>,
    // Constraints applied to a reservation before its spawn, with the `previous` of that moment;
    // applied when the spawn fulfils it.
    pub(crate) deferred: ThinVec<(crate::constraint::Constraint, Option<NodeId>)>,
    // Group triggers applied to a reservation before its spawn.
    pub(crate) deferred_groups: ThinVec<super::arm::GroupTrigger>,
    // The task this node is an instance of, when it differs from its instance name.
    pub(crate) task: Option<Name>,
    // Handlers attached from outside to this node's task (`Engine::handler_for`), tried after
    // `handlers`, with their own use counts.
    pub(crate) class_handlers: ThinVec<HandlerEntry<F>>,
    // For a retry: the first run of the task, whose handlers (own and attached, with their use
    // counts) the retry shares (docs/semantics.md, "Exceptions and handlers", rule 7).
    pub(crate) retry_of: Option<NodeId>,
    // For a failed node: the retry of it (the last of a chain of retries) that succeeded; its
    // outcome is then that retry's.
    pub(crate) recovered_by: Option<NodeId>,
    // Constraints on the node itself that a retry keeps (`expand first`, `delay expansion`).
    pub(crate) retry_constraints: ThinVec<crate::constraint::Constraint>,
    // Where its own failure goes when no handler on it takes it, instead of being searched for
    // further up (`Engine::propagate`, `Engine::propagate_to_parent`).
    pub(crate) propagate: Propagate,
    // The resources it uses (`resource.rs`), and where it stands with them.
    pub(crate) uses: Option<Box<super::resource::Uses>>,
    pub(crate) grant: super::resource::Grant,
    // Its `skip if` and `with invariant` conditions (`state.rs`), and whether it was skipped.
    pub(crate) skip_if: ThinVec<crate::ids::CondId>,
    pub(crate) invariants: ThinVec<crate::ids::CondId>,
    pub(crate) skipped: bool,
    // Steering (`steer.rs`): approved after it was held for approval; a fault stands for its
    // action and it never ends.
    pub(crate) approved: bool,
    pub(crate) never_ends: bool,
    // Held at its turn to start until approved (`Spawn::approval`), with its timeout.
    pub(crate) approval: Option<Option<std::time::Duration>>,
    // For an activation made by an external event raised with data, or by a trigger that carries
    // data (`Then::ActivateWith`): that data.
    pub(crate) data: Option<std::sync::Arc<dyn std::any::Any + Send + Sync>>,
    // For a monitor: the data its activation triggers carry (`Engine::activate_when`), by the
    // index `Then::ActivateWith` names.
    pub(crate) payloads: ThinVec<std::sync::Arc<dyn std::any::Any + Send + Sync>>,
}

/// Where a node's failure goes when no handler on the node takes it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub(crate) enum Propagate {
    /// Up the tree: the handlers of its ancestors are searched (TDL's rule).
    #[default]
    Up,
    /// To the action waiting for its value, which fails with it.
    Waiter,
    /// To its parent, which fails with it.
    Parent,
}

impl<A, F> Default for Cold<A, F> {
    fn default() -> Self {
        Cold {
            failure: None,
            on_terminate: ThinVec::new(),
            reservations: ThinVec::new(),
            monitor: None,
            activation_of: None,
            handlers: ThinVec::new(),
            handler: None,
            retry: None,
            handled: false,
            taps_open: ThinVec::new(),
            tapped_before: false,
            tap_failure: None,
            deferred: ThinVec::new(),
            deferred_groups: ThinVec::new(),
            task: None,
            class_handlers: ThinVec::new(),
            retry_of: None,
            recovered_by: None,
            retry_constraints: ThinVec::new(),
            propagate: Propagate::Up,
            uses: None,
            grant: super::resource::Grant::None,
            skip_if: ThinVec::new(),
            invariants: ThinVec::new(),
            skipped: false,
            approved: false,
            never_ends: false,
            approval: None,
            data: None,
            payloads: ThinVec::new(),
        }
    }
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
            stopping: false,
            open_expansions: 0,
            open_executions: 0,
            terminating_children: 0,
            live_children: 0,
            waiters: Waiters::default(),
            action: None,
            holding: false,
            cold: None,
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

    /// Whether the end of one of its children (its expansion or execution completing, its
    /// termination, its reclaim; the child's counts already updated) may let this node progress.
    /// When it may not, its progress is not queued for it: `progress` would find every branch
    /// closed. Only the completion branches depend on children, and each needs the handling
    /// completed (reclaim through the execution) or a termination; the counts then say which one
    /// could be reached.
    #[inline]
    pub(crate) fn child_end_may_progress(&self) -> bool {
        if self.kind == NodeKind::Root {
            return false;
        }
        if self.termination != Termination::Alive {
            return true;
        }
        if self.state(Facet::Handling) != State::Completed {
            return false;
        }
        if self.state(Facet::Expansion) != State::Completed {
            self.open_expansions == 0
        } else if self.state(Facet::Execution) != State::Completed {
            self.open_executions == 0
        } else {
            self.live_children == 0
        }
    }

    /// The rarely used part, allocated on first write.
    pub(crate) fn cold_mut(&mut self) -> &mut Cold<A, F> {
        self.cold.get_or_insert_with(Box::default)
    }

    /// Whether it holds open reservations (most nodes have no cold part at all).
    pub(crate) fn holds_reservations(&self) -> bool {
        self.cold
            .as_ref()
            .is_some_and(|c| !c.reservations.is_empty())
    }

    /// The reservations its on-terminate tasks fulfil (TDL labels on them).
    pub(crate) fn on_terminate_labels(&self) -> Vec<NodeId> {
        self.cold.as_ref().map_or_else(Vec::new, |c| {
            c.on_terminate.iter().filter_map(|ot| ot.fulfils).collect()
        })
    }

    pub(crate) fn monitor(&self) -> Option<&Monitor<F>> {
        self.cold.as_ref().and_then(|c| c.monitor.as_deref())
    }

    pub(crate) fn monitor_mut(&mut self) -> Option<&mut Monitor<F>> {
        self.cold.as_mut().and_then(|c| c.monitor.as_deref_mut())
    }

    pub(crate) fn activation_of(&self) -> Option<NodeId> {
        self.cold.as_ref().and_then(|c| c.activation_of)
    }

    pub(crate) fn handlers(&self) -> &[HandlerEntry<F>] {
        self.cold.as_ref().map_or(&[], |c| c.handlers.as_slice())
    }

    /// Every handler the search tries at this node, in order: its own (`handlers`), then those
    /// attached to its task from outside (`class_handlers`). The search's handler index counts
    /// along this sequence.
    pub(crate) fn all_handlers(&self) -> impl Iterator<Item = &HandlerEntry<F>> {
        let class = self
            .cold
            .as_ref()
            .map_or(&[][..], |c| c.class_handlers.as_slice());
        self.handlers().iter().chain(class)
    }

    /// The handler at `index` of [`Node::all_handlers`].
    pub(crate) fn handler_entry_mut(&mut self, index: usize) -> Option<&mut HandlerEntry<F>> {
        let c = self.cold.as_mut()?;
        match index.checked_sub(c.handlers.len()) {
            None => c.handlers.get_mut(index),
            Some(i) => c.class_handlers.get_mut(i),
        }
    }

    /// What a handler node handles.
    pub(crate) fn handler_ctx(&self) -> Option<&HandlerCtx> {
        self.cold.as_ref().and_then(|c| c.handler.as_deref())
    }

    /// A handler node whose body asked to pass its exception on.
    pub(crate) fn bypass_requested(&self) -> bool {
        self.handler_ctx().is_some_and(|h| h.bypass)
    }

    /// The name of the task this node is an instance of: its task name if it was renamed, else its
    /// instance name.
    pub(crate) fn task_name(&self) -> &Name {
        self.renamed_task().unwrap_or(&self.name)
    }

    /// The task name, only if it differs from the instance name.
    pub(crate) fn renamed_task(&self) -> Option<&Name> {
        self.cold.as_ref().and_then(|c| c.task.as_ref())
    }

    pub(crate) fn retry(&self) -> Option<&F> {
        self.cold.as_ref().and_then(|c| c.retry.as_ref())
    }

    pub(crate) fn skip_conditions(&self) -> &[crate::ids::CondId] {
        self.cold.as_ref().map_or(&[], |c| &c.skip_if)
    }

    pub(crate) fn invariant_conditions(&self) -> &[crate::ids::CondId] {
        self.cold.as_ref().map_or(&[], |c| &c.invariants)
    }

    pub(crate) fn skipped(&self) -> bool {
        self.cold.as_ref().is_some_and(|c| c.skipped)
    }

    pub(crate) fn failure(&self) -> Option<&Failure> {
        self.cold.as_ref().and_then(|c| c.failure.as_ref())
    }

    /// The first run of the task this node is a retry of, if it is one.
    pub(crate) fn retry_of(&self) -> Option<NodeId> {
        self.cold.as_ref().and_then(|c| c.retry_of)
    }

    /// The retry whose success recovered this failed node.
    pub(crate) fn recovered_by(&self) -> Option<NodeId> {
        self.cold.as_ref().and_then(|c| c.recovered_by)
    }

    /// Its own failure goes to its parent when no handler on it takes it.
    pub(crate) fn propagates(&self) -> Propagate {
        self.cold.as_ref().map_or(Propagate::Up, |c| c.propagate)
    }

    /// The resources it uses, if any (most nodes have no cold part at all).
    pub(crate) fn uses(&self) -> Option<&super::resource::Uses> {
        self.cold.as_ref().and_then(|c| c.uses.as_deref())
    }

    /// Where it stands with its resources.
    pub(crate) fn grant(&self) -> super::resource::Grant {
        self.cold
            .as_ref()
            .map_or(super::resource::Grant::None, |c| c.grant)
    }

    pub(crate) fn set_grant(&mut self, grant: super::resource::Grant) {
        self.cold_mut().grant = grant;
    }

    pub(crate) fn handled(&self) -> bool {
        self.cold.as_ref().is_some_and(|c| c.handled)
    }

    /// Whether a fault stands for its action and it never ends (`steer.rs`, rule 4).
    pub(crate) fn never_ends(&self) -> bool {
        self.cold.as_ref().is_some_and(|c| c.never_ends)
    }

    pub(crate) fn taps_pending(&self) -> usize {
        self.cold.as_ref().map_or(0, |c| c.taps_open.len())
    }

    pub(crate) fn tapped_before(&self) -> bool {
        self.cold.as_ref().is_some_and(|c| c.tapped_before)
    }

    /// Takes a list out of the cold part without allocating it.
    pub(crate) fn take_cold<T>(
        &mut self,
        f: impl FnOnce(&mut Cold<A, F>) -> &mut ThinVec<T>,
    ) -> ThinVec<T> {
        match self.cold.as_mut() {
            Some(c) => std::mem::take(f(c)),
            None => ThinVec::new(),
        }
    }
}
