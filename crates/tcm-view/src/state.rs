//! State variables over the run (docs/semantics.md, "State and conditions"): each variable's
//! changes as the fold recorded its values ([`tcm_trace::Replay::state_values`]), so that the page
//! draws a lane per variable and the model reads a variable's value, and a condition's, at any
//! cursor, with since when a variable has its value.

use serde::Serialize;
use tcm::{Expr, StateValue};

use crate::model::Mark;

/// One state variable's values over the run.
#[derive(Clone, Debug, Serialize)]
pub struct StateLane {
    /// Its name.
    pub name: String,
    /// Its type, as TDL writes it (`bool`, `int`, `float`, `string`).
    pub ty: &'static str,
    /// Its declared value, then each change, with when; a set to the value it had is not a
    /// change and is left out.
    pub changes: Vec<(Mark, StateValue)>,
    /// How many times it was set (changes or not).
    pub sets: u64,
}

/// A variable a condition reads, as it was at a moment.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct VarAt {
    /// The variable.
    pub name: String,
    /// Its value, as TDL writes it (`unknown`, `true`, `42`, `1.5`, `"text"`); `undeclared` before
    /// its declaration.
    pub value: String,
    /// Since when it has that value, ns (its declaration or the change to it).
    pub since: Option<u64>,
}

impl VarAt {
    /// `name = value since t`, for people.
    pub fn text(&self) -> String {
        match self.since {
            Some(t) => format!(
                "{} = {} since {}",
                self.name,
                self.value,
                crate::why::secs(t)
            ),
            None => format!("{} = {}", self.name, self.value),
        }
    }
}

/// The variables of a run, in the order they were declared.
#[derive(Debug, Default)]
pub(crate) struct States {
    lanes: Vec<StateLane>,
    /// How many of the fold's values were taken in.
    seen: usize,
    /// The lane the last record applied changed (or declared), if any.
    changed: Option<usize>,
}

impl States {
    /// Takes in the values the fold recorded since the last call (after each record).
    pub(crate) fn keep(&mut self, replay: &tcm_trace::Replay) {
        self.changed = None;
        let all = replay.state_values();
        for (mark, name, value) in all.get(self.seen..).unwrap_or_default() {
            let i = match self.lanes.iter().position(|l| &l.name == name) {
                Some(i) => i,
                None => {
                    let ty = replay
                        .states()
                        .find(|(n, _, _)| n == name)
                        .map_or("unknown", |(_, ty, _)| ty.name());
                    self.lanes.push(StateLane {
                        name: name.clone(),
                        ty,
                        changes: Vec::new(),
                        sets: 0,
                    });
                    self.lanes.len() - 1
                }
            };
            let lane = &mut self.lanes[i];
            lane.sets += 1;
            if lane.changes.last().is_none_or(|(_, v)| v != value) {
                lane.changes.push((*mark, value.clone()));
                self.changed = Some(i);
            }
        }
        self.seen = all.len();
    }

    pub(crate) fn lanes(&self) -> &[StateLane] {
        &self.lanes
    }

    pub(crate) fn changed(&self) -> Option<&StateLane> {
        self.changed.map(|i| &self.lanes[i])
    }

    fn lane(&self, name: &str) -> Option<&StateLane> {
        self.lanes.iter().find(|l| l.name == name)
    }

    /// A variable's value after record `seq`, with the moment it got it; `None` before its
    /// declaration (or for a name never declared).
    pub(crate) fn value_at(&self, name: &str, seq: u64) -> Option<(&StateValue, Mark)> {
        let lane = self.lane(name)?;
        match lane.changes.partition_point(|(m, _)| m.seq <= seq) {
            0 => None,
            i => Some((&lane.changes[i - 1].1, lane.changes[i - 1].0)),
        }
    }

    /// A condition's value after record `seq` (an error, for one that cannot be evaluated then,
    /// as the text of the error).
    pub(crate) fn eval_at(&self, cond: &Expr, seq: u64) -> Result<StateValue, String> {
        cond.eval(&|n| self.value_at(n, seq).map(|(v, _)| v.clone()))
            .map_err(|e| e.to_string())
    }

    /// The first moment in `from..=to` (both included, `from` the moment the condition was
    /// applied) at which `cond` held: at `from` itself, or at a change of a variable it reads.
    pub(crate) fn first_held(&self, cond: &Expr, from: Mark, to: u64) -> Option<Mark> {
        if from.seq > to {
            return None;
        }
        let mut moments = vec![from];
        for name in cond.vars() {
            if let Some(lane) = self.lane(name) {
                moments.extend(
                    lane.changes
                        .iter()
                        .map(|(m, _)| *m)
                        .filter(|m| m.seq > from.seq && m.seq <= to),
                );
            }
        }
        moments.sort_by_key(|m| m.seq);
        moments.dedup();
        moments
            .into_iter()
            .find(|m| self.eval_at(cond, m.seq).is_ok_and(|v| v.is_true()))
    }

    /// Each variable `cond` reads, as it was after record `seq`.
    pub(crate) fn reading(&self, cond: &Expr, seq: u64) -> Vec<VarAt> {
        cond.vars()
            .into_iter()
            .map(|name| match self.value_at(name, seq) {
                Some((v, m)) => VarAt {
                    name: name.to_string(),
                    value: v.to_string(),
                    since: Some(m.t),
                },
                None => VarAt {
                    name: name.to_string(),
                    value: "undeclared".to_string(),
                    since: None,
                },
            })
            .collect()
    }
}
