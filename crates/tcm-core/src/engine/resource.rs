//! Resources (the Task Control Architecture's fourth control construct; docs/semantics.md,
//! "Resources"): a robot's base, arms, camera or CPU, each with a capacity, granted to the nodes
//! that use them.
//!
//! 1. [`Engine::declare_resource`] declares a resource with its capacity and pending limit.
//! 2. A node spawned with [`Uses`] asks for them when its handling is enabled and it would start
//!    (`start` in `progress.rs`): a `requested` record. It stays enabled, not active, until they
//!    are granted: all at once or nothing.
//! 3. Waiting requests are granted in order of priority (lower first), then of request. A request
//!    that does not fit holds its place on every resource it needs: no later request is granted
//!    any of them before it (so a big request is never starved by small ones); later requests
//!    for other resources go ahead. A locked resource, or one reserved for a subtree the node is
//!    not in, is granted to nobody else, and such a request holds no place.
//! 4. A request that cannot be granted at once fails its node with [`ResourceDenied`] if it asked
//!    not to wait (`deny_if_busy`), or always when it asks for more than a capacity. A new request
//!    past a resource's pending limit drops the oldest waiting one: its node fails with
//!    [`ResourceDropped`].
//! 5. A node holds its grant while its handling runs: it releases it right before its handling
//!    completes (succeeded or failed), when it is terminated, or, if it was terminated while its
//!    action ran, once the shell reports that the action stopped. A node terminated while waiting
//!    withdraws its request.
//!
//! Every step is a trace record; the grant scan runs in `settle` whenever something may have
//! freed room (`dirty`), before the next ready node starts.

use super::node::Node;
use super::{Engine, EngineError};
use crate::Name;
use crate::arena::Keep;
use crate::failure::Failure;
use crate::ids::{NodeId, ResourceId};
use crate::time::Time;
use std::collections::BTreeMap;
use tcm_trace::{Facet, ResourceUse, State, TraceKind};

/// What a node uses of its run's resources (docs/semantics.md, "Resources").
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Uses {
    /// Each resource and the amount of its capacity, all granted at once.
    pub amounts: Vec<(ResourceId, u32)>,
    /// Lower is granted first; requests of one priority are granted in the order they were made.
    pub priority: i32,
    /// Fail at once with [`ResourceDenied`] instead of waiting when the request cannot be granted
    /// when it is made.
    pub deny_if_busy: bool,
}

impl Uses {
    /// `amount` of `resource`, added to what is used already.
    pub fn and(mut self, resource: ResourceId, amount: u32) -> Uses {
        self.amounts.push((resource, amount));
        self
    }
}

/// The exception of a request that is refused: its node asked not to wait (`deny if busy`) and
/// the resource could not be granted at once, or it asks for more than the resource's capacity.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("resource `{resource}` denied: {reason}")]
pub struct ResourceDenied {
    /// The resource that could not be granted.
    pub resource: String,
    /// Why, for people.
    pub reason: String,
}

/// The exception of a waiting request dropped because a newer one went past the resource's
/// pending limit (TCA: the oldest pending request goes).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("request for resource `{resource}` dropped: {reason}")]
pub struct ResourceDropped {
    /// The resource whose pending limit was passed.
    pub resource: String,
    /// Why, for people.
    pub reason: String,
}

/// A snapshot of one resource ([`Engine::resource_info`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ResourceInfo {
    /// Its name.
    pub name: String,
    /// Its capacity.
    pub capacity: u32,
    /// Most requests that may wait for it.
    pub pending_limit: Option<u32>,
    /// Units granted and not released.
    pub in_use: u32,
    /// The nodes holding some of it, in grant order, with their amounts.
    pub holders: Vec<(NodeId, u32)>,
    /// The nodes whose request for it waits, in the order they would be granted.
    pub waiting: Vec<NodeId>,
    /// The node whose subtree alone may be granted it.
    pub reserved_for: Option<NodeId>,
    /// Whether it is locked.
    pub locked: bool,
}

