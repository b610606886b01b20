//! The walking plan: arcs one after the other, steps planned one ahead of their execution, the
//! monitors wiretapped on every move.

use crate::util::{at, failures, nodes, taps, walk};
use ambler::world::{Obstacle, Terrain};
use tdl::{Facet, RunOutcome, State};

#[test]
fn each_step_is_planned_while_the_previous_one_executes() {
    let w = walk(Terrain::flat(1, 4));
    let t = &w.trace;
    let (plans, legs, bodies) = (
        nodes(t, "take_step"),
        nodes(t, "move_leg"),
        nodes(t, "move_body"),
    );
    assert_eq!((plans.len(), legs.len(), bodies.len()), (4, 4, 4));
    for k in 0..3 {
        // Step k executes from its leg move's start to its body move's end; step k+1's planning
        // is the handling of its take_step.
        let exec = (
            at(t, legs[k], Facet::Handling, State::Active),
            at(t, bodies[k], Facet::Handling, State::Completed),
        );
        let plan = (
            at(t, plans[k + 1], Facet::Handling, State::Active),
            at(t, plans[k + 1], Facet::Handling, State::Completed),
        );
        // Planned one step ahead: while step k executes, not before it started.
        assert!(
            exec.0 <= plan.0 && plan.0 < exec.1,
            "step {}: planned {plan:?}, step {k} executed {exec:?}",
            k + 1
        );
        // The moves themselves stay in order: step k+1's leg waits for step k's body.
        let next_leg = at(t, legs[k + 1], Facet::Handling, State::Active);
        assert!(
            next_leg >= exec.1,
            "step {} moved its leg at {next_leg:?}",
            k + 1
        );
        assert!(
            plan.1 <= next_leg,
            "step {} moved before it was planned",
            k + 1
        );
    }
    assert_eq!(w.walker.log().body_moves, 4);
}

#[test]
fn an_arc_is_planned_only_once_the_previous_one_is_traversed() {
    let w = walk(Terrain::flat(3, 2));
    let t = &w.trace;
    let (arcs, plans) = (nodes(t, "traverse_arc"), nodes(t, "plan_arc"));
    assert_eq!((arcs.len(), plans.len()), (3, 3));
    for a in 0..2 {
        let traversed = at(t, arcs[a], Facet::Execution, State::Completed);
        let planned = at(t, plans[a + 1], Facet::Handling, State::Active);
        assert!(
            planned >= traversed,
            "arc {} planned at {planned:?}, arc {a} traversed at {traversed:?}",
            a + 1
        );
    }
    assert_eq!(w.walker.log().body_moves, 6);
}

#[test]
fn the_monitors_tap_every_leg_and_body_move() {
    let w = walk(
        Terrain::flat(2, 3)
            .with_obstacle(0, 1, Obstacle::ROCK)
            .with_obstacle(1, 2, Obstacle::BOULDER),
    );
    let t = &w.trace;
    let taps = taps(t);
    let failed: Vec<u64> = failures(t).into_iter().map(|(n, _)| n).collect();
    let legs = nodes(t, "move_leg");
    let bodies = nodes(t, "move_body");
    // 6 steps, 3 contacts: each contact's leg move was made again.
    assert_eq!((legs.len(), bodies.len(), failed.len()), (9, 6, 3));
    for leg in &legs {
        // Stability before every leg move; footfall after every leg move that landed.
        let after = u32::from(!failed.contains(leg));
        assert_eq!(taps.get(leg), Some(&(1, after)), "move_leg node {leg}");
    }
    for body in &bodies {
        assert_eq!(taps.get(body), Some(&(1, 0)), "move_body node {body}");
    }
    let tapped: Vec<&u64> = taps.keys().collect();
    assert_eq!(
        tapped.len(),
        legs.len() + bodies.len(),
        "only the moves are tapped"
    );
    let log = w.walker.log();
    assert_eq!((log.stability_checks, log.footfall_checks), (15, 6));
}

#[test]
fn the_stability_monitor_vetoes_moves_on_too_steep_ground() {
    let w = walk(Terrain::flat(2, 2).with_tilt(1, 30.0));
    let t = &w.trace;
    let vetoed: Vec<String> = failures(t).into_iter().map(|(_, e)| e).collect();
    // Arc 1's two leg moves and two body moves are vetoed before they start.
    assert_eq!(vetoed, ["Unstable"; 4]);
    let log = w.walker.log();
    assert_eq!((log.leg_moves, log.body_moves), (2, 2));
    assert_eq!(log.stability_checks, 8);
}

#[test]
fn a_seeded_walk_completes_and_runs_the_same_twice() {
    let terrain = Terrain::generate(7, 4);
    let steps = terrain.steps();
    let (a, b) = (walk(terrain.clone()), walk(terrain));
    assert_eq!(a.report.outcome, RunOutcome::Completed);
    let log = a.walker.log();
    assert_eq!(log.body_moves, steps);
    assert_eq!(log.footfall_checks, steps);
    assert!(!log.recoveries.is_empty(), "seed 7 has obstacles: {log:?}");
    assert_eq!(log, b.walker.log());
    // The same trace, byte for byte (docs/semantics.md, "Determinism").
    assert_eq!(tdl::testing::lines(&a.trace), tdl::testing::lines(&b.trace));
}
