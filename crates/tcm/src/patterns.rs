//! Recovery patterns, each a few lines in a body (docs/from-behavior-trees.md tells which
//! behaviour-tree construct each stands for):
//!
//! - [`alternatives`]: try each task in turn until one succeeds (a fallback);
//! - [`InTurn`]: recoveries tried in turn, one round per failure, starting after the last one
//!   that worked, back to the first on [`InTurn::reset`] (a round robin);
//! - [`retry_around`]: a subtree run again after a recovery, a bounded number of times, with an
//!   immediate failure for the failures recovery cannot help (a recovery node);
//! - [`Preemption`]: a new goal ends what runs for the old one at that instant (a reactive
//!   fallback on "goal updated");
//! - replanning at a bounded rate while executing is a monitor with a period (TDL's
//!   `monitor m() with period 1s`), beside the task that executes; no function is needed.
//!
//! The language has the other half: `with propagate` (a child's failure fails its parent),
//! `retry;` in a handler on the parent (the whole subtree again), `with outcome` (how a child
//! ended, as a value) and `X failed` / `X succeeded` in constraints (docs/semantics.md,
//! "Failing the parent", "Outcomes").

use crate::Error;
use crate::ctx::{Ctx, Ended};
use crate::task::Task;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use tcm_core::{Constraint, Failure, Then, When};

/// Runs `tasks` one after the other, each only if the one before failed, and returns how the
/// first that succeeded ended, or the last failure (a behaviour-tree fallback). A task that is
/// terminated (its parent is being terminated, or a constraint ended it) ends the attempts: it
/// is returned as is. No task: `Ended::Failed` with exception `NoAlternative`.
pub async fn alternatives<T: 'static>(
    ctx: &Ctx,
    tasks: impl IntoIterator<Item = Task>,
) -> Result<Ended<T>, Error> {
    let mut last = Ended::Failed(Failure::new("NoAlternative", "no alternative was given"));
    for task in tasks {
        last = ctx.spawn(task).wait_outcome::<T>().await?;
        if !last.failed() {
            break;
        }
    }
    Ok(last)
}

type Make = dyn Fn(usize) -> Task + Send + Sync;

/// Recoveries tried in turn (a behaviour-tree round robin). Each [`InTurn::recover`] runs the
/// recoveries from the current one on, wrapping around, until one succeeds, and the next call
/// starts after that one; so a robot that keeps failing tries something different each time.
/// [`InTurn::reset`] (when what the recoveries served succeeded) starts again from the first.
///
/// Cloning shares the turn: give a clone to a handler and keep one in the task that resets it.
#[derive(Clone)]
pub struct InTurn {
    make: Arc<Make>,
    len: usize,
    next: Arc<AtomicUsize>,
    preemption: Option<Preemption>,
}

/// How one round of [`InTurn::recover`] ended.
#[derive(Clone, Debug, PartialEq)]
pub enum Recovered {
    /// Recovery `index` succeeded.
    By(usize),
    /// Every recovery failed; the last failure.
    Failed(Failure),
    /// A preemption ended the recovery that ran (see [`InTurn::preempted_by`]).
    Preempted,
    /// The recovery that ran was terminated otherwise.
    Terminated,
}

impl InTurn {
    /// `len` recoveries; `make(i)` is recovery `i`'s task (`i < len`).
    pub fn new(len: usize, make: impl Fn(usize) -> Task + Send + Sync + 'static) -> InTurn {
        InTurn {
            make: Arc::new(make),
            len,
            next: Arc::new(AtomicUsize::new(0)),
            preemption: None,
        }
    }

    /// Each recovery is terminated at once when `p` preempts (a new goal arrived): the round then
    /// ends [`Recovered::Preempted`], and whoever recovers goes on with the new goal.
    pub fn preempted_by(mut self, p: Preemption) -> InTurn {
        self.preemption = Some(p);
        self
    }

    /// The index of the recovery the next round starts with.
    pub fn next_index(&self) -> usize {
        self.next.load(Ordering::SeqCst)
    }

    /// Starts the next round with the first recovery again.
    pub fn reset(&self) {
        self.next.store(0, Ordering::SeqCst);
    }

