//! The robot a mission commands: the simulated world in this process ([`Robot::Local`]), or, with
//! the feature `distributed`, the world of a robot agent in another process, reached over zenoh
//! (`Robot::Remote`, `robot/remote.rs`; docs/distributed.md, "The distributed Xavier"). The mission's TDL is one source for both: its
//! command constructors here (`plan_path`, `turn`, ...) return xavier-world's local task, or a
//! remote task of the same name placed on the robot agent (`speak` on the voice agent), whose value
//! is read back into the same Rust type.
//!
//! The robot agent ([`serve`]) offers the commands under the names the local tasks have
//! (`planPath`, `turn`, `guardedMove`, `lookForDoor`, `speak`, `mailGone`, `motorTemperature`),
//! so a node's name is the same either way, and answers a few queries that are no nodes of the
//! tree, at `tdl/<system>/xavier/<what>`: `pose` (where the robot stands, for planning the legs),
//! `motor_temperature` (read by `let_motor_cool`), `hear` (a voice elsewhere speaks: the world
//! hears the text; the answer is how long speaking it takes, in seconds of the agent's clock) and
//! `summary` (what the run achieved, read at its end).

use tcm::{Failure, Task};
use xavier_world::{Pose, SharedWorld, Summary};

#[cfg(feature = "distributed")]
mod remote;
#[cfg(feature = "distributed")]
pub use remote::{RemoteRobot, query, query_key, serve, serve_queries};

/// The robot of a mission. Cheap to clone.
#[derive(Clone, Debug)]
pub enum Robot {
    /// The simulated world, in this process.
    Local(SharedWorld),
    /// A robot agent's world, in another process.
    #[cfg(feature = "distributed")]
    Remote(std::sync::Arc<RemoteRobot>),
}

impl Robot {
    /// The robot of agent `body`, which holds the world and offers every command, and of agent
    /// `voice` for `speak` (the same agent, or another), through `exec`.
    #[cfg(feature = "distributed")]
    pub fn remote(exec: tcm_zenoh::Executive, body: &str, voice: &str) -> Robot {
        Robot::Remote(std::sync::Arc::new(RemoteRobot::new(exec, body, voice)))
    }

    /// The local world, if the robot is in this process.
    pub fn world(&self) -> Option<&SharedWorld> {
        match self {
            Robot::Local(w) => Some(w),
            #[cfg(feature = "distributed")]
            Robot::Remote(_) => None,
        }
    }

    /// Where the robot stands, as the last command left it.
    pub async fn pose(&self) -> Result<Pose, Failure> {
        match self {
            Robot::Local(w) => Ok(w.inspect(|w| w.pose())),
            #[cfg(feature = "distributed")]
            Robot::Remote(r) => r.pose().await,
        }
    }

    /// Reads the motor temperature, in °C (it takes a sensor reading's time).
    pub async fn motor_temperature(&self) -> Result<f64, Failure> {
        match self {
            Robot::Local(w) => Ok(w.motor_temperature().await),
            #[cfg(feature = "distributed")]
            Robot::Remote(r) => r.motor_temperature().await,
        }
    }

    /// What the run achieved, as the last command left the world: for a remote robot, as
    /// [`Robot::fetch_summary`] read it (empty before).
    pub fn summary(&self) -> Summary {
        match self {
            Robot::Local(w) => w.summary(),
            #[cfg(feature = "distributed")]
            Robot::Remote(r) => r.summary(),
        }
    }

    /// For a remote robot: reads what the run achieved from its agent, for [`Robot::summary`].
    pub async fn fetch_summary(&self) -> Result<(), Failure> {
        match self {
            Robot::Local(_) => Ok(()),
            #[cfg(feature = "distributed")]
            Robot::Remote(r) => r.fetch_summary().await,
        }
    }
}

// --- the mission's commands --------------------------------------------------------------------

/// `planPath(room) -> Vec<Waypoint>` (xavier-world's [`xavier_world::plan_path`]).
pub fn plan_path(robot: &Robot, room: u32) -> Task {
    match robot {
        Robot::Local(w) => xavier_world::plan_path(w, room),
        #[cfg(feature = "distributed")]
        Robot::Remote(r) => r.plan_path(room),
    }
}

/// `turn(angle)`.
pub fn turn(robot: &Robot, angle: f64) -> Task {
    match robot {
        Robot::Local(w) => xavier_world::turn(w, angle),
        #[cfg(feature = "distributed")]
        Robot::Remote(r) => r.command::<(), _>("turn", angle),
    }
}

/// `guardedMove(dist)`.
pub fn guarded_move(robot: &Robot, dist: f64) -> Task {
    match robot {
        Robot::Local(w) => xavier_world::guarded_move(w, dist),
        #[cfg(feature = "distributed")]
        Robot::Remote(r) => r.command::<(), _>("guardedMove", dist),
    }
}

/// `lookForDoor(room) -> i32`.
pub fn look_for_door(robot: &Robot, room: u32) -> Task {
    match robot {
        Robot::Local(w) => xavier_world::look_for_door(w, room),
        #[cfg(feature = "distributed")]
        Robot::Remote(r) => r.command::<i32, _>("lookForDoor", room),
    }
}

/// `speak(text)`, on the voice agent when the robot is remote.
pub fn speak(robot: &Robot, text: impl Into<String>) -> Task {
    match robot {
        Robot::Local(w) => xavier_world::speak(w, text),
        #[cfg(feature = "distributed")]
        Robot::Remote(r) => r.speak(text.into()),
    }
}

/// `mailGone(room) -> bool`.
pub fn mail_gone(robot: &Robot, room: u32) -> Task {
    match robot {
        Robot::Local(w) => xavier_world::mail_gone(w, room),
        #[cfg(feature = "distributed")]
        Robot::Remote(r) => r.command::<bool, _>("mailGone", room),
    }
}

/// `motorTemperature() -> f64`.
pub fn motor_temperature(robot: &Robot) -> Task {
    match robot {
        Robot::Local(w) => xavier_world::motor_temperature(w),
        #[cfg(feature = "distributed")]
        Robot::Remote(r) => r.command::<f64, _>("motorTemperature", ()),
    }
}
