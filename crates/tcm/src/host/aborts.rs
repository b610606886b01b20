//! The running actions by node, for their cancellation ([`Aborts`]): a tokio task's abort handle,
//! a future the pump holds or parked.

use super::TaskRef;
use crate::pump::Parked;
use std::collections::BTreeMap;
use std::sync::Arc;
use tcm_core::NodeId;
use tokio::task::AbortHandle;

/// How a running action runs: held by the pump that polls it (`pump.rs`), as a tokio task, or
/// parked by the pump until its first wake-up.
pub(crate) enum Running {
    Inline,
    Task(AbortHandle),
    Parked(Arc<Parked>),
}

/// The running actions, by the node's storage slot (dense, so a vector beats a map on the path
/// every action takes). The vector is as long as the highest slot a running action has used, so an
/// entry is kept small (16 bytes: a million nodes alive at once cost 16 MB here): the node's
/// generation in its slot (all the nodes of one host are of one run) and, for a task, its abort
/// handle (none: the pump holds it).
#[derive(Default)]
pub(crate) struct Aborts {
    slots: Vec<AbortSlot>,
    len: usize,
    // The parked actions (fewer: only those that awaited), kept apart so that a slot stays small.
    parked: BTreeMap<NodeId, Arc<Parked>>,
}

#[derive(Default)]
struct AbortSlot {
    // The running node's generation plus one; 0: no action runs in this slot.
    tag: u32,
    // Whether the action is parked (in `Aborts::parked`).
    parked: bool,
    handle: Option<AbortHandle>,
}

/// What an entry of [`Aborts`] holds for `node` (its generation plus one: never 0).
fn tag(node: NodeId) -> u32 {
    node.generation().wrapping_add(1).max(1)
}

impl Aborts {
    #[inline]
    pub(super) fn insert(&mut self, node: NodeId, r: Running) {
        let i = node.slot() as usize;
        // Slots are mostly new one at a time, in order.
        while self.slots.len() <= i {
            self.slots.push(AbortSlot::default());
        }
        let (handle, parked) = match r {
            Running::Inline => (None, false),
            Running::Task(h) => (Some(h), false),
            Running::Parked(p) => {
                self.parked.insert(node, p);
                (None, true)
            }
        };
        let old = std::mem::replace(
            &mut self.slots[i],
            AbortSlot {
                tag: tag(node),
                parked,
                handle,
            },
        );
        if old.tag == 0 {
            self.len += 1;
        }
    }

    #[inline]
    pub(super) fn remove(&mut self, node: &NodeId) -> Option<Running> {
        let slot = self.slots.get_mut(node.slot() as usize)?;
        if slot.tag != tag(*node) {
            return None;
        }
        self.len -= 1;
        let AbortSlot { handle, parked, .. } = std::mem::take(slot);
        if parked {
            if let Some(p) = self.parked.remove(node) {
                return Some(Running::Parked(p));
            }
        }
        Some(match handle {
            Some(h) => Running::Task(h),
            None => Running::Inline,
        })
    }

    /// The action the pump held is parked; false if it is no longer running (cancelled).
    pub(super) fn set_parked(&mut self, node: NodeId, p: Arc<Parked>) -> bool {
        match self.slots.get_mut(node.slot() as usize) {
            Some(slot) if slot.tag == tag(node) => {
                slot.parked = true;
                self.parked.insert(node, p);
                true
            }
            _ => false,
        }
    }

    /// The action the pump held became a task; false if it is no longer running (cancelled).
    pub(super) fn set_task(&mut self, node: NodeId, h: AbortHandle) -> bool {
        match self.slots.get_mut(node.slot() as usize) {
            Some(slot) if slot.tag == tag(node) => {
                slot.handle = Some(h);
                true
            }
            _ => false,
        }
    }

    pub(crate) fn contains(&self, node: NodeId) -> bool {
        self.slots
            .get(node.slot() as usize)
            .is_some_and(|s| s.tag == tag(node))
    }

    /// Takes every running task (those the pump holds, it drops itself).
    pub(crate) fn drain(&mut self) -> impl Iterator<Item = TaskRef> + '_ {
        self.len = 0;
        let parked = std::mem::take(&mut self.parked);
        self.slots
            .iter_mut()
            .filter_map(|s| std::mem::take(s).handle.map(TaskRef::Task))
            .chain(parked.into_values().map(TaskRef::Parked))
    }
}
