//! Running a walk and reading its trace.

use ambler::world::{Terrain, Walker};
use std::collections::BTreeMap;
use std::time::Duration;
use tdl::{Facet, Report, State, TraceEvent, TraceKind};

/// A finished walk: the walker's state, the report, the trace.
pub(crate) struct Walked {
    pub(crate) walker: Walker,
    pub(crate) report: Report,
    pub(crate) trace: Vec<TraceEvent>,
}

/// Walks `terrain` with the monitors wiretapped, on virtual time, through `run_checked`.
pub(crate) fn walk(terrain: Terrain) -> Walked {
    let walker = Walker::new(terrain);
    let rt = ambler::monitored(&walker);
    let run = async {
        Ok::<_, tdl::Error>(tdl::testing::run_checked(rt, ambler::walk(walker.clone())).await)
    };
    let (report, trace) = match tdl::block_on_virtual(run) {
        Ok(done) => done,
        Err(e) => panic!("cannot start a virtual-time runtime: {e}"),
    };
    Walked {
        walker,
        report,
        trace,
    }
}

/// The nodes named `name`, in the order they were spawned.
pub(crate) fn nodes(trace: &[TraceEvent], name: &str) -> Vec<u64> {
    trace
        .iter()
        .filter_map(|e| match &e.kind {
            TraceKind::Spawned { node, name: n, .. } if n == name => Some(*node),
            _ => None,
        })
        .collect()
}

/// When `node`'s `facet` reached `state`, if it did.
pub(crate) fn when(
    trace: &[TraceEvent],
    node: u64,
    facet: Facet,
    state: State,
) -> Option<Duration> {
    trace.iter().find_map(|e| match &e.kind {
        TraceKind::Transition {
            node: n,
            facet: f,
            to,
            ..
        } if *n == node && *f == facet && *to == state => Some(Duration::from_nanos(e.t)),
        _ => None,
    })
}

/// Like [`when`], panicking when it did not.
#[track_caller]
pub(crate) fn at(trace: &[TraceEvent], node: u64, facet: Facet, state: State) -> Duration {
    match when(trace, node, facet, state) {
        Some(t) => t,
        None => panic!("node {node}: {facet:?} never {state:?}"),
    }
}

/// The wiretap checks started, by tapped node: `before`/`after` counts.
pub(crate) fn taps(trace: &[TraceEvent]) -> BTreeMap<u64, (u32, u32)> {
    let mut out: BTreeMap<u64, (u32, u32)> = BTreeMap::new();
    for e in trace {
        if let TraceKind::Tapped { node, when, .. } = &e.kind {
            let entry = out.entry(*node).or_default();
            match when.as_str() {
                "before" => entry.0 += 1,
                "after" => entry.1 += 1,
                other => panic!("a wiretap record with when = {other:?}"),
            }
        }
    }
    out
}

/// The nodes that failed, with their exception.
pub(crate) fn failures(trace: &[TraceEvent]) -> Vec<(u64, String)> {
    trace
        .iter()
        .filter_map(|e| match &e.kind {
            TraceKind::Failed {
                node, exception, ..
            } => Some((*node, exception.clone())),
            _ => None,
        })
        .collect()
}

/// The retries: (the new node, the node that failed), in order.
pub(crate) fn retries(trace: &[TraceEvent]) -> Vec<(u64, u64)> {
    trace
        .iter()
        .filter_map(|e| match &e.kind {
            TraceKind::Retried { node, of } => Some((*node, *of)),
            _ => None,
        })
        .collect()
}
