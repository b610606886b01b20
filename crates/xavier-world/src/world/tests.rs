//! Unit tests of the world model, stepped by hand: seeded schedules, guarded moves, temperature,
//! the door sensor and the mail tray.

use super::*;

fn quiet(scenario: Scenario) -> World {
    World::with_config(
        7,
        Config {
            traffic: false,
            ..scenario.config()
        },
    )
}

fn cart_at(x: f64, leaves: Option<Duration>) -> Obstacle {
    Obstacle {
        kind: ObstacleKind::Cart,
        at: Point::new(x, 0.0),
        appears: Duration::ZERO,
        leaves,
        on_map: false,
    }
}

fn secs(s: u64) -> Duration {
    Duration::from_secs(s)
}

/// Runs motion `id` to its end (at most `limit`), returning how it ended.
fn finish(w: &mut World, id: MotionId, limit: Duration) -> Option<Result<(), RobotError>> {
    let until = w.clock() + limit;
    while w.clock() < until {
        w.advance(TICK);
        if let Some(res) = w.take_motion_result(id) {
            return Some(res);
        }
    }
    None
}

#[test]
fn the_same_seed_gives_the_same_schedule_and_delays() {
    let (a, b) = (
        World::new(42, Scenario::Nominal),
        World::new(42, Scenario::Nominal),
    );
    assert!(a.obstacles().len() > 50, "an hour of traffic");
    assert_eq!(a.obstacles(), b.obstacles());
    let delays = |w: &World| -> Vec<Duration> {
        w.floor()
            .rooms()
            .iter()
            .filter_map(|r| w.pickup_delay(r.number).ok())
            .collect()
    };
    assert_eq!(delays(&a), delays(&b));
    assert!(delays(&a).iter().all(|d| (secs(3)..secs(15)).contains(d)));

    let c = World::new(43, Scenario::Nominal);
    assert_ne!(a.obstacles(), c.obstacles());
    assert_ne!(delays(&a), delays(&c));
    // Streams are independent: the traffic does not shift the mail delays.
    assert_eq!(delays(&a), delays(&quiet_with_seed(42)));
}

fn quiet_with_seed(seed: u64) -> World {
    World::with_config(
        seed,
        Config {
            traffic: false,
            ..Config::default()
        },
    )
}

#[test]
fn a_guarded_move_stops_before_an_obstacle_and_fails_with_the_distance_left() {
    let mut w = quiet(Scenario::Nominal);
    w.place(cart_at(5.0, None));
    let id = w.begin_move(10.0).map_err(|e| e.to_string());
    let res = id.map(|id| finish(&mut w, id, secs(60)));
    let Ok(Some(Err(RobotError::Blocked(b)))) = res else {
        panic!("expected Blocked, got {res:?}");
    };
    assert_eq!(b.obstacle, ObstacleKind::Cart);
    assert!((b.distance_left - 6.0).abs() < 1e-9, "{b:?}");
    assert!((w.pose().x - (5.0 - SAFETY_DISTANCE)).abs() < 1e-9);
    // It drove 4 s, then waited PATIENCE before giving up.
    assert_eq!(w.clock(), secs(4) + PATIENCE);
    // The cart is on the map now, so the planner avoids it.
    assert_eq!(w.known_blockages(), vec![Point::new(5.0, 0.0)]);
}

#[test]
fn a_guarded_move_waits_for_someone_who_leaves() {
    let mut w = quiet(Scenario::Nominal);
    w.place(Obstacle {
        kind: ObstacleKind::Person,
        ..cart_at(5.0, Some(secs(7)))
    });
    let res = w.begin_move(10.0).map(|id| finish(&mut w, id, secs(60)));
    assert_eq!(res, Ok(Some(Ok(()))));
    assert!((w.pose().x - 10.0).abs() < 1e-9);
    // 10 s of driving plus the 3 s stop (from 4 s to 7 s).
    assert_eq!(w.clock(), secs(13));
    assert!(w.known_blockages().is_empty());
}

#[test]
fn a_guarded_move_stops_at_a_wall() {
    let mut w = quiet(Scenario::Nominal);
    let res = w.begin_move(50.0).map(|id| finish(&mut w, id, secs(60)));
    let Ok(Some(Err(RobotError::Blocked(b)))) = res else {
        panic!("expected Blocked, got {res:?}");
    };
    assert_eq!(b.obstacle, ObstacleKind::Wall);
    assert!((b.distance_left - 9.5).abs() < 1e-9, "{b:?}");
}

