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
//! - [`RunOnce`]: a task run to its end once, skipped every later time (a run-once
//!   decorator);
//! - [`Cooldown`]: a task skipped for a while after it succeeded (a cooldown decorator);
//! - replanning at a bounded rate while executing is a monitor with a period (TDL's
//!   `monitor m() with period 1s, serial`, with `Overrun::Skip` for a tree's rate), beside the
//!   task that executes; no function is needed.
//!
//! A decorator that decides not to run its task still spawns it, `skip if true`: the node is
//! skipped when its turn comes (a `skipped` record, outcome skipped, its action never run), so the
//! trace shows the decision where a behaviour tree would show a skipped node, and the caller gets
//! [`Ended::Skipped`].
//!
//! The language has the other half: `with propagate` (a child's failure fails its parent),
//! `retry;` in a handler on the parent (the whole subtree again), `with outcome` (how a child
//! ended, as a value) and `X failed` / `X succeeded` in constraints (docs/semantics.md,
//! "Failing the parent", "Outcomes").

use crate::Error;
use crate::ctx::{Ctx, Ended};
use crate::task::Task;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;
use tcm_core::{Constraint, Expr, Failure, Then, Value, When};

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

/// Spawns `task` with `skip if true` and waits: it is skipped when its turn comes, so the trace
/// shows it skipped and it ends [`Ended::Skipped`] (or [`Ended::Terminated`], if its parent is
/// terminated first).
async fn skipped<T: 'static>(ctx: &Ctx, task: Task) -> Result<Ended<T>, Error> {
    let always = ctx.condition(&[], Expr::Lit(Value::Bool(true)))?;
    ctx.spawn(task)
        .with(Constraint::skip_if(always))
        .wait_outcome::<T>()
        .await
}

#[derive(Clone, Debug, Default)]
enum Once {
    #[default]
    NotRun,
    Running,
    Ended(Option<Failure>),
}

/// A task run to its end once (a behaviour-tree run-once decorator): the first
/// [`RunOnce::run`] runs it and returns how it ended; every later call, and any call while it
/// runs, spawns the task given skipped and returns [`Ended::Skipped`]. A run that ends
/// succeeded or failed counts; one that was terminated (or skipped) did not run to its end, and
/// the next call runs the task again. [`RunOnce::reset`] forgets the run.
///
/// With state variables the language has the same without Rust: the task sets a variable when
/// it is done, and is spawned `skip if done` (docs/from-behavior-trees.md, "Decorators").
///
/// Cloning shares it: give a clone to each activation or task that may run the task.
#[derive(Clone, Debug, Default)]
pub struct RunOnce {
    state: Arc<Mutex<Once>>,
}

impl RunOnce {
    /// Not run yet.
    pub fn new() -> RunOnce {
        RunOnce::default()
    }

    /// Runs `task` if it never ran to its end (and is not running), and waits for it; otherwise
    /// skips it (see the type).
    pub async fn run<T: 'static>(&self, ctx: &Ctx, task: Task) -> Result<Ended<T>, Error> {
        if !self.claim() {
            return skipped(ctx, task).await;
        }
        // Until it ended, a dropped wait (the caller was terminated) leaves it not run.
        let mut run = Claimed {
            once: self,
            ended: None,
        };
        let ended = ctx.spawn(task).wait_outcome::<T>().await;
        run.ended = Some(match &ended {
            Ok(Ended::Succeeded(_)) => Once::Ended(None),
            Ok(Ended::Failed(f)) => Once::Ended(Some(f.clone())),
            _ => Once::NotRun,
        });
        ended
    }

    /// Marks it running if it never ran to its end and is not running; whether it did.
    fn claim(&self) -> bool {
        let mut state = self.lock();
        let free = matches!(*state, Once::NotRun);
        if free {
            *state = Once::Running;
        }
        free
    }

    /// Whether the task ran to its end.
    pub fn done(&self) -> bool {
        matches!(*self.lock(), Once::Ended(_))
    }

    /// How the run ended: `Some(None)` succeeded, `Some(Some(failure))` failed, `None` not yet.
    pub fn ended(&self) -> Option<Option<Failure>> {
        match &*self.lock() {
            Once::Ended(f) => Some(f.clone()),
            _ => None,
        }
    }

    /// Forgets the run: the next call runs the task again (a run in progress still counts when
    /// it ends).
    pub fn reset(&self) {
        let mut state = self.lock();
        if matches!(*state, Once::Ended(_)) {
            *state = Once::NotRun;
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Once> {
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

/// A run of a [`RunOnce`]: when it is dropped, the state it ended in (`ended`), or not run if
/// the wait for it was dropped unfinished.
struct Claimed<'a> {
    once: &'a RunOnce,
    ended: Option<Once>,
}

impl Drop for Claimed<'_> {
    fn drop(&mut self) {
        *self.once.lock() = self.ended.take().unwrap_or(Once::NotRun);
    }
}

/// A task skipped for a while after it succeeded (a behaviour-tree cooldown decorator):
/// [`Cooldown::run`] runs the task and waits for it, unless the last success was less than the
/// cooldown ago, in the run's time ([`Ctx::now`]); then it spawns the task given skipped and
/// returns [`Ended::Skipped`]. A failure or a termination starts no cooldown, so the next call
/// runs the task again at once. Calls while one runs are not held back: the cooldown starts when
/// a run's success is seen. [`Cooldown::reset`] ends the cooldown.
///
/// Cloning shares it.
#[derive(Clone, Debug)]
pub struct Cooldown {
    period: Duration,
    until: Arc<Mutex<Option<Duration>>>,
}

impl Cooldown {
    /// A cooldown of `period` after each success.
    pub fn new(period: Duration) -> Cooldown {
        Cooldown {
            period,
            until: Arc::new(Mutex::new(None)),
        }
    }

    /// Runs `task` unless it is cooling down, and waits for it (see the type).
    pub async fn run<T: 'static>(&self, ctx: &Ctx, task: Task) -> Result<Ended<T>, Error> {
        if !self.remaining(ctx).is_zero() {
            return skipped(ctx, task).await;
        }
        let ended = ctx.spawn(task).wait_outcome::<T>().await?;
        if ended.succeeded() {
            *self.lock() = Some(ctx.now() + self.period);
        }
        Ok(ended)
    }

    /// How long the cooldown still lasts at `ctx`'s time (zero: the next call runs the task).
    pub fn remaining(&self, ctx: &Ctx) -> Duration {
        self.lock()
            .map_or(Duration::ZERO, |until| until.saturating_sub(ctx.now()))
    }

    /// Ends the cooldown: the next call runs the task.
    pub fn reset(&self) {
        *self.lock() = None;
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Option<Duration>> {
        self.until.lock().unwrap_or_else(PoisonError::into_inner)
    }
}