/// One declared resource.
#[derive(Clone)]
pub(crate) struct Resource {
    pub(crate) name: Name,
    pub(crate) capacity: u32,
    pub(crate) pending_limit: Option<u32>,
    pub(crate) in_use: u32,
    // Holders in grant order.
    pub(crate) holders: Vec<(NodeId, u32)>,
    pub(crate) reserved_for: Option<NodeId>,
    pub(crate) locked: bool,
}

/// A waiting request.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Request {
    pub(crate) node: NodeId,
    pub(crate) priority: i32,
    pub(crate) order: u64,
}

/// Where a node stands with its resources.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) enum Grant {
    /// It has not asked (or it gave everything back).
    #[default]
    None,
    /// Its request waits.
    Waiting,
    /// It holds its grant.
    Held,
}

/// The run's resources and waiting requests.
#[derive(Clone, Default)]
pub(crate) struct Resources {
    pub(crate) list: Vec<Resource>,
    names: BTreeMap<Name, u32>,
    // Waiting requests in grant order: (priority, order).
    pub(crate) waiting: Vec<Request>,
    next_order: u64,
    // Something may have made room (a release, a withdrawal, an unlock …): scan before the next
    // ready node starts.
    pub(crate) dirty: bool,
    // How many resources are reserved (their reservations end with their holder's execution).
    reserved: u32,
    // The node whose request is being made (`request_resources`): it starts at once if granted.
    asking: Option<NodeId>,
}

/// Why a request cannot be granted now, for one of its resources.
pub(crate) enum Why {
    /// It asks for more than the capacity.
    OverCapacity { asked: u32 },
    /// Locked.
    Locked,
    /// Reserved for a subtree the node is not in.
    Reserved(NodeId),
    /// Not enough room: held by these.
    Held(Vec<NodeId>),
    /// Earlier requests that do not fit wait for it.
    Behind(Vec<NodeId>),
}

impl<A, F: Clone, S: Keep<Node<A, F>>> Engine<A, F, S> {
    /// Declares a resource of `capacity` units (at least 1), with at most `pending_limit` requests
    /// waiting for it (`None`: no limit; past it the oldest waiting request is dropped). The name
    /// must be new in the run. Traced as a `resource` record.
    pub fn declare_resource(
        &mut self,
        name: impl Into<Name>,
        capacity: u32,
        pending_limit: Option<u32>,
    ) -> Result<ResourceId, EngineError> {
        let name = name.into();
        if self.res.names.contains_key(&name) {
            return Err(EngineError::DuplicateResource(name.into_owned()));
        }
        if capacity == 0 {
            return Err(EngineError::ZeroCapacity(name.into_owned()));
        }
        let idx = self.res.list.len() as u32;
        self.res.names.insert(name.clone(), idx);
        emit!(
            self,
            TraceKind::Resource {
                resource: name.to_string(),
                capacity,
                pending_limit,
            }
        );
        self.res.list.push(Resource {
            name,
            capacity,
            pending_limit,
            in_use: 0,
            holders: Vec::new(),
            reserved_for: None,
            locked: false,
        });
        Ok(ResourceId { run: self.run, idx })
    }

    /// The resource declared under `name`.
    pub fn resource_id(&self, name: &str) -> Option<ResourceId> {
        self.res.names.get(name).map(|idx| ResourceId {
            run: self.run,
            idx: *idx,
        })
    }

    /// A snapshot of a resource; `None` for a resource of another run.
    pub fn resource_info(&self, r: ResourceId) -> Option<ResourceInfo> {
        let res = self.resource(r).ok()?;
        let waiting = self
            .res
            .waiting
            .iter()
            .filter(|q| {
                self.node(q.node)
                    .uses()
                    .is_some_and(|u| u.amounts.iter().any(|(x, _)| *x == r))
            })
            .map(|q| q.node)
            .collect();
        Some(ResourceInfo {
            name: res.name.to_string(),
            capacity: res.capacity,
            pending_limit: res.pending_limit,
            in_use: res.in_use,
            holders: res.holders.clone(),
            waiting,
            reserved_for: res.reserved_for,
            locked: res.locked,
        })
    }

