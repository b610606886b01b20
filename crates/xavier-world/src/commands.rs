//! The robot's commands against a shared world: async methods on [`SharedWorld`] that take
//! simulated time, and `tcm` command constructors (`guarded_move`, `turn`, ...) that wrap them so a
//! goal can spawn them. Time comes from tokio's clock; under a paused clock it is virtual.
//!
//! How time flows: the first command to touch the world pins world time to tokio's clock; from
//! then on every command first advances the world to tokio's now (in [`TICK`] steps), then acts.
//! A motion polls every [`TICK`]. Since all commands advance the same clock to the same "now",
//! commands running side by side (a move and a mail-gone monitor) never count time twice, and under
//! tokio's paused clock the world's times are the same on every run. A world made with
//! [`SharedWorld::scaled`] runs faster than tokio's clock, as a run with `Runtime::time_scale` does.

use crate::error::RobotError;
use crate::floor::Waypoint;
use crate::world::{MotionId, Snapshot, Summary, TICK, World};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Duration;
use tcm::Task;
use tokio::time::Instant;

/// How long the planner takes.
pub const PLAN_TIME: Duration = Duration::from_millis(500);
/// How long one look for a door takes.
pub const LOOK_TIME: Duration = Duration::from_secs(1);
/// How long a plain sensor reading (mail gone, motor temperature) takes.
pub const SENSOR_TIME: Duration = Duration::from_millis(100);
/// Speaking takes this long per character...
pub const SPEECH_PER_CHAR: Duration = Duration::from_millis(60);
/// ...and at least this long.
pub const SPEECH_MIN: Duration = Duration::from_millis(500);

/// How long saying `text` takes.
pub fn speech_duration(text: &str) -> Duration {
    let chars = u32::try_from(text.chars().count()).unwrap_or(u32::MAX);
    SPEECH_PER_CHAR.saturating_mul(chars).max(SPEECH_MIN)
}

/// The world shared by the commands of a run. Cheap to clone.
#[derive(Clone, Debug)]
pub struct SharedWorld {
    inner: Arc<Mutex<Inner>>,
    // World time per unit of tokio's time (1, unless `scaled`).
    scale: f64,
}

#[derive(Debug)]
struct Inner {
    world: World,
    /// The tokio instant and world time that were pinned together at the first command.
    pinned: Option<(Instant, Duration)>,
}

impl SharedWorld {
    /// Shares `world` between commands.
    pub fn new(world: World) -> SharedWorld {
        SharedWorld::scaled(world, 1.0)
    }

    /// Shares `world` between commands, its time running `scale` times as fast as tokio's clock
    /// (a finite number above 0; else 1): for a run whose clock is scaled the same
    /// (`tcm::Runtime::time_scale`).
    pub fn scaled(world: World, scale: f64) -> SharedWorld {
        SharedWorld {
            inner: Arc::new(Mutex::new(Inner {
                world,
                pinned: None,
            })),
            scale: if scale.is_finite() && scale > 0.0 {
                scale
            } else {
                1.0
            },
        }
    }

    /// `d` of world time in tokio's time.
    fn tokio_time(&self, d: Duration) -> Duration {
        if self.scale == 1.0 {
            d
        } else {
            d.div_f64(self.scale)
        }
    }

    /// The lock. The model is plain data changed in short, non-panicking steps, so a poisoned
    /// lock (a panic elsewhere while holding it) still guards a consistent world: recover it.
    fn lock(&self) -> MutexGuard<'_, Inner> {
        self.inner.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Advances the world to tokio's now, then runs `f` on it.
    pub fn synced<R>(&self, f: impl FnOnce(&mut World) -> R) -> R {
        let mut inner = self.lock();
        let now = Instant::now();
        let clock = inner.world.clock();
        let (base, at) = *inner.pinned.get_or_insert((now, clock));
        let elapsed = now.saturating_duration_since(base);
        let target = if self.scale == 1.0 {
            at + elapsed
        } else {
            at + elapsed.mul_f64(self.scale)
        };
        inner.world.advance_to(target);
        f(&mut inner.world)
    }

    /// Runs `f` on the world as the last command left it, without advancing time.
    pub fn inspect<R>(&self, f: impl FnOnce(&World) -> R) -> R {
        f(&self.lock().world)
    }

    /// The world as the last command left it.
    pub fn snapshot(&self) -> Snapshot {
        self.inspect(World::snapshot)
    }

    /// What the run achieved, as the last command left the world.
    pub fn summary(&self) -> Summary {
        self.inspect(World::summary)
    }

    /// Lets `d` pass, keeping the world in step at both ends (the first command of a run pins
    /// world time to tokio's clock when it starts, not when it ends).
    async fn take_time(&self, d: Duration) {
        self.synced(|_| ());
        tokio::time::sleep(self.tokio_time(d)).await;
        self.synced(|_| ());
    }

