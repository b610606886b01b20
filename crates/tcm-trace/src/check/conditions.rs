//! The checker's side of conditions over state variables (docs/semantics.md, "State and
//! conditions"): the values come from the `state_declared` and `state_set` records (folded by the
//! replay), and each transition a condition explains is checked against them ([`Rule::Condition`]):
//!
//! - an enabling trigger on a condition is satisfied once the condition held at some record since
//!   it was applied (latched), and its facet may not be enabled before;
//! - a terminating one makes a termination due when its condition first holds (checked as every
//!   termination, [`Rule::Terminate`]);
//! - a `skipped` record needs a `skip if` condition of the node that holds, and a node with one
//!   whose handling goes active needs each to not hold;
//! - an `InvariantFailed` failure needs an invariant of the node that is false.

use super::{Checker, Rule};
use crate::event::{TraceEvent, TraceKind, TraceThen};
use crate::state::{Facet, State};
use tcm_expr::{Expr, Value};

/// A trigger on a condition, as applied.
#[derive(Clone, Debug)]
pub(super) struct CondTrigger {
    node: u64,
    cond: Expr,
    then: TraceThen,
    // For an enabling or terminating trigger: whether the condition has held since it was applied.
    held: bool,
}

impl Checker {
    fn holds(&self, cond: &Expr) -> bool {
        self.replay.eval(cond).is_ok_and(|v| v.is_true())
    }

    /// A `constrained` record with a condition: remembered, and latched if it holds already.
    pub(super) fn condition_applied(
        &mut self,
        ev: &TraceEvent,
        node: u64,
        cond: &Expr,
        then: TraceThen,
    ) {
        if let Err(e) = self.replay.eval(cond) {
            let msg = format!("the condition `{cond}` cannot be evaluated: {e}");
            self.flag(ev.seq, Some(node), Rule::Condition, msg);
            return;
        }
        let held = self.holds(cond);
        if held && then == TraceThen::Terminate {
            self.owe_now(node, ev);
        }
        self.conditions.push(CondTrigger {
            node,
            cond: cond.clone(),
            then,
            held,
        });
    }

    /// After a `state_set`: triggers whose condition now holds are latched, and terminating ones
    /// make their termination due.
    pub(super) fn state_set(&mut self, ev: &TraceEvent) {
        let mut due = Vec::new();
        for i in 0..self.conditions.len() {
            let c = &self.conditions[i];
            if c.held || !matches!(c.then, TraceThen::Enable(_) | TraceThen::Terminate) {
                continue;
            }
            if self.holds(&c.cond) {
                self.conditions[i].held = true;
                if self.conditions[i].then == TraceThen::Terminate {
                    due.push(self.conditions[i].node);
                }
            }
        }
        for node in due {
            self.owe_now(node, ev);
        }
    }

    /// What an enabling trigger on `cond` of `node` still waits for, if it has not held.
    pub(super) fn condition_pending(&self, node: Option<u64>, cond: &Expr) -> Option<String> {
        let held = self.conditions.iter().any(|c| {
            Some(c.node) == node
                && matches!(c.then, TraceThen::Enable(_))
                && c.held
                && c.cond == *cond
        });
        (!held).then(|| {
            let values = self.values_of(cond);
            format!("it waits for `{cond}`, which has not held since it was applied ({values})")
        })
    }

    /// `name = value` for each variable the condition reads.
    fn values_of(&self, cond: &Expr) -> String {
        cond.vars()
            .iter()
            .map(|v| {
                let value = self
                    .replay
                    .state_value(v)
                    .cloned()
                    .unwrap_or(Value::Unknown);
                format!("{v} = {value}")
            })
            .collect::<Vec<_>>()
            .join(", ")
    }

    fn node_conditions(&self, node: u64, then: TraceThen) -> Vec<Expr> {
        self.conditions
            .iter()
            .filter(|c| c.node == node && c.then == then)
            .map(|c| c.cond.clone())
            .collect()
    }

    /// Checks the records a condition explains.
    pub(super) fn check_condition_record(&mut self, ev: &TraceEvent) {
        match &ev.kind {
            TraceKind::Skipped { node } => {
                let conds = self.node_conditions(*node, TraceThen::Skip);
                if !conds.iter().any(|c| self.holds(c)) {
                    let msg = if conds.is_empty() {
                        format!(
                            "{} is skipped, but it has no `skip if` condition",
                            self.name(*node)
                        )
                    } else {
                        let text: Vec<String> = conds
                            .iter()
                            .map(|c| format!("`{c}` ({})", self.values_of(c)))
                            .collect();
                        format!(
                            "{} is skipped, but none of its skip conditions holds: {}",
                            self.name(*node),
                            text.join(", ")
                        )
                    };
                    self.flag(ev.seq, Some(*node), Rule::Condition, msg);
                }
            }
            TraceKind::Transition {
                node,
                facet: Facet::Handling,
                to: State::Active,
                ..
            } => {
                for c in self.node_conditions(*node, TraceThen::Skip) {
                    if self.holds(&c) {
                        let msg = format!(
                            "{} starts, but its `skip if {c}` holds ({})",
                            self.name(*node),
                            self.values_of(&c)
                        );
                        self.flag(ev.seq, Some(*node), Rule::Condition, msg);
                    }
                }
            }
            TraceKind::Failed {
                node, exception, ..
            } if exception == "InvariantFailed" => {
                let conds = self.node_conditions(*node, TraceThen::Invariant);
                let broken = conds
                    .iter()
                    .any(|c| self.replay.eval(c) == Ok(Value::Bool(false)));
                if !broken {
                    let msg = format!(
                        "{} fails with InvariantFailed, but none of its invariants is false",
                        self.name(*node)
                    );
                    self.flag(ev.seq, Some(*node), Rule::Condition, msg);
                }
            }
            _ => {}
        }
    }
}
