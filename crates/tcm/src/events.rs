//! Raising external events and setting state from outside the run ([`EventHandle`]).

use crate::Error;
use crate::host::Shared;
use std::sync::Arc;
use std::sync::atomic::Ordering;

/// A handle to raise named external events from any thread or task. While any handle is open, a
/// run with nothing else to do waits for it instead of ending as stuck.
pub struct EventHandle {
    shared: Arc<Shared>,
}

impl EventHandle {
    /// A handle counted among the open ones.
    pub(crate) fn new(shared: Arc<Shared>) -> EventHandle {
        EventHandle { shared }
    }

    /// Raises the event `name` (latched: constraints applied later find it raised). After the
    /// run ended, [`Error::RunEnded`].
    pub fn raise(&self, name: &str) -> Result<(), Error> {
        raise(&self.shared, name, None)
    }

    /// Raises the external event `name` carrying `data`: each monitor activation it makes reads
    /// it with [`Ctx::activation_data`] (TCM's external event with data).
    pub fn raise_with<T: std::any::Any + Send + Sync>(
        &self,
        name: &str,
        data: T,
    ) -> Result<(), Error> {
        raise(&self.shared, name, Some(Arc::new(data)))
    }

    /// Sets the state variable `name` (declared by the program or the runtime; an undeclared one
    /// is declared with the value's type): an input to the engine, recorded with its value
    /// (docs/semantics.md, "State and conditions"). After the run ended, [`Error::RunEnded`], so
    /// a feed of values knows to stop.
    pub fn set_state(&self, name: &str, value: impl Into<crate::StateValue>) -> Result<(), Error> {
        let mut s = self.shared.enter()?;
        if s.ended {
            return Err(Error::RunEnded);
        }
        let now = s.engine.at_clock();
        Ok(crate::state::set_by_name(
            &mut s.engine,
            now,
            name,
            value.into(),
        )?)
    }

    /// Spawns `fut` as a tokio task of the program beside the run: work outside the tree that
    /// feeds it (a task reading a socket and raising events or setting state, TCM's
    /// external-event callbacks). The run counts its wake-ups as it counts its own tasks', so
    /// once an action wakes it, it runs before the next action is polled, as TCM's agenda
    /// dispatched external input between any two actions; a task spawned with plain
    /// `tokio::spawn` waits, on a current-thread runtime, until the actions that end without
    /// awaiting let the thread go (docs/semantics.md, "Work beside the tree"). It runs on the
    /// current tokio runtime; outside one, [`Error::NoRuntime`].
    pub fn spawn<F>(&self, fut: F) -> Result<tokio::task::JoinHandle<F::Output>, Error>
    where
        F: std::future::Future + Send + 'static,
        F::Output: Send + 'static,
    {
        let rt = tokio::runtime::Handle::try_current().map_err(|_| Error::NoRuntime)?;
        let fut = crate::pump::Tracked::new(Box::pin(fut), &self.shared.queued, true);
        Ok(rt.spawn(fut))
    }
}

impl Clone for EventHandle {
    fn clone(&self) -> Self {
        self.shared.handles.fetch_add(1, Ordering::SeqCst);
        EventHandle {
            shared: self.shared.clone(),
        }
    }
}

impl Drop for EventHandle {
    fn drop(&mut self) {
        self.shared.handles.fetch_sub(1, Ordering::SeqCst);
        self.shared.wake.notify_one();
    }
}

/// Raises the external event `name`, with `data` if any (an input to the engine).
pub(crate) fn raise(
    shared: &Arc<Shared>,
    name: &str,
    data: Option<Arc<dyn std::any::Any + Send + Sync>>,
) -> Result<(), Error> {
    let mut s = shared.enter()?;
    if s.ended {
        return Err(Error::RunEnded);
    }
    let now = s.engine.at_clock();
    let id = s.engine.external(name);
    s.engine.handle_external_with(now, id, data);
    Ok(())
}
