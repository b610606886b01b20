//! Unit tests for `replay.rs`: the rebuilt tree, its aggregates, and refused records.

use super::{Replay, ReplayError};
use crate::event::{TraceConstraint, TraceEvent, TraceKind};
use crate::state::{Facet, NodeKind, Point, State, Termination};
use crate::test_util::*;

fn replay(trace: &[TraceEvent]) -> Replay {
    let mut r = Replay::new();
    for ev in trace {
        assert_eq!(r.apply(ev), Ok(()), "record {ev:?}");
    }
    r
}

#[test]
fn small_run_is_rebuilt() {
    let r = replay(&small_run());
    let Some(n) = r.node(1) else {
        panic!("node 1 missing")
    };
    assert_eq!(
        (n.name(), n.kind(), n.parent(), n.children()),
        ("deliver", Some(NodeKind::Goal), Some(0), &[2][..])
    );
    assert!(Facet::ALL.iter().all(|f| n.state(*f) == State::Completed));
    assert!(n.is_reclaimed());
    assert_eq!(
        n.reached_at(Facet::Execution, Point::Completed),
        Some(S + S / 2)
    );
    assert_eq!(n.reached_at(Facet::Execution, Point::Enabled), Some(0));
    assert_eq!(r.root().children(), &[1]);
    assert_eq!(r.n_records(), small_run().len() as u64);
    assert_eq!(r.run(), Some(0));
}

#[test]
fn aggregates_follow_the_subtree() {
    let mut b = Tb::new();
    b.goal(1, 0, "a")
        .start_goal(1)
        .goal(2, 1, "b")
        .command(3, 2, "c");
    let r = replay(&b.build());
    let n1 = r.node(1).map(|n| {
        (
            n.goals_done(),
            n.goal_started_below,
            n.command_started_below,
        )
    });
    assert_eq!(n1, Some((false, true, false)));
    b.start_goal(2)
        .tr(1, X, D, E)
        .tr(2, X, D, E)
        .start_command(3)
        .tr(2, H, A, C)
        .tr(1, H, A, C);
    let r = replay(&b.build());
    let n1 = r.node(1).map(|n| {
        (
            n.goals_done(),
            n.command_started_below,
            n.n_children_exec_open,
        )
    });
    assert_eq!(n1, Some((true, true, 1)));
}

#[test]
fn flags_constraints_and_reservations() {
    let mut b = Tb::new();
    b.push(TraceKind::Reserved {
        node: 2,
        parent: 0,
        name: "later".into(),
    });
    b.command(1, 0, "c")
        .constrain(1, TraceConstraint::ExpandFirst);
    b.push(TraceKind::Suspended { node: 1 })
        .push(TraceKind::Failed {
            node: 1,
            exception: "E".into(),
            message: String::new(),
        });
    b.push(TraceKind::Terminating { node: 1 });
    let r = replay(&b.build());
    let Some(n) = r.node(1) else {
        panic!("node 1 missing")
    };
    assert!(n.is_suspended() && n.is_failed());
    assert_eq!(n.termination(), Termination::Terminating);
    assert_eq!(n.constraints(), &[TraceConstraint::ExpandFirst]);
    assert_eq!(n.state(Facet::Expansion), State::Completed);
    assert!(
        r.node(2)
            .is_some_and(|n| n.is_reserved() && !n.is_spawned())
    );
    b.push(TraceKind::Dead { node: 2 });
    let r = replay(&b.build());
    assert!(
        r.node(2)
            .is_some_and(|n| n.is_dead() && !n.is_reserved() && n.was_reserved())
    );
}

#[test]
fn bad_records_are_refused() {
    let mut r = replay(&small_run());
    let ev = |kind| TraceEvent {
        seq: 99,
        t: 9,
        kind,
    };
    assert_eq!(
        r.apply(&ev(TraceKind::Terminated { node: 7 })),
        Err(ReplayError::UnknownNode { node: 7 })
    );
    assert_eq!(
        r.apply(&ev(TraceKind::Terminating { node: 0 })),
        Err(ReplayError::Root)
    );
    assert_eq!(
        r.apply(&ev(TraceKind::Transition {
            node: 2,
            facet: H,
            from: C,
            to: A
        })),
        Err(ReplayError::Backwards {
            node: 2,
            facet: H,
            from: C,
            to: A
        })
    );
    assert_eq!(
        r.apply(&ev(TraceKind::Spawned {
            node: 2,
            parent: 0,
            kind: NodeKind::Goal,
            name: "x".into(),
            version: None,
            args: None,
        })),
        Err(ReplayError::Duplicate { node: 2 })
    );
    assert_eq!(
        r.apply(&ev(TraceKind::Spawned {
            node: 5,
            parent: 1,
            kind: NodeKind::Goal,
            name: "x".into(),
            version: None,
            args: None,
        })),
        Err(ReplayError::UnknownParent { node: 5, parent: 1 })
    );
    assert_eq!(r.n_records(), small_run().len() as u64);
}
