//! What the conditions over state say of a node at a moment: each trigger on a condition with
//! its value and the variables it reads (`CondView`), and the pause that holds a suspended node.

use serde::Serialize;
use tcm::{Expr, StateValue};
use tcm_trace::{Facet, Point, TraceConstraint, TraceThen, TraceWhen};

use super::{reads_text, secs};
use crate::model::{M_SKIPPED, M_TERMINATING, Mark, Row, RunModel, m_point};
use crate::state::VarAt;

/// A trigger on a condition over state, at a moment.
#[derive(Debug, Serialize)]
pub struct CondView {
    /// What it does: `disable handling until`, `terminate when`, `activate when`, `activate on
    /// change of`, `skip if`, `invariant`, `pause while`.
    pub form: String,
    /// The condition as TDL writes it (for `activate on change of`, the variable).
    pub condition: String,
    /// Its value at that moment: `true`, `false`, `unknown` (or why it cannot be evaluated); for
    /// `activate on change of`, the variable's value.
    pub value: String,
    /// What that means for the node at that moment.
    pub state: String,
    /// The variables it reads, each with its value at that moment and since when.
    pub reads: Vec<VarAt>,
    /// When it was applied, ns.
    pub applied: u64,
}

/// A condition's value for people: `true`, `false`, `unknown`, or why it cannot be evaluated.
pub(super) fn value_text(v: &Result<StateValue, String>) -> String {
    match v {
        Ok(v) => v.to_string(),
        Err(e) => format!("cannot be evaluated: {e}"),
    }
}

impl RunModel {
    /// The nearest node from `row` up (itself first) whose `pause while` condition, applied by
    /// `at`, holds at `at`, with that condition: what pauses a suspended node.
    pub(super) fn pause_of(&self, row: &Row, at: Mark) -> Option<(u64, Expr)> {
        let mut cur = Some(row);
        let mut steps = 0;
        while let Some(r) = cur {
            for (_, c) in r.constraints.iter().filter(|(m, _)| m.seq <= at.seq) {
                if let TraceConstraint::Trigger {
                    when: TraceWhen::Condition(cond),
                    then: TraceThen::Pause,
                } = c
                {
                    if self.eval_at(cond, at.seq).is_ok_and(|v| v.is_true()) {
                        return Some((r.number, cond.clone()));
                    }
                }
            }
            steps += 1;
            if steps > self.rows().len() {
                return None;
            }
            cur = r.parent.and_then(|p| self.rows().get(p as usize));
        }
        None
    }

    /// `it is paused by `pause while C`: v = x since t` (or `its ancestor … is paused …`).
    pub(super) fn pause_text(&self, row: &Row, by: u64, cond: &Expr, at: Mark) -> String {
        let who = if by == row.number {
            "it is".to_string()
        } else {
            format!("its ancestor {} is", self.label(by))
        };
        format!(
            "{who} paused by `pause while {cond}`: {}",
            reads_text(&self.reading(cond, at.seq))
        )
    }

    /// The node's triggers on conditions over state applied by `at`, each with its value at `at`
    /// and what that means for the node then.
    pub(super) fn conditions(&self, row: &Row, at: Mark) -> Vec<CondView> {
        let mut out = Vec::new();
        let reached = |m: usize| row.marks[m].filter(|mk| mk.seq <= at.seq);
        let started = reached(m_point(Facet::Handling, Point::Active));
        let ended = reached(m_point(Facet::Execution, Point::Completed));
        let terminating = reached(M_TERMINATING);
        for (applied, c) in row.constraints.iter().filter(|(m, _)| m.seq <= at.seq) {
            let TraceConstraint::Trigger { when, then } = c else {
                continue;
            };
            let cond = match when {
                TraceWhen::Condition(cond) => cond,
                TraceWhen::Changed(var) => {
                    let reads = self.reading(&Expr::var(var.as_str()), at.seq);
                    out.push(CondView {
                        form: "activate on change of".to_string(),
                        condition: var.clone(),
                        value: reads.first().map_or(String::new(), |r| r.value.clone()),
                        state: "activates the monitor at each change".to_string(),
                        reads,
                        applied: applied.t,
                    });
                    continue;
                }
                _ => continue,
            };
            let value = self.eval_at(cond, at.seq);
            let holds = value.as_ref().is_ok_and(StateValue::is_true);
            let held = || self.first_held(cond, *applied, at.seq);
            let (form, state) = match then {
                TraceThen::Enable(facet) => (
                    format!("disable {facet} until"),
                    match held() {
                        Some(m) => format!("held at {}: met for good", secs(m.t)),
                        None => "has not held yet: the facet waits for it".to_string(),
                    },
                ),
                TraceThen::Terminate => (
                    "terminate when".to_string(),
                    match held() {
                        Some(m) => format!("held at {}: terminates the node", secs(m.t)),
                        None => "has not held yet".to_string(),
                    },
                ),
                TraceThen::Activate => (
                    "activate when".to_string(),
                    "activates the monitor each time it becomes true".to_string(),
                ),
                TraceThen::Skip => (
                    "skip if".to_string(),
                    match (reached(M_SKIPPED), started, terminating) {
                        (Some(m), _, _) => {
                            format!("held when its turn came: skipped at {}", secs(m.t))
                        }
                        (None, Some(m), _) => format!(
                            "did not hold when its turn came ({} at {}): it ran",
                            value_text(&self.eval_at(cond, m.seq)),
                            secs(m.t)
                        ),
                        (None, None, Some(_)) => "never read: terminated first".to_string(),
                        (None, None, None) => {
                            "read when its turn comes (handling enabled, about to start)"
                                .to_string()
                        }
                    },
                ),
                TraceThen::Invariant => (
                    "invariant".to_string(),
                    match (started, ended) {
                        (None, _) => "watched once it starts".to_string(),
                        (Some(_), Some(m)) => {
                            format!("watched until its execution completed at {}", secs(m.t))
                        }
                        (Some(_), None) if terminating.is_some() => {
                            "no longer watched: terminating".to_string()
                        }
                        (Some(_), None) => match &value {
                            Ok(StateValue::Bool(true)) => "watched: holds".to_string(),
                            Ok(StateValue::Bool(false)) => {
                                "watched: false, the node fails with InvariantFailed".to_string()
                            }
                            _ => "watched: not false, so it does not fail".to_string(),
                        },
                    },
                ),
                TraceThen::Pause => (
                    "pause while".to_string(),
                    if terminating.is_some() {
                        "no longer acts: terminating".to_string()
                    } else if holds {
                        "holds: its subtree is paused (nothing new starts in it)".to_string()
                    } else {
                        "does not hold: not paused".to_string()
                    },
                ),
            };
            out.push(CondView {
                form,
                condition: cond.to_string(),
                value: value_text(&value),
                state,
                reads: self.reading(cond, at.seq),
                applied: applied.t,
            });
        }
        out
    }
}
