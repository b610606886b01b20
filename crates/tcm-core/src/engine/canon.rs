//! A canonical hash of a run's state, for model checkers that explore every behaviour of a program
//! and must recognise a state they have already seen (`tdl-verify`).
//!
//! Two engines get the same hash when they will behave alike from now on, whatever history led
//! each there: the hash covers everything that decides the future (every live node with its
//! states, blocks, waiters, monitor counts, handler uses and deferred constraints; the live timers;
//! the external events; the resources, their grants, reservations, locks and waiting requests)
//! and leaves out what only records the past:
//!
//! - node handles and display numbers: nodes are numbered in a canonical order instead (a walk
//!   from the root through children in spawn order, each node's reservations after its children),
//!   and every reference to a node is hashed as that number, or as the fate of a node gone;
//! - the clock: every time is hashed relative to now (a timer due in 1 s is the same timer at 3 s
//!   and at 10 s), so a loop in time (a monitor polling forever) comes back to the same state;
//! - counters of the past: trace sequence numbers, failures and warnings counted, the list of
//!   unhandled failures, watch tokens (the shell routes them; it hashes what it waits for itself,
//!   with [`Canonical::index`]);
//! - counts no maximum limits: a monitor's activations and triggers, a handler's uses, and an
//!   activation's number are hashed only up to their maximum, if they have one. The engine's
//!   behaviour does not depend on them otherwise; only a shell whose actions read them
//!   (`Ctx::activation`) would see a difference, and it must hash what it reads itself. Without
//!   this, a monitor polling forever would never come back to a state seen before.
//!
//! The shell's action and factory types are hashed with their own `Hash`: they must not hold node
//! handles (or must hash them canonically themselves). Hashing reads the engine only.

use super::arm::{External, GroupTrigger, Join};
use super::exception::{HandlerCtx, HandlerEntry};
use super::node::{Link, Node, Payload, Purpose, WaitKind, Waiter};
use super::timers::TimerKind;
use super::{Engine, Work};
use crate::Name;
use crate::arena::Keep;
use crate::arena::{Fate, Lookup};
use crate::constraint::{Constraint, Event, NodeRef, Then, When};
use crate::failure::Failure;
use crate::ids::NodeId;
use crate::time::Time;
use std::hash::{Hash, Hasher};
use tcm_trace::{State, Termination};

/// The canonical numbering of the live nodes computed by [`Engine::canonical_hash`], for the
/// shell to hash its own references to nodes the same way.
#[derive(Clone, Debug, Default)]
pub struct Canonical {
    // By slot: (generation, canonical number + 1), 0 for a slot not numbered.
    slots: Vec<(u32, u32)>,
    // Nodes in canonical order.
    order: Vec<NodeId>,
}

impl Canonical {
    /// The canonical number of a live node, `None` for a node gone (or of another run).
    pub fn index(&self, id: NodeId) -> Option<u32> {
        match self.slots.get(id.idx as usize) {
            Some(&(generation, n)) if generation == id.generation && n > 0 => Some(n - 1),
            _ => None,
        }
    }

    /// The live nodes in canonical order (the root first).
    pub fn nodes(&self) -> &[NodeId] {
        &self.order
    }

    fn number(&mut self, id: NodeId) {
        let idx = id.idx as usize;
        if self.slots.len() <= idx {
            self.slots.resize(idx + 1, (0, 0));
        }
        if self.slots[idx].1 != 0 && self.slots[idx].0 == id.generation {
            return;
        }
        self.order.push(id);
        let n = u32::try_from(self.order.len()).unwrap_or(u32::MAX);
        self.slots[idx] = (id.generation, n);
    }
}

/// Hashes `now - t` (or `t - now`): a time relative to the present.
fn rel(t: Time, now: Time, h: &mut impl Hasher) {
    (i128::from(t.as_nanos()) - i128::from(now.as_nanos())).hash(h);
}

