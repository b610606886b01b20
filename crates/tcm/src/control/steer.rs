//! Steering a run through its [`Control`] handle (docs/semantics.md, "Steering a run"): pause,
//! step and continue, breakpoints, faults and approvals, suspension of a subtree. Each request
//! names who asked (`by`), which its `control` record says.

use super::Control;
use crate::Error;
use tcm_core::{Approval, Breakpoint, Fault, NodeId, SteerId};

impl Control {
    /// Pauses the run: `false` if it was paused already.
    pub fn pause(&self, by: &str) -> Result<bool, Error> {
        self.operate(|e, now| e.pause(now, by))
    }

    /// Resumes a paused run: `false` if it was not paused.
    pub fn resume(&self, by: &str) -> Result<bool, Error> {
        self.operate(|e, now| e.resume(now, by))
    }

    /// Lets one held start or timer happen, then pauses again: `false` if the run was not paused.
    pub fn step(&self, by: &str) -> Result<bool, Error> {
        self.operate(|e, now| e.step(now, by))
    }

    /// Resumes until the next node's turn to start and pauses before it: `false` if the run was
    /// not paused.
    pub fn step_to_start(&self, by: &str) -> Result<bool, Error> {
        self.operate(|e, now| e.step_to_start(now, by))
    }

    /// Whether the run is paused.
    pub fn is_paused(&self) -> Result<bool, Error> {
        self.engine(|e, _| e.is_paused())
    }

    /// Adds a breakpoint; returns its number, for [`Control::remove`].
    pub fn add_breakpoint(&self, bp: Breakpoint, by: &str) -> Result<SteerId, Error> {
        self.operate(|e, now| e.add_breakpoint(now, bp, by))
    }

    /// Injects a fault for the next ends of the nodes it matches; returns its number.
    pub fn inject(&self, fault: Fault, by: &str) -> Result<SteerId, Error> {
        self.operate(|e, now| e.inject(now, fault, by))
    }

    /// Holds the nodes `rule` matches until an operator approves them; returns its number.
    pub fn require_approval(&self, rule: Approval, by: &str) -> Result<SteerId, Error> {
        self.operate(|e, now| e.require_approval(now, rule, by))
    }

    /// Removes a breakpoint, fault or approval rule: `false` if there is none of that number.
    pub fn remove(&self, id: SteerId, by: &str) -> Result<bool, Error> {
        self.operate(|e, now| e.remove_steer(now, id, by))
    }

    /// The nodes held for approval, in the order held.
    pub fn held(&self) -> Result<Vec<NodeId>, Error> {
        self.engine(|e, _| e.held())
    }

    /// Approves a node held for approval.
    pub fn approve(&self, node: NodeId, by: &str) -> Result<(), Error> {
        self.operate(|e, now| e.approve(now, node, by))?
            .map_err(Error::from)
    }

    /// Refuses a node held for approval: it fails with `ApprovalRefused`.
    pub fn refuse(&self, node: NodeId, by: &str, reason: &str) -> Result<(), Error> {
        self.operate(|e, now| e.refuse(now, node, by, reason))?
            .map_err(Error::from)
    }

    /// Removes every breakpoint and approval rule, approves the held nodes and resumes: what a
    /// viewer does when its controlling page went silent.
    pub fn release(&self, by: &str) -> Result<(), Error> {
        self.operate(|e, now| e.release(now, by))
    }

    /// Suspends `node`'s subtree (docs/semantics.md, "Suspension"), as `by` asked.
    pub fn suspend(&self, node: NodeId, by: &str) -> Result<(), Error> {
        self.operate(|e, now| e.suspend_as(now, node, true, by))?
            .map_err(Error::from)
    }

    /// Ends the suspension of `node`'s subtree, as `by` asked.
    pub fn unsuspend(&self, node: NodeId, by: &str) -> Result<(), Error> {
        self.operate(|e, now| e.suspend_as(now, node, false, by))?
            .map_err(Error::from)
    }

    /// Terminates `node`'s subtree as `by`, an operator, asked: an operation from outside the
    /// run, which its journal keeps and a replay carries out again (the program's own
    /// termination is [`Control::terminate`]).
    pub fn terminate_as(&self, node: NodeId, by: &str) -> Result<(), Error> {
        self.operate(|e, now| e.terminate_as(now, node, by))?
            .map_err(Error::from)
    }

    /// What `node` is now (`None` once it is gone).
    pub fn info(&self, node: NodeId) -> Result<Option<tcm_core::NodeInfo>, Error> {
        self.ctx.info(node)
    }

    /// Finds a live node by its display number (the number traces and the viewer show).
    pub fn node_by_number(&self, number: u64) -> Result<Option<NodeId>, Error> {
        self.engine(|e, _| e.node_by_display(number))
    }
}
