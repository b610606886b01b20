//! The timer queue of the agenda: a binary heap ordered by (deadline, sequence number), so timers
//! due at the same time fire in the order they were set (FIFO; docs/semantics.md, "Agenda and release order").
//!
//! Timers are never removed when they stop mattering (their node completed, was terminated or
//! reclaimed); they are skipped when they surface, and the heap is compacted when stale entries
//! could outnumber live ones, so memory stays proportional to live timers.

use crate::constraint::Then;
use crate::ids::{NodeId, WatchToken};
use crate::time::Time;
use std::cmp::Reverse;
use std::collections::BinaryHeap;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum TimerKind {
    /// A trigger of the target fires (see `engine/arm.rs`).
    Trigger { target: NodeId, then: Then },
    /// Polling activation `k` of a monitor (due at its start + k periods).
    Poll { monitor: NodeId, k: u64 },
    /// Tell the shell ([`super::Effect::Notify`]): a timer callback is due (`callback.rs`).
    Notify { token: WatchToken },
    /// A node held for approval waited `after` for it (`steer.rs`).
    Approval {
        node: NodeId,
        after: std::time::Duration,
    },
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Entry {
    at: Time,
    seq: u64,
    kind: TimerKind,
}

impl Ord for Entry {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        (self.at, self.seq).cmp(&(other.at, other.seq))
    }
}

impl PartialOrd for Entry {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

/// Compaction runs when the heap holds more than this many entries and twice the live count
/// measured at the last compaction: the amortised cost per timer stays O(log n).
const COMPACT_MIN: usize = 4096;

#[derive(Clone, Default)]
pub(crate) struct Timers {
    heap: BinaryHeap<Reverse<Entry>>,
    seq: u64,
    compact_at: usize,
}

impl Timers {
    /// Whether no timer is pending at all (stale ones included).
    #[inline]
    pub(crate) fn is_empty(&self) -> bool {
        self.heap.is_empty()
    }

    pub(crate) fn push(&mut self, at: Time, kind: TimerKind) {
        let seq = self.seq;
        self.seq += 1;
        self.heap.push(Reverse(Entry { at, seq, kind }));
    }

    fn compact(&mut self, live: impl Fn(&TimerKind) -> bool) {
        if self.heap.len() > COMPACT_MIN.max(self.compact_at) {
            let entries = std::mem::take(&mut self.heap).into_vec();
            self.heap = entries.into_iter().filter(|e| live(&e.0.kind)).collect();
            self.compact_at = self.heap.len() * 2;
        }
    }

    /// Removes the enabling timers whose target `forced` names and returns them in the order they
    /// would have fired: a node terminated before it started has its delays released at once
    /// (docs/semantics.md, "Termination").
    pub(crate) fn take_enables(
        &mut self,
        forced: impl Fn(NodeId) -> bool,
    ) -> Vec<(NodeId, crate::constraint::Then)> {
        let (mut taken, kept): (Vec<Entry>, Vec<Entry>) = std::mem::take(&mut self.heap)
            .into_vec()
            .into_iter()
            .map(|Reverse(e)| e)
            .partition(|e| match e.kind {
                TimerKind::Trigger {
                    target,
                    then: Then::Enable(_),
                } => forced(target),
                _ => false,
            });
        self.heap = kept.into_iter().map(Reverse).collect();
        taken.sort();
        taken
            .into_iter()
            .filter_map(|e| match e.kind {
                TimerKind::Trigger { target, then } => Some((target, then)),
                TimerKind::Poll { .. } | TimerKind::Notify { .. } | TimerKind::Approval { .. } => {
                    None
                }
            })
            .collect()
    }

    /// Moves every queued timer `by` later (a paused run resumes, `steer.rs`); their order stays.
    pub(crate) fn shift(&mut self, by: std::time::Duration) {
        let entries = std::mem::take(&mut self.heap).into_vec();
        self.heap = entries
            .into_iter()
            .map(|Reverse(mut e)| {
                e.at = e.at + by;
                Reverse(e)
            })
            .collect();
    }

    /// Every timer still queued, live or not, in the order they would fire.
    pub(crate) fn pending(&self) -> Vec<(Time, TimerKind)> {
        let mut entries: Vec<Entry> = self.heap.iter().map(|Reverse(e)| *e).collect();
        entries.sort();
        entries.into_iter().map(|e| (e.at, e.kind)).collect()
    }

    /// The earliest deadline among live timers; stale timers on top are dropped.
    pub(crate) fn next_deadline(&mut self, live: impl Fn(&TimerKind) -> bool) -> Option<Time> {
        self.compact(&live);
        while let Some(Reverse(top)) = self.heap.peek() {
            if live(&top.kind) {
                return Some(top.at);
            }
            self.heap.pop();
        }
        None
    }

    /// Removes and returns the earliest live timer due before `now` (or at `now`, if `inclusive`),
    /// with its deadline.
    pub(crate) fn pop_due(
        &mut self,
        now: Time,
        inclusive: bool,
        live: impl Fn(&TimerKind) -> bool,
    ) -> Option<(Time, TimerKind)> {
        while let Some(Reverse(top)) = self.heap.peek() {
            if top.at > now || (!inclusive && top.at == now) {
                return None;
            }
            let (at, kind) = (top.at, top.kind);
            self.heap.pop();
            if live(&kind) {
                return Some((at, kind));
            }
        }
        None
    }
}
