//! The robot's failures, one type per exception so that `?` in a `tcm` action fails the node with a
//! TDL exception named after the type (`Blocked`, `NoPath`, ...), and [`RobotError`], the union the
//! async commands return. See `commands.rs` for where they are raised.

use crate::scenario::ObstacleKind;
use std::fmt;
use tcm::Failure;

/// A guarded move stopped before an obstacle (or a wall) and gave up.
///
/// The robot stands [`crate::SAFETY_DISTANCE`] before the obstacle; the blockage is now on the
/// robot's map for a while, so planning again finds a detour (TDL paper, "Introduction": retry,
/// then replan).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("blocked by {obstacle} with {distance_left:.2} m of the move left")]
pub struct Blocked {
    /// How much of the commanded distance was not travelled, in metres (always positive).
    pub distance_left: f64,
    /// What stopped the robot.
    pub obstacle: ObstacleKind,
}

/// Every route to the room is blocked on the robot's map.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("no path to room {room}: every route is blocked")]
pub struct NoPath {
    /// The room that cannot be reached.
    pub room: u32,
}

/// There is no room with this number on the floor.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("there is no room {room} on this floor")]
pub struct UnknownRoom {
    /// The number asked for.
    pub room: u32,
}

/// The door sensor sees no door of this room: the robot is too far from it.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("door of room {room} not in sight ({distance:.1} m away)")]
pub struct DoorNotFound {
    /// The room whose door was looked for.
    pub room: u32,
    /// How far the door really is, in metres.
    pub distance: f64,
}

/// The motor is too hot to move: it reached [`crate::MOTOR_CUTOFF_C`].
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("motor overheating at {temperature:.1} °C")]
pub struct Overheating {
    /// The motor temperature when the motion was refused or cut, in °C.
    pub temperature: f64,
}

/// Another motion (move or turn) is already under way; the robot has one drive.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("another motion is under way")]
pub struct MotorBusy;

/// The robot is not on any corridor, so the planner cannot place it on the graph.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("robot at ({x:.2}, {y:.2}) is not on any corridor")]
pub struct Lost {
    /// The robot's x, in metres.
    pub x: f64,
    /// The robot's y, in metres.
    pub y: f64,
}

/// A command got an argument it cannot act on (a distance or angle that is not finite).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("bad argument: {0}")]
pub struct BadArgument(pub String);

/// Any failure of a robot command.
///
/// This enum deliberately does not implement [`std::error::Error`]: `tcm`'s blanket conversion
/// would then name every exception `RobotError`. Its own `From` impl instead converts the variant
/// inside, so `?` in an action raises `Blocked`, `NoPath`, ... as the TDL exception.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum RobotError {
    /// See [`Blocked`].
    Blocked(Blocked),
    /// See [`NoPath`].
    NoPath(NoPath),
    /// See [`UnknownRoom`].
    UnknownRoom(UnknownRoom),
    /// See [`DoorNotFound`].
    DoorNotFound(DoorNotFound),
    /// See [`Overheating`].
    Overheating(Overheating),
    /// See [`MotorBusy`].
    MotorBusy(MotorBusy),
    /// See [`Lost`].
    Lost(Lost),
    /// See [`BadArgument`].
    BadArgument(BadArgument),
}

impl RobotError {
    /// The exception name this error raises in a task tree (the inner type's name).
    pub fn exception(&self) -> &'static str {
        match self {
            RobotError::Blocked(_) => "Blocked",
            RobotError::NoPath(_) => "NoPath",
            RobotError::UnknownRoom(_) => "UnknownRoom",
            RobotError::DoorNotFound(_) => "DoorNotFound",
            RobotError::Overheating(_) => "Overheating",
            RobotError::MotorBusy(_) => "MotorBusy",
            RobotError::Lost(_) => "Lost",
            RobotError::BadArgument(_) => "BadArgument",
        }
    }
}

impl fmt::Display for RobotError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RobotError::Blocked(e) => e.fmt(f),
            RobotError::NoPath(e) => e.fmt(f),
            RobotError::UnknownRoom(e) => e.fmt(f),
            RobotError::DoorNotFound(e) => e.fmt(f),
            RobotError::Overheating(e) => e.fmt(f),
            RobotError::MotorBusy(e) => e.fmt(f),
            RobotError::Lost(e) => e.fmt(f),
            RobotError::BadArgument(e) => e.fmt(f),
        }
    }
}

impl From<RobotError> for Failure {
    fn from(e: RobotError) -> Failure {
        match e {
            RobotError::Blocked(e) => Failure::from(e),
            RobotError::NoPath(e) => Failure::from(e),
            RobotError::UnknownRoom(e) => Failure::from(e),
            RobotError::DoorNotFound(e) => Failure::from(e),
            RobotError::Overheating(e) => Failure::from(e),
            RobotError::MotorBusy(e) => Failure::from(e),
            RobotError::Lost(e) => Failure::from(e),
            RobotError::BadArgument(e) => Failure::from(e),
        }
    }
}

macro_rules! into_robot_error {
    ($($t:ident),*) => {$(
        impl From<$t> for RobotError {
            fn from(e: $t) -> RobotError {
                RobotError::$t(e)
            }
        }
    )*};
}

into_robot_error!(
    Blocked,
    NoPath,
    UnknownRoom,
    DoorNotFound,
    Overheating,
    MotorBusy,
    Lost,
    BadArgument
);
