//! Unit tests for `history.rs`: rows, marks, exception stories and resources at a moment.

use crate::event::{ResourceUse, TraceEvent, TraceKind};
use crate::replay::{M_FAILED, M_RESERVED, M_SPAWNED, Mark, Replay, Row, m_point};
use crate::state::{Facet, NodeKind, Point};
use crate::test_util::*;

fn fold(trace: &[TraceEvent]) -> Replay {
    let mut r = Replay::with_history();
    for ev in trace {
        assert_eq!(r.apply(ev), Ok(()), "record {ev:?}");
    }
    r
}

#[test]
fn a_row_marks_the_record_of_each_point_reached() {
    let trace = small_run();
    let r = fold(&trace);
    let speak = r.row(2).expect("speak's row");
    assert_eq!((speak.name.as_str(), speak.parent), ("speak", Some(1)));
    let spawned = speak.marks[M_SPAWNED].expect("spawned");
    assert_eq!(trace[spawned.seq as usize].kind.node(), Some(2));
    // A command's expansion is completed at its spawn.
    assert_eq!(
        speak.marks[m_point(Facet::Expansion, Point::Completed)],
        Some(spawned)
    );
    let done = speak.marks[m_point(Facet::Execution, Point::Completed)].expect("completed");
    assert_eq!(done.t, S + S / 2);
    assert_eq!(
        speak.point_at(Facet::Execution, done.seq - 1),
        Some(Point::Active)
    );
    assert_eq!(
        speak.point_at(Facet::Execution, done.seq),
        Some(Point::Completed)
    );
    assert_eq!(r.path(2), "deliver/speak");
    assert_eq!(r.label(2), "speak {2}");
    // Without the history, only the root's row is there.
    let mut bare = Replay::new();
    for ev in &trace {
        assert_eq!(bare.apply(ev), Ok(()));
    }
    assert_eq!(bare.rows().len(), 1);
    assert!(bare.row(2).is_none());
}

#[test]
fn a_row_keeps_the_lines_its_body_logged_with_when() {
    let mut b = Tb::new();
    b.command(1, 0, "dig").start_command(1);
    let log = |message: &str| TraceKind::Log {
        node: 1,
        message: message.into(),
    };
    b.at(S).push(log("dug 3 cm"));
    b.at(2 * S).push(log("dug 6 cm")).finish_command(1);
    let trace = b.build();
    let r = fold(&trace);
    let logs: Vec<_> = r
        .row(1)
        .expect("dig")
        .logs
        .iter()
        .map(|(at, line)| (at.t, line.as_str(), trace[at.seq as usize].kind.node()))
        .collect();
    assert_eq!(
        logs,
        [(S, "dug 3 cm", Some(1)), (2 * S, "dug 6 cm", Some(1))]
    );
    assert_eq!(r.row(0).map(|row| row.logs.len()), Some(0));
}

#[test]
fn an_exception_story_follows_the_handler_the_bypass_and_the_retry() {
    let mut b = Tb::new();
    b.goal(1, 0, "mission").start_goal(1);
    b.push(TraceKind::Reserved {
        node: 2,
        parent: 1,
        name: "later".into(),
    });
    let reserved = b.build().len() as u64 - 1;
    b.command(3, 1, "move").start_command(3);
    b.at(S).push(TraceKind::Failed {
        node: 3,
        exception: "Blocked".into(),
        message: "no way".into(),
    });
    b.spawn(4, 3, NodeKind::Handler, "detour");
    b.push(TraceKind::HandlerChosen {
        node: 4,
        failing: 3,
        attached: 1,
        exception: "Blocked".into(),
        handler: "detour".into(),
    });
    b.push(TraceKind::Bypassed {
        node: 4,
        exception: "Blocked".into(),
    });
    b.command(5, 4, "move");
    b.push(TraceKind::Retried { node: 5, of: 3 });
    b.push(TraceKind::Warning {
        node: Some(3),
        message: "No exception handler found for exception type \"Blocked\"".into(),
    });
    let r = fold(&b.build());
    assert_eq!(
        r.row(2)
            .and_then(|row| row.marks[M_RESERVED])
            .map(|m| m.seq),
        Some(reserved)
    );
    // Children in reservation (or spawn) order.
    assert_eq!(r.row(1).map(|row| row.children.clone()), Some(vec![2, 3]));
    let move_row = r.row(3).expect("move");
    assert_eq!(move_row.marks[M_FAILED].map(|m| m.t), Some(S));
    assert_eq!(move_row.failures.len(), 1);
    assert_eq!(
        r.row(4).and_then(|row| row.handles.clone()),
        Some((3, "detour".into()))
    );
    assert_eq!(r.row(5).and_then(|row| row.retry_of), Some(3));
    let stories = r.exceptions();
    assert_eq!(stories.len(), 1);
    let story = &stories[0];
    assert_eq!((story.node, story.path.as_str()), (3, "mission/move"));
    let steps: Vec<_> = story
        .steps
        .iter()
        .map(|s| (s.what, s.node, s.detail.as_str(), s.attached))
        .collect();
    assert_eq!(
        steps,
        [
            ("chosen", Some(4), "detour", Some(1)),
            ("bypassed", Some(4), "passed Blocked on", None),
            ("retried", Some(5), "", None),
            (
                "unhandled",
                None,
                "No exception handler found for exception type \"Blocked\"",
                None
            ),
        ]
    );
}

