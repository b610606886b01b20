//! Exceptions: handler search up the tree, bypass, re-raise and retry (TDL paper, "Task Trees";
//! docs/semantics.md, "Exceptions and handlers"). Wiretaps are in `wiretap.rs`.
//!
//! Handler search, as numbered steps:
//! 1. A node's action fails with a [`Failure`]: the node is marked failed and the search starts at
//!    the node itself. A failure raised by a handler node starts above the node that handler was
//!    attached to, as an exception thrown inside a `catch` block propagates to the enclosing `try`.
//! 2. At each node, its handlers are tried in their order (see [`HandlerSpec`]); a handler matches
//!    if it handles the failure's exception type or one of its ancestors, and is skipped if its
//!    maximum activations are used up. Then the parent, up to the root.
//! 3. Found: its use count grows, and a new *handler node* is inserted as a child of the failing
//!    node, running the handler's body with the failure, the failing node and the attachment node.
//!    The tree is not unwound: the failing node's handling completes (failed), its execution waits
//!    for the handler's subtree, siblings go on. The handler decides what to terminate, add or retry.
//! 4. Not found: the node stays failed with the warning TCM printed; under
//!    [`crate::FailurePolicy::Fatal`] the run's outcome becomes that failure.
//! 5. Bypass ([`Engine::request_bypass`], carried out when the handler's body ends): the search
//!    goes on after the bypassing handler (same node's later
//!    handlers first, then ancestors); the next handler node becomes a child of the bypassing one,
//!    whose handling then completes.
//! 6. Retry ([`Engine::retry`]): a fresh node of the failing task (same kind, name and arguments,
//!    from the factory given at spawn) is inserted under the handler node; its failures search from
//!    there upward, so the handler's maximum activations bound the attempts.

use super::node::Node;
use super::node::{Payload, Propagate, Purpose};
use super::{Engine, EngineError, Work};
use crate::arena::Keep;
use crate::failure::{Failure, FailurePolicy, FatalFailure};
use crate::ids::NodeId;
use crate::time::Time;
use crate::{Name, NodeKind};
use tcm_trace::{Facet, State, TraceKind};

/// An exception handler attached to a node (at spawn, `Spawn::handlers`).
#[derive(Clone, Debug)]
pub struct HandlerSpec<F> {
    /// Instance name of the handler nodes it creates.
    pub name: Name,
    /// The exception type it handles (and every type that names it as an ancestor).
    pub exception: Name,
    /// How many times it may be used; unlimited when `None`.
    pub max_activations: Option<u32>,
    /// The body's factory, invoked once per use.
    pub body: F,
}

#[derive(Clone)]
pub(crate) struct HandlerEntry<F> {
    pub(crate) spec: HandlerSpec<F>,
    pub(crate) uses: u32,
    // The attachment it came from (`Engine::handler_for`), 0 for the node's own handlers.
    pub(crate) attach: u32,
}

/// What a handler node handles, for bypass and retry.
#[derive(Clone)]
pub(crate) struct HandlerCtx {
    pub(crate) failure: Failure,
    pub(crate) failing: NodeId,
    pub(crate) attached: NodeId,
    pub(crate) index: usize,
    /// The handler's body asked to pass the exception on when it ends.
    pub(crate) bypass: bool,
}

impl<A, F: Clone, S: Keep<Node<A, F>>> Engine<A, F, S> {
    /// The handler node `node`, still running, asks to pass its exception on (step 5): when its
    /// body ends, whatever it returns, the search goes on after it.
    pub fn request_bypass(&mut self, now: Time, node: NodeId) -> Result<(), EngineError> {
        self.advance(now);
        let n = self.live(node)?;
        let display = n.display;
        if n.handler_ctx().is_none() {
            return Err(EngineError::NotAHandler(display));
        }
        if n.state(Facet::Handling) != State::Active || !n.alive() {
            return Err(EngineError::NotRunning(node));
        }
        if let Some(ctx) = self.node_mut(node).cold_mut().handler.as_deref_mut() {
            ctx.bypass = true;
        }
        Ok(())
    }

    /// Step 5: the body of the handler node `node`, which asked to bypass, ended.
    pub(super) fn bypass(&mut self, node: NodeId) {
        let n = self.node(node);
        let display = n.display;
        let Some(ctx) = n.handler_ctx() else {
            return;
        };
        let (failure, failing, attached, index) =
            (ctx.failure.clone(), ctx.failing, ctx.attached, ctx.index);
        emit!(
            self,
            TraceKind::Bypassed {
                node: display,
                exception: failure.exception.to_string(),
            }
        );
        self.search(failing, failure, Some(attached), index + 1, node);
        self.complete_handling(node);
    }

