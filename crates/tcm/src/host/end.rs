//! A run's end: how its top-level tasks decide its outcome, its report, and what is stopped
//! and closed when it ends (`end_run`).

use super::{Root, Shared, lock};
use crate::Error;
use crate::outcome::{Report, RunOutcome};
use std::sync::Arc;
use tcm_core::WatchOutcome;

/// How a run of these top-level tasks ended, once each did: the first, in spawn order, that
/// did not complete normally decides (its action failed, or it was terminated); otherwise the
/// run completed. `None` while one runs.
pub(crate) fn outcome_of_roots(roots: &[Root]) -> Option<RunOutcome> {
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
