//! A run controlled from outside while it runs ([`Session::control`](crate::Session::control)):
//! what a serving executive does to the runs it holds, from any task or thread.
//!
//! - Top-level tasks started, awaited and terminated; external events raised.
//! - Handlers attached to a task and detached again, wiretaps added and removed (TCA's modules
//!   extending a running tree; `tcm_core`'s `engine/extend.rs` gives the rules). Each is a trace
//!   record, as is [`Control::note`], an operation from outside named with who asked.
//!
//! A control handle is not an open event handle: it does not keep a run with nothing left to do
//! from ending.

mod steer;

use crate::Error;
use crate::ctx::Ctx;
use crate::host::Shared;
use crate::task::{Attached, Factory, Handler, Task};
use std::any::Any;
use std::sync::Arc;
use tcm_core::{AttachId, NodeId, Stats, TapWhen, WatchOutcome, WiretapId};

/// A handle on a running session: see the module's documentation. Cheap to clone.
#[derive(Clone)]
pub struct Control {
    // A context of the root, of no job.
    pub(crate) ctx: Ctx,
}

impl Control {
    fn engine<T>(
        &self,
        f: impl FnOnce(&mut tcm_core::Engine<crate::task::Action, Factory>, tcm_core::Time) -> T,
    ) -> Result<T, Error> {
        let mut inner = self.ctx.shared.enter()?;
        if inner.ended {
            return Err(Error::RunEnded);
        }
        let now = inner.engine.at_clock();
        Ok(f(&mut inner.engine, now))
    }

    /// [`Control::engine`] for an operation from outside, which is an input of the run: refused
    /// while the run replays its journal, whose inputs come first ([`Error::Replaying`]).
    fn operate<T>(
        &self,
        f: impl FnOnce(&mut tcm_core::Engine<crate::task::Action, Factory>, tcm_core::Time) -> T,
    ) -> Result<T, Error> {
        if self.replaying()? {
            return Err(Error::Replaying);
        }
        self.engine(f)
    }

    /// Whether the run is replaying its journal (a resumed run, before it goes on live), when an
    /// operation from outside is refused ([`Error::Replaying`]).
    pub fn replaying(&self) -> Result<bool, Error> {
        let inner = crate::host::lock(&self.ctx.shared)?;
        Ok(inner.replay.as_ref().is_some_and(|r| r.active()))
    }

    /// The root node, the parent of every top-level task.
    pub fn root(&self) -> NodeId {
        self.ctx.node
    }

    /// Inserts `task` as a top-level task, as [`Session::spawn`](crate::Session::spawn) does.
    pub fn spawn(&self, task: Task) -> Result<NodeId, Error> {
        spawn_top(&self.ctx.shared, task)
    }

    /// Waits until `node`'s execution completes (see [`Ctx::wait`]).
    pub async fn wait(&self, node: NodeId) -> Result<WatchOutcome, Error> {
        self.ctx.wait(node).await
    }

    /// Terminates `node` and its subtree (its on-terminate cleanup runs).
    pub fn terminate(&self, node: NodeId) -> Result<(), Error> {
        self.ctx.terminate(node)
    }

    /// Raises the external event `name`.
    pub fn raise(&self, name: &str) -> Result<(), Error> {
        crate::events::raise(&self.ctx.shared, name, None)
    }

    /// Raises the external event `name` carrying `data`, which each monitor activation it makes
    /// reads with [`Ctx::activation_data`].
    pub fn raise_with<T: Any + Send + Sync>(&self, name: &str, data: T) -> Result<(), Error> {
        crate::events::raise(&self.ctx.shared, name, Some(std::sync::Arc::new(data)))
    }

    /// The live top-level tasks, in spawn order.
    pub fn top_level(&self) -> Result<Vec<NodeId>, Error> {
        self.ctx.children(self.ctx.node)
    }

    /// The run's counts now (live nodes among them).
    pub fn stats(&self) -> Result<Stats, Error> {
        self.engine(|e, _| e.stats())
    }

    /// Attaches a handler built for one task (TDL's `handler h() handles E for T`) to that task's
    /// nodes, alive and to come; returns its attachment, for [`Control::detach`].
    pub fn attach(&self, attached: Attached) -> Result<AttachId, Error> {
        self.handler_for(attached.task, attached.handler)
    }

    /// Attaches `handler` to the nodes of the task named `task`, alive and to come.
    pub fn handler_for(
        &self,
        task: impl Into<tcm_core::Name>,
        handler: Handler,
    ) -> Result<AttachId, Error> {
        let task = task.into();
        self.engine(|e, now| e.attach(now, task, handler.spec))
    }

    /// Detaches a handler attached by [`Control::attach`]: `false` when it was not attached.
    pub fn detach(&self, id: AttachId) -> Result<bool, Error> {
        self.engine(|e, now| e.detach(now, id))
    }

    /// Adds a wiretap on the task named `task` (see
    /// [`Runtime::wiretap`](crate::Runtime::wiretap)); returns it, for [`Control::untap`].
    pub fn wiretap<F, Fut, T>(
        &self,
        task: impl Into<tcm_core::Name>,
        when: TapWhen,
        check: F,
    ) -> Result<WiretapId, Error>
    where
        F: Fn(Ctx) -> Fut + Send + Sync + 'static,
        Fut: Future<Output = Result<T, tcm_core::Failure>> + Send + 'static,
        T: Any + Send,
    {
        self.wiretap_factory(task, when, crate::task::factory(check))
    }

    /// As [`Control::wiretap`], with the check's factory built already.
    pub fn wiretap_factory(
        &self,
        task: impl Into<tcm_core::Name>,
        when: TapWhen,
        check: Factory,
    ) -> Result<WiretapId, Error> {
        let task = task.into();
        self.engine(|e, now| e.tap(now, task, false, when, check))
    }

    /// Adds a wiretap built for one task (TDL's `wiretap w() before T`); returns it, for
    /// [`Control::untap`].
    pub fn tap(&self, tap: crate::task::Tap) -> Result<WiretapId, Error> {
        self.wiretap_factory(tap.task, tap.when, tap.check)
    }

    /// Removes a wiretap: `false` when it was not in place.
    pub fn untap(&self, id: WiretapId) -> Result<bool, Error> {
        self.engine(|e, now| e.untap(now, id))
    }

    /// Records an operation from outside the run in its trace: `what` was done, `by` asked.
    pub fn note(&self, what: &str, by: &str) -> Result<(), Error> {
        self.operate(|e, now| e.note_control(now, what, by))
    }

    /// [`Control::note`] for an operation whose effect is the input that comes next (an event
    /// raised through this handle): a replay of the run's journal writes the record again and
    /// gives that input, where it refuses an operation only noted.
    pub fn note_input(&self, what: &str, by: &str) -> Result<(), Error> {
        self.operate(|e, now| e.note_input(now, what, by))
    }
}

/// Inserts `task` as a top-level task of the run.
pub(crate) fn spawn_top(shared: &Arc<Shared>, task: Task) -> Result<NodeId, Error> {
    let mut inner = shared.enter()?;
    if inner.ended {
        return Err(Error::RunEnded);
    }
    let now = inner.engine.at_clock();
    let root = inner.engine.root();
    let (spec, kept) = task.into_parts(root);
    Ok(inner.spawn_root(now, spec, kept)?)
}
