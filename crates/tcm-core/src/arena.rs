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

#[derive(Clone)]
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

/// Slots per chunk. Storage grows a chunk at a time and never moves: no reallocation copies
/// (which would briefly double the memory of a million-node tree), and no slot ever moves.
const CHUNK_BITS: u32 = 10;
const CHUNK: usize = 1 << CHUNK_BITS;

#[derive(Clone)]
pub(crate) struct Arena<A, F> {
    run: u32,
    // Invariant: every chunk but the last is full (CHUNK slots); each has capacity CHUNK.
    chunks: Vec<Vec<Slot<A, F>>>,
    n_slots: usize,
    free: Vec<u32>,
    live: usize,
    high_water: usize,
}

impl<A, F> Arena<A, F> {
    pub(crate) fn new(run: u32) -> Arena<A, F> {
        Arena {
            run,
            chunks: Vec::new(),
            n_slots: 0,
            free: Vec::new(),
            live: 0,
            high_water: 0,
        }
    }

    pub(crate) fn insert(&mut self, node: Node<A, F>) -> NodeId {
        self.live += 1;
        self.high_water = self.high_water.max(self.live);
        let run = self.run;
        if let Some(idx) = self.free.pop() {
            let Some(slot) = self.slot_mut(idx) else {
                unreachable!("a free index names an existing slot");
            };
            slot.generation = slot.generation.wrapping_add(1);
            slot.node = Some(node);
            NodeId {
                run,
                idx,
                generation: slot.generation,
            }
        } else {
            let idx = u32::try_from(self.n_slots).expect("more than 2^32 live nodes");
            if self.n_slots % CHUNK == 0 {
                self.chunks.push(Vec::with_capacity(CHUNK));
            }
            if let Some(chunk) = self.chunks.last_mut() {
                chunk.push(Slot {
                    generation: 0,
                    node: Some(node),
                    fate: Fate::Completed,
                });
            }
            self.n_slots += 1;
            NodeId {
                run: self.run,
                idx,
                generation: 0,
            }
        }
    }

    fn slot(&self, idx: u32) -> Option<&Slot<A, F>> {
        self.chunks
            .get((idx >> CHUNK_BITS) as usize)?
            .get(idx as usize & (CHUNK - 1))
    }

    fn slot_mut(&mut self, idx: u32) -> Option<&mut Slot<A, F>> {
        self.chunks
            .get_mut((idx >> CHUNK_BITS) as usize)?
            .get_mut(idx as usize & (CHUNK - 1))
    }

    pub(crate) fn remove(&mut self, id: NodeId, fate: Fate) -> Option<Node<A, F>> {
        let slot = self.slot_mut(id.idx)?;
        if slot.generation != id.generation {
            return None;
        }
        let node = slot.node.take()?;
        slot.fate = fate;
        self.free.push(id.idx);
        self.live -= 1;
        Some(node)
    }

    /// Frees the node's slot, dropping the node where it lies (no copy out).
    pub(crate) fn discard(&mut self, id: NodeId, fate: Fate) {
        let Some(slot) = self.slot_mut(id.idx) else {
            return;
        };
        if slot.generation != id.generation || slot.node.is_none() {
            return;
        }
        slot.node = None;
        slot.fate = fate;
        self.free.push(id.idx);
        self.live -= 1;
    }

    /// The node a handle names, if it is live. The run is not checked here (this is the engine's
    /// hottest path): the engine's entry points check it once (`Engine::check_run`).
    pub(crate) fn get(&self, id: NodeId) -> Option<&Node<A, F>> {
        let slot = self.slot(id.idx)?;
        if slot.generation != id.generation {
            return None;
        }
        slot.node.as_ref()
    }

    pub(crate) fn get_mut(&mut self, id: NodeId) -> Option<&mut Node<A, F>> {
        let slot = self.slot_mut(id.idx)?;
        if slot.generation != id.generation {
            return None;
        }
        slot.node.as_mut()
    }

    /// Whether the handle names a live node or a reclaimed one (and how it ended). A handle whose
    /// slot was reused since counts as completed: every point of that node has long passed.
    pub(crate) fn lookup(&self, id: NodeId) -> Lookup {
        match self.slot(id.idx) {
            Some(slot) if slot.generation == id.generation => match slot.node {
                Some(_) => Lookup::Live,
                None => Lookup::Gone(slot.fate),
            },
            _ => Lookup::Gone(Fate::Completed),
        }
    }

    /// The handle of the live node in slot `link`, if any.
    pub(crate) fn id_at(&self, link: crate::engine::node::Link) -> Option<NodeId> {
        let slot = self.slot(link.0)?;
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
        self.chunks
            .iter()
            .flatten()
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