#[test]
fn backwards_and_turns() {
    let mut w = quiet(Scenario::Nominal);
    let res = w.begin_move(10.0).map(|id| finish(&mut w, id, secs(60)));
    assert_eq!(res, Ok(Some(Ok(()))));
    let res = w.begin_move(-4.0).map(|id| finish(&mut w, id, secs(60)));
    assert_eq!(res, Ok(Some(Ok(()))));
    assert!((w.pose().x - 6.0).abs() < 1e-9);
    let before = w.clock();
    let res = w
        .begin_turn(FRAC_PI_2)
        .map(|id| finish(&mut w, id, secs(60)));
    assert_eq!(res, Ok(Some(Ok(()))));
    assert_eq!(w.pose().heading, FRAC_PI_2);
    assert_eq!(w.clock() - before, secs(1));
    assert!((w.snapshot().distance_travelled - 14.0).abs() < 1e-9);
}

#[test]
fn one_drive_only() {
    let mut w = quiet(Scenario::Nominal);
    assert!(w.begin_move(5.0).is_ok());
    assert_eq!(w.begin_turn(1.0), Err(MotorBusy.into()));
    assert_eq!(
        w.begin_move(f64::NAN),
        Err(BadArgument("move distance NaN is not finite".to_string()).into())
    );
}

#[test]
fn halting_stops_the_robot_where_it_is() {
    let mut w = quiet(Scenario::Nominal);
    let id = w.begin_move(10.0);
    w.advance(secs(3));
    if let Ok(id) = id {
        w.halt(id);
    }
    w.advance(secs(3));
    assert!((w.pose().x - 3.0).abs() < 1e-9);
    assert!(!w.snapshot().moving);
}

#[test]
fn the_motor_heats_while_moving_and_cools_while_idle() {
    let mut w = quiet(Scenario::Nominal);
    assert_eq!(w.temperature(), AMBIENT_C);
    let res = w.begin_move(30.0).map(|id| finish(&mut w, id, secs(60)));
    assert_eq!(res, Ok(Some(Ok(()))));
    let hot = w.temperature();
    assert!(hot > AMBIENT_C + 5.0, "{hot}");
    assert!(
        hot < OVERHEAT_WARNING_C,
        "nominal heating stays below the warning: {hot}"
    );
    w.advance(secs(30));
    let cooler = w.temperature();
    assert!(cooler < hot && cooler > AMBIENT_C, "{hot} -> {cooler}");
}

#[test]
fn the_overheat_scenario_crosses_the_warning_and_then_cuts_out() {
    let mut w = quiet(Scenario::Overheat);
    let mut warned_at = None;
    let mut sign = 1.0;
    let mut last: Result<(), RobotError> = Ok(());
    // Back and forth along the south corridor until the drive cuts out.
    for _ in 0..10 {
        let id = match w.begin_move(sign * 30.0) {
            Ok(id) => id,
            Err(e) => {
                last = Err(e);
                break;
            }
        };
        sign = -sign;
        // A 30 m move ends within 40 s.
        for _ in 0..400 {
            w.advance(TICK);
            if warned_at.is_none() && w.temperature() > OVERHEAT_WARNING_C {
                warned_at = Some(w.clock());
            }
            if let Some(res) = w.take_motion_result(id) {
                last = res;
                break;
            }
        }
        if last.is_err() {
            break;
        }
    }
    let warned_at = warned_at.map(|t| t.as_secs_f64());
    assert!(
        warned_at.is_some_and(|t| (20.0..35.0).contains(&t)),
        "{warned_at:?}"
    );
    let Err(RobotError::Overheating(o)) = last else {
        panic!("expected Overheating, got {last:?}");
    };
    assert!(o.temperature >= MOTOR_CUTOFF_C);
    // Cooling below MOTOR_COOL_C lets it move again.
    w.advance(secs(120));
    assert!(w.temperature() < MOTOR_COOL_C);
    assert!(w.begin_move(1.0).is_ok());
}

