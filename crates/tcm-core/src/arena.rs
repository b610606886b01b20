//! Node storage: a generational arena.
//!
//! Slots are reused after a node is reclaimed; every reuse bumps the slot's generation, so an old
//! [`NodeId`] can never reach the new occupant. The slot remembers the fate of its last occupant,
//! which lets the engine answer constraints naming a node that was already reclaimed.

use crate::engine::node::Node;
use crate::ids::NodeId;

/// How a reclaimed node ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Fate {
    /// Its execution completed normally.
    Completed,
    /// It was terminated.
    Terminated,
    /// It was reserved for a spawn that never happened.
    Dead,
}

struct Slot<A, F> {
    generation: u32,
    node: Option<Node<A, F>>,
    // Invariant: meaningful only while `node` is None and generation > 0.
    fate: Fate,
}

/// What a handle refers to.
pub(crate) enum Lookup {
    /// The node is in the arena.
    Live,
    /// The node was reclaimed; this is how it ended.
    Gone(Fate),
}

pub(crate) struct Arena<A, F> {
    run: u32,
    slots: Vec<Slot<A, F>>,
    free: Vec<u32>,
    live: usize,
    high_water: usize,
}

impl<A, F> Arena<A, F> {
    pub(crate) fn new(run: u32) -> Arena<A, F> {
        Arena {
            run,
            slots: Vec::new(),
            free: Vec::new(),
            live: 0,
            high_water: 0,
        }
    }

    pub(crate) fn insert(&mut self, node: Node<A, F>) -> NodeId {
        self.live += 1;
        self.high_water = self.high_water.max(self.live);
        if let Some(idx) = self.free.pop() {
            let slot = &mut self.slots[idx as usize];
            slot.generation = slot.generation.wrapping_add(1);
            slot.node = Some(node);
            NodeId {
                run: self.run,
                idx,
                generation: slot.generation,
            }
        } else {
            let idx = u32::try_from(self.slots.len()).expect("more than 2^32 live nodes");
            self.slots.push(Slot {
                generation: 0,
                node: Some(node),
                fate: Fate::Completed,
            });
            NodeId {
                run: self.run,
                idx,
                generation: 0,
            }
        }
    }

    pub(crate) fn remove(&mut self, id: NodeId, fate: Fate) -> Option<Node<A, F>> {
        let slot = self.slots.get_mut(id.idx as usize)?;
        if slot.generation != id.generation {
            return None;
        }
        let node = slot.node.take()?;
        slot.fate = fate;
        self.free.push(id.idx);
        self.live -= 1;
        Some(node)
    }

    pub(crate) fn get(&self, id: NodeId) -> Option<&Node<A, F>> {
        let slot = self.slots.get(id.idx as usize)?;
        if slot.generation != id.generation {
            return None;
        }
        slot.node.as_ref()
    }

    pub(crate) fn get_mut(&mut self, id: NodeId) -> Option<&mut Node<A, F>> {
        let slot = self.slots.get_mut(id.idx as usize)?;
        if slot.generation != id.generation {
            return None;
        }
        slot.node.as_mut()
    }

    /// Whether the handle names a live node or a reclaimed one (and how it ended). A handle whose
    /// slot was reused since counts as completed: every point of that node has long passed.
    pub(crate) fn lookup(&self, id: NodeId) -> Lookup {
        match self.slots.get(id.idx as usize) {
            Some(slot) if slot.generation == id.generation => match slot.node {
                Some(_) => Lookup::Live,
                None => Lookup::Gone(slot.fate),
            },
            _ => Lookup::Gone(Fate::Completed),
        }
    }

    /// The handle of the live node in slot `link`, if any.
    pub(crate) fn id_at(&self, link: crate::engine::node::Link) -> Option<NodeId> {
        let slot = self.slots.get(link.0 as usize)?;
        slot.node.as_ref()?;
        Some(NodeId {
            run: self.run,
            idx: link.0,
            generation: slot.generation,
        })
    }

    pub(crate) fn live(&self) -> usize {
        self.live
    }

    pub(crate) fn high_water(&self) -> usize {
        self.high_water
    }

    pub(crate) fn iter(&self) -> impl Iterator<Item = (NodeId, &Node<A, F>)> {
        let run = self.run;
        self.slots
            .iter()
            .enumerate()
            .filter_map(move |(idx, slot)| {
                slot.node.as_ref().map(|n| {
                    (
                        NodeId {
                            run,
                            idx: idx as u32,
                            generation: slot.generation,
                        },
                        n,
                    )
                })
            })
    }
}
