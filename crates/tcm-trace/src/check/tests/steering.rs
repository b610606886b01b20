//! The rules of a steered run: no node starts while the run is paused, nor while it is held for
//! approval without an `approved` record.

use super::{caught, passes};
use crate::check::Rule;
use crate::event::TraceKind;
use crate::test_util::*;

#[test]
fn nothing_starts_while_paused_or_held() {
    let paused = || TraceKind::Paused {
        node: None,
        why: "asked by operator".into(),
    };
    let mut b = Tb::new();
    b.goal(1, 0, "a").tr(1, P, D, E).tr(1, H, D, E);
    b.push(paused()).tr(1, H, E, A);
    caught(&b.build(), Rule::ActiveWhilePaused);
    let mut b = Tb::new();
    b.goal(1, 0, "a").tr(1, P, D, E).tr(1, H, D, E);
    b.push(paused())
        .push(TraceKind::Resumed { held_ns: 5 })
        .tr(1, H, E, A);
    passes(&b.build());
    let mut b = Tb::new();
    b.goal(1, 0, "a").tr(1, P, D, E).tr(1, H, D, E);
    b.push(TraceKind::Held { node: 1 }).tr(1, H, E, A);
    caught(&b.build(), Rule::ActiveWhileHeld);
    let mut b = Tb::new();
    b.goal(1, 0, "a").tr(1, P, D, E).tr(1, H, D, E);
    b.push(TraceKind::Held { node: 1 })
        .push(TraceKind::Approved {
            node: 1,
            by: "operator".into(),
        })
        .tr(1, H, E, A);
    passes(&b.build());
}
