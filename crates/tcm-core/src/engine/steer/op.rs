//! An operation from outside as a run's input records it (`InputRecord::Control`), so that the
//! replay of a journal gives it again at the same step (docs/semantics.md, "Durable runs"): nodes
//! by their display numbers, matchers and faults by what they say. A fault whose value or whose
//! failure's data only the program can make (`FaultValue`, `Failure::data`) has no recorded form,
//! and its replay is refused.

use super::{Approval, BreakAt, Breakpoint, Fault, FaultOutcome, Matcher, SteerId};
use crate::arena::Keep;
use crate::engine::node::Node;
use crate::engine::{Engine, EngineError};
use crate::failure::Failure;
use crate::time::Time;
use serde::{Deserialize, Serialize};
use std::time::Duration;

/// An operation from outside, as recorded.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "op", rename_all = "snake_case")]
pub enum SteerOp {
    /// [`Engine::pause`].
    Pause,
    /// [`Engine::resume`].
    Resume,
    /// [`Engine::step`].
    Step,
    /// [`Engine::step_to_start`].
    StepToStart,
    /// [`Engine::release`].
    Release,
    /// [`Engine::note_input`]: only the record; what was done is the input that follows.
    Noted,
    /// [`Engine::terminate_as`].
    Terminate {
        /// The node's display number.
        node: u64,
    },
    /// [`Engine::suspend_as`], suspending (`on`) or ending a suspension.
    Suspend {
        /// The node's display number.
        node: u64,
        /// Suspends, or ends the suspension.
        on: bool,
    },
    /// [`Engine::add_breakpoint`].
    Breakpoint {
        /// When it pauses.
        at: BreakAt,
        /// For which nodes.
        on: MatcherOp,
    },
    /// [`Engine::remove_steer`].
    Remove {
        /// The breakpoint's, fault's or rule's number.
        id: u32,
    },
    /// [`Engine::require_approval`].
    Approval {
        /// For which nodes.
        on: MatcherOp,
        /// How long a node waits, in nanoseconds.
        timeout_ns: Option<u64>,
    },
    /// [`Engine::approve`].
    Approve {
        /// The node's display number.
        node: u64,
    },
    /// [`Engine::refuse`].
    Refuse {
        /// The node's display number.
        node: u64,
        /// Why.
        reason: String,
    },
    /// [`Engine::inject`].
    Fault {
        /// For which nodes.
        on: MatcherOp,
        /// How many of their starts it takes.
        times: u32,
        /// What stands for their ends.
        outcome: FaultOp,
    },
}

/// A [`Matcher`] as recorded: a node by its display number.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MatcherOp {
    /// [`Matcher::Any`].
    Any,
    /// [`Matcher::Task`].
    Task(String),
    /// [`Matcher::Path`].
    Path(String),
    /// [`Matcher::Node`], by display number.
    Node(u64),
    /// [`Matcher::Exception`].
    Exception(String),
}

/// A [`FaultOutcome`] with no value of the program's.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FaultOp {
    /// Fails with this exception (no data).
    Fail {
        /// The exception's type name.
        exception: String,
        /// Its message.
        message: String,
        /// Its ancestors, nearest first.
        ancestry: Vec<String>,
    },
    /// Succeeds with no value.
    Succeed,
    /// Never ends.
    Never,
}

impl<A, F: Clone, S: Keep<Node<A, F>>> Engine<A, F, S> {
    /// `m` as recorded.
    pub(super) fn on_of(&self, m: &Matcher) -> MatcherOp {
        match m {
            Matcher::Any => MatcherOp::Any,
            Matcher::Task(t) => MatcherOp::Task(t.to_string()),
            Matcher::Path(p) => MatcherOp::Path(p.clone()),
            Matcher::Node(n) => MatcherOp::Node(self.display_of(*n)),
            Matcher::Exception(e) => MatcherOp::Exception(e.to_string()),
        }
    }

    fn matcher_of(&self, on: &MatcherOp) -> Result<Matcher, EngineError> {
        Ok(match on {
            MatcherOp::Any => Matcher::Any,
            MatcherOp::Task(t) => Matcher::Task(t.clone().into()),
            MatcherOp::Path(p) => Matcher::Path(p.clone()),
            MatcherOp::Node(n) => Matcher::Node(self.numbered(*n)?),
            MatcherOp::Exception(e) => Matcher::Exception(e.clone().into()),
        })
    }

