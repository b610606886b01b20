//! How a run ended ([`RunOutcome`]), its [`Report`], and the end of a run: what runs is
//! stopped, the journal closed (`end_run`).

use crate::Error;
use crate::host::{Panicked, Root, Shared, lock};
use std::sync::Arc;
use std::time::Duration;
use tcm_core::{Blocked, Failure, FatalFailure, Stats, WatchOutcome};

/// How a run ended.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum RunOutcome {
    /// The top-level task's execution completed (it and its whole subtree).
    Completed,
    /// The top-level task's own action failed (whether or not a handler then took the failure).
    TaskFailed(Failure),
    /// The top-level task was terminated.
    Terminated,
    /// An unhandled failure under [`FailurePolicy::Fatal`].
    Fatal(FatalFailure),
    /// Nothing can progress (no action runs but those parked in an await on the engine, nothing is
    /// ready, no timer is pending) and no event handle is open: these nodes wait on events that
    /// will never come (docs/semantics.md, "Run outcome").
    Stuck(Vec<Blocked>),
    /// A replay ([`Runtime::replay`]) reached the end of its journal with the run still going
    /// after `inputs` inputs (a journal cut by a crash).
    JournalEnded {
        /// The inputs given.
        inputs: u64,
    },
    /// A replay ([`Runtime::replay`], [`Runtime::resume`]) found the program doing otherwise than
    /// the run its journal recorded: where, and both versions (docs/semantics.md, "Durable runs").
    Diverged(String),
}

impl RunOutcome {
    /// How a run of these top-level tasks ended, once each did: the first, in spawn order, that
    /// did not complete normally decides (its action failed, or it was terminated); otherwise the
    /// run completed. `None` while one runs.
    pub(crate) fn of_roots(roots: &[Root]) -> Option<RunOutcome> {
        let mut outcome = RunOutcome::Completed;
        for r in roots {
            match r.outcome.as_ref()? {
                WatchOutcome::Reached | WatchOutcome::Recovered { .. } | WatchOutcome::Skipped => {}
                WatchOutcome::Failed(f) | WatchOutcome::Handled(f) => {
                    if outcome == RunOutcome::Completed {
                        outcome = RunOutcome::TaskFailed(f.clone());
                    }
                }
                WatchOutcome::Terminated | WatchOutcome::Dead => {
                    if outcome == RunOutcome::Completed {
                        outcome = RunOutcome::Terminated;
                    }
                }
            }
        }
        Some(outcome)
    }
}

/// The result of [`Runtime::run`].
#[derive(Clone, Debug)]
pub struct Report {
    /// How the run ended.
    pub outcome: RunOutcome,
    /// Virtual (or real) time from the start of the run to its end.
    pub elapsed: Duration,
    /// Engine counters at the end.
    pub stats: Stats,
    /// The actions (and timer callbacks) that panicked, in order. Each panic failed its node and
    /// the run went on; `tcm::testing::run_checked` fails the test for them.
    pub panics: Vec<Panicked>,
    /// Every failure no handler took, in order: the node's number and path of instance names,
    /// the exception's type name and its data as text (the failure's message). Under the default
    /// policy the run goes on after each (docs/semantics.md, "Failure without a handler"), so an
    /// outcome `Completed` may come with unhandled failures: check this list, or
    /// [`Report::is_clean`].
    pub unhandled: Vec<FatalFailure>,
    /// Nodes that failed during the run, handled or not.
    pub failures: u64,
    /// Warnings of the run (`warning` trace records, such as "No exception handler found"), each
    /// also logged through `tracing` at `WARN` level with target `tcm`.
    pub warnings: u64,
}

impl Report {
    /// Whether the run completed with no unhandled failure, no warning and no panic.
    pub fn is_clean(&self) -> bool {
        self.outcome == RunOutcome::Completed
            && self.unhandled.is_empty()
            && self.warnings == 0
            && self.panics.is_empty()
    }
}

impl std::fmt::Display for Report {
    /// The outcome, then one line per unhandled failure and panic, then the counts.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.outcome {
            RunOutcome::Completed => write!(f, "completed")?,
            RunOutcome::TaskFailed(fl) => {
                write!(f, "task failed: {}: {}", fl.exception, fl.message)?;
            }
            RunOutcome::Terminated => write!(f, "terminated")?,
            RunOutcome::Fatal(fl) => write!(f, "fatal: {fl}")?,
            RunOutcome::Stuck(b) => write!(f, "stuck ({} waiting nodes)", b.len())?,
            RunOutcome::JournalEnded { inputs } => {
                write!(
                    f,
                    "the journal ended, after {inputs} inputs, with the run going on"
                )?;
            }
            RunOutcome::Diverged(why) => write!(f, "diverged from the journal: {why}")?,
        }
        write!(f, " after {:?}", self.elapsed)?;
        for u in &self.unhandled {
            write!(f, "\n{u}")?;
        }
        for p in &self.panics {
            write!(f, "\n{p}")?;
        }
        write!(
            f,
            "\n{} unhandled failure(s), {} failure(s), {} warning(s), {} panic(s)",
            self.unhandled.len(),
            self.failures,
            self.warnings,
            self.panics.len()
        )
    }
}

/// The report of a run that ended with `outcome`.
pub(crate) fn report(shared: &Arc<Shared>, outcome: RunOutcome) -> Result<Report, Error> {
    let mut inner = lock(shared)?;
    let stats = inner.final_stats.unwrap_or_else(|| inner.engine.stats());
    Ok(Report {
        outcome,
        elapsed: shared.now().since_start(),
        stats,
        panics: std::mem::take(&mut inner.panics),
        unhandled: inner.engine.unhandled().to_vec(),
        failures: stats.failures,
        warnings: stats.warnings,
    })
}

/// The run is over: whatever still runs belongs to a run that is over, no callback will run, and
/// whoever waits is told.
pub(crate) fn end_run(shared: &Arc<Shared>) {
    let mut launches = Vec::new();
    let mut parked = Vec::new();
    if let Ok(mut inner) = lock(shared) {
        inner.ended = true;
        for t in inner.aborts.drain() {
            match t {
                crate::host::TaskRef::Task(h) => h.abort(),
                crate::host::TaskRef::Parked(p) => parked.extend(p.take()),
            }
        }
        launches = std::mem::take(&mut inner.launches);
        inner.cancels.end();
        inner.callbacks.clear();
        inner.due.clear();
        inner.watchers.clear();
        // The journal's last inputs are written and synced.
        if let Some(mut j) = inner.journal.take() {
            j.drain(&mut inner.engine);
            if let Err(why) = j.close() {
                tracing::error!(target: "tcm", "the run's journal is incomplete: {why}");
            }
        }
        shared.status.send_modify(|s| s.ended = true);
    }
    // Started but never polled, or parked: dropped outside the lock (a drop may take it).
    drop(launches);
    drop(parked);
}