    /// The handler node `node` asks for a fresh run of the task that failed (step 6). Returns the
    /// new node. The failing task must have been spawned with a retry factory (`Spawn::retry`).
    ///
    /// The task that failed is the failing node, or, when that is a handler that re-raised, the
    /// task that handler handled (and so on down a chain of re-raising handlers): a handler of a
    /// re-raised exception that says `retry` runs the original task again. The new run is the same
    /// task again: it shares the first run's handlers (their use counts included), keeps its own
    /// constraints (`expand first`, `delay expansion`), persistence and task name, and takes over
    /// its on-terminate tasks.
    pub fn retry(&mut self, now: Time, node: NodeId) -> Result<NodeId, EngineError> {
        self.advance(now);
        let n = self.live(node)?;
        let display = n.display;
        let Some(ctx) = n.handler_ctx() else {
            return Err(EngineError::NotAHandler(display));
        };
        let failing = self.retried_task(ctx.failing);
        let f = self.live(failing)?;
        let Some(factory) = f.retry().cloned() else {
            return Err(EngineError::NotRetryable(f.display));
        };
        let (kind, name, of_display, persistent) =
            (f.kind, f.name.clone(), f.display, f.persistent);
        let propagate = f.propagates();
        let origin = f.retry_of().unwrap_or(failing);
        let id = self.insert(
            node,
            kind,
            name,
            Payload::Invoke(
                factory.clone(),
                std::sync::Arc::new(Purpose::Retry { of: failing }),
            ),
        );
        let task = self.node(failing).renamed_task().cloned();
        // Labelled on-terminate tasks stay: their reservations belong to the first run.
        let c = self.node_mut(failing).cold_mut();
        let (labelled, on_terminate): (Vec<_>, Vec<_>) = std::mem::take(&mut c.on_terminate)
            .into_iter()
            .partition(|ot| ot.fulfils.is_some());
        c.on_terminate = labelled.into();
        let constraints = c.retry_constraints.clone();
        // A retry uses the same resources as the run it repeats.
        let uses = c.uses.clone();
        let new = self.node_mut(id);
        new.persistent = persistent;
        let cold = new.cold_mut();
        cold.retry = Some(factory);
        cold.task = task;
        cold.retry_of = Some(origin);
        cold.propagate = propagate;
        cold.on_terminate = on_terminate.into();
        cold.retry_constraints = constraints.clone();
        cold.uses = uses;
        for c in constraints {
            self.apply(id, node, None, c);
        }
        let new_display = self.node(id).display;
        emit!(
            self,
            TraceKind::Retried {
                node: new_display,
                of: of_display,
            }
        );
        self.queue_progress(id);
        self.settle();
        Ok(id)
    }

    /// Makes `node`'s own failure, when no handler on it takes it, its parent's business: the
    /// search ends at `node` (no handler above it is tried, nothing is reported unhandled). For
    /// a child whose parent's action waits for its value (the shell's waited spawn), which then
    /// fails with that failure. A retry of `node` inherits it.
    pub fn propagate(&mut self, node: NodeId) -> Result<(), EngineError> {
        self.live(node)?;
        self.node_mut(node).cold_mut().propagate = Propagate::Waiter;
        Ok(())
    }

    /// Makes `node`'s own failure, when no handler on it takes it, its parent's failure (what a
    /// behaviour-tree sequence does with a failing child): the search ends at `node`, and the
    /// parent fails with the same failure, as if its action had raised it. Its action is stopped
    /// if it still runs, its other children are terminated, and the search goes on from the
    /// parent, so a handler there may `retry` the whole subtree (docs/semantics.md, "Failing
    /// the parent"). A parent already failed or terminating is left alone; under the root the
    /// failure is searched for as usual. A retry of `node` inherits it; for a monitor, so does
    /// each activation (its failure is the monitor's, which then activates no more).
    pub fn propagate_to_parent(&mut self, node: NodeId) -> Result<(), EngineError> {
        self.live(node)?;
        self.node_mut(node).cold_mut().propagate = Propagate::Parent;
        Ok(())
    }

