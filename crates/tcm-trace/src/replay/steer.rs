//! What the fold knows of a steered run (docs/semantics.md, "Steering a run"): whether it is
//! paused, and which nodes are held for approval.

use super::Replay;
use crate::state::State;

impl Replay {
    /// Why the run is paused after the records applied so far, if it is (docs/semantics.md,
    /// "Steering a run").
    pub fn paused(&self) -> Option<&str> {
        self.paused.as_deref()
    }

    /// The nodes held for an operator's approval now (`held` records not yet followed by their
    /// `approved`, nor by the end of their handling), in number order.
    pub fn held(&self) -> impl Iterator<Item = u64> + '_ {
        self.held.iter().copied().filter(|n| {
            self.nodes
                .get(n)
                .is_some_and(|n| n.facets[0] != State::Completed)
        })
    }
}
