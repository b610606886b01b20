//! Unit tests for `history.rs`: rows, marks, exception stories and resources at a moment.

use crate::event::{ResourceUse, TraceEvent, TraceKind};
use crate::replay::{M_FAILED, M_RESERVED, M_SPAWNED, Mark, Replay, m_point};
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
