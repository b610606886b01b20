//! "Why is it waiting": for a node at a moment of the run, each condition that still holds one of
//! its facets back (the paper's "constraints between nodes that are not yet satisfied"): the
//! constraints applied to it whose event has not happened, the structural couplings to its
//! parent and to its own facets (docs/semantics.md, "Facets and states"), a condition over state
//! variables (with each variable it reads, its value then and since when), a suspension (a pause
//! named with its condition), or its turn to start; each with the event it waits for and since
//! when. And its triggers on conditions (skip, invariant, pause, …) with their values then.

use serde::Serialize;
use tcm_trace::{Facet, Outcome, Point, TraceConstraint, TraceEventRef, TraceThen, TraceWhen};

use crate::state::VarAt;

mod conditions;

pub use conditions::CondView;
use conditions::value_text;

use crate::model::{
    M_DEAD, M_RECLAIMED, M_RESERVED, M_SKIPPED, M_SPAWNED, M_TERMINATED, M_TERMINATING, Mark, Row,
    RunModel, kind_str, m_point,
};

/// What the page shows of a node at a moment.
#[derive(Debug, Serialize)]
pub struct NodeView {
    /// Display number.
    pub node: u64,
    /// Name.
    pub name: String,
    /// Kind (`goal`, `command`, …; `reserved` before its spawn).
    pub kind: &'static str,
    /// Path from the root.
    pub path: String,
    /// The parent, if any.
    pub parent: Option<u64>,
    /// The moment asked about.
    pub at: Mark,
    /// Each facet's state at that moment.
    pub states: [&'static str; 3],
    /// `alive`, `terminating`, `terminated`; `reclaimed`, `dead`, `not yet spawned`.
    pub life: &'static str,
    /// What holds it back at that moment (empty when nothing does).
    pub waits: Vec<Wait>,
    /// Constraints that will terminate or activate it, and whether they fired yet (those on
    /// conditions over state are in `conditions`).
    pub triggers: Vec<String>,
    /// Its triggers on conditions over state (every form: enable, terminate, activate, skip,
    /// invariant, pause), each with its value at that moment and the variables it reads.
    pub conditions: Vec<CondView>,
    /// When it is suspended by a `pause while` condition (its own or an ancestor's) that holds at
    /// that moment: which, and the variables that hold it.
    pub paused: Option<String>,
    /// Every point reached so far, in order: `(what, t)`.
    pub history: Vec<(String, u64)>,
    /// Failures, as `exception: message` with when.
    pub failures: Vec<(String, u64)>,
    /// The lines its body wrote to the run's log by that moment, with when.
    pub logs: Vec<(String, u64)>,
    /// The arguments its task was given (`name = value, …`), once spawned, when its task
    /// describes them.
    pub args: Option<String>,
    /// The handling's duration (active to completed, or to the moment), ns.
    pub ran_ns: Option<u64>,
    /// The wait between enabled and active, ns.
    pub queued_ns: Option<u64>,
    /// A monitor's activations and triggers at that moment.
    pub activations: u32,
    /// See `activations`.
    pub triggers_count: u32,
    /// For a handler node: the node it handles, and the handler's name.
    pub handles: Option<(u64, String)>,
    /// For a retry: the node it runs again.
    pub retry_of: Option<u64>,
    /// The agent its action runs on, if it was placed on one by that moment.
    pub agent: Option<String>,
    /// Children reserved or spawned by that moment, by number.
    pub children: Vec<u64>,
}

/// One thing a node waits for.
#[derive(Debug, Serialize)]
pub struct Wait {
    /// The facet held back (`handling`, `expansion`, `execution`), or `start` for an enabled
    /// handling that did not start yet.
    pub facet: &'static str,
    /// For people.
    pub what: String,
    /// The event waited for, when it is one.
    pub event: Option<EventView>,
    /// The time waited for, ns, when it is one.
    pub time: Option<u64>,
    /// The external event waited for, when it is one.
    pub external: Option<String>,
    /// The condition over state waited for, when it is one, as TDL writes it.
    pub condition: Option<String>,
    /// The variables that condition reads, each with its value at that moment and since when.
    pub reads: Vec<VarAt>,
    /// Since when it waits, ns.
    pub since: u64,
}

/// The variables read, as `a = v since t, b = w since u`.
pub(super) fn reads_text(reads: &[VarAt]) -> String {
    reads.iter().map(VarAt::text).collect::<Vec<_>>().join(", ")
}

/// An event, with the node's path.
#[derive(Debug, Serialize)]
pub struct EventView {
    /// The node.
    pub node: u64,
    /// Its path.
    pub path: String,
    /// Facet.
    pub facet: &'static str,
    /// Point.
    pub point: &'static str,
    /// The outcome asked for, if any.
    pub outcome: Option<&'static str>,
}

fn point_str(p: Point) -> &'static str {
    match p {
        Point::Enabled => "enabled",
        Point::Active => "active",
        Point::Completed => "completed",
    }
}

