//! Where a counterexample breaks its property: the record of its trace that `tdl view --at` opens
//! and the page's time cursor starts on ([`Counterexample::failing_seq`]), the one choice that
//! `tdl verify` and `tdl sim` share, from the facts the search and the walks know ([`Breaks`]).

use tcm_trace::TraceKind;

use crate::Counterexample;
use crate::machine::{Fault, State};

/// What a counterexample's path ends on, for [`Counterexample::failing_seq`]: which property kind
/// it breaks, with what the choice of its failing record needs to know.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum Breaks {
    /// The property is broken where the path ends: a stuck run (nothing can happen any more), a
    /// property of the user's broken by the last transition or never met by the end of the run,
    /// a simulated run going on past a bound.
    #[default]
    AtEnd,
    /// A failure no handler takes: the node whose action failed (its display number, as the
    /// trace's `failed` record names it) and the exception.
    Unhandled {
        /// The failing node's display number.
        node: u64,
        /// The exception's name.
        exception: String,
    },
    /// A run that never ends: the path's last transitions repeat forever from the one that wrote
    /// the record at this index of the trace (the trace's length when they wrote none).
    Repeats {
        /// The index in [`Counterexample::trace`] of the repeating part's first record.
        record: usize,
    },
    /// The trace checker rejects the trace: its first complaint is about the record of this
    /// `seq`.
    TraceChecker {
        /// The `seq` of the record the first complaint names.
        seq: u64,
    },
}

impl Counterexample {
    /// The `seq` of the record of [`Counterexample::trace`] at which the property is broken,
    /// `None` for an empty trace:
    /// - a stuck run, or a property broken at the end of the path ([`Breaks::AtEnd`]): the last
    ///   record;
    /// - a failure no handler takes: the `failed` record of that node with that exception (the
    ///   last one, should the node have several), else the last record;
    /// - a run that never ends: the first record of the part that repeats, else (the repeating
    ///   transitions wrote none) the last record;
    /// - the trace checker: the record its first complaint names (at most the last).
    pub fn failing_seq(&self) -> Option<u64> {
        let last = self.trace.last()?.seq;
        Some(match &self.breaks {
            Breaks::AtEnd => last,
            Breaks::Unhandled { node, exception } => self
                .trace
                .iter()
                .rev()
                .find(|r| {
                    matches!(&r.kind, TraceKind::Failed { node: n, exception: e, .. }
                        if n == node && e == exception)
                })
                .map_or(last, |r| r.seq),
            Breaks::Repeats { record } => self.trace.get(*record).map_or(last, |r| r.seq),
            Breaks::TraceChecker { seq } => (*seq).min(last),
        })
    }
}

/// The failure no handler takes that made `s`'s fault, as [`Breaks::Unhandled`]: the engine's
/// unhandled failure of the fault's exception at the fault's path. [`Breaks::AtEnd`] when `s` has
/// no such fault.
pub(crate) fn unhandled(s: &State) -> Breaks {
    let Some(Fault::Unhandled { exception, path }) = &s.fault else {
        return Breaks::AtEnd;
    };
    s.engine
        .unhandled()
        .iter()
        .find(|f| f.path == *path && f.failure.exception == exception.as_str())
        .map_or(Breaks::AtEnd, |f| Breaks::Unhandled {
            node: f.node,
            exception: exception.clone(),
        })
}

/// The `seq` of the first record the trace checker complains about, if it does.
pub(crate) fn first_complaint(
    checked: &Result<tcm_trace::CheckReport, Vec<tcm_trace::Violation>>,
) -> Option<u64> {
    checked.as_ref().err()?.iter().map(|v| v.seq).min()
}
