//! How a steering request is told in its `control` record: nodes, matchers, breakpoints and
//! faults in words.

use super::{BreakAt, FaultOutcome, Matcher};
use crate::arena::Keep;
use crate::engine::Engine;
use crate::engine::node::Node;
use crate::ids::NodeId;

impl<A, F: Clone, S: Keep<Node<A, F>>> Engine<A, F, S> {
    pub(super) fn node_text(&self, node: NodeId) -> String {
        self.nodes.get(node).map_or_else(
            || "a node gone".into(),
            |n| format!("{} {{{}}}", n.name, n.display),
        )
    }

    pub(super) fn matcher_text(&self, m: &Matcher) -> String {
        match m {
            Matcher::Any => "every node".into(),
            Matcher::Task(t) => format!("task {t}"),
            Matcher::Path(p) => format!("path {p}"),
            Matcher::Node(n) => self.node_text(*n),
            Matcher::Exception(e) => format!("exception {e}"),
        }
    }
}

pub(super) fn at_text(at: BreakAt) -> &'static str {
    match at {
        BreakAt::Start => "before the start of",
        BreakAt::End => "after the end of",
        BreakAt::Raised => "on an exception of",
        BreakAt::Handler => "on a handler chosen for",
    }
}

pub(super) fn outcome_text(o: &FaultOutcome) -> String {
    match o {
        FaultOutcome::Fail(f) => format!("fail {}: {}", f.exception, f.message),
        FaultOutcome::Succeed(None) => "succeed".into(),
        FaultOutcome::Succeed(Some(v)) => format!("succeed with {}", v.text()),
        FaultOutcome::Never => "never ends".into(),
    }
}