    /// Reserves `r` for `holder` (TCA: reserved for one module): until it is unreserved, only
    /// `holder` and its descendants are granted it; others wait. A reservation for another holder
    /// is replaced. It ends by itself when the holder's execution completes.
    pub fn reserve_resource(
        &mut self,
        now: Time,
        r: ResourceId,
        holder: NodeId,
    ) -> Result<(), EngineError> {
        self.advance(now);
        self.resource(r)?;
        let display = self.live(holder)?.display;
        let res = &mut self.res.list[r.idx as usize];
        if res.reserved_for == Some(holder) {
            return Ok(());
        }
        if res.reserved_for.replace(holder).is_none() {
            self.res.reserved += 1;
        }
        let resource = res.name.to_string();
        emit!(
            self,
            TraceKind::ResourceReserved {
                resource,
                holder: display,
            }
        );
        self.res.dirty = true;
        self.settle();
        Ok(())
    }

    /// Ends the reservation of `r`, if it has one.
    pub fn unreserve_resource(&mut self, now: Time, r: ResourceId) -> Result<(), EngineError> {
        self.advance(now);
        self.resource(r)?;
        self.unreserve(r.idx);
        self.settle();
        Ok(())
    }

    /// Locks `r`: nobody is granted it until it is unlocked (grants already made stay).
    pub fn lock_resource(&mut self, now: Time, r: ResourceId) -> Result<(), EngineError> {
        self.set_locked(now, r, true)
    }

    /// Unlocks `r`: waiting requests may be granted it again.
    pub fn unlock_resource(&mut self, now: Time, r: ResourceId) -> Result<(), EngineError> {
        self.set_locked(now, r, false)
    }

    fn set_locked(&mut self, now: Time, r: ResourceId, on: bool) -> Result<(), EngineError> {
        self.advance(now);
        self.resource(r)?;
        let res = &mut self.res.list[r.idx as usize];
        if res.locked == on {
            return Ok(());
        }
        res.locked = on;
        let resource = res.name.to_string();
        emit!(
            self,
            if on {
                TraceKind::ResourceLocked { resource }
            } else {
                TraceKind::ResourceUnlocked { resource }
            }
        );
        self.res.dirty = true;
        self.settle();
        Ok(())
    }

    fn resource(&self, r: ResourceId) -> Result<&Resource, EngineError> {
        if r.run != self.run {
            return Err(EngineError::ForeignResource { run: self.run });
        }
        self.res
            .list
            .get(r.idx as usize)
            .ok_or(EngineError::ForeignResource { run: self.run })
    }

    /// Checks a spawn's uses against the declared resources, merging repeated resources.
    pub(super) fn validate_uses(&self, uses: &mut Uses) -> Result<(), EngineError> {
        let mut merged: Vec<(ResourceId, u32)> = Vec::with_capacity(uses.amounts.len());
        for (r, amount) in &uses.amounts {
            let res = self.resource(*r)?;
            if *amount == 0 {
                return Err(EngineError::ZeroAmount(res.name.to_string()));
            }
            match merged.iter_mut().find(|(x, _)| x == r) {
                Some((_, total)) => *total = total.saturating_add(*amount),
                None => merged.push((*r, *amount)),
            }
        }
        uses.amounts = merged;
        Ok(())
    }

    fn traced_uses(&self, uses: &Uses) -> Vec<ResourceUse> {
        uses.amounts
            .iter()
            .map(|(r, a)| ResourceUse::new(self.res.list[r.idx as usize].name.to_string(), *a))
            .collect()
    }

