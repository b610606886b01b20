//! Node storage: a generational arena.
//!
//! Slots are reused after a node is reclaimed; every reuse bumps the slot's generation, so an old
//! [`NodeId`] can never reach the new occupant. The slot remembers the fate of its last occupant,
//! which lets the engine answer constraints naming a node that was already reclaimed.
//!
//! A slot keeps its node as the engine's store says ([`Keep`]): in place ([`Owned`], a run), or
//! shared between clones of an engine until one of them writes it ([`Shared`], the model checker,
//! which clones an engine for every transition and changes a few of its nodes).

use crate::engine::node::Node;
use crate::ids::NodeId;
use std::rc::Rc;

mod sealed {
    pub trait Sealed {}
    impl Sealed for super::Owned {}
    impl Sealed for super::Shared {}
}

/// How an engine keeps its nodes: [`Owned`] or [`Shared`]. Sealed: the two are the only ones.
pub trait Keep<T>: sealed::Sealed {
    #[doc(hidden)]
    type Slot;
    #[doc(hidden)]
    fn wrap(t: T) -> Self::Slot;
    #[doc(hidden)]
    fn get(s: &Self::Slot) -> &T;
    #[doc(hidden)]
    fn get_mut(s: &mut Self::Slot) -> &mut T;
    #[doc(hidden)]
    fn unwrap(s: Self::Slot) -> T;
    #[doc(hidden)]
    fn dup(s: &Self::Slot) -> Self::Slot
    where
        T: Clone;
    /// The arena's chunks hold `1 << CHUNK_BITS` slots.
    #[doc(hidden)]
    const CHUNK_BITS: u32;
    /// How the arena keeps a chunk of slots.
    #[doc(hidden)]
    type Chunk<E>;
    /// A new chunk, its slots never used (`empty` makes one).
    #[doc(hidden)]
    fn new_chunk<E>(empty: impl FnMut() -> E) -> Self::Chunk<E>;
    /// Slot `i` of a chunk (`i < 1 << CHUNK_BITS`), if it exists.
    #[doc(hidden)]
    fn at<E>(c: &Self::Chunk<E>, i: usize) -> Option<&E>;
    #[doc(hidden)]
    fn at_mut<E>(c: &mut Self::Chunk<E>, i: usize) -> Option<&mut E>;
    /// Fills slot `i`, the first never used in the chunk.
    #[doc(hidden)]
    fn put<E>(c: &mut Self::Chunk<E>, i: usize, e: E);
    #[doc(hidden)]
    fn dup_chunk<E: Clone>(c: &Self::Chunk<E>) -> Self::Chunk<E>;
    /// The chunk's slots, in order (those never used included, or not).
    #[doc(hidden)]
    fn slots<E>(c: &Self::Chunk<E>) -> &[E];
}

/// Each node in its slot, owned by one engine: what a run uses (the default).
#[derive(Clone, Copy, Debug, Default)]
pub struct Owned;

/// Nodes shared between clones of an engine until one of them changes the node (copy on write):
/// cloning the engine copies a pointer per node, and a transition then copies only the nodes it
/// changes. For engines cloned often, as a model checker does; not `Send`.
#[derive(Clone, Copy, Debug, Default)]
pub struct Shared;