fn outcome_str(o: Outcome) -> &'static str {
    o.as_str()
}

fn state_str(p: Option<Point>) -> &'static str {
    p.map_or("disabled", point_str)
}

pub(crate) fn secs(ns: u64) -> String {
    format!("{:.3} s", ns as f64 / 1e9)
}

impl RunModel {
    /// The node `n` as it was after record `seq`, with what it waited for then.
    pub fn node_view(&self, n: u64, seq: u64) -> Option<NodeView> {
        let row = self.node(n)?;
        let seq = seq.min(self.len().saturating_sub(1));
        let at = Mark {
            seq,
            t: self.t_of(seq),
        };
        let states = Facet::ALL.map(|f| state_str(row.point_at(f, seq)));
        let life = if !row.reached(M_SPAWNED, seq) {
            if row.reached(M_DEAD, seq) {
                "dead"
            } else {
                "not yet spawned"
            }
        } else if row.reached(M_RECLAIMED, seq) {
            "reclaimed"
        } else if row.reached(M_TERMINATED, seq) {
            "terminated"
        } else if row.reached(M_TERMINATING, seq) {
            "terminating"
        } else {
            "alive"
        };
        let mut history = Vec::new();
        let names = [
            (M_SPAWNED, "spawned".to_string()),
            (M_TERMINATING, "terminating".to_string()),
            (M_TERMINATED, "terminated".to_string()),
            (M_RECLAIMED, "reclaimed".to_string()),
            (M_DEAD, "dead".to_string()),
            (M_SKIPPED, "skipped (completed without running)".to_string()),
        ];
        let mut marks: Vec<(Mark, String)> = names
            .into_iter()
            .filter_map(|(m, s)| row.marks[m].map(|mk| (mk, s)))
            .collect();
        for f in Facet::ALL {
            for p in [Point::Enabled, Point::Active, Point::Completed] {
                if let Some(mk) = row.marks[m_point(f, p)] {
                    marks.push((mk, format!("{f} {}", point_str(p))));
                }
            }
        }
        marks.sort_by_key(|(m, _)| m.seq);
        for (m, s) in marks.into_iter().filter(|(m, _)| m.seq <= seq) {
            history.push((s, m.t));
        }
        let active = row.marks[m_point(Facet::Handling, Point::Active)];
        let done = row.marks[m_point(Facet::Handling, Point::Completed)];
        let enabled = row.marks[m_point(Facet::Handling, Point::Enabled)];
        let ran_ns = active
            .filter(|a| a.seq <= seq)
            .map(|a| done.filter(|d| d.seq <= seq).map_or(at.t, |d| d.t) - a.t);
        let queued_ns = enabled
            .filter(|e| e.seq <= seq)
            .map(|e| active.filter(|a| a.seq <= seq).map_or(at.t, |a| a.t) - e.t);
        let (activations, triggers_count) = self.counts_at(n, seq);
        let spawned = row.reached(M_SPAWNED, seq);
        let children = row
            .children
            .iter()
            .copied()
            .filter(|&c| {
                self.node(c)
                    .is_some_and(|c| c.reached(M_SPAWNED, seq) || c.reached(M_RESERVED, seq))
            })
            .collect();
        Some(NodeView {
            node: n,
            name: row.name.clone(),
            kind: row.kind.map_or("reserved", kind_str),
            path: self.path(n),
            parent: row.parent,
            at,
            states,
            life,
            waits: self.waits(row, at),
            triggers: self.triggers(row, at),
            conditions: self.conditions(row, at),
            paused: self
                .suspended_by(row, at)
                .and_then(|_| self.pause_of(row, at))
                .map(|(p, c)| self.pause_text(row, p, &c, at)),
            history,
            failures: row
                .failures
                .iter()
                .filter(|f| f.at.seq <= seq)
                .map(|f| (format!("{}: {}", f.exception, f.message), f.at.t))
                .collect(),
            logs: row
                .logs
                .iter()
                .filter(|(at, _)| at.seq <= seq)
                .map(|(at, line)| (line.clone(), at.t))
                .collect(),
            args: row.args.clone().filter(|_| spawned),
            ran_ns,
            queued_ns,
            activations,
            triggers_count,
            handles: row.handles.clone().filter(|_| spawned),
            retry_of: row.retry_of.filter(|_| spawned),
            agent: self.agent_at(n, seq).map(str::to_string),
            children,
        })
    }