#[test]
fn holders_and_reservations_are_read_at_a_moment() {
    let base = || vec![ResourceUse::new("base", 1)];
    let mut b = Tb::new();
    b.push(TraceKind::Resource {
        resource: "base".into(),
        capacity: 1,
        pending_limit: None,
    });
    b.goal(1, 0, "plan");
    b.command(2, 0, "drive");
    b.command(3, 0, "park");
    b.push(TraceKind::ResourceReserved {
        resource: "base".into(),
        holder: 1,
    });
    b.push(TraceKind::Requested {
        node: 2,
        uses: base(),
        priority: 0,
    });
    b.push(TraceKind::Granted {
        node: 2,
        uses: base(),
    });
    b.push(TraceKind::Requested {
        node: 3,
        uses: base(),
        priority: 0,
    });
    let asked = b.build().len() as u64 - 1;
    b.at(S).push(TraceKind::Released {
        node: 2,
        uses: base(),
    });
    b.push(TraceKind::ResourceUnreserved {
        resource: "base".into(),
    });
    let r = fold(&b.build());
    assert_eq!(r.holders_at("base", asked).collect::<Vec<_>>(), [2]);
    assert_eq!(r.holders_at("base", u64::MAX).count(), 0);
    let reservation = &r.restrictions()[0];
    assert_eq!(reservation.holder, Some(1));
    assert!(reservation.holds_at(asked));
    assert!(!reservation.holds_at(u64::MAX));
    let park = r.row(3).expect("park");
    assert_eq!(
        park.request.as_ref().map(|(m, _)| *m),
        Some(Mark { seq: asked, t: 0 })
    );
    assert_eq!((park.granted, park.refused), (None, None));
}

/// Applies each record of `trace` and holds `changed_rows` to the rows themselves: exactly the
/// rows that differ from before the record (a number not allocated before counts as an empty
/// row), each once.
fn changed_rows_are_exact(trace: &[TraceEvent]) {
    let mut r = Replay::with_history();
    for ev in trace {
        let before = r.rows().to_vec();
        assert_eq!(r.apply(ev), Ok(()), "record {ev:?}");
        let differ: Vec<u64> = r
            .rows()
            .iter()
            .filter(|row| match before.get(row.number as usize) {
                Some(was) => was != *row,
                None => **row != Row::new(row.number),
            })
            .map(|row| row.number)
            .collect();
        let mut changed = r.changed_rows().to_vec();
        changed.sort_unstable();
        changed.dedup();
        assert_eq!(
            changed.len(),
            r.changed_rows().len(),
            "each row once: {ev:?}"
        );
        assert_eq!(changed, differ, "record {ev:?}");
    }
}

#[test]
fn the_rows_a_record_changed_are_named_after_it() {
    changed_rows_are_exact(&small_run());

    let base = || vec![ResourceUse::new("base", 1)];
    let mut b = Tb::new();
    b.push(TraceKind::Resource {
        resource: "base".into(),
        capacity: 1,
        pending_limit: None,
    });
    b.goal(1, 0, "mission").start_goal(1);
    b.push(TraceKind::Reserved {
        node: 2,
        parent: 1,
        name: "later".into(),
    });
    b.command(3, 1, "move");
    b.push(TraceKind::Requested {
        node: 3,
        uses: base(),
        priority: 0,
    });
    b.push(TraceKind::Granted {
        node: 3,
        uses: base(),
    });
    b.push(TraceKind::Placed {
        node: 3,
        agent: "arm".into(),
    });
    b.start_command(3);
    b.push(TraceKind::Suspended { node: 3 });
    b.push(TraceKind::Unsuspended { node: 3 });
    b.push(TraceKind::External { name: "go".into() });
    b.at(S).push(TraceKind::Failed {
        node: 3,
        exception: "Blocked".into(),
        message: "no way".into(),
    });
    b.push(TraceKind::Released {
        node: 3,
        uses: base(),
    });
    b.spawn(4, 3, NodeKind::Handler, "detour");
    b.push(TraceKind::HandlerChosen {
        node: 4,
        failing: 3,
        attached: 1,
        exception: "Blocked".into(),
        handler: "detour".into(),
    });
    b.command(5, 4, "move");
    b.push(TraceKind::Retried { node: 5, of: 3 });
    b.push(TraceKind::Dead { node: 2 });
    b.push(TraceKind::Terminating { node: 5 });
    b.push(TraceKind::Terminated { node: 5 });
    b.push(TraceKind::Reclaimed { node: 5 });
    let trace = b.build();
    changed_rows_are_exact(&trace);

    // What the rows of a few records are: a spawn changes the node and its parent, an external
    // event no row, a refused record none.
    let mut r = Replay::with_history();
    let spawn_move = trace
        .iter()
        .position(|ev| matches!(ev.kind, TraceKind::Spawned { node: 3, .. }))
        .expect("move's spawn");
    for ev in &trace[..=spawn_move] {
        assert_eq!(r.apply(ev), Ok(()));
    }
    assert_eq!(r.changed_rows(), [3, 1]);
    let external = TraceEvent {
        seq: spawn_move as u64 + 1,
        t: 0,
        kind: TraceKind::External { name: "go".into() },
    };
    assert_eq!(r.apply(&external), Ok(()));
    assert!(r.changed_rows().is_empty());
    let spawn_again = trace[spawn_move].clone();
    assert!(r.apply(&spawn_again).is_err());
    assert!(r.changed_rows().is_empty());
    // Without the history, no row is ever named.
    let mut bare = Replay::new();
    for ev in &trace[..=spawn_move] {
        assert_eq!(bare.apply(ev), Ok(()));
    }
    assert!(bare.changed_rows().is_empty());
}