impl<T> Keep<T> for Owned {
    type Slot = T;
    #[inline]
    fn wrap(t: T) -> T {
        t
    }
    #[inline]
    fn get(s: &T) -> &T {
        s
    }
    #[inline]
    fn get_mut(s: &mut T) -> &mut T {
        s
    }
    #[inline]
    fn unwrap(s: T) -> T {
        s
    }
    #[inline]
    fn dup(s: &T) -> T
    where
        T: Clone,
    {
        s.clone()
    }
    // A run's chunk is an array of its full size, every slot made empty at once, so that a
    // slot's place in it needs no check: the engine's hottest path, every lookup of a node. It is
    // small (13 KB for 64 slots of a 200-byte node), so that a run's first spawn does not pay the
    // first touch of a large block: 1,024 slots cost a polling monitor's start 60-90 us of page
    // faults, which every activation's lateness then carried.
    const CHUNK_BITS: u32 = 6;
    type Chunk<E> = Box<[E; OWNED_CHUNK]>;
    fn new_chunk<E>(empty: impl FnMut() -> E) -> Box<[E; OWNED_CHUNK]> {
        full_chunk(std::iter::repeat_with(empty))
    }
    #[inline(always)]
    fn at<E>(c: &Box<[E; OWNED_CHUNK]>, i: usize) -> Option<&E> {
        Some(&c[i & (OWNED_CHUNK - 1)])
    }
    #[inline(always)]
    fn at_mut<E>(c: &mut Box<[E; OWNED_CHUNK]>, i: usize) -> Option<&mut E> {
        Some(&mut c[i & (OWNED_CHUNK - 1)])
    }
    #[inline]
    fn put<E>(c: &mut Box<[E; OWNED_CHUNK]>, i: usize, e: E) {
        c[i & (OWNED_CHUNK - 1)] = e;
    }
    fn dup_chunk<E: Clone>(c: &Box<[E; OWNED_CHUNK]>) -> Box<[E; OWNED_CHUNK]> {
        full_chunk(c.iter().cloned())
    }
    fn slots<E>(c: &Box<[E; OWNED_CHUNK]>) -> &[E] {
        &c[..]
    }
}

/// Slots per chunk of an [`Owned`] store.
const OWNED_CHUNK: usize = 1 << <Owned as Keep<()>>::CHUNK_BITS;

/// A chunk of the first `OWNED_CHUNK` elements of `slots`, built on the heap.
fn full_chunk<E>(slots: impl Iterator<Item = E>) -> Box<[E; OWNED_CHUNK]> {
    let all: Box<[E]> = slots.take(OWNED_CHUNK).collect();
    match all.try_into() {
        Ok(chunk) => chunk,
        Err(_) => unreachable!("a chunk is made of OWNED_CHUNK slots"),
    }
}

impl<T: Clone> Keep<T> for Shared {
    type Slot = Rc<T>;
    #[inline]
    fn wrap(t: T) -> Rc<T> {
        Rc::new(t)
    }
    #[inline]
    fn get(s: &Rc<T>) -> &T {
        s
    }
    #[inline]
    fn get_mut(s: &mut Rc<T>) -> &mut T {
        Rc::make_mut(s)
    }
    #[inline]
    fn unwrap(s: Rc<T>) -> T {
        Rc::unwrap_or_clone(s)
    }
    #[inline]
    fn dup(s: &Rc<T>) -> Rc<T> {
        Rc::clone(s)
    }
    // A model checker keeps many engines, most of them small: a chunk holds the slots used so
    // far, and a clone only those (one allocation for up to 1,024 of them).
    const CHUNK_BITS: u32 = 10;
    type Chunk<E> = Vec<E>;
    fn new_chunk<E>(_: impl FnMut() -> E) -> Vec<E> {
        Vec::with_capacity(1 << <Self as Keep<T>>::CHUNK_BITS)
    }
    #[inline]
    fn at<E>(c: &Vec<E>, i: usize) -> Option<&E> {
        c.get(i)
    }
    #[inline]
    fn at_mut<E>(c: &mut Vec<E>, i: usize) -> Option<&mut E> {
        c.get_mut(i)
    }
    fn put<E>(c: &mut Vec<E>, _: usize, e: E) {
        c.push(e);
    }
    fn dup_chunk<E: Clone>(c: &Vec<E>) -> Vec<E> {
        c.clone()
    }
    fn slots<E>(c: &Vec<E>) -> &[E] {
        c
    }
}

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

