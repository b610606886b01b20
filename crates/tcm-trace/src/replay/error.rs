//! Why a record cannot be applied to a [`Replay`](super::Replay), and the check of a recorded
//! state value against its variable's type.

use crate::state::{Facet, State, Termination};

/// Why a record could not be applied to a [`Replay`]; the replay is left unchanged.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum ReplayError {
    /// The record names a node that was never reserved or spawned.
    #[error("node {node} was never reserved or spawned")]
    UnknownNode {
        /// The node.
        node: u64,
    },
    /// The record needs a spawned node, but the node is only reserved, or dead.
    #[error("node {node} is not spawned")]
    NotSpawned {
        /// The node.
        node: u64,
    },
    /// A node number was reserved or spawned twice.
    #[error("node {node} already exists")]
    Duplicate {
        /// The node.
        node: u64,
    },
    /// The parent of a new node is unknown or not spawned.
    #[error("parent {parent} of node {node} is not a spawned node")]
    UnknownParent {
        /// The node.
        node: u64,
        /// Its parent.
        parent: u64,
    },
    /// The record would change the implicit root.
    #[error("the root (node 0) is implicit and never changes")]
    Root,
    /// A resource record does not fit the resources as declared and used so far (an unknown or
    /// twice declared resource, a grant without a request, a release without a grant).
    #[error("{0}")]
    Resource(String),
    /// A state record does not fit the variables declared so far (declared twice, set before it
    /// is declared, a value of another type).
    #[error("{0}")]
    State(String),
    /// A facet would move backwards or stay in place.
    #[error("node {node}: {facet} cannot move from {from} to {to}")]
    Backwards {
        /// The node.
        node: u64,
        /// The facet.
        facet: Facet,
        /// Its current state.
        from: State,
        /// The requested state.
        to: State,
    },
    /// Termination would move backwards or skip Terminating.
    #[error("node {node}: termination cannot move from {from:?} to {to:?}")]
    Termination {
        /// The node.
        node: u64,
        /// Its current termination state.
        from: Termination,
        /// The requested termination state.
        to: Termination,
    },
}

/// A recorded value must be of its variable's type (an unknown is of every type).
pub(crate) fn check_value(
    var: &str,
    ty: tcm_expr::Type,
    value: &tcm_expr::Value,
) -> Result<(), ReplayError> {
    match value.type_of() {
        Some(t) if t != ty => Err(ReplayError::State(format!(
            "state variable `{var}` is a `{ty}`, but the record gives it `{value}`"
        ))),
        _ => Ok(()),
    }
}