    /// Step 2: `id`, about to start, asks for its resources. Returns whether they are granted now
    /// (it may start); otherwise it waits (a later scan queues it when granted) or it failed.
    pub(super) fn request_resources(&mut self, id: NodeId) -> bool {
        let Some(uses) = self.node(id).uses().cloned() else {
            return true;
        };
        let display = self.node(id).display;
        if self.tracing {
            let traced = self.traced_uses(&uses);
            self.push_trace(TraceKind::Requested {
                node: display,
                uses: traced,
                priority: uses.priority,
            });
        }
        let order = self.res.next_order;
        self.res.next_order += 1;
        let req = Request {
            node: id,
            priority: uses.priority,
            order,
        };
        let at = self
            .res
            .waiting
            .partition_point(|q| (q.priority, q.order) <= (req.priority, req.order));
        self.res.waiting.insert(at, req);
        self.node_mut(id).set_grant(Grant::Waiting);
        // Asking for more than a capacity can never be granted.
        if let Some((r, asked)) = uses
            .amounts
            .iter()
            .find(|(r, a)| *a > self.res.list[r.idx as usize].capacity)
        {
            let why = Why::OverCapacity { asked: *asked };
            self.deny(id, *r, &why);
            return false;
        }
        self.res.asking = Some(id);
        self.scan_resources();
        self.res.asking = None;
        if self.node(id).grant() == Grant::Held {
            return true;
        }
        if uses.deny_if_busy {
            if let Some((r, why)) = self.why_waiting(id).into_iter().next() {
                self.deny(id, r, &why);
                return false;
            }
        }
        // A request past a pending limit drops the oldest waiting request for that resource.
        let mut dropped_self = false;
        for (r, _) in &uses.amounts {
            let Some(limit) = self.res.list[r.idx as usize].pending_limit else {
                continue;
            };
            loop {
                let waiting = self.waiting_for(*r);
                if waiting.len() <= limit as usize {
                    break;
                }
                let Some(oldest) = self
                    .res
                    .waiting
                    .iter()
                    .filter(|q| waiting.contains(&q.node))
                    .min_by_key(|q| q.order)
                    .map(|q| q.node)
                else {
                    break;
                };
                dropped_self |= oldest == id;
                self.drop_request(oldest, *r, limit, id);
            }
        }
        !dropped_self && self.node(id).grant() == Grant::Held
    }

    /// The waiting requests that use `r`, in grant order.
    fn waiting_for(&self, r: ResourceId) -> Vec<NodeId> {
        self.res
            .waiting
            .iter()
            .filter(|q| {
                self.nodes
                    .get(q.node)
                    .and_then(Node::uses)
                    .is_some_and(|u| u.amounts.iter().any(|(x, _)| *x == r))
            })
            .map(|q| q.node)
            .collect()
    }

    /// Takes `id`'s request out of the waiting list.
    fn unqueue(&mut self, id: NodeId) {
        self.res.waiting.retain(|q| q.node != id);
        self.node_mut(id).set_grant(Grant::None);
        self.res.dirty = true;
    }

    /// Step 4: `id`'s request is refused; it fails with [`ResourceDenied`].
    fn deny(&mut self, id: NodeId, r: ResourceId, why: &Why) {
        self.unqueue(id);
        let resource = self.res.list[r.idx as usize].name.to_string();
        let display = self.node(id).display;
        let reason = self.why_text(r, why);
        emit!(
            self,
            TraceKind::Denied {
                node: display,
                resource: resource.clone(),
            }
        );
        self.fail(id, Failure::from(ResourceDenied { resource, reason }));
        self.complete_handling(id);
    }

    /// Step 4: the waiting request of `id` is dropped for `newer`, past `r`'s pending `limit`; it
    /// fails with [`ResourceDropped`].
    fn drop_request(&mut self, id: NodeId, r: ResourceId, limit: u32, newer: NodeId) {
        self.unqueue(id);
        let resource = self.res.list[r.idx as usize].name.to_string();
        let display = self.node(id).display;
        let newer = self
            .nodes
            .get(newer)
            .map_or_else(String::new, |n| format!(" ({} {{{}}})", n.name, n.display));
        let reason = format!(
            "{limit} request(s) may wait for it, and a newer one came{newer}: the oldest waiting \
             request goes"
        );
        emit!(
            self,
            TraceKind::Dropped {
                node: display,
                resource: resource.clone(),
            }
        );
        self.fail(id, Failure::from(ResourceDropped { resource, reason }));
        self.complete_handling(id);
    }