    /// One round: runs the recoveries from the current one on until one succeeds (the next round
    /// starts after it); when every one failed, the next round starts where this one did.
    pub async fn recover(&self, ctx: &Ctx) -> Result<Recovered, Error> {
        let first = self.next_index();
        let mut last = Recovered::Failed(Failure::new("NoRecovery", "no recovery was given"));
        for k in 0..self.len {
            let i = (first + k) % self.len;
            let mut spawn = ctx.spawn((self.make)(i));
            let event = match &self.preemption {
                Some(p) => {
                    let (event, id) = p.watch(ctx)?;
                    spawn = spawn.with(Constraint::Trigger(When::External(id), Then::Terminate));
                    Some(event)
                }
                None => None,
            };
            match spawn.wait_outcome::<()>().await? {
                Ended::Succeeded(()) => {
                    self.next.store((i + 1) % self.len, Ordering::SeqCst);
                    return Ok(Recovered::By(i));
                }
                Ended::Failed(f) => last = Recovered::Failed(f),
                // It did not run, so it recovered nothing: the next one is tried.
                Ended::Skipped => {}
                Ended::Terminated => {
                    let preempted = event
                        .zip(self.preemption.as_ref())
                        .is_some_and(|(e, p)| p.happened(e));
                    return Ok(if preempted {
                        Recovered::Preempted
                    } else {
                        Recovered::Terminated
                    });
                }
            }
        }
        Ok(last)
    }
}

/// A preemption, such as a new goal arriving: [`Preemption::preempt`] terminates, at that
/// instant, every node spawned with [`Preemption::terminates`] since the last preemption.
///
/// External events are latched (a constraint applied after its event was raised fires at once,
/// docs/semantics.md, "Events"), so each preemption raises its own event, `name#0`, `name#1`, …:
/// what is spawned after a preemption waits for the next one. Cloning shares it.
#[derive(Clone, Debug)]
pub struct Preemption {
    name: Arc<str>,
    count: Arc<AtomicU64>,
}

impl Preemption {
    /// A preemption whose events are named after `name`.
    pub fn new(name: &str) -> Preemption {
        Preemption {
            name: name.into(),
            count: Arc::new(AtomicU64::new(0)),
        }
    }

    /// The name of the event the next preemption raises.
    pub fn next_event(&self) -> String {
        format!("{}#{}", self.name, self.count.load(Ordering::SeqCst))
    }

    /// How many preemptions there were.
    pub fn count(&self) -> u64 {
        self.count.load(Ordering::SeqCst)
    }

    /// Preempts: raises the current event through `raise` (`|n| ctx.raise(n)`, or an
    /// `EventHandle`'s or a session's `raise`), then moves on to the next.
    pub fn preempt(&self, raise: impl FnOnce(&str) -> Result<(), Error>) -> Result<(), Error> {
        let event = self.next_event();
        self.count.fetch_add(1, Ordering::SeqCst);
        raise(&event)
    }

    /// The constraint that terminates a node at the next preemption (for `Spawner::with` or
    /// `Task::with`).
    pub fn terminates(&self, ctx: &Ctx) -> Result<Constraint, Error> {
        let (_, id) = self.watch(ctx)?;
        Ok(Constraint::Trigger(When::External(id), Then::Terminate))
    }

    fn watch(&self, ctx: &Ctx) -> Result<(u64, tcm_core::ExternalId), Error> {
        let n = self.count();
        Ok((n, ctx.external(&format!("{}#{n}", self.name))?))
    }

    /// Preemption number `n` happened.
    fn happened(&self, n: u64) -> bool {
        self.count() > n
    }
}

/// Runs `body(attempt)` (attempt 0, 1, …); when it fails with a failure `recoverable` accepts,
/// runs one round of `recoveries` and, if that worked (or was preempted), runs the body again, at
/// most `retries` times (a behaviour-tree recovery node). When the body succeeds, the turn of the
/// recoveries is reset. Returns how the last run of the body ended; a failure recovery cannot
/// help, or a round in which every recovery failed, ends it at once with that failure.
///
/// With the language alone, the same is `spawn body() with exception handler h()` where `h`
/// handles the recoverable exception type `with maximum activate N` and says `retry;` after its
/// recovery: use that when the body's children fail it `with propagate`.
pub async fn retry_around<T: 'static>(
    ctx: &Ctx,
    retries: u32,
    mut body: impl FnMut(u32) -> Task,
    recoveries: &InTurn,
    recoverable: impl Fn(&Failure) -> bool,
) -> Result<Ended<T>, Error> {
    let mut attempt = 0;
    loop {
        let ended = ctx.spawn(body(attempt)).wait_outcome::<T>().await?;
        let failure = match &ended {
            Ended::Succeeded(_) => {
                recoveries.reset();
                return Ok(ended);
            }
            Ended::Terminated | Ended::Skipped => return Ok(ended),
            Ended::Failed(f) => f,
        };
        if attempt >= retries || !recoverable(failure) {
            return Ok(ended);
        }
        match recoveries.recover(ctx).await? {
            Recovered::By(_) | Recovered::Preempted => attempt += 1,
            Recovered::Failed(f) => return Ok(Ended::Failed(f)),
            Recovered::Terminated => return Ok(Ended::Terminated),
        }
    }
}
