//! Small missions on virtual time: navigate with planned legs of turns and guarded moves, detour
//! after `Blocked`, give up on `NoPath`, centre on a door and wait for the mail to go.

use crate::util::{lines, run_checked, story};
use std::time::Duration;
use tcm::{Facet, Failure, NodeRef, RunOutcome, Task, TraceKind, WatchOutcome};
use xavier_world::{
    Blocked, CENTRING_STEP, Config, ObstacleKind, Point, Scenario, SharedWorld, Waypoint, World,
    guarded_move, legs, look_for_door, mail_gone, motor_temperature, plan_path, speak, turn,
};

/// `navigateToLocn(room)`: plans, then spawns a turn and a guarded move per leg, each waited for.
/// A leg failing with `Blocked` leaves the obstacle on the map, so planning again detours.
fn navigate(w: &SharedWorld, room: u32) -> Task {
    let w = w.clone();
    Task::goal("navigateToLocn", move |ctx| async move {
        for _attempt in 0..3 {
            let path: Vec<Waypoint> = ctx.spawn(plan_path(&w, room)).wait_value().await?;
            let pose = w.inspect(|w| w.pose());
            let mut blocked = false;
            for leg in legs(pose, &path) {
                ctx.spawn(turn(&w, leg.turn)).wait().await?;
                match ctx.spawn(guarded_move(&w, leg.distance)).wait().await? {
                    WatchOutcome::Reached => {}
                    WatchOutcome::Failed(f) if &*f.exception == "Blocked" => {
                        // The failure carries the typed exception for handlers to read.
                        match f.data::<Blocked>() {
                            Some(b) if b.distance_left > 0.0 => {}
                            _ => return Err(Failure::new("NoBlockedData", f.message)),
                        }
                        blocked = true;
                        break;
                    }
                    other => return Err(Failure::new("LegFailed", format!("{other:?}"))),
                }
            }
            if !blocked {
                return Ok(());
            }
        }
        Err(Failure::new(
            "GaveUp",
            format!("room {room}: still blocked"),
        ))
    })
}

/// `centerOnDoor(room)`: look, correct by a step towards the door, until centred.
fn center_on_door(w: &SharedWorld, room: u32) -> Task {
    let w = w.clone();
    Task::goal("centerOnDoor", move |ctx| async move {
        for _ in 0..20 {
            let side: i32 = ctx.spawn(look_for_door(&w, room)).wait_value().await?;
            if side == 0 {
                return Ok(());
            }
            ctx.spawn(guarded_move(&w, f64::from(side) * CENTRING_STEP))
                .wait()
                .await?;
        }
        Err(Failure::new("NotCentred", format!("room {room}")))
    })
}

/// `deliverMail(room)`, in the shape of Figure 4 without monitors: navigate, centre, then speak
/// while polling the mail-gone sensor every 1.5 s (Figure 6's period).
fn deliver_mail(w: &SharedWorld, room: u32) -> Task {
    let w = w.clone();
    Task::goal("deliverMail", move |ctx| async move {
        ctx.spawn(navigate(&w, room)).start()?;
        ctx.spawn(center_on_door(&w, room))
            .sequential(Facet::Execution, NodeRef::Previous)
            .start()?;
        ctx.spawn(speak(&w, "Xavier here with your mail"))
            .sequential(Facet::Execution, NodeRef::Previous)
            .start()?;
        let w2 = w.clone();
        ctx.spawn(Task::goal("monitorPickup", move |ctx| async move {
            for _ in 0..15 {
                if ctx.spawn(mail_gone(&w2, room)).wait_value::<bool>().await? {
                    return Ok(());
                }
                tokio::time::sleep(Duration::from_millis(1500)).await;
            }
            Err(Failure::new("NoPickup", format!("room {room}")))
        }))
        .sequential(Facet::Execution, NodeRef::Previous)
        .start()?;
        Ok(())
    })
}

fn door(w: &SharedWorld, room: u32) -> Point {
    match w.inspect(|w| w.floor().door(room)) {
        Ok(p) => p,
        Err(e) => panic!("{e}"),
    }
}

#[track_caller]
fn assert_at(w: &SharedWorld, p: Point) {
    let pose = w.snapshot().pose;
    assert!(
        pose.position().distance(p) < 1e-6,
        "robot at {pose:?}, expected {p:?}"
    );
}

#[tokio::test(start_paused = true)]
async fn plans_and_drives_to_room_12_through_traffic() {
    let w = SharedWorld::new(World::new(3, Scenario::Nominal));
    let t0 = tokio::time::Instant::now();
    let (report, trace) = run_checked(navigate(&w, 12)).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_at(&w, door(&w, 12));
    let st = story(&trace);
    assert!(
        !st.iter().any(|l| l.contains("failed")),
        "{}",
        st.join("\n")
    );
    // Plan 0.5 s, 40 m east, a quarter turn (1 s), 10 m north; passers-by may add a little.
    let snap = w.snapshot();
    assert!((snap.distance_travelled - 50.0).abs() < 1e-6);
    assert!(
        snap.time >= Duration::from_millis(51_500),
        "{:?}",
        snap.time
    );
    // The world's clock is tokio's: it never runs ahead of it.
    assert!(
        snap.time <= t0.elapsed(),
        "{:?} > {:?}",
        snap.time,
        t0.elapsed()
    );
}

