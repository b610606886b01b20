//! The mission: Xavier's mail round. Everything is TDL (`src/mission.tdl`, compiled by `tdl-build`
//! and included here) but the mission's shared state ([`Mission`]) and two helpers the handlers
//! call ([`stop_the_rest`], [`give_up`]).
//!
//! Recovery, as the tree sees it:
//! - `Blocked` (a guarded move gave up before an obstacle): `detour`, attached to the navigation,
//!   terminates the rest of the old route and spawns `navigate_to_locn` again, which plans from
//!   where the robot stands on a map that now knows the blockage (at most 3 times).
//! - `Overheating` (a move cut at the motor's cutoff): `cool_down`, attached to the navigation,
//!   stops the old route, waits for the motor to cool, and navigates again (at most 3 times).
//! - `NoPath`, and whatever the two above give up on (`Blocked`, `Overheating`), and
//!   `DoorNotFound`: the `give_up_*` handlers, attached to the delivery, record the room as
//!   undeliverable and terminate the delivery, so the round goes on with the next room.
//! - `watch_motor` polls the motor temperature while the robot travels and, at
//!   [`OVERHEAT_WARNING_C`], reserves the base for itself: every motion command uses the base, so
//!   the running stretch finishes and the next one waits, enabled, for the base; below
//!   [`MOTOR_COOL_C`] it gives the reservation up (docs/semantics.md, "Resources").

use crate::robot::{
    Robot, guarded_move, look_for_door, mail_gone, motor_temperature, plan_path, speak, turn,
};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Duration;
use tdl::{Ctx, Failure};
use xavier_world::{CENTRING_STEP, MOTOR_COOL_C, OVERHEAT_WARNING_C, SharedWorld, Waypoint, legs};

/// The code `tdl-build` generated from `src/mission.tdl`: per task an argument struct and a
/// constructor function returning a [`Task`].
// Generated code: its argument structs have undocumented public fields, and the generator's
// argument passing (autoref specialisation, `(&tdl_args).tdl_args()`) needs a borrow that clippy
// calls needless.
#[allow(missing_docs, clippy::needless_borrow)]
mod generated {
    use super::*;
    include!(concat!(env!("OUT_DIR"), "/mission.rs"));
}
pub use generated::*;

/// How long notifying a sender takes.
pub const NOTIFY_TIME: Duration = Duration::from_millis(300);
/// How often `let_motor_cool` reads the temperature.
pub const COOLING_POLL: Duration = Duration::from_secs(1);
/// Turns smaller than this (radians) are not spawned.
pub const TURN_EPSILON: f64 = 1e-6;
/// Legs are driven in guarded moves of at most this many metres: when the motor monitor takes the
/// base, the robot stops at the end of the stretch under way.
pub const STRETCH: f64 = 5.0;

/// `distance` metres cut into stretches of at most [`STRETCH`] metres, as equal as can be.
pub fn stretches(distance: f64) -> Vec<f64> {
    if !(distance.is_finite() && distance > 0.0) {
        return Vec::new();
    }
    let n = (distance / STRETCH).ceil().max(1.0);
    // `n` is at most distance / 5 + 1 for a finite distance on a 40 m floor.
    let count = n as usize;
    vec![distance / n; count]
}

/// A room the robot gave up on, and why.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Undeliverable {
    /// The room.
    pub room: u32,
    /// The exception that made the robot give up (`NoPath`, ...).
    pub exception: String,
    /// Its message.
    pub reason: String,
}

#[derive(Debug, Default)]
struct Log {
    undeliverable: Vec<Undeliverable>,
    notified: Vec<u32>,
}

/// What the mission's tasks share: the robot and the mission's own log. Cheap to clone.
#[derive(Clone, Debug)]
pub struct Mission {
    /// The robot: the simulated floor in this process, or a robot agent's.
    pub robot: Robot,
    log: Arc<Mutex<Log>>,
}

impl Mission {
    /// A mission in `world`, in this process.
    pub fn new(world: SharedWorld) -> Mission {
        Mission::with_robot(Robot::Local(world))
    }

    /// A mission commanding `robot`.
    pub fn with_robot(robot: Robot) -> Mission {
        Mission {
            robot,
            log: Arc::default(),
        }
    }

    fn log(&self) -> MutexGuard<'_, Log> {
        // The log is plain data changed in non-panicking steps: a poisoned lock still guards it.
        self.log.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Called by `notify_sender`.
    pub fn notified(&self, room: u32) {
        self.log().notified.push(room);
    }

    /// The rooms whose sender was notified, in order.
    pub fn notifications(&self) -> Vec<u32> {
        self.log().notified.clone()
    }

    /// Records `room` as undeliverable because of `failure`.
    pub fn give_up(&self, room: u32, failure: Option<&Failure>) {
        let (exception, reason) = match failure {
            Some(f) => (f.exception.to_string(), f.message.clone()),
            None => ("?".to_string(), "unknown failure".to_string()),
        };
        self.log().undeliverable.push(Undeliverable {
            room,
            exception,
            reason,
        });
    }

    /// The rooms given up, in order.
    pub fn undeliverable(&self) -> Vec<Undeliverable> {
        self.log().undeliverable.clone()
    }
}

/// Where the robot stands, read through the run's journal (`Ctx::record_async`): a run resumed
/// after a crash plans its legs from where the robot stood when the crashed run planned them, not
/// from where it stands now (docs/semantics.md, "Durable runs").
pub async fn pose_now(ctx: &Ctx, m: &Mission) -> Result<xavier_world::Pose, Failure> {
    let read = ctx
        .record_async(|| async {
            m.robot
                .pose()
                .await
                .map(|p| (p.x, p.y, p.heading))
                .map_err(|f| f.message)
        })
        .await?;
    let (x, y, heading) = read.map_err(|why| Failure::new("RemoteError", why))?;
    Ok(xavier_world::Pose { x, y, heading })
}

/// In a handler: terminates the later siblings of the failed node (the rest of the old route).
pub fn stop_the_rest(ctx: &Ctx) -> Result<(), Failure> {
    if let Some(failing) = ctx.failing_node() {
        ctx.terminate_siblings(failing).map_err(Failure::from)?;
    }
    Ok(())
}

/// In a handler attached to `deliver_mail`: records `room` as undeliverable with the failure being
/// handled, and terminates the delivery.
pub fn give_up(ctx: &Ctx, m: &Mission, room: u32) -> Result<(), Failure> {
    m.give_up(room, ctx.failure());
    if let Some(delivery) = ctx.attached_node() {
        ctx.terminate(delivery).map_err(Failure::from)?;
    }
    Ok(())
}
