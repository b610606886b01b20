//! A simulated office floor for Xavier, the mail-delivery robot of the TDL paper (Simmons &
//! Apfelbaum 1998, Figures 2, 4 and 6), and the robot's commands as `tcm` tasks.
//!
//! # The floor
//!
//! A 40 m by 20 m loop of corridors with a cross corridor, six junctions (A to F) and twelve rooms
//! (numbers on the corridors, at their doors). The robot starts at A facing east, with a letter
//! for every room on its tray.
//!
//! ```text
//!        x=0     6        14    20     26      33     40
//!  y=20   D=======2========4=====E======6=======8======F    north
//!         |                      |                     |
//!  y=14   |                     11                     |
//!  y=10   9                      |                    12    west | middle | east
//!  y=6    |                     10                     |
//!         |                      |                     |
//!  y=0    A====1=======3=========B======5=======7======C    south
//!        x=0   5       12       20     27      34     40
//! ```
//!
//! # Key types
//!
//! - [`World`] is the model: plain data and step functions, no async and no clock of its own
//!   but the sum of its steps ([`World::advance`]). It holds the [`Floor`], the robot's [`Pose`],
//!   motion and motor temperature, the seeded [`Obstacle`] schedule, the mail tray and the log of
//!   [`Utterance`]s. [`World::new`] takes a seed and a [`Scenario`].
//! - [`SharedWorld`] shares a world between the commands of a run and keeps it in step with
//!   tokio's clock: each command first advances the world to tokio's now, in [`TICK`] steps, so
//!   commands running side by side never count time twice (details in `commands.rs`).
//!   [`SharedWorld::snapshot`] and [`SharedWorld::summary`] report on it.
//! - The commands, as `tcm` command constructors: [`guarded_move`], [`turn`], [`plan_path`],
//!   [`look_for_door`], [`speak`], [`mail_gone`], [`motor_temperature`]. Each takes simulated time.
//!   Failures are one type per TDL exception ([`Blocked`], [`NoPath`], [`Overheating`], ...), so
//!   the trace names the exception after the type, and the failure carries the value: a handler
//!   reads `failure.data::<Blocked>()` for the distance left.
//! - [`legs`] turns a planned path into the turns and moves a mission spawns.
//!
//! # Scenarios
//!
//! - [`Scenario::Nominal`]: random passers-by only. They leave within [`PATIENCE`], so they delay
//!   a guarded move but never fail it.
//! - [`Scenario::BlockedCorridor`]: a cart stands on the south corridor at x = 30 m for 300 s. A
//!   guarded move towards room 7 from the west fails with `Blocked`; the cart is then on the map,
//!   and planning again gives the detour round the loop. Waiting 300 s also works.
//! - [`Scenario::NoPath`]: the east corridor is closed at y = 3 m and y = 17 m (known to the map),
//!   so planning to room 12 fails with `NoPath`; every other room is reachable.
//! - [`Scenario::Overheat`]: the motor heats four times as fast; about 26 s of driving crosses
//!   [`OVERHEAT_WARNING_C`], idling cools it below [`MOTOR_COOL_C`] in about 35 s, and at
//!   [`MOTOR_CUTOFF_C`] moves fail with `Overheating`.
//!
//! # Example: navigate to room 7 from a goal
//!
//! ```
//! use tcm::{Facet, NodeRef, RunOutcome, Runtime, Task};
//! use xavier_world::{Scenario, SharedWorld, Waypoint, World, guarded_move, legs, plan_path, turn};
//!
//! let world = SharedWorld::new(World::new(1, Scenario::Nominal));
//! let w = world.clone();
//! let navigate = Task::goal("navigateToLocn", move |ctx| async move {
//!     let path: Vec<Waypoint> = ctx.spawn(plan_path(&w, 7)).wait_value().await?;
//!     let pose = w.inspect(|w| w.pose());
//!     for leg in legs(pose, &path) {
//!         ctx.spawn(turn(&w, leg.turn))
//!             .sequential(Facet::Execution, NodeRef::Previous)
//!             .start()?;
//!         ctx.spawn(guarded_move(&w, leg.distance))
//!             .sequential(Facet::Execution, NodeRef::Previous)
//!             .start()?;
//!     }
//!     Ok(())
//! });
//! let report = tcm::block_on_virtual(Runtime::new().run(navigate))?;
//! assert_eq!(report.outcome, RunOutcome::Completed);
//! let door = world.inspect(|w| w.floor().door(7))?;
//! assert!(world.snapshot().pose.position().distance(door) < 1e-6);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # Architecture invariants
//!
//! - Determinism: all randomness comes from the seed, through ChaCha8 streams (traffic, mail
//!   delays, door positions, sensor noise: one stream each, so they do not disturb each other) and
//!   only raw `u64` draws. World time is a sum of [`std::time::Duration`] steps, so it is exact;
//!   under tokio's paused clock the same program and seed give the same world.
//! - The model never waits and never reads a clock; only `commands.rs` touches tokio.
//! - One drive: at most one motion at a time; a second fails with `MotorBusy`. A terminated
//!   motion command stops the robot where it is.
//! - The robot stays inside corridors: moves stop at walls (`Blocked` by a wall).
#![warn(missing_docs)]

mod commands;
mod error;
mod floor;
mod random;
mod scenario;
mod world;

pub use commands::{
    LOOK_TIME, PLAN_TIME, SENSOR_TIME, SPEECH_MIN, SPEECH_PER_CHAR, SharedWorld, guarded_move,
    look_for_door, mail_gone, motor_temperature, plan_path, speak, speech_duration, turn,
};
pub use error::{
    BadArgument, Blocked, DoorNotFound, Lost, MotorBusy, NoPath, Overheating, RobotError,
    UnknownRoom,
};
pub use floor::{
    CORRIDOR_CLEARANCE, CORRIDOR_HALF_WIDTH, Corridor, Floor, Junction, Point, Room, Waypoint,
};
pub use scenario::{
    Config, NOMINAL_HEAT_RATE, OVERHEAT_HEAT_RATE, Obstacle, ObstacleKind, Scenario,
    TRAFFIC_HORIZON, UnknownScenario,
};
pub use world::{
    AMBIENT_C, ANNOUNCE_RANGE, BLOCKAGE_MEMORY, CENTRING_STEP, COOLING_RATE, DOOR_NOISE,
    DOOR_SENSOR_RANGE, DOOR_TOLERANCE, Delivery, Leg, MOTOR_COOL_C, MOTOR_CUTOFF_C, MotionId,
    OVERHEAT_WARNING_C, PATIENCE, Pose, SAFETY_DISTANCE, SPEED, Snapshot, Summary, TICK, TURN_RATE,
    Utterance, World, legs,
};