#[tokio::test(start_paused = true)]
async fn a_blocked_corridor_fails_the_move_and_planning_again_detours() {
    let w = SharedWorld::new(World::new(1, Scenario::BlockedCorridor));
    let (report, trace) = run_checked(navigate(&w, 7)).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let st = story(&trace);
    let failed: Vec<&String> = st.iter().filter(|l| l.contains("failed")).collect();
    assert_eq!(failed.len(), 1, "{}", st.join("\n"));
    assert!(
        failed[0].ends_with("guardedMove failed Blocked"),
        "{failed:?}"
    );
    // The exception carries the distance left: the leg was 34 m and the robot stopped at 29 m.
    let messages: Vec<&str> = trace
        .iter()
        .filter_map(|ev| match &ev.kind {
            TraceKind::Failed { message, .. } => Some(message.as_str()),
            _ => None,
        })
        .collect();
    assert_eq!(messages, ["blocked by a cart with 5.00 m of the move left"]);
    assert_at(&w, door(&w, 7));
    let snap = w.snapshot();
    // 29 m to the cart, then back to B and round the loop: 9 + 20 + 20 + 20 + 6 = 75 m.
    assert!((snap.distance_travelled - 104.0).abs() < 1e-6, "{snap:?}");
    assert!(
        snap.obstacles
            .iter()
            .any(|o| o.kind == ObstacleKind::Cart && o.at == Point::new(30.0, 0.0))
    );
}

#[tokio::test(start_paused = true)]
async fn no_path_fails_planning_and_other_rooms_are_still_reachable() {
    let w = SharedWorld::new(World::new(2, Scenario::NoPath));
    let w2 = w.clone();
    let top = Task::goal("deliverAll", move |ctx| async move {
        let mut undeliverable = Vec::new();
        for room in [12, 8] {
            match ctx.spawn(plan_path(&w2, room)).wait().await? {
                WatchOutcome::Failed(f) if &*f.exception == "NoPath" => {
                    undeliverable.push(room);
                }
                _ => {
                    ctx.spawn(navigate(&w2, room)).wait().await?;
                }
            }
        }
        Ok(undeliverable)
    });
    let (report, trace) = run_checked(top).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let st = story(&trace);
    let failed: Vec<&String> = st.iter().filter(|l| l.contains("failed")).collect();
    assert_eq!(failed.len(), 1, "{}", st.join("\n"));
    assert!(failed[0].ends_with("planPath failed NoPath"), "{failed:?}");
    assert_at(&w, door(&w, 8));
}

#[tokio::test(start_paused = true)]
async fn delivers_mail_to_room_3() {
    let w = SharedWorld::new(World::new(4, Scenario::Nominal));
    let (report, trace) = run_checked(deliver_mail(&w, 3)).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let st = story(&trace);
    assert!(
        !st.iter().any(|l| l.contains("failed")),
        "{}",
        st.join("\n")
    );
    let snap = w.snapshot();
    assert_eq!(snap.delivered.len(), 1);
    assert_eq!(snap.delivered[0].room, 3);
    assert_eq!(snap.utterances.len(), 1);
    assert_eq!(snap.utterances[0].text, "Xavier here with your mail");
    assert!(!snap.tray.contains(&3));
    // Centring needed at least one look that was not "centred".
    let looks = st
        .iter()
        .filter(|l| l.ends_with("lookForDoor handling active"))
        .count();
    assert!(looks >= 2, "{}", st.join("\n"));
    let summary = w.summary();
    assert_eq!(summary.delivered, vec![3]);
}

#[tokio::test(start_paused = true)]
async fn commands_side_by_side_share_one_clock() {
    let w = SharedWorld::new(World::with_config(
        5,
        Config {
            traffic: false,
            ..Config::default()
        },
    ));
    let w2 = w.clone();
    let t0 = tokio::time::Instant::now();
    let top = Task::goal("moveAndWatch", move |ctx| async move {
        ctx.spawn(guarded_move(&w2, 10.0)).start()?;
        let mut temps = Vec::new();
        for _ in 0..30 {
            temps.push(
                ctx.spawn(motor_temperature(&w2))
                    .wait_value::<f64>()
                    .await?,
            );
        }
        Ok(temps)
    });
    let (report, _) = run_checked(top).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let snap = w.snapshot();
    // Two commands advanced the world in parallel, yet world time is tokio's elapsed time.
    let elapsed = t0.elapsed();
    assert!(snap.time <= elapsed && elapsed - snap.time <= Duration::from_millis(200));
    assert!((snap.pose.x - 10.0).abs() < 1e-9);
    assert!(snap.time >= Duration::from_secs(10));
    assert!(snap.temperature > 20.0);
}

#[tokio::test(start_paused = true)]
async fn the_same_seed_gives_the_same_trace_and_world() {
    let run = || async {
        let w = SharedWorld::new(World::new(9, Scenario::BlockedCorridor));
        let (_, trace) = run_checked(deliver_mail(&w, 7)).await;
        (lines(&trace), w.snapshot())
    };
    let (trace_a, world_a) = run().await;
    let (trace_b, world_b) = run().await;
    assert!(trace_a.len() > 100);
    assert_eq!(trace_a, trace_b);
    assert_eq!(world_a, world_b);
    assert_eq!(world_a.delivered.len(), 1);
}