/// A name: a borrowed one (a `&'static str`, as shells that name many nodes use) by its address
/// and length, which is cheaper than its text and as faithful (the same address and length is
/// the same text); an owned one by its text. The same text once borrowed and once owned hashes
/// apart, which only costs a merge.
fn name(n: &Name, h: &mut impl Hasher) {
    match n {
        std::borrow::Cow::Borrowed(s) => {
            0u8.hash(h);
            (s.as_ptr() as usize).hash(h);
            s.len().hash(h);
        }
        std::borrow::Cow::Owned(s) => {
            1u8.hash(h);
            s.hash(h);
        }
    }
}

/// A count as far as a maximum makes it matter: none without one, else up to the maximum.
fn limited(n: u32, max: Option<u32>) -> Option<u32> {
    max.map(|m| n.min(m))
}

fn failure(f: &Failure, h: &mut impl Hasher) {
    name(&f.exception, h);
    f.message.hash(h);
    f.ancestry.hash(h);
}

impl<A: Hash, F: Hash + Clone, S: Keep<Node<A, F>>> Engine<A, F, S> {
    /// Feeds `h` a canonical form of the whole state (see the module documentation) and returns
    /// the numbering of the live nodes it used.
    pub fn canonical_hash<H: Hasher>(&self, h: &mut H) -> Canonical {
        let mut canon = Canonical::default();
        self.number_from(self.root, &mut canon);
        // Nodes no walk reaches (a reservation taken over by an on-terminate task), in slot order.
        for (id, _) in self.nodes.iter() {
            if canon.index(id).is_none() {
                canon.number(id);
            }
        }
        let c = Hashing {
            engine: self,
            canon: &canon,
        };
        canon.order.len().hash(h);
        for &id in &canon.order {
            if let Some(n) = self.nodes.get(id) {
                c.node(n, h);
            }
        }
        // Timers in the order they fire, relative to now.
        let mut timers = self.timers.pending();
        timers.retain(|(_, kind)| super::timer_is_live(&self.nodes, kind));
        timers.len().hash(h);
        for (at, kind) in &timers {
            rel(*at, self.now, h);
            match *kind {
                TimerKind::Trigger { target, then } => {
                    0u8.hash(h);
                    c.node_ref(target, h);
                    c.then(then, h);
                }
                TimerKind::Poll { monitor, k } => {
                    1u8.hash(h);
                    c.node_ref(monitor, h);
                    let next = self
                        .nodes
                        .get(monitor)
                        .and_then(Node::monitor)
                        .map_or(0, |m| m.next_poll);
                    (i128::from(k) - i128::from(next)).hash(h);
                }
                TimerKind::Notify { .. } => 2u8.hash(h),
                TimerKind::Approval { node, .. } => {
                    3u8.hash(h);
                    c.node_ref(node, h);
                }
            }
        }
        // External events by name (ids are numbered in the order names were first used).
        self.externals.len().hash(h);
        let mut externals: Vec<&External> = self.externals.iter().collect();
        if externals.len() > 1 {
            externals.sort_by(|a, b| a.name.cmp(&b.name));
        }
        for ext in externals {
            ext.name.hash(h);
            ext.raised.hash(h);
            ext.waiters.len().hash(h);
            for w in &ext.waiters {
                c.wait_kind(w, h);
            }
            ext.activators.len().hash(h);
            for a in &ext.activators {
                c.node_ref(*a, h);
            }
        }
        // State variables by name (ids are numbered in the order they were declared), with their
        // watches.
        self.states
            .hash_canonical(h, &mut |id, h| c.node_ref(id, h));
        // A run of children is hashed as the entries it stands for (those of its children still
        // linked; an unlinked child's entry is a no-op, and the queue is empty between inputs).
        let mut work: Vec<Work> = Vec::with_capacity(self.work.len());
        for w in &self.work {
            match *w {
                Work::Children(run) => {
                    if let Some(r) = self.runs.iter().find(|r| r.id == run) {
                        let mut at = self.nodes.id_at(r.next);
                        while let Some(child) = at {
                            work.push(Work::Progress(child));
                            let n = self.node(child);
                            at = (Link::to(child) != r.last)
                                .then(|| self.nodes.id_at(n.next_sibling))
                                .flatten();
                        }
                    }
                }
                other => work.push(other),
            }
        }
        work.len().hash(h);
        for w in &work {
            match *w {
                Work::Children(_) => {}
                Work::Progress(n) => {
                    0u8.hash(h);
                    c.node_ref(n, h);
                }
                Work::Terminate { node, explicit } => {
                    1u8.hash(h);
                    c.node_ref(node, h);
                    explicit.hash(h);
                }
            }
        }
        self.ready.len().hash(h);
        for r in &self.ready {
            c.node_ref(*r, h);
        }
        self.running.hash(h);
        self.fatal.is_some().hash(h);
        c.resources(h);
        canon
    }