    /// For a handler node: the task a `retry` from it runs again (the failed node, or the task a
    /// re-raising handler handled). `None` for another node.
    pub fn failed_task(&self, handler: NodeId) -> Option<NodeId> {
        let failing = self.nodes.get(handler)?.handler_ctx()?.failing;
        Some(self.retried_task(failing))
    }

    /// The task a retry asked for with `failing` as the failed node runs again: `failing`, or the
    /// task a re-raising handler handled.
    fn retried_task(&self, mut failing: NodeId) -> NodeId {
        while let Some(h) = self.nodes.get(failing).and_then(|n| n.handler_ctx()) {
            failing = h.failing;
        }
        failing
    }

    /// The node whose handler entries the search uses at `at`: the first run of a retried task.
    fn handler_owner(&self, at: NodeId) -> NodeId {
        self.nodes
            .get(at)
            .and_then(|n| n.retry_of())
            .filter(|o| self.nodes.get(*o).is_some())
            .unwrap_or(at)
    }

    /// Step 1: `node`'s action failed.
    pub(crate) fn fail(&mut self, node: NodeId, failure: Failure) {
        let display = self.node(node).display;
        emit!(
            self,
            TraceKind::Failed {
                node: display,
                exception: failure.exception.to_string(),
                message: failure.message.clone(),
            }
        );
        // A handler's own failure searches above the node it was attached to.
        let from = match self.node(node).handler_ctx() {
            Some(ctx) => {
                let attached = ctx.attached;
                self.warn_skipped(node, attached, &failure);
                self.nodes.get(attached).and_then(|a| a.parent)
            }
            None => Some(node),
        };
        self.node_mut(node).cold_mut().failure = Some(failure.clone());
        if self.steer.is_some() {
            self.break_at(super::BreakAt::Raised, node, Some(&failure));
        }
        self.search(node, failure, from, 0, node);
    }

    /// `child`'s failure fails `parent` (`Engine::propagate_to_parent`): the parent's other
    /// children are terminated, its action, if it runs, is stopped and its handling completes,
    /// and the failure is the parent's own (step 1 from the parent).
    fn fail_parent(&mut self, child: NodeId, parent: NodeId, failure: Failure) {
        self.fail_from_outside(parent, failure, Some(child));
    }

    /// `node` fails from outside its action (a child's failure propagated to it, an invariant
    /// that no longer holds): its children but `spare` are terminated, its action, if it runs,
    /// is stopped and its handling completes, and the failure is its own (step 1). A node already
    /// failed or terminating is left alone.
    pub(super) fn fail_from_outside(
        &mut self,
        node: NodeId,
        failure: Failure,
        spare: Option<NodeId>,
    ) {
        let p = self.node(node);
        if !p.alive() || p.failure().is_some() {
            return;
        }
        let monitor = p.monitor().is_some();
        let running = p.state(Facet::Handling) == State::Active
            && !monitor
            && p.taps_pending() == 0
            && !p.never_ends();
        let mut c = self.first_child(node);
        while let Some(ch) = c {
            if Some(ch) != spare {
                self.work.push_back(Work::Terminate {
                    node: ch,
                    explicit: false,
                });
            }
            c = self.next_sibling(ch);
        }
        if running && !self.cancel_action(node) {
            self.node_mut(node).stopping = true;
        }
        self.fail(node, failure);
        if running {
            self.complete_handling(node);
        } else if monitor {
            // A failed monitor activates no more.
            self.monitor_done(node);
        }
    }

    /// A failing handler's search skips the nodes from itself up to its attachment, where TCM
    /// searched first: the handlers there that would have matched are named in a warning, so the
    /// difference shows in the trace (docs/semantics.md, "Exceptions and handlers", rule 6).
    fn warn_skipped(&mut self, handler: NodeId, attached: NodeId, failure: &Failure) {
        if !self.tracing {
            return;
        }
        let mut skipped = Vec::new();
        let mut cur = Some(handler);
        while let Some(at) = cur {
            let Some(n) = self.nodes.get(at) else { break };
            for h in n.handlers() {
                if failure.is_a(&h.spec.exception)
                    && h.spec.max_activations.is_none_or(|m| h.uses < m)
                {
                    skipped.push(format!("{} (on {} {{{}}})", h.spec.name, n.name, n.display));
                }
            }
            if at == attached {
                break;
            }
            cur = n.parent;
        }
        if skipped.is_empty() {
            return;
        }
        let n = self.node(handler);
        let message = format!(
            "Handler {} {{{}}} failed with \"{}\": searching above the node it was attached to, \
             so these handlers TCM would have tried first are skipped: {}",
            n.name,
            n.display,
            failure.exception,
            skipped.join(", ")
        );
        let node = Some(n.display);
        emit!(self, TraceKind::Warning { node, message });
    }

