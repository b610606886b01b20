//! The Ambler's program loaded at run time from `src/walk.tdl` and `src/terrain.tdl` (the files
//! the build compiles), its world registered in Rust, runs as the compiled program runs: the
//! same trace, record for record, and the same walk, on every terrain the other tests walk.

use ambler::world::{
    ARC_PLANNING, BODY_MOVE, LEG_MOVE, NOMINAL_LIFT, Obstacle, RAISED_LIFT, SHUFFLE, SHUFFLED_LIFT,
    STEP_PLANNING, Terrain, Walker,
};
use tdl::{Ctx, Failure, Recorder, Runtime, TapWhen};
use tdl_interp::{Args, FromValue, Host, IntoValue, Program, Registry, Value};

/// The Ambler's world, as the program calls it.
fn registry() -> Registry {
    let mut r = Registry::new();
    r.host_type("Walker")
        .method("Walker", "arcs", |w: Host<Walker>| w.0.arcs())
        .method("Walker", "plan_arc", |w: Host<Walker>, arc: u32| {
            w.0.plan_arc(arc)
        })
        .method(
            "Walker",
            "plan_step",
            |w: Host<Walker>, arc: u32, step: u32| {
                w.0.plan_step(arc, step);
            },
        )
        .method(
            "Walker",
            "swing_leg",
            |w: Host<Walker>, arc: u32, step: u32, lift: f64| w.0.swing_leg(arc, step, lift),
        )
        .method(
            "Walker",
            "move_body",
            |w: Host<Walker>, arc: u32, step: u32| {
                w.0.move_body(arc, step);
            },
        )
        .method(
            "Walker",
            "raise_leg",
            |w: Host<Walker>, arc: u32, step: u32| {
                w.0.raise_leg(arc, step);
            },
        )
        .method(
            "Walker",
            "replan_footfall",
            |w: Host<Walker>, arc: u32, step: u32| {
                w.0.replan_footfall(arc, step);
            },
        )
        .method(
            "Walker",
            "shuffle_feet",
            |w: Host<Walker>, arc: u32, step: u32| {
                w.0.shuffle_feet(arc, step);
            },
        )
        .constant("NOMINAL_LIFT", NOMINAL_LIFT)
        .constant("RAISED_LIFT", RAISED_LIFT)
        .constant("SHUFFLED_LIFT", SHUFFLED_LIFT)
        .constant("ARC_PLANNING", ARC_PLANNING)
        .constant("STEP_PLANNING", STEP_PLANNING)
        .constant("LEG_MOVE", LEG_MOVE)
        .constant("BODY_MOVE", BODY_MOVE)
        .constant("SHUFFLE", SHUFFLE);
    r
}

fn program() -> Program {
    let dir = env!("CARGO_MANIFEST_DIR");
    let files = [
        format!("{dir}/src/terrain.tdl"),
        format!("{dir}/src/walk.tdl"),
    ];
    match Program::load(&files, &registry()) {
        Ok(p) => p,
        Err(e) => panic!("{e}"),
    }
}

/// The walker, the arc and the step of a tapped move's kept arguments.
fn tapped(ctx: &Ctx) -> Option<(Walker, u32, u32)> {
    let args = ctx.tapped_args::<Args>()?;
    let w = Host::<Walker>::from_value(args.0.first()?)?.0;
    let arc = u32::from_value(args.0.get(1)?)?;
    let step = u32::from_value(args.0.get(2)?)?;
    Some((w, arc, step))
}

/// `ambler::monitored`'s wiretaps, reading an interpreted move's arguments.
fn monitored(program: &Program) -> Runtime {
    let unknown = || Err(Failure::new("Unstable", "a move without its arguments"));
    let mut rt = Runtime::new();
    for a in program.attached() {
        rt = rt.attach(a);
    }
    rt.wiretap("move_leg", TapWhen::Before, move |ctx: Ctx| async move {
        match tapped(&ctx) {
            Some((w, arc, step)) => w.check_stability(arc, step),
            None => unknown(),
        }
    })
    .wiretap("move_body", TapWhen::Before, move |ctx: Ctx| async move {
        match tapped(&ctx) {
            Some((w, arc, step)) => w.check_stability(arc, step),
            None => unknown(),
        }
    })
    .wiretap("move_leg", TapWhen::After, |ctx: Ctx| async move {
        match tapped(&ctx) {
            Some((w, arc, step)) => w.check_footfall(arc, step),
            None => Err(Failure::new(
                "BadFoothold",
                "a leg move without its arguments",
            )),
        }
    })
}

/// Walks `terrain` compiled and interpreted; asserts the same trace and the same walk.
fn alike(terrain: &Terrain) {
    let run = async {
        let compiled = Walker::new(terrain.clone());
        let rec = Recorder::new();
        let rt = ambler::monitored(&compiled).with_sink(rec.clone());
        rt.run(ambler::walk(compiled.clone())).await?;
        let compiled_trace = rec.events();

        let program = program();
        let interpreted = Walker::new(terrain.clone());
        let rec = Recorder::new();
        let task = match program.task("walk", vec![Host(interpreted.clone()).into_value()]) {
            Ok(t) => t,
            Err(e) => panic!("{e}"),
        };
        monitored(&program).with_sink(rec.clone()).run(task).await?;
        let interpreted_trace = rec.events();
        tdl::testing::assert_checked(&interpreted_trace);
        Ok::<_, tdl::Error>((compiled, compiled_trace, interpreted, interpreted_trace))
    };
    let (cw, ct, iw, it) = match tdl::block_on_virtual(run) {
        Ok(done) => done,
        Err(e) => panic!("{e}"),
    };
    tdl::testing::assert_same_trace(&ct, &it, "compiled, then interpreted");
    assert_eq!(cw.log(), iw.log());
}

#[test]
fn a_flat_walk_runs_interpreted_as_compiled() {
    alike(&Terrain::flat(2, 3));
}

#[test]
fn every_recovery_runs_interpreted_as_compiled() {
    alike(&Terrain::flat(1, 3).with_obstacle(0, 1, Obstacle::ROCK));
    alike(&Terrain::flat(1, 1).with_obstacle(0, 0, Obstacle::BOULDER));
    alike(&Terrain::flat(1, 4).with_obstacle(0, 2, Obstacle::RIDGE));
    let mut ridges = Terrain::flat(1, 4);
    for step in 0..4 {
        ridges = ridges.with_obstacle(0, step, Obstacle::RIDGE);
    }
    alike(&ridges);
    alike(&Terrain::flat(2, 2).with_tilt(1, 30.0));
}

#[test]
fn seeded_walks_run_interpreted_as_compiled() {
    for seed in [1, 7, 42] {
        alike(&Terrain::generate(seed, 4));
    }
}

#[test]
fn the_values_of_a_walk_cross_as_host_values() {
    let w = Walker::new(Terrain::flat(1, 1));
    let v = Host(w).into_value();
    assert_eq!(v.kind(), "Walker");
    assert!(matches!(v, Value::Host(_)));
}