    /// Hashes a reference the shell holds to a node as [`Engine::canonical_hash`] hashes the
    /// engine's own: its number in `canon`, or how it ended if it is gone.
    pub fn hash_node_ref<H: Hasher>(&self, canon: &Canonical, id: NodeId, h: &mut H) {
        Hashing {
            engine: self,
            canon,
        }
        .node_ref(id, h);
    }

    /// Numbers `root`'s subtree: each node, then its children in spawn order, then its open
    /// reservations (iteratively: the depth of the tree costs no stack).
    fn number_from(&self, root: NodeId, canon: &mut Canonical) {
        let mut stack = vec![root];
        while let Some(id) = stack.pop() {
            let Some(n) = self.nodes.get(id) else {
                continue;
            };
            canon.number(id);
            // Pushed in reverse so that they come off in order: reservations last, then
            // children from the last to the first.
            if let Some(cold) = n.cold.as_ref() {
                stack.extend(cold.reservations.iter().rev().copied());
            }
            let mark = stack.len();
            let mut c = self.first_child(id);
            while let Some(ch) = c {
                stack.push(ch);
                c = self.next_sibling(ch);
            }
            stack[mark..].reverse();
        }
    }
}

/// What hashing reads: the engine and the numbering.
struct Hashing<'a, A, F, S: Keep<Node<A, F>>> {
    engine: &'a Engine<A, F, S>,
    canon: &'a Canonical,
}