    /// Steps 2 to 4: searches from `(from, index)` upward; a found handler's node goes under
    /// `under`.
    fn search(
        &mut self,
        failing: NodeId,
        failure: Failure,
        from: Option<NodeId>,
        mut index: usize,
        under: NodeId,
    ) {
        let mut cur = from;
        // Handler lists already searched through a retry of their task (a retry shares the first
        // run's handlers; the first run, further up, is not searched twice).
        let mut searched: Vec<NodeId> = Vec::new();
        while let Some(at) = cur {
            let Some(n) = self.nodes.get(at) else { break };
            if n.kind == NodeKind::Root {
                break;
            }
            let parent = n.parent;
            // A node without a cold part has no handlers, is no retry and passes its failure up:
            // the search goes straight on to its parent.
            if n.cold.is_none() {
                cur = parent;
                index = 0;
                continue;
            }
            let owner = self.handler_owner(at);
            if !searched.contains(&owner) {
                if owner != at {
                    searched.push(owner);
                }
                let found = self
                    .node(owner)
                    .all_handlers()
                    .enumerate()
                    .skip(index)
                    .find(|(_, h)| {
                        failure.is_a(&h.spec.exception)
                            && h.spec.max_activations.is_none_or(|m| h.uses < m)
                    });
                if let Some((i, _)) = found {
                    self.use_handler(failing, failure, at, i, under);
                    return;
                }
            }
            // A task whose failure its parent takes (a waited value: the waiting body fails with
            // it, as a function call's exception reaches its caller; or a child that fails its
            // parent): the search ends here, and the task's outcome is this failure (its
            // retry's, when a retry failed).
            // For a retry, the task is its first run: that run's parent takes the failure.
            let to = self.node(owner).propagates();
            let own = at == failing || self.handler_owner(failing) == at;
            let taker = self.node(owner).parent;
            let parent_takes = to == Propagate::Parent
                && taker.is_some_and(|p| self.node(p).kind != NodeKind::Root);
            if own && (to == Propagate::Waiter || parent_takes) {
                if owner != failing {
                    self.node_mut(owner).cold_mut().failure = Some(failure.clone());
                }
                if let (true, Some(p)) = (parent_takes, taker) {
                    self.fail_parent(owner, p, failure);
                }
                return;
            }
            cur = parent;
            index = 0;
        }
        let display = self.node(failing).display;
        emit!(
            self,
            TraceKind::Warning {
                node: Some(display),
                message: format!(
                    "No exception handler found for exception type \"{}\"",
                    failure.exception
                ),
            }
        );
        let unhandled = FatalFailure {
            failure,
            node: display,
            path: self.path(failing),
        };
        if self.policy == FailurePolicy::Fatal && self.fatal.is_none() {
            self.fatal = Some(unhandled.clone());
        }
        self.unhandled.push(unhandled);
    }

    fn use_handler(
        &mut self,
        failing: NodeId,
        failure: Failure,
        attached: NodeId,
        index: usize,
        under: NodeId,
    ) {
        let owner = self.handler_owner(attached);
        let Some(entry) = self.node_mut(owner).handler_entry_mut(index) else {
            return;
        };
        entry.uses += 1;
        let (body, name) = (entry.spec.body.clone(), entry.spec.name.clone());
        self.node_mut(failing).cold_mut().handled = true;
        let purpose = Purpose::Handler {
            failure: failure.clone(),
            failing,
            attached,
        };
        let id = self.insert(
            under,
            NodeKind::Handler,
            name,
            Payload::Invoke(body, std::sync::Arc::new(purpose)),
        );
        let (d, fd, ad) = (
            self.node(id).display,
            self.node(failing).display,
            self.node(attached).display,
        );
        emit!(
            self,
            TraceKind::HandlerChosen {
                node: d,
                failing: fd,
                attached: ad,
                exception: failure.exception.to_string(),
                handler: self.node(id).name.to_string(),
            }
        );
        if self.steer.is_some() {
            self.break_at(super::BreakAt::Handler, id, Some(&failure));
        }
        self.node_mut(id).cold_mut().handler = Some(Box::new(HandlerCtx {
            failure,
            failing,
            attached,
            index,
            bypass: false,
        }));
        self.queue_progress(id);
    }
}
