//! A running tree extended from outside (TCA's modules, which added recovery and wiretaps to the
//! task tree while it ran; docs/semantics.md, "Handlers attached to a task" and "Wiretaps"):
//!
//! 1. [`Engine::attach`] attaches a handler to a task's nodes: those alive now (after their own
//!    handlers and those attached before) and those spawned from now on. Recorded as
//!    `handler_attached`.
//! 2. [`Engine::detach`] removes it: no node tries it from now on; a use of it already running goes
//!    on (its node keeps the entry, which can no longer be chosen). Recorded as
//!    `handler_detached`.
//! 3. [`Engine::tap`] and [`Engine::untap`] add and remove a wiretap: checks start for nodes that
//!    reach the tapped point from then on. Recorded as `tap_added` and `tap_removed`.
//! 4. [`Engine::note_control`] records an operation from outside (`control`): what, and who asked.
//!
//! None of them changes a node's state, so none settles.

use super::Engine;
use super::exception::{HandlerEntry, HandlerSpec};
use super::node::Node;
use super::wiretap::Wiretap;
use crate::arena::Keep;
use crate::ids::{AttachId, TapWhen, WiretapId};
use crate::{Name, Time};
use tcm_trace::TraceKind;

impl<A, F: Clone, S: Keep<Node<A, F>>> Engine<A, F, S> {
    /// Attaches `spec` to every node of the task named `task`, alive or spawned from now on (see
    /// the module's rule 1); returns the attachment's number, for [`Engine::detach`].
    pub fn attach(&mut self, now: Time, task: impl Into<Name>, spec: HandlerSpec<F>) -> AttachId {
        self.advance(now);
        let task = task.into();
        let id = self.handler_for(task.clone(), spec.clone());
        let alive: Vec<_> = self
            .nodes
            .iter()
            .filter(|(_, n)| n.task_name() == &task)
            .map(|(node, _)| node)
            .collect();
        for node in alive {
            self.node_mut(node)
                .cold_mut()
                .class_handlers
                .push(HandlerEntry {
                    spec: spec.clone(),
                    uses: 0,
                    attach: id.0,
                });
        }
        if self.tracing {
            self.push_trace(TraceKind::HandlerAttached {
                attach: id.0,
                task: task.to_string(),
                handler: spec.name.to_string(),
                exception: spec.exception.to_string(),
            });
        }
        id
    }

    /// Removes an attached handler (rule 2): `false` when there is no such attachment (never
    /// made, or removed already).
    pub fn detach(&mut self, now: Time, id: AttachId) -> bool {
        self.advance(now);
        let mut found = false;
        self.class_handlers.retain(|_, specs| {
            let before = specs.len();
            specs.retain(|(a, _)| *a != id);
            found |= specs.len() != before;
            !specs.is_empty()
        });
        if !found {
            return false;
        }
        let holders: Vec<_> = self
            .nodes
            .iter()
            .filter(|(_, n)| {
                n.cold
                    .as_ref()
                    .is_some_and(|c| c.class_handlers.iter().any(|e| e.attach == id.0))
            })
            .map(|(node, _)| node)
            .collect();
        for node in holders {
            for e in self.node_mut(node).cold_mut().class_handlers.iter_mut() {
                if e.attach == id.0 {
                    // Never chosen again; its place in the node's list (which a running use
                    // names by index) stays.
                    e.spec.max_activations = Some(0);
                }
            }
        }
        if self.tracing {
            self.push_trace(TraceKind::HandlerDetached { attach: id.0 });
        }
        true
    }

    /// Adds a wiretap on the task (or, with `instance`, the instance name) `task` while the run
    /// runs (rule 3).
    pub fn tap(
        &mut self,
        now: Time,
        task: impl Into<Name>,
        instance: bool,
        when: TapWhen,
        body: F,
    ) -> WiretapId {
        self.advance(now);
        let task = task.into();
        let id = if instance {
            self.wiretap_instance(task.clone(), when, body)
        } else {
            self.wiretap(task.clone(), when, body)
        };
        if self.tracing {
            self.push_trace(TraceKind::TapAdded {
                tap: id.0,
                task: task.to_string(),
                instance,
                when: when_text(when).into(),
            });
        }
        id
    }

    /// Removes a wiretap (rule 3): `false` when there is none of that number still in place.
    pub fn untap(&mut self, now: Time, id: WiretapId) -> bool {
        self.advance(now);
        match self.taps.get_mut(id.0 as usize) {
            Some(Wiretap { removed, .. }) if !*removed => {
                *removed = true;
                if self.tracing {
                    self.push_trace(TraceKind::TapRemoved { tap: id.0 });
                }
                true
            }
            _ => false,
        }
    }

    /// Records an operation from outside the run (rule 4), one a replay cannot carry out again.
    pub fn note_control(&mut self, now: Time, what: &str, by: &str) {
        self.note_operation(now, what, by, None);
    }

    /// Records an operation from outside the run whose effect is an input of its own that comes
    /// next (an event raised): a replay writes its record again and gives that input.
    pub fn note_input(&mut self, now: Time, what: &str, by: &str) {
        self.note_operation(now, what, by, Some(super::SteerOp::Noted));
    }

    fn note_operation(&mut self, now: Time, what: &str, by: &str, op: Option<super::SteerOp>) {
        self.advance(now);
        self.record(|_| super::InputRecord::Control {
            what: what.to_string(),
            by: by.to_string(),
            op,
        });
        if self.tracing {
            self.push_trace(TraceKind::Control {
                what: what.to_string(),
                by: by.to_string(),
            });
        }
    }
}

/// How the trace writes `when`.
pub(crate) fn when_text(when: TapWhen) -> &'static str {
    match when {
        TapWhen::Before => "before",
        TapWhen::After => "after",
    }
}