    /// Waits for motion `id` to end, polling every [`TICK`]; halts it if dropped first.
    async fn finish_motion(&self, id: MotionId) -> Result<(), RobotError> {
        let _halt = HaltOnDrop {
            world: self.clone(),
            id,
        };
        // Ends: every motion ends in bounded world time (a move by its distance, a wall, or
        // PATIENCE after stopping; a turn by its angle), and each round advances world time.
        loop {
            if let Some(res) = self.synced(|w| w.take_motion_result(id)) {
                return res;
            }
            tokio::time::sleep(self.tokio_time(TICK)).await;
        }
    }

    /// Drives `dist` metres along the heading (backwards if negative), stopping
    /// [`crate::SAFETY_DISTANCE`] before obstacles. Fails with `Blocked` if an obstacle stays
    /// [`crate::PATIENCE`] or a wall is reached, `Overheating` at [`crate::MOTOR_CUTOFF_C`].
    pub async fn guarded_move(&self, dist: f64) -> Result<(), RobotError> {
        let id = self.synced(|w| w.begin_move(dist))?;
        self.finish_motion(id).await
    }

    /// Turns in place by `angle` radians, counter-clockwise positive.
    pub async fn turn(&self, angle: f64) -> Result<(), RobotError> {
        let id = self.synced(|w| w.begin_turn(angle))?;
        self.finish_motion(id).await
    }

    /// Plans the shortest path from here to `room`'s door on the robot's current map.
    pub async fn plan_path(&self, room: u32) -> Result<Vec<Waypoint>, RobotError> {
        self.take_time(PLAN_TIME).await;
        self.synced(|w| w.plan(room))
    }

    /// Looks for `room`'s door: -1 behind, 1 ahead, 0 centred. See [`World::look_for_door`].
    pub async fn look_for_door(&self, room: u32) -> Result<i32, RobotError> {
        self.take_time(LOOK_TIME).await;
        self.synced(|w| w.look_for_door(room))
    }

    /// Says `text`; takes [`speech_duration`]. Rooms whose door is near hear it at the start.
    pub async fn speak(&self, text: &str) {
        self.synced(|w| w.speak(text));
        self.take_time(speech_duration(text)).await;
    }

    /// Reads the mail-gone sensor for `room`.
    pub async fn mail_gone(&self, room: u32) -> Result<bool, RobotError> {
        self.take_time(SENSOR_TIME).await;
        Ok(self.synced(|w| w.mail_gone(room))?)
    }

    /// Reads the motor temperature, in °C.
    pub async fn motor_temperature(&self) -> f64 {
        self.take_time(SENSOR_TIME).await;
        self.synced(|w| w.temperature())
    }
}

/// Stops a motion whose command was dropped (terminated by TCM) before it ended, as a real drive
/// stops when its controller goes away.
struct HaltOnDrop {
    world: SharedWorld,
    id: MotionId,
}

impl Drop for HaltOnDrop {
    fn drop(&mut self) {
        let id = self.id;
        self.world.synced(|w| w.halt(id));
    }
}

/// `Command guardedMove(double dist)`: see [`SharedWorld::guarded_move`]. Raises `Blocked`
/// (with the distance left), `Overheating`, `MotorBusy` or `BadArgument`.
pub fn guarded_move(world: &SharedWorld, dist: f64) -> Task {
    let world = world.clone();
    Task::command("guardedMove", move |_| async move {
        world.guarded_move(dist).await?;
        Ok(())
    })
}

/// `Command turn(double angle)`: see [`SharedWorld::turn`].
pub fn turn(world: &SharedWorld, angle: f64) -> Task {
    let world = world.clone();
    Task::command("turn", move |_| async move {
        world.turn(angle).await?;
        Ok(())
    })
}

/// `Command planPath(int room) -> Vec<Waypoint>`: raises `NoPath` when every route is blocked,
/// `UnknownRoom`, or `Lost`. Read the path with `wait_value::<Vec<Waypoint>>()`.
pub fn plan_path(world: &SharedWorld, room: u32) -> Task {
    let world = world.clone();
    Task::command("planPath", move |_| async move {
        Ok(world.plan_path(room).await?)
    })
}

/// `Command lookForDoor(int room) -> i32`: raises `DoorNotFound` when out of sensor range.
pub fn look_for_door(world: &SharedWorld, room: u32) -> Task {
    let world = world.clone();
    Task::command("lookForDoor", move |_| async move {
        Ok(world.look_for_door(room).await?)
    })
}

/// `Command speak(string text)`.
pub fn speak(world: &SharedWorld, text: impl Into<String>) -> Task {
    let world = world.clone();
    let text = text.into();
    Task::command("speak", move |_| async move {
        world.speak(&text).await;
        Ok(())
    })
}

/// `Command mailGone(int room) -> bool`: the mail-gone sensor.
pub fn mail_gone(world: &SharedWorld, room: u32) -> Task {
    let world = world.clone();
    Task::command("mailGone", move |_| async move {
        Ok(world.mail_gone(room).await?)
    })
}

/// `Command motorTemperature() -> f64`, in °C.
pub fn motor_temperature(world: &SharedWorld) -> Task {
    let world = world.clone();
    Task::command("motorTemperature", move |_| async move {
        Ok(world.motor_temperature().await)
    })
}
