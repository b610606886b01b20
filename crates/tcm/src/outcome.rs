//! How a run ended ([`RunOutcome`]) and its [`Report`], with the actions that panicked
//! ([`Panicked`]).

use std::fmt;
use std::time::Duration;
use tcm_core::{Blocked, Failure, FatalFailure, Stats};

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

/// An action (or wiretap check, or timer callback) that panicked: its node failed with
/// `ActionPanicked`, and the run went on (docs/semantics.md, "Exceptions and handlers").
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Panicked {
    /// Display number of the node whose action panicked (for a callback, of the node that set it;
    /// `None` when the program set it).
    pub node: Option<u64>,
    /// The node's instance name, or the callback's name.
    pub name: String,
    /// Instance names from the top-level task down to the node, joined by `/`.
    pub path: String,
    /// Whether it was a timer callback rather than an action.
    pub callback: bool,
    /// The panic's message.
    pub message: String,
}

impl fmt::Display for Panicked {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let what = if self.callback { "callback" } else { "action" };
        write!(f, "{what} {}", self.name)?;
        if let Some(n) = self.node {
            write!(f, " {{{n}}}")?;
        }
        if !self.path.is_empty() {
            write!(f, " ({})", self.path)?;
        }
        write!(f, " panicked: {}", self.message)
    }
}