    /// Whether `event` had happened by `at` (a dead node satisfies any event on it; an outcome
    /// event needs that outcome).
    fn happened(&self, event: &TraceEventRef, at: Mark) -> Option<Mark> {
        let row = self.rows().get(event.node as usize)?;
        if let Some(dead) = row.marks[M_DEAD].filter(|m| m.seq <= at.seq) {
            return Some(dead);
        }
        let reached = [Point::Completed, Point::Active, Point::Enabled]
            .into_iter()
            .filter(|p| *p >= event.point)
            .filter_map(|p| row.marks[m_point(event.facet, p)])
            .filter(|m| m.seq <= at.seq)
            .min_by_key(|m| m.seq)?;
        match event.outcome {
            None => Some(reached),
            Some(want) => {
                let got = if row.reached(M_TERMINATING, at.seq) {
                    Outcome::Terminated
                } else if row.failures.iter().any(|f| f.at.seq <= at.seq) {
                    Outcome::Failed
                } else if row.reached(M_SKIPPED, at.seq) {
                    Outcome::Skipped
                } else {
                    Outcome::Succeeded
                };
                (got == want).then_some(reached)
            }
        }
    }

    fn event_view(&self, e: &TraceEventRef) -> EventView {
        EventView {
            node: e.node,
            path: self.path(e.node),
            facet: e.facet.as_str(),
            point: point_str(e.point),
            outcome: e.outcome.map(outcome_str),
        }
    }

    fn event_text(&self, e: &TraceEventRef) -> String {
        let mut s = format!(
            "{} {} {}",
            self.label(e.node),
            e.facet.as_str(),
            point_str(e.point)
        );
        if let Some(o) = e.outcome {
            s.push_str(&format!(" ({})", outcome_str(o)));
        }
        s
    }

