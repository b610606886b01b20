//! Identifiers handed out by the core.
//!
//! A [`NodeId`] names a node of one run: it carries the run's number, so a handle from another run is
//! refused rather than silently aliased, and a generation, so a handle to a reclaimed node can never
//! reach the node that reuses its slot.

use std::fmt;

/// A handle to a task-tree node of one run. Copyable; it stays valid (and harmless) after the node is
/// reclaimed: the engine then answers from the node's recorded fate.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct NodeId {
    pub(crate) run: u32,
    pub(crate) idx: u32,
    pub(crate) generation: u32,
}

impl NodeId {
    /// The number of the run this node belongs to.
    pub fn run(self) -> u32 {
        self.run
    }

    /// The index of the node's storage slot: small and dense, so a shell can keep per-node data in
    /// a vector. Slots are reused after a node is reclaimed: compare the whole id too.
    pub fn slot(self) -> u32 {
        self.idx
    }

    /// How many nodes used its storage slot before it: with [`NodeId::slot`] and the run, what
    /// tells this node apart from the others that use or used the same slot.
    pub fn generation(self) -> u32 {
        self.generation
    }
}

impl fmt::Display for NodeId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "node#{}.{}@run{}", self.idx, self.generation, self.run)
    }
}

/// A named external event (or a manual signal gate), interned by the engine.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct ExternalId(pub(crate) u32);

/// A state variable, declared with `Engine::declare_state`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct StateId(pub(crate) u32);

/// A condition over state variables, registered (and interned by its text) with
/// `Engine::condition`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct CondId(pub(crate) u32);

/// A token the shell chooses when it asks to be told about an event (`Engine::watch`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct WatchToken(pub u64);

/// A handler attached from outside to a task (`Engine::handler_for`, `Engine::attach`), for
/// `Engine::detach`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct AttachId(pub(crate) u32);

impl AttachId {
    /// Its number, as the trace's `handler_attached` record gives it.
    pub fn number(self) -> u32 {
        self.0
    }
}

/// A wiretap registered with `Engine::wiretap`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct WiretapId(pub(crate) u32);

impl WiretapId {
    /// Its number, as the trace's `tapped` records give it.
    pub fn number(self) -> u32 {
        self.0
    }
}

/// When a wiretap runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum TapWhen {
    /// When a tapped node is about to start its action: a failing check fails the node instead.
    Before,
    /// When a tapped node's action returned successfully: a failing check fails the node.
    After,
}

/// A resource of one run, declared with `Engine::declare_resource` (docs/semantics.md,
/// "Resources"). It carries its run's number: a resource of another run is refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct ResourceId {
    pub(crate) run: u32,
    pub(crate) idx: u32,
}
