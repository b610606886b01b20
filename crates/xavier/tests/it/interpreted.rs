//! The mail round loaded at run time from `src/mission.tdl` (the file the build compiles), the
//! robot's commands and functions registered in Rust, runs as the compiled round runs: the same
//! trace, record for record, and the same deliveries, on every scenario and three seeds each.

use tdl::{Ctx, Failure, Recorder, Runtime};
use tdl_interp::{Host, IntoValue, Program, Registry, Value};
use xavier::mission::{self, Mission};
use xavier::robot::{self, Robot};
use xavier_world::{
    CENTRING_STEP, Leg, MOTOR_COOL_C, OVERHEAT_WARNING_C, Pose, Scenario, SharedWorld, Waypoint,
    World,
};

/// The robot's commands and the mission's functions, as the program calls them.
pub(crate) fn registry() -> Registry {
    let mut r = Registry::new();
    let waypoints =
        |path: Vec<Waypoint>| Value::list(path.into_iter().map(|w| Host(w).into_value()));
    r.host_type("Mission")
        .host_type("Robot")
        .alias("Waypoint", "Point")
        .host_type("Pose")
        .host_type("Leg")
        .field("Mission", "robot", |m: Host<Mission>| Host(m.0.robot))
        .method("Mission", "notified", |m: Host<Mission>, room: u32| {
            m.0.notified(room)
        })
        .async_method("Robot", "pose", |r: Host<Robot>| async move {
            r.0.pose().await.map(Host)
        })
        .async_method("Robot", "motor_temperature", |r: Host<Robot>| async move {
            r.0.motor_temperature().await
        })
        .field("Leg", "turn", |l: Host<Leg>| l.0.turn)
        .field("Leg", "distance", |l: Host<Leg>| l.0.distance)
        .function("legs", |pose: Host<Pose>, path: Vec<Host<Waypoint>>| {
            let path: Vec<Waypoint> = path.into_iter().map(|w| w.0).collect();
            xavier_world::legs(pose.0, &path)
                .into_iter()
                .map(Host)
                .collect::<Vec<_>>()
        })
        .function("stretches", mission::stretches)
        .async_function("pose_now", |ctx: Ctx, m: Host<Mission>| async move {
            mission::pose_now(&ctx, &m.0).await.map(Host)
        })
        .function("stop_the_rest", |ctx: Ctx| mission::stop_the_rest(&ctx))
        .function("give_up", |ctx: Ctx, m: Host<Mission>, room: u32| {
            mission::give_up(&ctx, &m.0, room)
        })
        .task_returning_with(
            "plan_path",
            |r: Host<Robot>, room: u32| robot::plan_path(&r.0, room),
            waypoints,
        )
        .task("turn", |r: Host<Robot>, angle: f64| {
            robot::turn(&r.0, angle)
        })
        .task("guarded_move", |r: Host<Robot>, d: f64| {
            robot::guarded_move(&r.0, d)
        })
        .task("look_for_door", |r: Host<Robot>, room: u32| {
            robot::look_for_door(&r.0, room)
        })
        .task("speak", |r: Host<Robot>, text: String| {
            robot::speak(&r.0, text)
        })
        .task("mail_gone", |r: Host<Robot>, room: u32| {
            robot::mail_gone(&r.0, room)
        })
        .task("motor_temperature", |r: Host<Robot>| {
            robot::motor_temperature(&r.0)
        })
        .constant("TURN_EPSILON", mission::TURN_EPSILON)
        .constant("CENTRING_STEP", CENTRING_STEP)
        .constant("MOTOR_COOL_C", MOTOR_COOL_C)
        .constant("OVERHEAT_WARNING_C", OVERHEAT_WARNING_C)
        .constant("NOTIFY_TIME", mission::NOTIFY_TIME)
        .constant("COOLING_POLL", mission::COOLING_POLL);
    r
}

fn program() -> Program {
    let file = format!("{}/src/mission.tdl", env!("CARGO_MANIFEST_DIR"));
    match Program::load(&[file], &registry()) {
        Ok(p) => p,
        Err(e) => panic!("{e}"),
    }
}

/// Runs the round on `scenario` with `seed`, compiled and interpreted; asserts the same trace
/// and the same deliveries.
fn alike(program: &Program, scenario: Scenario, seed: u64) {
    let rooms = xavier::DEFAULT_ROOMS.to_vec();
    let run = async {
        let compiled = Mission::new(SharedWorld::new(World::new(seed, scenario)));
        let rec = Recorder::new();
        Runtime::new()
            .with_sink(rec.clone())
            .run(mission::deliver_all(compiled.clone(), rooms.clone()))
            .await?;
        let compiled_trace = rec.events();

        let interpreted = Mission::new(SharedWorld::new(World::new(seed, scenario)));
        let args = vec![
            Host(interpreted.clone()).into_value(),
            rooms.clone().into_value(),
        ];
        let task = match program.task("deliver_all", args) {
            Ok(t) => t,
            Err(e) => panic!("{e}"),
        };
        let rec = Recorder::new();
        Runtime::new().with_sink(rec.clone()).run(task).await?;
        let interpreted_trace = rec.events();
        tdl::testing::assert_checked(&interpreted_trace);
        Ok::<_, tdl::Error>((compiled, compiled_trace, interpreted, interpreted_trace))
    };
    let (cm, ct, im, it) = match tdl::block_on_virtual(run) {
        Ok(done) => done,
        Err(e) => panic!("{e}"),
    };
    let what = format!("{scenario:?} seed {seed}, compiled then interpreted");
    tdl::testing::assert_same_trace(&ct, &it, &what);
    assert_eq!(cm.notifications(), im.notifications());
    assert_eq!(cm.undeliverable(), im.undeliverable());
}

#[test]
fn the_round_runs_interpreted_as_compiled_on_every_scenario_and_three_seeds() {
    let program = program();
    for scenario in [
        Scenario::Nominal,
        Scenario::BlockedCorridor,
        Scenario::NoPath,
        Scenario::Overheat,
    ] {
        for seed in [1, 2, 3] {
            alike(&program, scenario, seed);
        }
    }
}

#[test]
fn a_failure_of_a_registered_function_fails_the_node_with_its_exception() {
    let mut r = Registry::new();
    r.function("check", |x: i64| {
        if x > 2 {
            Err(Failure::new("TooFar", format!("{x} is too far")))
        } else {
            Ok(x)
        }
    });
    let src = "pub command c(x: i64) -> i64 {\n    check(x)?\n}\n";
    let program = match Program::from_sources(&[("c.tdl".into(), src.into())], &r) {
        Ok(p) => p,
        Err(e) => panic!("{e}"),
    };
    let task = match program.task("c", vec![Value::Int(5)]) {
        Ok(t) => t,
        Err(e) => panic!("{e}"),
    };
    let rec = Recorder::new();
    let run = Runtime::new().with_sink(rec.clone()).run(task);
    if let Err(e) = tdl::block_on_virtual(run) {
        panic!("{e}");
    }
    let story = tdl::testing::story(&rec.events()).join("\n");
    assert!(story.contains("TooFar"), "{story}");
}