impl<A: Hash, F: Hash + Clone, S: Keep<Node<A, F>>> Hashing<'_, A, F, S> {
    /// A reference to a node: its number, or how it ended if it is gone.
    fn node_ref(&self, id: NodeId, h: &mut impl Hasher) {
        match self.canon.index(id) {
            Some(n) => {
                0u8.hash(h);
                n.hash(h);
            }
            None => {
                let fate = match self.engine.nodes.lookup(id) {
                    Lookup::Live => 3u8,
                    Lookup::Gone(Fate::Completed) => 0,
                    Lookup::Gone(Fate::Terminated) => 1,
                    Lookup::Gone(Fate::Dead) => 2,
                };
                1u8.hash(h);
                fate.hash(h);
            }
        }
    }

    fn opt_ref(&self, id: Option<NodeId>, h: &mut impl Hasher) {
        match id {
            Some(id) => {
                1u8.hash(h);
                self.node_ref(id, h);
            }
            None => 0u8.hash(h),
        }
    }

    fn then(&self, then: Then, h: &mut impl Hasher) {
        match then {
            Then::Enable(f) => {
                0u8.hash(h);
                f.hash(h);
            }
            Then::Skip => 3u8.hash(h),
            Then::Invariant => 4u8.hash(h),
            Then::Pause => 5u8.hash(h),
            Then::Terminate => 1u8.hash(h),
            Then::Activate => 2u8.hash(h),
            Then::ActivateWith(i) => {
                6u8.hash(h);
                i.hash(h);
            }
        }
    }

    fn reference(&self, r: NodeRef, h: &mut impl Hasher) {
        match r {
            NodeRef::Node(id) => {
                0u8.hash(h);
                self.node_ref(id, h);
            }
            NodeRef::Previous => 1u8.hash(h),
            NodeRef::This => 2u8.hash(h),
            NodeRef::Parent => 3u8.hash(h),
        }
    }

    fn event(&self, e: &Event, h: &mut impl Hasher) {
        self.reference(e.node, h);
        e.facet.hash(h);
        e.point.hash(h);
        e.outcome.hash(h);
    }

    fn constraint(&self, c: &Constraint, h: &mut impl Hasher) {
        let now = self.engine.now;
        match c {
            Constraint::ExpandFirst => 0u8.hash(h),
            Constraint::DelayExpansion => 1u8.hash(h),
            Constraint::Sequential(f, r) => {
                2u8.hash(h);
                f.hash(h);
                self.reference(*r, h);
            }
            Constraint::Serial(r) => {
                3u8.hash(h);
                self.reference(*r, h);
            }
            Constraint::Parallel => 4u8.hash(h),
            Constraint::Approval(within) => {
                6u8.hash(h);
                within.hash(h);
            }
            Constraint::Trigger(when, then) => {
                5u8.hash(h);
                match when {
                    When::Now => 0u8.hash(h),
                    When::At(t) => {
                        1u8.hash(h);
                        rel(*t, now, h);
                    }
                    When::In(d) => {
                        2u8.hash(h);
                        d.hash(h);
                    }
                    When::Event(e) => {
                        3u8.hash(h);
                        self.event(e, h);
                    }
                    When::After(d, e) => {
                        4u8.hash(h);
                        d.hash(h);
                        self.event(e, h);
                    }
                    When::External(id) => {
                        5u8.hash(h);
                        let name = self.engine.externals.get(id.0 as usize).map(|e| &e.name);
                        name.hash(h);
                    }
                    When::Condition(c) => {
                        6u8.hash(h);
                        self.engine
                            .condition_expr(*c)
                            .map(ToString::to_string)
                            .hash(h);
                    }
                    When::Changed(v) => {
                        7u8.hash(h);
                        self.engine.state(*v).map(|s| s.0).hash(h);
                    }
                }
                self.then(*then, h);
            }
        }
    }

    fn join(&self, join: u32, h: &mut impl Hasher) {
        match self
            .engine
            .joins
            .get(join as usize)
            .and_then(Option::as_ref)
        {
            Some(Join {
                target,
                then,
                delay,
                remaining,
                never,
            }) => {
                1u8.hash(h);
                self.node_ref(*target, h);
                self.then(*then, h);
                delay.hash(h);
                remaining.hash(h);
                never.hash(h);
            }
            None => 0u8.hash(h),
        }
    }

    fn wait_kind(&self, w: &WaitKind, h: &mut impl Hasher) {
        match *w {
            WaitKind::Trigger {
                target,
                then,
                delay,
            } => {
                0u8.hash(h);
                self.node_ref(target, h);
                self.then(then, h);
                delay.get().hash(h);
            }
            // The token is the shell's routing; it hashes what it waits for itself.
            WaitKind::Watch { .. } => 1u8.hash(h),
            WaitKind::Join { join, then } => {
                2u8.hash(h);
                self.join(join, h);
                self.then(then, h);
            }
        }
    }

    fn waiter(&self, w: &Waiter, h: &mut impl Hasher) {
        w.facet.hash(h);
        w.point.hash(h);
        w.outcome.hash(h);
        self.wait_kind(&w.kind, h);
    }

    fn handler(&self, e: &HandlerEntry<F>, h: &mut impl Hasher) {
        name(&e.spec.name, h);
        name(&e.spec.exception, h);
        e.spec.max_activations.hash(h);
        e.spec.body.hash(h);
        limited(e.uses, e.spec.max_activations).hash(h);
    }

    fn handler_ctx(&self, c: &HandlerCtx, h: &mut impl Hasher) {
        failure(&c.failure, h);
        self.node_ref(c.failing, h);
        self.node_ref(c.attached, h);
        c.index.hash(h);
        c.bypass.hash(h);
    }

    fn purpose(&self, p: &Purpose, h: &mut impl Hasher) {
        match p {
            Purpose::Activation {
                monitor,
                number,
                triggers,
            } => {
                0u8.hash(h);
                self.node_ref(*monitor, h);
                let spec = self
                    .engine
                    .nodes
                    .get(*monitor)
                    .and_then(Node::monitor)
                    .map(|m| (m.spec.max_activations, m.spec.max_triggers));
                let (max_a, max_t) = spec.unwrap_or((None, None));
                limited(*number, max_a).hash(h);
                limited(*triggers, max_t).hash(h);
            }
            Purpose::Handler {
                failure: f,
                failing,
                attached,
            } => {
                1u8.hash(h);
                failure(f, h);
                self.node_ref(*failing, h);
                self.node_ref(*attached, h);
            }
            Purpose::Retry { of } => {
                2u8.hash(h);
                self.node_ref(*of, h);
            }
            Purpose::Tap { tap, when } => {
                3u8.hash(h);
                tap.hash(h);
                when.hash(h);
            }
        }
    }

    fn group(&self, g: &GroupTrigger, h: &mut impl Hasher) {
        g.members.len().hash(h);
        for m in &g.members {
            self.node_ref(*m, h);
        }
        g.facet.hash(h);
        g.point.hash(h);
        g.delay.hash(h);
        self.then(g.then, h);
    }

    fn node(&self, n: &Node<A, F>, h: &mut impl Hasher) {
        let now = self.engine.now;
        // The small fields packed into a few words: hashing is a fifth of a search's time.
        let flags = [
            n.expand_first,
            n.delay_expansion,
            n.suspended,
            n.parked,
            n.persistent,
            n.reserved,
            n.immune,
            n.stopping,
            n.holding,
        ]
        .iter()
        .fold(0u64, |acc, f| (acc << 1) | u64::from(*f));
        let state = |s: State| s as u64;
        let termination = match n.termination {
            Termination::Alive => 0u64,
            Termination::Terminating => 1,
            Termination::Terminated => 2,
        };
        let word = flags
            | (n.kind as u64) << 16
            | state(n.states[0]) << 24
            | state(n.states[1]) << 28
            | state(n.states[2]) << 32
            | termination << 36;
        word.hash(h);
        let packed = |a: u32, b: u32| (u64::from(a) << 32) | u64::from(b);
        packed(n.blocks[0], n.blocks[1]).hash(h);
        packed(n.blocks[2], n.open_expansions).hash(h);
        packed(n.open_executions, n.terminating_children).hash(h);
        n.live_children.hash(h);
        name(&n.name, h);
        self.opt_ref(n.parent, h);
        self.opt_ref(n.last_spawned, h);
        n.waiters.iter().len().hash(h);
        for w in n.waiters.iter() {
            self.waiter(w, h);
        }
        match &n.action {
            None => 0u8.hash(h),
            Some(Payload::Action(a)) => {
                1u8.hash(h);
                a.hash(h);
            }
            Some(Payload::Invoke(f, purpose)) => {
                2u8.hash(h);
                f.hash(h);
                self.purpose(purpose, h);
            }
        }
        let Some(cold) = n.cold.as_ref() else {
            0u8.hash(h);
            return;
        };
        1u8.hash(h);
        cold.failure.is_some().hash(h);
        if let Some(f) = &cold.failure {
            failure(f, h);
        }
        cold.on_terminate.len().hash(h);
        for ot in &cold.on_terminate {
            ot.kind.hash(h);
            name(&ot.name, h);
            ot.action.hash(h);
            self.opt_ref(ot.fulfils, h);
        }
        cold.reservations.len().hash(h);
        for r in &cold.reservations {
            self.node_ref(*r, h);
        }
        match cold.monitor.as_deref() {
            None => 0u8.hash(h),
            Some(m) => {
                1u8.hash(h);
                m.spec.body.hash(h);
                m.spec.max_activations.hash(h);
                m.spec.max_triggers.hash(h);
                m.spec.period.hash(h);
                m.spec.initial_wait.hash(h);
                m.spec.overrun.hash(h);
                let e = m.spec.each;
                (
                    e.serial,
                    e.sequential_execution,
                    e.sequential_expansion,
                    e.expand_first,
                    e.delay_expansion,
                )
                    .hash(h);
                m.spec
                    .activation_name
                    .as_ref()
                    .map(|n| name(n, h))
                    .is_some()
                    .hash(h);
                limited(m.activations, m.spec.max_activations).hash(h);
                limited(m.triggers, m.spec.max_triggers).hash(h);
                self.opt_ref(m.last, h);
                // The schedule: when the armed poll is due, relative to now (as `poll_due`); a
                // held poll has none (it restarts the schedule when it is made).
                m.held.hash(h);
                match m.spec.period {
                    Some(_) if m.held => 0u8.hash(h),
                    Some(p) => {
                        let (at, k0) = m.anchor;
                        let k = u32::try_from(m.next_poll.saturating_sub(k0)).unwrap_or(u32::MAX);
                        rel(at.saturating_add(p.saturating_mul(k)), now, h);
                    }
                    None => 0u8.hash(h),
                }
            }
        }
        self.opt_ref(cold.activation_of, h);
        cold.handlers.len().hash(h);
        for e in &cold.handlers {
            self.handler(e, h);
        }
        match cold.handler.as_deref() {
            None => 0u8.hash(h),
            Some(c) => {
                1u8.hash(h);
                self.handler_ctx(c, h);
            }
        }
        cold.retry.hash(h);
        cold.handled.hash(h);
        cold.taps_open.hash(h);
        cold.tapped_before.hash(h);
        cold.tap_failure.is_some().hash(h);
        if let Some(f) = cold.tap_failure.as_deref() {
            failure(f, h);
        }
        cold.deferred.len().hash(h);
        for (c, prev) in &cold.deferred {
            self.constraint(c, h);
            self.opt_ref(*prev, h);
        }
        cold.deferred_groups.len().hash(h);
        for g in &cold.deferred_groups {
            self.group(g, h);
        }
        cold.task.as_ref().map(|n| name(n, h)).is_some().hash(h);
        cold.class_handlers.len().hash(h);
        for e in &cold.class_handlers {
            self.handler(e, h);
        }
        self.opt_ref(cold.retry_of, h);
        self.opt_ref(cold.recovered_by, h);
        cold.retry_constraints.len().hash(h);
        for c in &cold.retry_constraints {
            self.constraint(c, h);
        }
        cold.propagate.hash(h);
        // Its conditions, by text (ids are numbered in the order conditions were registered).
        for conds in [&cold.skip_if, &cold.invariants] {
            conds.len().hash(h);
            for c in conds.iter() {
                self.engine
                    .condition_expr(*c)
                    .map(ToString::to_string)
                    .hash(h);
            }
        }
        cold.skipped.hash(h);
        // The resources it uses and where it stands with them.
        match cold.uses.as_deref() {
            None => 0u8.hash(h),
            Some(u) => {
                1u8.hash(h);
                u.amounts.len().hash(h);
                for (r, n) in &u.amounts {
                    r.idx.hash(h);
                    n.hash(h);
                }
                u.priority.hash(h);
                u.deny_if_busy.hash(h);
            }
        }
        (cold.grant as u8).hash(h);
    }

    /// The run's resources: what each has granted, to whom, its reservation and lock, and the
    /// waiting requests in grant order (their order numbers only record when they were made).
    fn resources(&self, h: &mut impl Hasher) {
        let res = &self.engine.res;
        res.list.len().hash(h);
        for r in &res.list {
            name(&r.name, h);
            r.capacity.hash(h);
            r.pending_limit.hash(h);
            r.in_use.hash(h);
            r.holders.len().hash(h);
            for (node, n) in &r.holders {
                self.node_ref(*node, h);
                n.hash(h);
            }
            self.opt_ref(r.reserved_for, h);
            r.locked.hash(h);
        }
        res.waiting.len().hash(h);
        for q in &res.waiting {
            self.node_ref(q.node, h);
            q.priority.hash(h);
        }
        res.dirty.hash(h);
    }
}
