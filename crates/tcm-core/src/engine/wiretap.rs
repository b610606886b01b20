//! Wiretaps (the TCA paper's wiretap monitors; docs/semantics.md, "Wiretaps"): checks attached
//! from outside to a task name, without touching the task's code.
//!
//! 1. [`Engine::wiretap`] registers a check on a class of tasks: the nodes that are instances of a
//!    task (whatever their instance names, [`Spawn::task`](super::Spawn)), before the action
//!    starts or after it returned successfully; [`Engine::wiretap_instance`] on the nodes of one
//!    instance name instead.
//! 2. When a matching node is about to start (`start` in `progress.rs`) or has returned
//!    (`handle_action_finished`), each matching check becomes an [`Effect::Invoke`] whose [`Job`]
//!    names the check; the node waits, enabled or active, until every check has reported.
//! 3. When the last check reports: all passed, the node starts (before) or completes (after); one
//!    failed, the node fails with the first failure instead (a "before" check vetoes the action).

use super::node::Node;
use super::node::Purpose;
use super::{Effect, Engine, EngineError, Job};
use crate::Name;
use crate::arena::Keep;
use crate::failure::Failure;
use crate::ids::{NodeId, TapWhen, WiretapId};
use tcm_trace::TraceKind;

/// A registered wiretap.
#[derive(Clone)]
pub(crate) struct Wiretap<F> {
    pub(crate) task: Name,
    // Match the instance name instead of the task name.
    pub(crate) instance: bool,
    pub(crate) when: TapWhen,
    pub(crate) body: F,
    // Removed (`Engine::untap`): no check of it starts any more. Its number stays taken.
    pub(crate) removed: bool,
}

impl<A, F: Clone, S: Keep<Node<A, F>>> Engine<A, F, S> {
    /// Registers a wiretap on a class of tasks: `body` runs whenever a node that is an instance of
    /// the task `task` (whatever its instance name) is about to start its action (`Before`) or
    /// has returned successfully (`After`), without touching that task's code. A failing check
    /// fails the tapped node with the check's failure.
    pub fn wiretap(&mut self, task: impl Into<Name>, when: TapWhen, body: F) -> WiretapId {
        self.add_tap(task.into(), false, when, body)
    }

    /// As [`Engine::wiretap`], on the nodes whose instance name is `instance` (whatever their
    /// task).
    pub fn wiretap_instance(
        &mut self,
        instance: impl Into<Name>,
        when: TapWhen,
        body: F,
    ) -> WiretapId {
        self.add_tap(instance.into(), true, when, body)
    }

    fn add_tap(&mut self, task: Name, instance: bool, when: TapWhen, body: F) -> WiretapId {
        let id = WiretapId(self.taps.len() as u32);
        self.taps.push(Wiretap {
            task,
            instance,
            when,
            body,
            removed: false,
        });
        id
    }

    /// Step 3: a wiretap check on `node` finished (reported through `handle_action_finished`,
    /// which settles afterwards).
    pub(super) fn tap_finished(
        &mut self,
        node: NodeId,
        tap: WiretapId,
        result: Result<(), Failure>,
    ) -> Result<(), EngineError> {
        let Some(when) = self.taps.get(tap.0 as usize).map(|t| t.when) else {
            return Err(EngineError::NotRunning(node));
        };
        let Some(n) = self.nodes.get_mut(node) else {
            // Its node was terminated (and reclaimed) meanwhile: the check stopped counting as
            // running then (`terminate.rs`) and has nothing left to decide.
            return Ok(());
        };
        let alive = n.alive();
        let c = n.cold_mut();
        // Each check ends once: a second report of the same check, or the report of a check of
        // a node terminated meanwhile, is refused.
        let Some(i) = c.taps_open.iter().position(|t| *t == tap) else {
            return Err(EngineError::NotRunning(node));
        };
        c.taps_open.swap_remove(i);
        self.running -= 1;
        if let Err(f) = result {
            if c.tap_failure.is_none() {
                c.tap_failure = Some(Box::new(f));
            }
        }
        if !c.taps_open.is_empty() || !alive {
            return Ok(());
        }
        let failure = c.tap_failure.take().map(|f| *f);
        match (when, failure) {
            (TapWhen::Before, None) => self.ready.push_back(node),
            (TapWhen::Before, Some(f)) => {
                // Vetoed: the action never runs; the node fails in its place.
                self.fail(node, f);
                self.complete_handling(node);
            }
            (TapWhen::After, None) => self.complete_handling(node),
            (TapWhen::After, Some(f)) => {
                self.fail(node, f);
                self.complete_handling(node);
            }
        }
        Ok(())
    }

    /// Starts the wiretaps of `node` for `when`; returns how many started.
    #[inline]
    pub(crate) fn start_taps(&mut self, node: NodeId, when: TapWhen) -> u32 {
        if self.taps.is_empty() {
            return 0;
        }
        self.start_matching_taps(node, when)
    }

    fn start_matching_taps(&mut self, node: NodeId, when: TapWhen) -> u32 {
        let n = self.node(node);
        let (name, task) = (n.name.clone(), n.task_name().clone());
        let matching: Vec<(WiretapId, F)> = self
            .taps
            .iter()
            .enumerate()
            .filter(|(_, t)| {
                !t.removed && t.when == when && &t.task == if t.instance { &name } else { &task }
            })
            .map(|(i, t)| (WiretapId(i as u32), t.body.clone()))
            .collect();
        let k = matching.len() as u32;
        if k == 0 {
            return 0;
        }
        let display = self.node(node).display;
        let open = matching.iter().map(|(tap, _)| *tap);
        self.node_mut(node).cold_mut().taps_open.extend(open);
        for (tap, body) in matching {
            self.running += 1;
            emit!(
                self,
                TraceKind::Tapped {
                    node: display,
                    tap: tap.0,
                    when: match when {
                        TapWhen::Before => "before".into(),
                        TapWhen::After => "after".into(),
                    },
                }
            );
            self.effects.push_back(Effect::Invoke {
                job: Job::check(node, tap),
                body,
                purpose: std::sync::Arc::new(Purpose::Tap { tap, when }),
            });
        }
        k
    }
}