    /// Step 3: grants the waiting requests that fit, in grant order, each all at once; queues the
    /// granted nodes to start (but `start`'s own, which goes on at once).
    #[cold]
    #[inline(never)]
    pub(super) fn scan_resources(&mut self) {
        self.res.dirty = false;
        if self.res.waiting.is_empty() {
            return;
        }
        // Resources an earlier request that does not fit waits for: nobody overtakes it there.
        let mut blocked = vec![false; self.res.list.len()];
        let mut i = 0;
        while i < self.res.waiting.len() {
            let q = self.res.waiting[i];
            let Some(n) = self.nodes.get(q.node) else {
                self.res.waiting.remove(i);
                continue;
            };
            let Some(uses) = n.uses() else {
                self.res.waiting.remove(i);
                continue;
            };
            // A suspended node is granted nothing while suspended, and holds no place.
            if n.suspended || !self.eligible(q.node, uses) {
                i += 1;
                continue;
            }
            let fits = uses.amounts.iter().all(|(r, a)| {
                let res = &self.res.list[r.idx as usize];
                !blocked[r.idx as usize] && res.in_use + a <= res.capacity
            });
            if !fits {
                for (r, _) in &uses.amounts {
                    blocked[r.idx as usize] = true;
                }
                i += 1;
                continue;
            }
            let uses = uses.clone();
            self.res.waiting.remove(i);
            self.grant(q.node, &uses);
        }
    }

    /// Whether no resource of the request is locked or reserved for a subtree `id` is not in.
    fn eligible(&self, id: NodeId, uses: &Uses) -> bool {
        uses.amounts.iter().all(|(r, _)| {
            let res = &self.res.list[r.idx as usize];
            !res.locked && res.reserved_for.is_none_or(|h| self.in_subtree(id, h))
        })
    }

    /// Whether `id` is `ancestor` or one of its descendants.
    pub(super) fn in_subtree(&self, id: NodeId, ancestor: NodeId) -> bool {
        let mut cur = Some(id);
        while let Some(c) = cur {
            if c == ancestor {
                return true;
            }
            cur = self.nodes.get(c).and_then(|n| n.parent);
        }
        false
    }

    fn grant(&mut self, id: NodeId, uses: &Uses) {
        for (r, a) in &uses.amounts {
            let res = &mut self.res.list[r.idx as usize];
            res.in_use += a;
            res.holders.push((id, *a));
        }
        self.node_mut(id).set_grant(Grant::Held);
        let display = self.node(id).display;
        if self.tracing {
            let traced = self.traced_uses(uses);
            self.push_trace(TraceKind::Granted {
                node: display,
                uses: traced,
            });
        }
        // It starts in its turn (`start` goes on at once with a grant made while it asks).
        if self.res.asking != Some(id) && self.node(id).state(Facet::Handling) == State::Enabled {
            self.ready.push_back(id);
        }
    }

    /// Step 5: `id` gives back its grant, or withdraws its waiting request.
    pub(super) fn release_resources(&mut self, id: NodeId) {
        // A run without resources pays one check here.
        if self.res.list.is_empty() {
            return;
        }
        let Some(n) = self.nodes.get(id) else { return };
        match n.grant() {
            Grant::None => {}
            Grant::Waiting => {
                let display = n.display;
                self.unqueue(id);
                emit!(self, TraceKind::Withdrawn { node: display });
            }
            Grant::Held => {
                let display = n.display;
                let Some(uses) = n.uses().cloned() else {
                    return;
                };
                for (r, a) in &uses.amounts {
                    let res = &mut self.res.list[r.idx as usize];
                    res.in_use -= a;
                    res.holders.retain(|(h, _)| *h != id);
                }
                self.node_mut(id).set_grant(Grant::None);
                self.res.dirty = true;
                if self.tracing {
                    let traced = self.traced_uses(&uses);
                    self.push_trace(TraceKind::Released {
                        node: display,
                        uses: traced,
                    });
                }
            }
        }
    }