struct Slot<A, F, S: Keep<Node<A, F>>> {
    generation: u32,
    node: Option<S::Slot>,
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

// Storage grows a chunk at a time and never moves: no reallocation copies (which would briefly
// double the memory of a million-node tree), and no slot ever moves. How large a chunk is, and
// how it is kept, depend on the store (`Keep::CHUNK_BITS`, `Keep::Chunk`).

pub(crate) struct Arena<A, F, S: Keep<Node<A, F>>> {
    run: u32,
    // Invariant: every chunk but the last is full; the slots from `n_slots` on were never used
    // (empty, generation 0; in a `Shared` store, not there yet).
    chunks: Vec<S::Chunk<Slot<A, F, S>>>,
    n_slots: usize,
    free: Vec<u32>,
    live: usize,
    high_water: usize,
}

impl<A: Clone, F: Clone, S: Keep<Node<A, F>>> Clone for Slot<A, F, S> {
    fn clone(&self) -> Self {
        Slot {
            generation: self.generation,
            node: self.node.as_ref().map(S::dup),
            fate: self.fate,
        }
    }
}

impl<A: Clone, F: Clone, S: Keep<Node<A, F>>> Clone for Arena<A, F, S> {
    fn clone(&self) -> Self {
        Arena {
            run: self.run,
            chunks: self.chunks.iter().map(S::dup_chunk).collect(),
            n_slots: self.n_slots,
            free: self.free.clone(),
            live: self.live,
            high_water: self.high_water,
        }
    }
}

impl<A, F, S: Keep<Node<A, F>>> Arena<A, F, S> {
    pub(crate) fn new(run: u32) -> Arena<A, F, S> {
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
            slot.node = Some(S::wrap(node));
            NodeId {
                run,
                idx,
                generation: slot.generation,
            }
        } else {
            let idx = u32::try_from(self.n_slots).expect("more than 2^32 live nodes");
            let mask = (1usize << S::CHUNK_BITS) - 1;
            if self.n_slots & mask == 0 {
                self.chunks.push(S::new_chunk(|| Slot {
                    generation: 0,
                    node: None,
                    fate: Fate::Completed,
                }));
            }
            if let Some(chunk) = self.chunks.last_mut() {
                S::put(
                    chunk,
                    idx as usize & mask,
                    Slot {
                        generation: 0,
                        node: Some(S::wrap(node)),
                        fate: Fate::Completed,
                    },
                );
            }
            self.n_slots += 1;
            NodeId {
                run: self.run,
                idx,
                generation: 0,
            }
        }
    }

    #[inline]
    fn slot(&self, idx: u32) -> Option<&Slot<A, F, S>> {
        S::at(
            self.chunks.get((idx >> S::CHUNK_BITS) as usize)?,
            idx as usize & ((1 << S::CHUNK_BITS) - 1),
        )
    }

    #[inline]
    fn slot_mut(&mut self, idx: u32) -> Option<&mut Slot<A, F, S>> {
        S::at_mut(
            self.chunks.get_mut((idx >> S::CHUNK_BITS) as usize)?,
            idx as usize & ((1 << S::CHUNK_BITS) - 1),
        )
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
        Some(S::unwrap(node))
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
    #[inline]
    pub(crate) fn get(&self, id: NodeId) -> Option<&Node<A, F>> {
        let slot = self.slot(id.idx)?;
        if slot.generation != id.generation {
            return None;
        }
        slot.node.as_ref().map(S::get)
    }

    #[inline]
    pub(crate) fn get_mut(&mut self, id: NodeId) -> Option<&mut Node<A, F>> {
        let slot = self.slot_mut(id.idx)?;
        if slot.generation != id.generation {
            return None;
        }
        slot.node.as_mut().map(S::get_mut)
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

    /// The live node in slot `link`, if any (a link names a live node, whose generation is the
    /// slot's).
    #[inline]
    pub(crate) fn get_mut_at(
        &mut self,
        link: crate::engine::node::Link,
    ) -> Option<&mut Node<A, F>> {
        self.slot_mut(link.0)?.node.as_mut().map(S::get_mut)
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
            .flat_map(|c| S::slots(c))
            .take(self.n_slots)
            .enumerate()
            .filter_map(move |(idx, slot)| {
                slot.node.as_ref().map(S::get).map(|n| {
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
