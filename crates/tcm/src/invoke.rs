//! Timer callbacks (TCM's `TCM_InvokeWhen` and `TCM_InvokeAfter`): a plain function run at an event
//! of a node, at a time, or after a delay. A callback is no node of the tree; it runs once, on the
//! driver's task, with a context of the node whose action set it, so it may spawn, terminate,
//! raise or activate, but not wait.
//!
//! The engine tells when each is due (`tcm-core/src/engine/callback.rs`) and traces it
//! (`callback_set`, `callback_ran`); the host keeps the function (`host.rs`). A pending timed
//! callback keeps the run alive, like any timer; a pending event callback does not, as in TCM
//! (docs/semantics.md, "Run outcome").

use crate::Error;
use crate::ctx::Ctx;
use crate::host::{Callback, PendingCallback};
use std::time::Duration;
use tcm_core::{EngineError, Event, Name, Time, WatchOutcome, WatchToken};

// ---- Timer callbacks.
impl Ctx {
    /// Runs `f` once when `event` happens (TCM's `TCM_InvokeWhen(point, fn, data)`), at once if it
    /// already did. `f` gets a context of this node and how the event's node got there (as
    /// [`Ctx::wait`] tells it: a node reaching its point by termination has reached it). Pending,
    /// it does not keep the run alive: if nothing else can happen, the run ends without it.
    pub fn invoke_when<F>(&self, name: impl Into<Name>, event: Event, f: F) -> Result<(), Error>
    where
        F: FnOnce(Ctx, WatchOutcome) + Send + 'static,
    {
        self.set_callback(name.into(), Box::new(f), |e, now, token, name, by| {
            e.invoke_when(now, event, token, name, by)
        })
    }

    /// Runs `f` once after `delay` (TCM's `TCM_InvokeAfter(delay, fn, data)`). Pending, it keeps
    /// the run alive like any timer.
    pub fn invoke_after<F>(&self, name: impl Into<Name>, delay: Duration, f: F) -> Result<(), Error>
    where
        F: FnOnce(Ctx) + Send + 'static,
    {
        let at = {
            let mut inner = self.shared.enter()?;
            inner.engine.clock_time() + delay
        };
        self.invoke_at(name, at, f)
    }

    /// Runs `f` once at the engine time `at` (TCM's `TCM_InvokeWhen(time, fn, data)`), at once if
    /// it has passed. Pending, it keeps the run alive like any timer.
    pub fn invoke_at<F>(&self, name: impl Into<Name>, at: Time, f: F) -> Result<(), Error>
    where
        F: FnOnce(Ctx) + Send + 'static,
    {
        self.set_callback(
            name.into(),
            Box::new(move |ctx, _| f(ctx)),
            |e, now, token, name, by| e.invoke_at(now, at, token, name, by),
        )
    }

    fn set_callback(
        &self,
        name: Name,
        f: Callback,
        arm: impl FnOnce(
            &mut tcm_core::Engine<crate::Action, crate::Factory>,
            Time,
            WatchToken,
            &str,
            Option<tcm_core::NodeId>,
        ) -> Result<(), EngineError>,
    ) -> Result<(), Error> {
        let mut inner = self.shared.enter()?;
        if inner.ended {
            return Err(Error::RunEnded);
        }
        let token = inner.next_token();
        let now = inner.engine.at_clock();
        arm(
            &mut inner.engine,
            now,
            WatchToken(token),
            &name,
            Some(self.node),
        )?;
        // Kept before this access ends, so before a notification can be carried out.
        inner.callbacks.insert(
            token,
            PendingCallback {
                name,
                node: self.node,
                f,
            },
        );
        Ok(())
    }
}
