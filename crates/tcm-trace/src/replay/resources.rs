//! Resources as the trace tells them (docs/semantics.md, "Resources"): each declared resource with
//! its holders, its waiting requests, its reservation and its lock, and each node's request and
//! grant. The checker reads this state just before each record; the text log names holders from it.

use super::{Replay, ReplayError, ReplayNode};
use crate::event::{ResourceUse, TraceKind};

/// One declared resource of a [`Replay`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ReplayResource {
    name: String,
    capacity: u32,
    pending_limit: Option<u32>,
    // Nodes holding a grant of it, in grant order, with their amounts.
    holders: Vec<(u64, u32)>,
    // Nodes whose request for it waits, in request order.
    pending: Vec<u64>,
    reserved_for: Option<u64>,
    locked: bool,
}

impl ReplayResource {
    /// Its name.
    pub fn name(&self) -> &str {
        &self.name
    }
    /// Its capacity.
    pub fn capacity(&self) -> u32 {
        self.capacity
    }
    /// Most requests that may wait for it.
    pub fn pending_limit(&self) -> Option<u32> {
        self.pending_limit
    }
    /// The units granted and not released.
    pub fn in_use(&self) -> u64 {
        self.holders.iter().map(|(_, a)| u64::from(*a)).sum()
    }
    /// The nodes holding some of it, in grant order, with their amounts.
    pub fn holders(&self) -> &[(u64, u32)] {
        &self.holders
    }
    /// The nodes whose request for it waits, in request order.
    pub fn pending(&self) -> &[u64] {
        &self.pending
    }
    /// The node whose subtree alone may be granted it, if it is reserved.
    pub fn reserved_for(&self) -> Option<u64> {
        self.reserved_for
    }
    /// Whether it is locked.
    pub fn is_locked(&self) -> bool {
        self.locked
    }
}

impl Replay {
    /// The declared resource `name`.
    pub fn resource(&self, name: &str) -> Option<&ReplayResource> {
        self.resources.get(name)
    }

    /// Every declared resource, by name.
    pub fn resources(&self) -> impl Iterator<Item = &ReplayResource> {
        self.resources.values()
    }

    /// Whether `node` is `ancestor` or one of its descendants.
    pub fn is_in_subtree(&self, node: u64, ancestor: u64) -> bool {
        let mut cur = Some(node);
        while let Some(n) = cur {
            if n == ancestor {
                return true;
            }
            cur = self.nodes.get(&n).and_then(ReplayNode::parent);
        }
        false
    }

    fn known(&self, uses: &[ResourceUse]) -> Result<(), ReplayError> {
        match uses
            .iter()
            .find(|u| !self.resources.contains_key(&u.resource))
        {
            Some(u) => Err(ReplayError::Resource(format!(
                "resource `{}` was never declared",
                u.resource
            ))),
            None => Ok(()),
        }
    }

    fn declared(&mut self, name: &str) -> Result<&mut ReplayResource, ReplayError> {
        self.resources
            .get_mut(name)
            .ok_or_else(|| ReplayError::Resource(format!("resource `{name}` was never declared")))
    }

    /// Applies a resource record; on error nothing changes.
    pub(super) fn apply_resource(&mut self, kind: &TraceKind) -> Result<(), ReplayError> {
        match kind {
            TraceKind::Resource {
                resource,
                capacity,
                pending_limit,
            } => {
                if self.resources.contains_key(resource) {
                    return Err(ReplayError::Resource(format!(
                        "resource `{resource}` is declared twice"
                    )));
                }
                self.resources.insert(
                    resource.clone(),
                    ReplayResource {
                        name: resource.clone(),
                        capacity: *capacity,
                        pending_limit: *pending_limit,
                        holders: Vec::new(),
                        pending: Vec::new(),
                        reserved_for: None,
                        locked: false,
                    },
                );
            }
            TraceKind::Requested { node, uses, .. } => {
                self.known(uses)?;
                let it = self.node_mut(*node)?;
                if it.request.is_some() || it.grant.is_some() {
                    return Err(ReplayError::Resource(format!(
                        "node {node} asks for resources while it waits for or holds some"
                    )));
                }
                it.request = Some(uses.clone());
                it.requested = true;
                for u in uses {
                    self.declared(&u.resource)?.pending.push(*node);
                }
            }
            TraceKind::Granted { node, uses } => {
                self.known(uses)?;
                let it = self.node_mut(*node)?;
                if it.request.is_none() {
                    return Err(ReplayError::Resource(format!(
                        "node {node} is granted resources it did not ask for"
                    )));
                }
                it.request = None;
                it.grant = Some(uses.clone());
                self.unqueue(*node);
                for u in uses {
                    self.declared(&u.resource)?.holders.push((*node, u.amount));
                }
            }
            TraceKind::Released { node, uses } => {
                self.known(uses)?;
                let it = self.node_mut(*node)?;
                if it.grant.is_none() {
                    return Err(ReplayError::Resource(format!(
                        "node {node} releases resources it does not hold"
                    )));
                }
                it.grant = None;
                for r in self.resources.values_mut() {
                    r.holders.retain(|(n, _)| n != node);
                }
            }
            TraceKind::Withdrawn { node }
            | TraceKind::Denied { node, .. }
            | TraceKind::Dropped { node, .. } => {
                let it = self.node_mut(*node)?;
                if it.request.take().is_none() {
                    return Err(ReplayError::Resource(format!(
                        "node {node} has no request waiting"
                    )));
                }
                self.unqueue(*node);
            }
            TraceKind::ResourceReserved { resource, holder } => {
                self.spawned(*holder)?;
                self.declared(resource)?.reserved_for = Some(*holder);
            }
            TraceKind::ResourceUnreserved { resource } => {
                self.declared(resource)?.reserved_for = None;
            }
            TraceKind::ResourceLocked { resource } => self.declared(resource)?.locked = true,
            TraceKind::ResourceUnlocked { resource } => self.declared(resource)?.locked = false,
            _ => {}
        }
        Ok(())
    }

    /// Takes `node` out of every resource's waiting list.
    fn unqueue(&mut self, node: u64) {
        for r in self.resources.values_mut() {
            r.pending.retain(|n| *n != node);
        }
    }
}
