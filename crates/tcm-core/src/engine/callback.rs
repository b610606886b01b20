//! Timer callbacks: TCM's `InvokeWhen` and `InvokeAfter`, a function the shell runs at an event of
//! a node or at a time. A callback is no node of the tree: the engine only tells the shell when it is
//! due ([`Effect::Notify`](super::Effect::Notify) with the shell's token) and traces it
//! (`callback_set`, `callback_ran`); the shell keeps and runs the function.
//!
//! An event callback is a watch ([`Engine::watch`], `arm.rs`); a timed one is a timer
//! ([`Engine::notify_at`]), so a pending one keeps the run alive like any timer, while a pending
//! event callback does not (docs/semantics.md, "Run outcome").

use super::node::Node;
use super::timers::TimerKind;
use super::{Engine, EngineError};
use crate::NodeKind;
use crate::arena::Keep;
use crate::arena::Lookup;
use crate::constraint::{Event, NodeRef};
use crate::ids::{NodeId, WatchToken};
use crate::time::Time;
use tcm_trace::{TraceEventRef, TraceKind, TraceWhen};

impl<A, F: Clone, S: Keep<Node<A, F>>> Engine<A, F, S> {
    /// Command: TCM's `InvokeWhen(point)`. The shell is told ([`Effect::Notify`] with `token`, and
    /// how the node got there, as for [`Engine::watch`]) when `event` happens, at once if it already
    /// did. Traced as `callback_set` named `name`; `by` is the node whose action set it, if any.
    ///
    /// [`Effect::Notify`]: super::Effect::Notify
    pub fn invoke_when(
        &mut self,
        now: Time,
        event: Event,
        token: WatchToken,
        name: &str,
        by: Option<NodeId>,
    ) -> Result<(), EngineError> {
        self.advance(now);
        let NodeRef::Node(node) = event.node else {
            return Err(EngineError::RelativeRef);
        };
        let when = match self.lookup(node)? {
            Lookup::Live => TraceWhen::Event(TraceEventRef {
                node: self.node(node).display,
                facet: event.facet,
                point: event.point,
                // A watch tells the shell how the node ended; it does not filter on it.
                outcome: None,
            }),
            // Its events are long past: the callback runs at once.
            Lookup::Gone(_) => TraceWhen::Now,
        };
        self.callback_set(token, name, by, when)?;
        self.watch(now, event, token)
    }

    /// Command: TCM's `InvokeWhen(time)` and `InvokeAfter(delay)`. The shell is told
    /// ([`Effect::Notify`](super::Effect::Notify) with `token`, outcome `Reached`) at `at`, or at
    /// once if `at` has passed. Traced as `callback_set` named `name`; `by` is the node whose action
    /// set it, if any. While pending it is a timer: it keeps the run alive.
    pub fn invoke_at(
        &mut self,
        now: Time,
        at: Time,
        token: WatchToken,
        name: &str,
        by: Option<NodeId>,
    ) -> Result<(), EngineError> {
        self.advance(now);
        self.callback_set(token, name, by, TraceWhen::At(at.as_nanos()))?;
        self.notify_at(now, at, token);
        Ok(())
    }

    /// Command: tell the shell ([`Effect::Notify`](super::Effect::Notify) with `token`, outcome
    /// `Reached`) at `at` (when the next timers fire, if `at` has passed). A timer like any other:
    /// timers due at the same time fire in the order they were set, and a pending one is a deadline
    /// of [`Engine::poll_timeout`].
    pub fn notify_at(&mut self, now: Time, at: Time, token: WatchToken) {
        self.advance(now);
        let now = self.time();
        self.timers.push(at.max(now), TimerKind::Notify { token });
    }

    /// The shell runs the callback of `token` now: traced as `callback_ran`.
    pub fn callback_ran(&mut self, token: WatchToken, name: &str) {
        emit!(
            self,
            TraceKind::CallbackRan {
                callback: token.0,
                name: name.to_string(),
            }
        );
    }

    fn callback_set(
        &mut self,
        token: WatchToken,
        name: &str,
        by: Option<NodeId>,
        when: TraceWhen,
    ) -> Result<(), EngineError> {
        if let Some(by) = by {
            self.check_run(by)?;
        }
        // A node gone by now (a callback set from a task its action left behind) is named by none.
        let node = by
            .and_then(|b| self.query(b))
            .filter(|n| n.kind != NodeKind::Root)
            .map(|n| n.display);
        emit!(
            self,
            TraceKind::CallbackSet {
                callback: token.0,
                name: name.to_string(),
                node,
                when,
            }
        );
        Ok(())
    }
}
