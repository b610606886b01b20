//! Unit tests of the scenarios: names, settings and the seeded traffic.

use super::*;
use crate::world::{PATIENCE, World};

#[test]
fn traffic_stays_on_corridors_and_leaves_within_patience() {
    let w = World::new(5, Scenario::Nominal);
    for o in w.obstacles() {
        assert!(w.floor().allows(o.at), "{o:?}");
        let stay = o.leaves.map(|l| l - o.appears);
        assert!(stay.is_some_and(|s| s < PATIENCE), "{o:?}");
    }
}

#[test]
fn scenarios_parse_from_their_names() {
    for sc in Scenario::ALL {
        assert_eq!(sc.name().parse::<Scenario>(), Ok(sc));
    }
    assert_eq!(
        "bogus".parse::<Scenario>(),
        Err(UnknownScenario("bogus".to_string()))
    );
}