    /// The execution of `id` completed: the reservations it holds end.
    pub(super) fn end_reservations_of(&mut self, id: NodeId) {
        if self.res.reserved == 0 {
            return;
        }
        for idx in 0..self.res.list.len() as u32 {
            if self.res.list[idx as usize].reserved_for == Some(id) {
                self.unreserve(idx);
            }
        }
    }

    fn unreserve(&mut self, idx: u32) {
        let res = &mut self.res.list[idx as usize];
        if res.reserved_for.take().is_none() {
            return;
        }
        self.res.reserved -= 1;
        emit!(
            self,
            TraceKind::ResourceUnreserved {
                resource: self.res.list[idx as usize].name.to_string(),
            }
        );
        self.res.dirty = true;
    }

    /// Why the waiting request of `id` is not granted, resource by resource (in its order); empty
    /// for a node that does not wait.
    pub(super) fn why_waiting(&self, id: NodeId) -> Vec<(ResourceId, Why)> {
        let mut out = Vec::new();
        let Some(n) = self.nodes.get(id) else {
            return out;
        };
        let Some(uses) = n.uses() else { return out };
        if n.grant() != Grant::Waiting {
            return out;
        }
        // The requests before it that do not fit, with what they ask for.
        let mut ahead: Vec<(NodeId, &Uses)> = Vec::new();
        for q in &self.res.waiting {
            if q.node == id {
                break;
            }
            if let Some(u) = self.nodes.get(q.node).and_then(Node::uses) {
                ahead.push((q.node, u));
            }
        }
        for (r, a) in &uses.amounts {
            let res = &self.res.list[r.idx as usize];
            let why = if *a > res.capacity {
                Why::OverCapacity { asked: *a }
            } else if res.locked {
                Why::Locked
            } else if let Some(h) = res.reserved_for.filter(|h| !self.in_subtree(id, *h)) {
                Why::Reserved(h)
            } else if res.in_use + a > res.capacity {
                Why::Held(res.holders.iter().map(|(h, _)| *h).collect())
            } else {
                let before: Vec<NodeId> = ahead
                    .iter()
                    .filter(|(_, u)| u.amounts.iter().any(|(x, _)| x == r))
                    .map(|(n, _)| *n)
                    .collect();
                if before.is_empty() {
                    continue;
                }
                Why::Behind(before)
            };
            out.push((*r, why));
        }
        out
    }

    /// `why` in words, about resource `r`.
    pub(super) fn why_text(&self, r: ResourceId, why: &Why) -> String {
        let res = &self.res.list[r.idx as usize];
        let names = |nodes: &[NodeId]| {
            let v: Vec<String> = nodes
                .iter()
                .filter_map(|n| self.nodes.get(*n))
                .map(|n| format!("{} {{{}}}", n.name, n.display))
                .collect();
            v.join(", ")
        };
        match why {
            Why::OverCapacity { asked } => format!(
                "it asks for {asked} of `{}`, whose capacity is {}",
                res.name, res.capacity
            ),
            Why::Locked => format!("`{}` is locked", res.name),
            Why::Reserved(h) => format!("`{}` is reserved for {}", res.name, names(&[*h])),
            Why::Held(holders) => format!(
                "{} of {} of `{}` are held by {}",
                res.in_use,
                res.capacity,
                res.name,
                names(holders)
            ),
            Why::Behind(nodes) => {
                format!("earlier requests wait for `{}`: {}", res.name, names(nodes))
            }
        }
    }
}