    fn waits(&self, row: &Row, at: Mark) -> Vec<Wait> {
        let mut out = Vec::new();
        if !row.reached(M_SPAWNED, at.seq)
            || row.reached(M_TERMINATING, at.seq)
            || row.reached(M_RECLAIMED, at.seq)
        {
            return out;
        }
        let since_spawn = row.marks[M_SPAWNED].map_or(0, |m| m.t);
        let parent = row.parent.and_then(|p| self.rows().get(p as usize));
        for facet in Facet::ALL {
            if row.point_at(facet, at.seq).is_some() {
                continue;
            }
            let f = facet.as_str();
            // Structural couplings.
            let structural: Option<(String, Option<EventView>)> = match facet {
                Facet::Handling => {
                    let own = if row.goal_like() {
                        Facet::Expansion
                    } else {
                        Facet::Execution
                    };
                    (row.point_at(own, at.seq).is_none()).then(|| {
                        (
                            format!("its own {own} to be enabled"),
                            Some(self.event_view(&TraceEventRef {
                                node: row.number,
                                facet: own,
                                point: Point::Enabled,
                                outcome: None,
                            })),
                        )
                    })
                }
                Facet::Expansion | Facet::Execution => parent
                    .filter(|p| p.point_at(facet, at.seq).is_none())
                    .map(|p| {
                        (
                            format!("its parent {} {facet} to be enabled", self.label(p.number)),
                            Some(self.event_view(&TraceEventRef {
                                node: p.number,
                                facet,
                                point: Point::Enabled,
                                outcome: None,
                            })),
                        )
                    }),
            };
            if let Some((what, event)) = structural {
                out.push(Wait {
                    facet: f,
                    what,
                    event,
                    time: None,
                    external: None,
                    condition: None,
                    reads: Vec::new(),
                    since: since_spawn,
                });
            }
            for (applied, c) in row.constraints.iter().filter(|(m, _)| m.seq <= at.seq) {
                match c {
                    TraceConstraint::ExpandFirst if facet == Facet::Execution => {
                        let e = TraceEventRef {
                            node: row.number,
                            facet: Facet::Expansion,
                            point: Point::Completed,
                            outcome: None,
                        };
                        if self.happened(&e, at).is_none() {
                            out.push(Wait {
                                facet: f,
                                what: "expand first: its own expansion to complete".to_string(),
                                event: Some(self.event_view(&e)),
                                time: None,
                                external: None,
                                condition: None,
                                reads: Vec::new(),
                                since: applied.t,
                            });
                        }
                    }
                    TraceConstraint::DelayExpansion if facet == Facet::Expansion => {
                        let e = TraceEventRef {
                            node: row.number,
                            facet: Facet::Execution,
                            point: Point::Enabled,
                            outcome: None,
                        };
                        if self.happened(&e, at).is_none() {
                            out.push(Wait {
                                facet: f,
                                what: "delay expansion: its own execution to be enabled"
                                    .to_string(),
                                event: Some(self.event_view(&e)),
                                time: None,
                                external: None,
                                condition: None,
                                reads: Vec::new(),
                                since: applied.t,
                            });
                        }
                    }
                    TraceConstraint::Trigger {
                        when,
                        then: TraceThen::Enable(target),
                    } if *target == facet => {
                        let text =
                            || c.text(|n| self.node(n).map_or(String::new(), |r| r.name.clone()));
                        if let Some(w) = self.unmet(when, *applied, at, f, &text) {
                            out.push(w);
                        }
                    }
                    _ => {}
                }
            }
        }
        // Enabled, not started.
        if row.point_at(Facet::Handling, at.seq) == Some(Point::Enabled) {
            let enabled = row.marks[m_point(Facet::Handling, Point::Enabled)].map_or(0, |m| m.t);
            let suspended = self.suspended_by(row, at);
            if suspended.is_none() {
                if let Some(w) = self.resource_wait(row, at) {
                    out.push(w);
                    return out;
                }
            }
            let paused = suspended.and_then(|_| self.pause_of(row, at));
            let what = match (suspended, paused) {
                (Some(_), Some((p, c))) => self.pause_text(row, p, &c, at),
                (Some(n), None) if n == row.number => "it is suspended".to_string(),
                (Some(n), None) => format!("its ancestor {} is suspended", self.label(n)),
                (None, _) => {
                    "its turn to start: enabled, it starts once the nodes before it started \
                         and its parent's action lets go of its children (returns or waits)"
                        .to_string()
                }
            };
            out.push(Wait {
                facet: "start",
                what,
                event: None,
                time: None,
                external: None,
                condition: None,
                reads: Vec::new(),
                since: enabled,
            });
        }
        out
    }

    /// The wait of a node that asked for resources and was not granted them yet at `at`: each
    /// resource it asked for, with who holds it, and whether it is reserved or locked.
    fn resource_wait(&self, row: &Row, at: Mark) -> Option<Wait> {
        let (asked, uses) = row.request.as_ref().filter(|(m, _)| m.seq <= at.seq)?;
        if row.granted.is_some_and(|g| g.seq <= at.seq)
            || row.refused.is_some_and(|(m, _)| m.seq <= at.seq)
        {
            return None;
        }
        let mut parts = Vec::new();
        for u in uses {
            let mut why = Vec::new();
            let holders: Vec<String> = self
                .replay()
                .holders_at(&u.resource, at.seq)
                .map(|n| self.label(n))
                .collect();
            if !holders.is_empty() {
                why.push(format!("held by {}", holders.join(", ")));
            }
            for r in self
                .restrictions()
                .iter()
                .filter(|r| r.resource == u.resource && r.holds_at(at.seq))
            {
                match r.holder {
                    Some(h) => why.push(format!("reserved for {}", self.label(h))),
                    None => why.push("locked".to_string()),
                }
            }
            let amount = if u.amount == 1 {
                String::new()
            } else {
                format!(" ({})", u.amount)
            };
            let why = if why.is_empty() {
                "queued behind an earlier request".to_string()
            } else {
                why.join(", ")
            };
            parts.push(format!("`{}`{amount}: {why}", u.resource));
        }
        Some(Wait {
            facet: "start",
            what: format!(
                "the resources it asked for, all at once: {}",
                parts.join("; ")
            ),
            event: None,
            time: None,
            external: None,
            condition: None,
            reads: Vec::new(),
            since: asked.t,
        })
    }

    fn suspended_by(&self, row: &Row, at: Mark) -> Option<u64> {
        let mut cur = Some(row);
        let mut steps = 0;
        while let Some(r) = cur {
            let open = r
                .suspensions
                .iter()
                .any(|(from, until)| from.seq <= at.seq && until.is_none_or(|u| u.seq > at.seq));
            if open {
                return Some(r.number);
            }
            steps += 1;
            if steps > self.rows().len() {
                return None;
            }
            cur = r.parent.and_then(|p| self.rows().get(p as usize));
        }
        None
    }