    fn numbered(&self, display: u64) -> Result<crate::ids::NodeId, EngineError> {
        self.node_by_display(display)
            .ok_or(EngineError::NoNodeNumbered(display))
    }

    /// Carries out `op`, recorded by a run, again, as `by` asked then (a replay, at the run's
    /// step and time).
    pub fn apply_steer(&mut self, now: Time, op: &SteerOp, by: &str) -> Result<(), EngineError> {
        match op {
            SteerOp::Pause => {
                self.pause(now, by);
            }
            SteerOp::Resume => {
                self.resume(now, by);
            }
            SteerOp::Step => {
                self.step(now, by);
            }
            SteerOp::StepToStart => {
                self.step_to_start(now, by);
            }
            SteerOp::Release => self.release(now, by),
            // Its record is the caller's to write again (`Engine::note_control`).
            SteerOp::Noted => {}
            SteerOp::Terminate { node } => self.terminate_as(now, self.numbered(*node)?, by)?,
            SteerOp::Suspend { node, on } => {
                self.suspend_as(now, self.numbered(*node)?, *on, by)?;
            }
            SteerOp::Breakpoint { at, on } => {
                let on = self.matcher_of(on)?;
                self.add_breakpoint(now, Breakpoint { at: *at, on }, by);
            }
            SteerOp::Remove { id } => {
                self.remove_steer(now, SteerId(*id), by);
            }
            SteerOp::Approval { on, timeout_ns } => {
                let on = self.matcher_of(on)?;
                let timeout = timeout_ns.map(Duration::from_nanos);
                self.require_approval(now, Approval { on, timeout }, by);
            }
            SteerOp::Approve { node } => self.approve(now, self.numbered(*node)?, by)?,
            SteerOp::Refuse { node, reason } => {
                self.refuse(now, self.numbered(*node)?, by, reason)?;
            }
            SteerOp::Fault { on, times, outcome } => {
                let on = self.matcher_of(on)?;
                let outcome = match outcome {
                    FaultOp::Fail {
                        exception,
                        message,
                        ancestry,
                    } => FaultOutcome::Fail(
                        Failure::new(exception.clone(), message.clone())
                            .with_ancestry(ancestry.iter().map(|a| a.clone().into()).collect()),
                    ),
                    FaultOp::Succeed => FaultOutcome::Succeed(None),
                    FaultOp::Never => FaultOutcome::Never,
                };
                let times = *times;
                self.inject(now, Fault { on, times, outcome }, by);
            }
        }
        Ok(())
    }
}

impl<A, F: Clone, S: Keep<Node<A, F>>> Engine<A, F, S> {
    /// Terminates `node`'s subtree, as `by` asked from outside the run: an operation, with its
    /// `control` record (a body's termination is [`Engine::terminate`]).
    pub fn terminate_as(
        &mut self,
        now: Time,
        node: crate::ids::NodeId,
        by: &str,
    ) -> Result<(), EngineError> {
        self.advance(now);
        self.check_run(node)?;
        let op = SteerOp::Terminate {
            node: self.display_of(node),
        };
        self.note(format!("terminate {}", self.node_text(node)), by, Some(op));
        self.terminate(now, node)
    }

    /// Suspends `node`'s subtree (`on`), or ends its suspension, as `by` asked from outside the
    /// run: an operation, with its `control` record.
    pub fn suspend_as(
        &mut self,
        now: Time,
        node: crate::ids::NodeId,
        on: bool,
        by: &str,
    ) -> Result<(), EngineError> {
        self.advance(now);
        self.check_run(node)?;
        let op = SteerOp::Suspend {
            node: self.display_of(node),
            on,
        };
        let what = if on {
            "suspend"
        } else {
            "end the suspension of"
        };
        self.note(format!("{what} {}", self.node_text(node)), by, Some(op));
        if on {
            self.suspend(now, node)
        } else {
            self.unsuspend(now, node)
        }
    }
}

/// `f` as recorded, if it has no value of the program's.
pub(super) fn fault_op(f: &FaultOutcome) -> Option<FaultOp> {
    match f {
        FaultOutcome::Fail(f) if f.data.is_none() => Some(FaultOp::Fail {
            exception: f.exception.to_string(),
            message: f.message.clone(),
            ancestry: f.ancestry.iter().map(ToString::to_string).collect(),
        }),
        FaultOutcome::Succeed(None) => Some(FaultOp::Succeed),
        FaultOutcome::Never => Some(FaultOp::Never),
        FaultOutcome::Fail(_) | FaultOutcome::Succeed(Some(_)) => None,
    }
}
