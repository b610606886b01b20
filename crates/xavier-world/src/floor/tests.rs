//! Unit tests of the floor: shortest paths, blocked corridors, and the walls' free space.

use super::*;

/// Plans from `from` to `room` around `blocked`, and compares the waypoints with `expect`.
#[track_caller]
fn check_plan(from: (f64, f64), room: u32, blocked: &[(f64, f64)], expect: &[(f64, f64)]) {
    let blocked: Vec<Point> = blocked.iter().map(|&(x, y)| Point::new(x, y)).collect();
    let got = Floor::office().plan(Point::new(from.0, from.1), room, &blocked);
    let want: Vec<Point> = expect.iter().map(|&(x, y)| Point::new(x, y)).collect();
    assert_eq!(got, Ok(want));
}

#[test]
fn straight_down_the_corridor() {
    check_plan((0.0, 0.0), 7, &[], &[(34.0, 0.0)]);
}

#[test]
fn turns_at_junctions() {
    check_plan((0.0, 0.0), 11, &[], &[(20.0, 0.0), (20.0, 14.0)]);
    check_plan((0.0, 0.0), 12, &[], &[(40.0, 0.0), (40.0, 10.0)]);
    check_plan((34.0, 0.0), 9, &[], &[(0.0, 0.0), (0.0, 10.0)]);
}

#[test]
fn from_the_middle_of_a_corridor_and_backwards() {
    check_plan((29.0, 0.0), 3, &[], &[(12.0, 0.0)]);
    check_plan((20.0, 10.0), 10, &[], &[(20.0, 6.0)]);
}

#[test]
fn already_there_is_an_empty_path() {
    check_plan((34.0, 0.0), 7, &[], &[]);
}

#[test]
fn detours_round_a_blocked_stretch() {
    // Stopped at x = 29 before a cart at x = 30: back to B, round the loop, in from C.
    check_plan(
        (29.0, 0.0),
        7,
        &[(30.0, 0.0)],
        &[
            (20.0, 0.0),
            (20.0, 20.0),
            (40.0, 20.0),
            (40.0, 0.0),
            (34.0, 0.0),
        ],
    );
}

#[test]
fn a_blockage_behind_the_robot_does_not_matter() {
    check_plan((29.0, 0.0), 7, &[(25.0, 0.0)], &[(34.0, 0.0)]);
}

#[test]
fn no_path_when_every_route_is_blocked() {
    let floor = Floor::office();
    let closed = [Point::new(40.0, 3.0), Point::new(40.0, 17.0)];
    let got = floor.plan(Point::new(0.0, 0.0), 12, &closed);
    assert_eq!(got, Err(NoPath { room: 12 }.into()));
    // The closures cut off room 12 only.
    assert_eq!(
        floor.plan(Point::new(0.0, 0.0), 8, &closed),
        Ok(vec![Point::new(0.0, 20.0), Point::new(33.0, 20.0)])
    );
}

#[test]
fn unknown_rooms_and_lost_robots() {
    let floor = Floor::office();
    assert_eq!(
        floor.plan(Point::new(0.0, 0.0), 99, &[]),
        Err(UnknownRoom { room: 99 }.into())
    );
    assert_eq!(
        floor.plan(Point::new(10.0, 10.0), 3, &[]),
        Err(Lost { x: 10.0, y: 10.0 }.into())
    );
}

#[test]
fn rooms_are_numbered_and_doors_are_on_corridors() {
    let floor = Floor::office();
    let numbers: Vec<u32> = floor.rooms().iter().map(|r| r.number).collect();
    assert_eq!(numbers, (1..=12).collect::<Vec<_>>());
    for r in floor.rooms() {
        let door = floor.door(r.number).map_err(|e| e.to_string());
        assert!(
            door.is_ok_and(|d| floor.allows(d)),
            "door of room {}",
            r.number
        );
    }
}

#[test]
fn free_distance_stops_at_walls() {
    let floor = Floor::office();
    let check = |from: (f64, f64), dir: (f64, f64), expect: f64| {
        let got = floor.free_distance(Point::new(from.0, from.1), dir);
        assert!(
            (got - expect).abs() < 1e-9,
            "{from:?} {dir:?}: {got} != {expect}"
        );
    };
    // Along the south corridor, through B, into the corner at C.
    check((0.0, 0.0), (1.0, 0.0), 40.5);
    // Out of A to the west: only the corner's clearance.
    check((0.0, 0.0), (-1.0, 0.0), 0.5);
    // Sideways in a corridor: the clearance to the wall.
    check((10.0, 0.0), (0.0, 1.0), 0.5);
    // Up the cross corridor from B.
    check((20.0, 0.0), (0.0, 1.0), 20.5);
    // Off the floor.
    check((10.0, 10.0), (1.0, 0.0), 0.0);
}