    /// The wait a `when` still imposes at `at`, if it is not met; `text` tells its constraint.
    fn unmet(
        &self,
        when: &TraceWhen,
        applied: Mark,
        at: Mark,
        facet: &'static str,
        text: &dyn Fn() -> String,
    ) -> Option<Wait> {
        let wait = |what: String, event, time, external| Wait {
            facet,
            what,
            event,
            time,
            external,
            condition: None,
            reads: Vec::new(),
            since: applied.t,
        };
        match when {
            TraceWhen::Now => None,
            // Met for good once it held at some moment since it was applied (latched).
            TraceWhen::Condition(c) => {
                if self.first_held(c, applied, at.seq).is_some() {
                    return None;
                }
                let reads = self.reading(c, at.seq);
                let value = value_text(&self.eval_at(c, at.seq));
                let mut w = wait(
                    format!("waits for `{c}` ({value}): {}", reads_text(&reads)),
                    None,
                    None,
                    None,
                );
                w.condition = Some(c.to_string());
                w.reads = reads;
                Some(w)
            }
            TraceWhen::At(t) => (at.t < *t).then(|| {
                wait(
                    format!("the time {} (held until then)", secs(*t)),
                    None,
                    Some(*t),
                    None,
                )
            }),
            TraceWhen::Event(e) => self.happened(e, at).is_none().then(|| {
                wait(
                    format!("{} (not yet)", self.event_text(e)),
                    Some(self.event_view(e)),
                    None,
                    None,
                )
            }),
            TraceWhen::After { delay_ns, event } => match self.happened(event, at) {
                None => Some(wait(
                    format!(
                        "{} after {} (the event has not happened yet)",
                        secs(*delay_ns),
                        self.event_text(event)
                    ),
                    Some(self.event_view(event)),
                    None,
                    None,
                )),
                Some(m) => {
                    let due = m.t.max(applied.t).saturating_add(*delay_ns);
                    (at.t < due).then(|| {
                        wait(
                            format!(
                                "{} after {} (due at {})",
                                secs(*delay_ns),
                                self.event_text(event),
                                secs(due)
                            ),
                            Some(self.event_view(event)),
                            Some(due),
                            None,
                        )
                    })
                }
            },
            TraceWhen::All { events, delay_ns } => {
                let missing: Vec<&TraceEventRef> = events
                    .iter()
                    .filter(|e| self.happened(e, at).is_none())
                    .collect();
                let first = missing.first()?;
                let mut what = format!(
                    "every member of a group: {} of {} still to come, first {}",
                    missing.len(),
                    events.len(),
                    self.event_text(first)
                );
                if let Some(d) = delay_ns {
                    what.push_str(&format!(", then {}", secs(*d)));
                }
                Some(wait(what, Some(self.event_view(first)), None, None))
            }
            // An external event; or a change of a variable (only ever activates, so never met
            // for good), held to be unmet.
            other => {
                let TraceWhen::External(name) = other else {
                    return Some(wait(format!("{} (not yet)", text()), None, None, None));
                };
                let raised = self
                    .externals()
                    .iter()
                    .any(|(m, n)| n == name && m.seq <= at.seq);
                (!raised).then(|| {
                    wait(
                        format!("the external event `{name}` (not raised yet)"),
                        None,
                        None,
                        Some(name.clone()),
                    )
                })
            }
        }
    }

    /// The triggers applied to the node by `at` other than those enabling a facet (terminate,
    /// activate, …), as TDL writes them, each with whether it is still pending.
    fn triggers(&self, row: &Row, at: Mark) -> Vec<String> {
        let mut out = Vec::new();
        for (applied, c) in row.constraints.iter().filter(|(m, _)| m.seq <= at.seq) {
            let TraceConstraint::Trigger { when, then } = c else {
                continue;
            };
            if matches!(then, TraceThen::Enable(_))
                || matches!(when, TraceWhen::Condition(_) | TraceWhen::Changed(_))
            {
                continue;
            }
            let text = || c.text(|n| self.node(n).map_or(String::new(), |r| r.name.clone()));
            let state = if self.unmet(when, *applied, at, "", &text).is_none() {
                "due or done"
            } else {
                "pending"
            };
            out.push(format!("{} ({state})", text()));
        }
        out
    }
}
