//! Helpers: run a mission on virtual time with a recorder, check its trace, and read the trace.

use std::collections::BTreeMap;
use std::time::Duration;
pub(crate) use tcm::testing::lines;
use tdl::{Facet, Recorder, State, TraceEvent, TraceKind, TraceSink};
use xavier::summary::Summary;
use xavier::{Done, Setup, display::EventLog};
use xavier_world::Scenario;

/// A setup.
pub(crate) fn setup(seed: u64, scenario: Scenario, rooms: &[u32]) -> Setup {
    Setup {
        seed,
        scenario,
        rooms: rooms.to_vec(),
    }
}

/// Runs `setup` on a paused clock; asserts the run ends and its trace passes the checker.
pub(crate) fn run_checked(setup: &Setup) -> (Summary, Vec<TraceEvent>, Done) {
    let rec = Recorder::new();
    let done = match tdl::block_on_virtual(xavier::run(setup, vec![Box::new(rec.clone())])) {
        Ok(done) => done,
        Err(e) => panic!("run failed: {e}"),
    };
    let trace = rec.events();
    match tcm_trace::check(&trace) {
        Ok(report) => assert!(report.n_transitions > 0, "the checker saw no transitions"),
        Err(violations) => {
            let text: Vec<String> = violations.iter().map(|v| v.to_string()).collect();
            panic!(
                "trace checker found violations:\n{}\n\nlog:\n{}",
                text.join("\n"),
                log_of(&trace)
            );
        }
    }
    (Summary::new(setup, &done, &trace), trace, done)
}

/// The plain event log of a trace, for failure messages.
pub(crate) fn log_of(trace: &[TraceEvent]) -> String {
    let mut buf = Vec::new();
    {
        let mut log = EventLog::new(&mut buf);
        for ev in trace {
            log.record(ev);
        }
    }
    String::from_utf8_lossy(&buf).into_owned()
}

/// Questions about a trace.
pub(crate) struct Story<'a> {
    trace: &'a [TraceEvent],
    names: BTreeMap<u64, String>,
}

impl<'a> Story<'a> {
    pub(crate) fn new(trace: &'a [TraceEvent]) -> Story<'a> {
        let names = trace
            .iter()
            .filter_map(|ev| match &ev.kind {
                TraceKind::Spawned { node, name, .. } => Some((*node, name.clone())),
                _ => None,
            })
            .collect();
        Story { trace, names }
    }

    pub(crate) fn name(&self, node: u64) -> &str {
        self.names.get(&node).map_or("?", String::as_str)
    }

    /// `(node, task name, exception)` of every `failed` record.
    pub(crate) fn failures(&self) -> Vec<(u64, String, String)> {
        self.trace
            .iter()
            .filter_map(|ev| match &ev.kind {
                TraceKind::Failed {
                    node, exception, ..
                } => Some((*node, self.name(*node).to_string(), exception.clone())),
                _ => None,
            })
            .collect()
    }

    /// `(handler node, handler name, attached node)` of the handlers chosen for `failing`.
    pub(crate) fn handlers_for(&self, failing: u64) -> Vec<(u64, String, u64)> {
        self.trace
            .iter()
            .filter_map(|ev| match &ev.kind {
                TraceKind::HandlerChosen {
                    node,
                    failing: f,
                    attached,
                    handler,
                    ..
                } if *f == failing => Some((*node, handler.clone(), *attached)),
                _ => None,
            })
            .collect()
    }

    pub(crate) fn completed(&self, node: u64) -> bool {
        self.trace.iter().any(|ev| {
            matches!(ev.kind, TraceKind::Transition { node: n, facet: Facet::Execution, to: State::Completed, .. } if n == node)
        })
    }

    pub(crate) fn terminated(&self, node: u64) -> bool {
        self.trace
            .iter()
            .any(|ev| matches!(ev.kind, TraceKind::Terminated { node: n } if n == node))
    }

    /// How many times monitors named `name` triggered.
    pub(crate) fn triggers(&self, name: &str) -> usize {
        self.trace
            .iter()
            .filter(|ev| matches!(&ev.kind, TraceKind::Triggered { monitor, .. } if self.name(*monitor) == name))
            .count()
    }

    /// Each reservation of `resource`: its holder, from when, until when (`None`: to the end).
    pub(crate) fn reservations(&self, resource: &str) -> Vec<(u64, Duration, Option<Duration>)> {
        let mut out: Vec<(u64, Duration, Option<Duration>)> = Vec::new();
        for ev in self.trace {
            let t = Duration::from_nanos(ev.t);
            match &ev.kind {
                TraceKind::ResourceReserved {
                    resource: r,
                    holder,
                } if r == resource => {
                    out.push((*holder, t, None));
                }
                TraceKind::ResourceUnreserved { resource: r } if r == resource => {
                    for s in out.iter_mut().filter(|s| s.2.is_none()) {
                        s.2 = Some(t);
                    }
                }
                _ => {}
            }
        }
        out
    }

    /// The guarded moves and turns whose action started strictly between `from` and `until`.
    pub(crate) fn motions_started_between(&self, from: Duration, until: Duration) -> Vec<u64> {
        self.trace
            .iter()
            .filter_map(|ev| match ev.kind {
                TraceKind::Transition {
                    node,
                    facet: Facet::Handling,
                    to: State::Active,
                    ..
                } if matches!(self.name(node), "guardedMove" | "turn") => {
                    let t = Duration::from_nanos(ev.t);
                    (from < t && t < until).then_some(node)
                }
                _ => None,
            })
            .collect()
    }
}
