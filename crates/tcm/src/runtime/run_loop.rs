//! The driver loop (`RunLoop`): each turn, the core's driver steps under the engine's lock (due
//! timers fire, the journal takes the inputs, effects are carried out by the `Host`, trace records
//! are taken), the records handed to the sinks outside the lock, the due timer callbacks run; then
//! it sleeps until something touches the engine or the next deadline. And the end of a run
//! (`end_run`): its tasks aborted, its journal closed.

use super::*;

/// The driver loop's view of the run after one turn.
struct Turn {
    next: Next,
    // How the run ended, if it did.
    end: Option<RunOutcome>,
    // Timer callbacks that came due, to run outside the lock.
    due: Vec<DueCallback>,
}

pub(crate) struct RunLoop {
    shared: Arc<Shared>,
    timer: Option<crate::timer::PreciseTimer>,
}

impl RunLoop {
    pub(crate) fn new(shared: Arc<Shared>, timer: Option<crate::timer::PreciseTimer>) -> RunLoop {
        RunLoop { shared, timer }
    }

    /// One turn of the core's driver under the lock: due timers fire, effects are carried out,
    /// trace records and due callbacks are taken; then whether the run ended, and, for
    /// [`Session::quiescent`], whether it is quiet.
    fn turn(&self, trace: &mut Vec<tcm_trace::TraceEvent>) -> Result<Turn, Error> {
        // A plain lock, not an `Access`: the driver decides itself what to do next, and waking
        // itself would spin while the run waits for an event handle.
        let mut inner = lock(&self.shared)?;
        let now = self.shared.now();
        inner.report_stopped(&self.shared, now);
        let next = if inner.replay.as_ref().is_some_and(|r| r.active()) {
            // The journal gives the inputs, time passing among them (`replay.rs`).
            crate::replay::turn(&mut inner, &self.shared)
        } else if inner.journal.is_some() {
            // The timers that fire are journaled before what they cause is carried out; a turn
            // with none due gives the engine nothing (a replay gives it no such turn).
            let fields = &mut *inner;
            if fields.engine.poll_timeout().is_some_and(|d| d <= now) {
                tcm_core::Driver::time(&mut fields.engine, now);
            }
            if let Some(j) = fields.journal.as_mut() {
                j.drain(&mut fields.engine);
            }
            let (engine, mut host) = inner.split(&self.shared);
            tcm_core::Driver::effects(engine, &mut host);
            tcm_core::Driver::trace(engine, &mut host);
            tcm_core::Driver::next(engine)
        } else {
            let (engine, mut host) = inner.split(&self.shared);
            tcm_core::Driver::turn(engine, &mut host, now)
        };
        trace.append(&mut inner.trace);
        inner.armed = next.deadline;
        inner.clear_roots_changed();
        let mut due = std::mem::take(&mut inner.due);
        let quiet = due.is_empty() && inner.quiet();
        let journal_failed = inner
            .journal
            .as_ref()
            .and_then(|j| j.failed.clone())
            .map(|why| crate::journal::failed_outcome(&why));
        let end = if let Some(f) = journal_failed {
            // A run never goes on unjournaled.
            due.clear();
            Some(RunOutcome::Fatal(f))
        } else if let Some(f) = inner.engine.fatal() {
            // The run ends at once: due callbacks do not run.
            due.clear();
            Some(RunOutcome::Fatal(f.clone()))
        } else if let Some(o) = crate::replay::outcome(&inner) {
            Some(o)
        } else if !due.is_empty() {
            // They run first, even if the run is about to end: they came due before it did.
            for d in &due {
                inner.engine.callback_ran(d.token, &d.name);
            }
            let (engine, mut host) = inner.split(&self.shared);
            tcm_core::Driver::trace(engine, &mut host);
            trace.append(&mut inner.trace);
            None
        } else if !inner.finishing {
            None
        } else if let Some(outcome) = crate::host::outcome_of_roots(&inner.roots) {
            Some(outcome)
        } else if quiet
            && self.shared.handles.load(Ordering::SeqCst) == 0
            && !inner.engine.waits_for_operator()
        {
            // The stuck report scans every node: only when the run is over.
            let awaits = inner.parking.awaits();
            Some(RunOutcome::Stuck(inner.engine.blocked_awaiting(&awaits)))
        } else {
            None
        };
        // Published under the lock, so a program that reads the turn number under it sees a turn
        // that began after its own changes (`Session::quiescent`).
        let ended = end.is_some();
        if ended {
            inner.final_stats = Some(inner.engine.stats());
        }
        self.shared.status.send_modify(|s| {
            s.turn += 1;
            s.quiet = quiet;
            s.ended = ended;
        });
        Ok(Turn { next, end, due })
    }

    /// The driver loop. It is the one intentionally endless loop of the runtime: each turn ends in
    /// an await on the next thing that can change the engine.
    pub(crate) async fn drive(self, sinks: &mut [Box<dyn TraceSink>]) -> Result<RunOutcome, Error> {
        let mut trace = Vec::new();
        // Warnings and log lines go through `tracing` once: here, unless a sink logs them already.
        let logged = sinks.iter().any(|s| s.logs_warnings());
        let result = loop {
            let turn = match self.turn(&mut trace) {
                Ok(turn) => turn,
                Err(e) => {
                    self.end();
                    return Err(e);
                }
            };
            for ev in trace.drain(..) {
                if !logged {
                    crate::sink::log_notable(&ev);
                }
                for s in sinks.iter_mut() {
                    s.record(&ev);
                }
            }
            if let Some(end) = turn.end {
                break end;
            }
            if !turn.due.is_empty() {
                for due in turn.due {
                    crate::host::run_callback(&self.shared, due);
                }
                // The callbacks may have changed the engine: look again at once.
                continue;
            }
            let mut sleep = turn.next.deadline.map(|t| self.shared.clock.instant(t));
            if let Some(timer) = &self.timer {
                timer.set(sleep.map(tokio::time::Instant::into_std));
                sleep = None;
            }
            tokio::select! {
                biased;
                () = self.shared.wake.notified() => {}
                () = sleep_until(sleep), if sleep.is_some() => {
                    // The next turn fires the timer; nobody need wake it for a deadline it set.
                    lock(&self.shared)?.armed = None;
                }
            }
        };
        self.end();
        Ok(result)
    }

    fn end(&self) {
        end_run(&self.shared);
    }
}

async fn sleep_until(at: Option<tokio::time::Instant>) {
    if let Some(at) = at {
        tokio::time::sleep_until(at).await;
    }
}
