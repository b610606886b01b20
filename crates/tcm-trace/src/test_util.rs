//! Hand-made traces for the unit tests of this crate: a builder that numbers records and keeps time.

use crate::check::{Rule, check};
use crate::event::{TRACE_FORMAT_VERSION, TraceConstraint, TraceEvent, TraceEventRef, TraceKind};
use crate::state::{Facet, NodeKind, Point, State};

/// Builds a trace; starts with `run_started` at t = 0.
pub(crate) struct Tb {
    evs: Vec<TraceEvent>,
    t: u64,
}

pub(crate) const S: u64 = 1_000_000_000;

pub(crate) use Facet::{Execution as X, Expansion as P, Handling as H};
pub(crate) use State::{Active as A, Completed as C, Disabled as D, Enabled as E};

pub(crate) fn ev_ref(node: u64, facet: Facet, point: Point) -> TraceEventRef {
    TraceEventRef {
        node,
        facet,
        point,
        outcome: None,
    }
}

impl Tb {
    pub(crate) fn new() -> Tb {
        let mut it = Tb {
            evs: Vec::new(),
            t: 0,
        };
        it.push(TraceKind::RunStarted {
            version: TRACE_FORMAT_VERSION,
            run: 0,
        });
        it
    }

    pub(crate) fn at(&mut self, t: u64) -> &mut Tb {
        self.t = t;
        self
    }

    pub(crate) fn push(&mut self, kind: TraceKind) -> &mut Tb {
        let seq = self.evs.len() as u64;
        self.evs.push(TraceEvent {
            seq,
            t: self.t,
            kind,
        });
        self
    }

    pub(crate) fn spawn(&mut self, node: u64, parent: u64, kind: NodeKind, name: &str) -> &mut Tb {
        self.push(TraceKind::Spawned {
            node,
            parent,
            kind,
            name: name.to_string(),
            version: None,
            args: None,
        })
    }

    pub(crate) fn goal(&mut self, node: u64, parent: u64, name: &str) -> &mut Tb {
        self.spawn(node, parent, NodeKind::Goal, name)
    }

    pub(crate) fn command(&mut self, node: u64, parent: u64, name: &str) -> &mut Tb {
        self.spawn(node, parent, NodeKind::Command, name)
    }

    pub(crate) fn tr(&mut self, node: u64, facet: Facet, from: State, to: State) -> &mut Tb {
        self.push(TraceKind::Transition {
            node,
            facet,
            from,
            to,
        })
    }

    pub(crate) fn constrain(&mut self, node: u64, constraint: TraceConstraint) -> &mut Tb {
        self.push(TraceKind::Constrained { node, constraint })
    }

    /// A goal's expansion and handling become enabled, then active.
    pub(crate) fn start_goal(&mut self, node: u64) -> &mut Tb {
        self.tr(node, P, D, E)
            .tr(node, H, D, E)
            .tr(node, H, E, A)
            .tr(node, P, E, A)
    }

    /// A command's execution and handling become enabled, then active.
    pub(crate) fn start_command(&mut self, node: u64) -> &mut Tb {
        self.tr(node, X, D, E)
            .tr(node, H, D, E)
            .tr(node, H, E, A)
            .tr(node, X, E, A)
    }

    /// A started command completes: handling, then execution.
    pub(crate) fn finish_command(&mut self, node: u64) -> &mut Tb {
        self.tr(node, H, A, C).tr(node, X, A, C)
    }

    pub(crate) fn build(&self) -> Vec<TraceEvent> {
        self.evs.clone()
    }
}

/// A valid trace: goal `deliver` {1} spawns command `speak` {2}, which runs; both complete and are
/// reclaimed.
pub(crate) fn small_run() -> Vec<TraceEvent> {
    let mut b = Tb::new();
    b.goal(1, 0, "deliver").start_goal(1);
    b.command(2, 1, "speak");
    b.tr(1, X, D, E).tr(1, H, A, C).tr(1, P, A, C);
    b.start_command(2).tr(1, X, E, A);
    b.at(S + S / 2).finish_command(2).tr(1, X, A, C);
    b.push(TraceKind::Reclaimed { node: 2 });
    b.push(TraceKind::Reclaimed { node: 1 });
    b.build()
}

impl Tb {
    /// A copy, to branch a trace into a passing and a failing ending.
    pub(crate) fn clone_for_test(&self) -> Tb {
        Tb {
            evs: self.evs.clone(),
            t: self.t,
        }
    }
}

/// The rules a trace breaks, in order; empty when the checker accepts it.
pub(crate) fn rules(trace: &[TraceEvent]) -> Vec<Rule> {
    match check(trace) {
        Ok(_) => Vec::new(),
        Err(vs) => vs.iter().map(|v| v.rule).collect(),
    }
}

/// Asserts that the checker catches `rule` in `trace`.
#[track_caller]
pub(crate) fn caught(trace: &[TraceEvent], rule: Rule) {
    match check(trace) {
        Ok(_) => panic!("expected a {rule} violation, the trace passed"),
        Err(vs) => {
            let text: Vec<String> = vs.iter().map(|v| v.to_string()).collect();
            assert!(
                vs.iter().any(|v| v.rule == rule),
                "expected {rule}, got:\n{}",
                text.join("\n")
            );
        }
    }
}
