//! Recovery from a terrain contact: raise the leg and retry (on the leg move), replan the footfall
//! and retry (on the step), shuffle the feet and retry (on the arc), in that order, each only when
//! the one before did not clear the obstacle.

use crate::util::{at, failures, nodes, retries, walk};
use ambler::world::{Obstacle, Recovery, Terrain};
use tdl::testing::handler_choices;
use tdl::{Facet, RunOutcome, State};

#[test]
fn a_rock_is_cleared_by_raising_the_leg() {
    let w = walk(Terrain::flat(1, 3).with_obstacle(0, 1, Obstacle::ROCK));
    assert_eq!(handler_choices(&w.trace), ["raise_leg<-TerrainContact"]);
    let log = w.walker.log();
    assert_eq!(log.recoveries, [(0, 1, Recovery::RaiseLeg)]);
    assert_eq!((log.contacts.len(), log.body_moves), (1, 3));
    // The leg move is re-executed with the raised trajectory as its argument.
    assert_eq!(
        log.lifts_mm,
        [(0, 0, 150), (0, 1, 150), (0, 1, 450), (0, 2, 150)]
    );
}

#[test]
fn a_boulder_needs_the_replan_after_the_raised_leg_hits_it_again() {
    let w = walk(Terrain::flat(1, 1).with_obstacle(0, 0, Obstacle::BOULDER));
    assert_eq!(
        handler_choices(&w.trace),
        ["raise_leg<-TerrainContact", "replan_step<-TerrainContact"]
    );
    let log = w.walker.log();
    assert_eq!(
        log.recoveries,
        [(0, 0, Recovery::RaiseLeg), (0, 0, Recovery::Replan)]
    );
    assert_eq!((log.contacts.len(), log.body_moves), (2, 1));
}

#[test]
fn a_persistent_obstacle_gets_the_three_recoveries_in_order() {
    // A ridge under the third step: the two earlier steps' replan handlers are above the third
    // step in the tree (each step takes the next), and pass its contact on.
    let w = walk(Terrain::flat(1, 4).with_obstacle(0, 2, Obstacle::RIDGE));
    let t = &w.trace;
    assert_eq!(
        handler_choices(t),
        [
            "raise_leg<-TerrainContact",
            "replan_step<-TerrainContact",
            "replan_step<-TerrainContact",
            "bypass",
            "replan_step<-TerrainContact",
            "bypass",
            "shuffle_and_retry<-TerrainContact",
        ]
    );
    let log = w.walker.log();
    assert_eq!(
        log.recoveries,
        [
            (0, 2, Recovery::RaiseLeg),
            (0, 2, Recovery::Replan),
            (0, 2, Recovery::Shuffle),
        ]
    );
    // Three leg moves of step 2 hit the ridge; the fourth, after the shuffle, lands, and only then
    // does step 2's body move.
    let contacts: Vec<(u64, String)> = failures(t);
    assert_eq!(contacts.len(), 3);
    assert!(contacts.iter().all(|(_, e)| e == "TerrainContact"));
    let legs = nodes(t, "move_leg");
    assert_eq!(legs.len(), 7, "4 steps, 3 retries");
    // Each retry makes again the leg move that just failed: the step's own, then the retries.
    let retried = retries(t);
    let failed: Vec<u64> = contacts.iter().map(|(n, _)| *n).collect();
    assert_eq!(retried.iter().map(|r| r.1).collect::<Vec<_>>(), failed);
    assert_eq!(failed[0], legs[2]);
    assert_eq!(failed[1..], [retried[0].0, retried[1].0]);
    // The last retry comes after the shuffle, and lands.
    let shuffle = nodes(t, "shuffle_feet");
    assert_eq!(shuffle.len(), 1);
    let shuffled = at(t, shuffle[0], Facet::Handling, State::Completed);
    let last = retried[2].0;
    assert!(at(t, last, Facet::Handling, State::Active) >= shuffled);
    let landed = at(t, last, Facet::Handling, State::Completed);
    let bodies = nodes(t, "move_body");
    assert!(at(t, bodies[2], Facet::Handling, State::Active) >= landed);
    assert_eq!(w.report.outcome, RunOutcome::Completed);
    assert_eq!((log.body_moves, log.footfall_checks), (4, 4));
}

#[test]
fn an_arc_of_ridges_uses_up_its_shuffles_and_a_footfall_is_missed() {
    // Four ridges in one arc, three shuffles per arc: the fourth contact is not handled. The run
    // still ends `Completed` (TCM's default for an unhandled failure), with that leg never down.
    let mut terrain = Terrain::flat(1, 4);
    for step in 0..4 {
        terrain = terrain.with_obstacle(0, step, Obstacle::RIDGE);
    }
    let w = walk(terrain);
    let choices = handler_choices(&w.trace);
    let shuffles = choices
        .iter()
        .filter(|c| c.starts_with("shuffle_and_retry"))
        .count();
    assert_eq!(shuffles, 3);
    let log = w.walker.log();
    assert_eq!(log.footfall_checks, 3, "the fourth leg never landed");
    assert_eq!(log.contacts.len(), 12);
    assert_eq!(w.report.outcome, RunOutcome::Completed);
}