#[test]
fn centring_on_a_door_takes_a_few_corrections() {
    for seed in 0..20 {
        let mut w = World::with_config(
            seed,
            Config {
                traffic: false,
                ..Config::default()
            },
        );
        let map_door = w.floor().door(3).map_err(|e| e.to_string());
        let Ok(map_door) = map_door else {
            panic!("{map_door:?}");
        };
        let res = w
            .begin_move(map_door.x)
            .map(|id| finish(&mut w, id, secs(60)));
        assert_eq!(res, Ok(Some(Ok(()))));
        let mut looks = 0;
        loop {
            looks += 1;
            assert!(looks < 30, "seed {seed}: centring does not converge");
            match w.look_for_door(3) {
                Ok(0) => break,
                Ok(side) => {
                    let res = w
                        .begin_move(f64::from(side) * CENTRING_STEP)
                        .map(|id| finish(&mut w, id, secs(10)));
                    assert_eq!(res, Ok(Some(Ok(()))));
                }
                Err(e) => panic!("seed {seed}: {e}"),
            }
        }
        assert!(looks >= 2, "seed {seed}: the map's door is never exact");
        let door = w.true_door(3).map_err(|e| e.to_string());
        let off = door.map(|d| (d.x - w.pose().x).abs());
        assert!(
            off.as_ref()
                .is_ok_and(|&o| o <= DOOR_TOLERANCE + DOOR_NOISE),
            "seed {seed}: {off:?}"
        );
    }
}

#[test]
fn the_door_sensor_needs_the_door_in_sight() {
    let mut w = quiet(Scenario::Nominal);
    let res = w.look_for_door(7);
    assert!(
        matches!(
            res,
            Err(RobotError::DoorNotFound(DoorNotFound { room: 7, .. }))
        ),
        "{res:?}"
    );
    assert_eq!(w.look_for_door(99), Err(UnknownRoom { room: 99 }.into()));
}

#[test]
fn mail_is_taken_after_the_announcement_and_the_delay() {
    let mut w = quiet(Scenario::Nominal);
    let Ok(delay) = w.pickup_delay(1) else {
        panic!("room 1 exists");
    };
    // Speaking away from any door: nobody hears.
    let res = w.begin_move(2.0).map(|id| finish(&mut w, id, secs(10)));
    assert_eq!(res, Ok(Some(Ok(()))));
    assert_eq!(w.speak("hello?"), Vec::<u32>::new());
    w.advance(secs(60));
    assert_eq!(w.mail_gone(1), Ok(false));
    // At room 1's door.
    let res = w.begin_move(3.0).map(|id| finish(&mut w, id, secs(10)));
    assert_eq!(res, Ok(Some(Ok(()))));
    let announced = w.clock();
    assert_eq!(w.speak("Xavier here with your mail"), vec![1]);
    w.advance(delay - Duration::from_millis(1));
    assert_eq!(w.mail_gone(1), Ok(false));
    w.advance(Duration::from_millis(1));
    assert_eq!(w.mail_gone(1), Ok(true));
    let snap = w.snapshot();
    assert_eq!(
        snap.delivered,
        vec![Delivery {
            room: 1,
            at: announced + delay
        }]
    );
    assert!(!snap.tray.contains(&1) && snap.tray.contains(&2));
    assert_eq!(snap.utterances.len(), 2);
    let summary = w.summary();
    assert_eq!(summary.delivered, vec![1]);
    assert!(
        summary
            .to_string()
            .starts_with("delivered to rooms [1], 2 utterances, 5.0 m")
    );
}

#[test]
fn legs_turn_then_drive() {
    let start = Pose {
        x: 0.0,
        y: 0.0,
        heading: 0.0,
    };
    let path = [
        Point::new(20.0, 0.0),
        Point::new(20.0, 14.0),
        Point::new(20.0, 6.0),
    ];
    let got = legs(start, &path);
    assert_eq!(got.len(), 3);
    assert_eq!((got[0].turn, got[0].distance), (0.0, 20.0));
    assert!((got[1].turn - FRAC_PI_2).abs() < 1e-12 && got[1].distance == 14.0);
    assert!((got[2].turn.abs() - PI).abs() < 1e-12 && got[2].distance == 8.0);
}

#[test]
fn the_no_path_scenario_closes_room_12_only() {
    let w = quiet(Scenario::NoPath);
    assert!(matches!(w.plan(12), Err(RobotError::NoPath(_))));
    for r in w.floor().rooms().iter().filter(|r| r.number != 12) {
        assert!(w.plan(r.number).is_ok(), "room {}", r.number);
    }
}
