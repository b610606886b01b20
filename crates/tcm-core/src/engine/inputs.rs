//! The engine's inputs, recorded for a journal (a durable run: `tcm-journal`; docs/semantics.md,
//! "Durable runs"): each input at the time the engine took it, in the order it took them, nodes
//! named by their display numbers. The engine does no I/O: the shell drains them
//! ([`Engine::poll_input`]) and writes them. Recording is off until [`Engine::record_inputs`].
//!
//! What is an input: an action's end (with its failure, if any: its value the shell keeps), its
//! stop after a cancellation, its grace period running out, an external event, a state variable
//! set, time passing with timers due, each reading of the shell's clock the engine took, and an
//! operation from outside (a `control` record's).
//! What bodies ask of the engine (spawns, constraints, waits) is not: a replay runs the bodies
//! again, and they ask it again.

use super::Engine;
use super::node::Node;
use crate::arena::Keep;
use crate::failure::Failure;
use crate::time::Time;
use std::collections::VecDeque;

/// One input, as recorded.
#[derive(Clone, Debug, PartialEq)]
pub enum InputRecord {
    /// A job the shell ran ended: `node`'s action or invocation (or, with `tap`, a wiretap check
    /// on it), well or with `failure`.
    Finished {
        /// The node's display number.
        node: u64,
        /// For a wiretap check: the wiretap's number.
        tap: Option<u32>,
        /// How it failed, if it did (boxed: most ends succeed, and inputs are queued one each).
        failure: Option<Box<Failure>>,
    },
    /// A cancelled job stopped.
    Stopped {
        /// The node's display number.
        node: u64,
    },
    /// A cancelled job did not stop within its grace period.
    Overdue {
        /// The node's display number.
        node: u64,
        /// The grace period.
        grace: std::time::Duration,
    },
    /// An external event was raised (its data, if any, the shell keeps).
    External {
        /// Its name.
        name: String,
    },
    /// A state variable was set.
    State {
        /// Its name.
        name: String,
        /// Its value.
        value: tcm_expr::Value,
    },
    /// Time passed to the record's time, and timers were due.
    Time,
    /// The engine read the shell's clock (`Engine::set_clock`), for an input or a command given
    /// the clock's time (`Engine::at_clock`): the record's time is the reading. A replay gives
    /// the engine these readings, in order, for the same commands to carry the same times.
    Clock,
    /// A body wrote a line to the run's log: a command's is given again by a replay, which does
    /// not run commands; another body's, the replay's body writes again.
    Log {
        /// The node's display number.
        node: u64,
        /// The line.
        message: String,
    },
    /// An operation from outside the run, as its `control` record says it.
    Control {
        /// What was done.
        what: String,
        /// Who asked.
        by: String,
        /// The operation, for a replay to carry out again (`None`: one it cannot: a handler or
        /// a wiretap attached, a fault with a value of the program's).
        op: Option<super::SteerOp>,
    },
}

impl<A, F: Clone, S: Keep<Node<A, F>>> Engine<A, F, S> {
    /// Records every input from now on, for [`Engine::poll_input`] (off by default).
    pub fn record_inputs(&mut self, on: bool) {
        self.inputs = on.then(VecDeque::new);
    }

    /// Output: the next recorded input, with the engine's time when it took it and the steps the
    /// run had taken when it came in ([`Engine::steps`]: a replay gives it the input at the same
    /// point of what the bodies ask).
    #[must_use]
    pub fn poll_input(&mut self) -> Option<(Time, u64, InputRecord)> {
        self.poll_input_given()
            .map(|(t, at, input, _)| (t, at, input))
    }

    /// [`Engine::poll_input`], with whether a body gave the input itself ([`Engine::by_body`]):
    /// a replay runs the body again, which gives it again.
    #[must_use]
    pub fn poll_input_given(&mut self) -> Option<(Time, u64, InputRecord, bool)> {
        self.inputs.as_mut()?.pop_front()
    }

    /// Whether a recorded input waits to be polled ([`Engine::poll_input`]).
    #[inline]
    #[must_use]
    pub fn has_inputs(&self) -> bool {
        self.inputs.as_ref().is_some_and(|q| !q.is_empty())
    }

    /// Carries out `request`, a request of a body that the replay of a journal runs again: an
    /// input it gives (an event it raises, a state variable it sets) is recorded as the body's.
    pub fn by_body<R>(&mut self, request: impl FnOnce(&mut Self) -> R) -> R {
        self.by_body = true;
        let r = request(self);
        self.by_body = false;
        r
    }

    /// Records an input at the engine's time, if recording.
    #[inline]
    pub(super) fn record(&mut self, input: impl FnOnce(&Self) -> InputRecord) {
        if self.inputs.is_some() {
            // An input given the clock's time reads it now (`Engine::at_clock`): the reading is
            // the input's time, which its entry holds, so it is no entry of its own. Only when
            // the time can matter (`Engine::wants_time`: traced, or a timer pending), as an
            // unjournaled run reads it: otherwise the input keeps the engine's latest time, which
            // its replay gives it again.
            if self.behind && self.wants_time() {
                self.catch_up_quietly();
            }
            let now = self.now;
            let input = input(self);
            let at = self.mark;
            let body = self.by_body;
            if let Some(q) = self.inputs.as_mut() {
                q.push_back((now, at, input, body));
            }
            self.recorded += 1;
        }
    }

    /// Whether the engine records its inputs (for a journal).
    #[must_use]
    pub fn records_inputs(&self) -> bool {
        self.inputs.is_some()
    }

    /// Carries out `request`, a request of a command's action, as no step of the run unless it is
    /// an input (a state variable set, say): a replay does not run commands, and must count what
    /// the run counted ([`Engine::steps`]).
    pub fn aside<R>(&mut self, request: impl FnOnce(&mut Self) -> R) -> R {
        let (steps, mark, recorded) = (self.steps, self.mark, self.recorded);
        let r = request(self);
        if self.recorded == recorded {
            (self.steps, self.mark) = (steps, mark);
        }
        r
    }

    /// The engine read its clock, `t`: recorded first, as the input it is.
    #[inline]
    pub(super) fn clock_read(&mut self, t: Time) {
        let at = self.steps;
        if let Some(q) = self.inputs.as_mut() {
            q.push_back((t, at, InputRecord::Clock, false));
        }
    }

    /// Records a job's end (`handle_action_finished`), off the hot path.
    #[cold]
    #[inline(never)]
    pub(super) fn record_finished(&mut self, job: super::Job, result: &Result<(), Failure>) {
        let failure = result.as_ref().err().cloned().map(Box::new);
        let node = job.node();
        self.record(|e| InputRecord::Finished {
            node: e.display_of(node),
            tap: job.tap().map(|t| t.0),
            failure,
        });
    }

    /// The steps the run took so far: the inputs and requests it was given a time for (each
    /// spawn, wait, constraint, end, event …; not what it is asked about). A replay gives each
    /// input when the run has taken as many as when it came in.
    #[must_use]
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// The display number of `node`, 0 once it is gone (an input for a node already gone changes
    /// nothing on replay either).
    pub(super) fn display_of(&self, node: crate::ids::NodeId) -> u64 {
        self.nodes.get(node).map_or(0, |n| n.display)
    }
}
