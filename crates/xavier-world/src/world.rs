//! The simulated world as plain data and step functions: the robot's pose, motion and motor
//! temperature, the obstacles of its scenario (`scenario.rs`), the mail tray and what the robot
//! said. Nothing here is async or reads a clock; time passes only through [`World::advance`], so a
//! seed and a sequence of calls give the same world on every machine. `commands.rs` drives it
//! from tokio's clock.

use crate::error::{
    BadArgument, Blocked, DoorNotFound, MotorBusy, Overheating, RobotError, UnknownRoom,
};
use crate::floor::{CORRIDOR_HALF_WIDTH, Floor, Point, Waypoint};
use crate::random::{millis_between, rng, stream, unit};
use crate::scenario::{Config, Obstacle, ObstacleKind, Scenario, traffic};
use rand_chacha::ChaCha8Rng;
use std::collections::BTreeMap;
use std::f64::consts::{FRAC_PI_2, PI, TAU};
use std::fmt;
use std::time::Duration;

/// The longest step the model integrates at once; longer advances are split into steps this long.
/// Commands also poll the world at this period.
pub const TICK: Duration = Duration::from_millis(100);
/// Driving speed, in metres per second.
pub const SPEED: f64 = 1.0;
/// Turning rate, in radians per second.
pub const TURN_RATE: f64 = FRAC_PI_2;
/// A guarded move keeps this far (centre to centre, in metres) from an obstacle ahead.
pub const SAFETY_DISTANCE: f64 = 1.0;
/// How long a guarded move waits, stopped before an obstacle, for it to leave before failing.
/// Passers-by leave sooner than this, so random traffic only delays the robot.
pub const PATIENCE: Duration = Duration::from_secs(5);
/// How long the robot's map remembers an obstacle that made a guarded move fail.
pub const BLOCKAGE_MEMORY: Duration = Duration::from_secs(120);
/// Room temperature, and the motor's temperature at the start, in °C.
pub const AMBIENT_C: f64 = 20.0;
/// Newton cooling: the motor loses this fraction per second of its excess over ambient.
pub const COOLING_RATE: f64 = 0.02;
/// Above this a mission's overheating monitor should stop motion (a warning, not enforced here).
pub const OVERHEAT_WARNING_C: f64 = 60.0;
/// Below this the motor is cool enough to resume after an overheating stop.
pub const MOTOR_COOL_C: f64 = 40.0;
/// At this the drive cuts out: moves and turns fail with [`Overheating`].
pub const MOTOR_CUTOFF_C: f64 = 90.0;
/// The door sensor sees doors up to this far, in metres.
pub const DOOR_SENSOR_RANGE: f64 = 3.0;
/// The door sensor reports "centred" when the door is within this, in metres.
pub const DOOR_TOLERANCE: f64 = 0.2;
/// The door sensor's reading is off by up to this much either way, in metres.
pub const DOOR_NOISE: f64 = 0.15;
/// A suggested correction step for centring on a door, in metres.
pub const CENTRING_STEP: f64 = 0.3;
/// People in rooms whose door is this close to the robot hear it speak, in metres.
pub const ANNOUNCE_RANGE: f64 = 2.0;

/// Tolerance for distances and angles.
const EPS: f64 = 1e-9;

/// Normalises an angle to `[-π, π)`.
fn normalize(a: f64) -> f64 {
    (a + PI).rem_euclid(TAU) - PI
}

/// Where the robot is and which way it faces.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    /// Metres east.
    pub x: f64,
    /// Metres north.
    pub y: f64,
    /// Radians counter-clockwise from east, in `[-π, π)`.
    pub heading: f64,
}

impl Pose {
    /// The position, without the heading.
    pub fn position(&self) -> Point {
        Point::new(self.x, self.y)
    }

    /// The unit vector the robot faces.
    fn facing(&self) -> (f64, f64) {
        (self.heading.cos(), self.heading.sin())
    }
}

/// One leg of a path: turn in place by `turn` radians (counter-clockwise positive), then drive
/// `distance` metres straight ahead.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Leg {
    /// The turn before driving, in `[-π, π)`.
    pub turn: f64,
    /// How far to drive, in metres.
    pub distance: f64,
}

/// The turns and moves that take a robot at `from` through `path` (from [`World::plan`]):
/// what a mission spawns as `turn` and `guardedMove` commands, one leg after the other.
pub fn legs(from: Pose, path: &[Waypoint]) -> Vec<Leg> {
    let mut pose = from;
    let mut out = Vec::with_capacity(path.len());
    for wp in path {
        let (dx, dy) = (wp.x - pose.x, wp.y - pose.y);
        let distance = dx.hypot(dy);
        if distance <= EPS {
            continue;
        }
        let heading = dy.atan2(dx);
        out.push(Leg {
            turn: normalize(heading - pose.heading),
            distance,
        });
        pose = Pose {
            x: wp.x,
            y: wp.y,
            heading: normalize(heading),
        };
    }
    out
}

/// Identifies one motion, so a command can ask how *its* move ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct MotionId(u64);

#[derive(Clone, Debug)]
enum Motion {
    Move {
        id: MotionId,
        /// Metres still to go, positive.
        remaining: f64,
        /// 1 forwards, -1 backwards.
        sign: f64,
        /// When the robot stopped before an obstacle, if it is stopped now.
        stopped_since: Option<Duration>,
    },
    Turn {
        id: MotionId,
        /// Radians still to turn, signed.
        remaining: f64,
        /// The heading at the end, exact.
        target: f64,
    },
}

impl Motion {
    fn id(&self) -> MotionId {
        match self {
            Motion::Move { id, .. } | Motion::Turn { id, .. } => *id,
        }
    }
}

/// A room's letter and door, as the world sees them.
#[derive(Clone, Debug)]
struct Mailbox {
    /// How far the real door is from where the map puts it, along the corridor, in metres.
    door_error: f64,
    /// How long after the robot's announcement the letter is taken.
    pickup_delay: Duration,
    /// When the robot first announced itself at this door.
    announced: Option<Duration>,
}

/// Something the robot said.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Utterance {
    /// When it started speaking, in world time.
    pub at: Duration,
    /// What it said.
    pub text: String,
}

/// A letter taken from the tray.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Delivery {
    /// The room.
    pub room: u32,
    /// When the letter was taken, in world time.
    pub at: Duration,
}

/// The world at one instant, for tests and displays.
#[derive(Clone, Debug, PartialEq)]
pub struct Snapshot {
    /// World time.
    pub time: Duration,
    /// The robot's pose.
    pub pose: Pose,
    /// The motor temperature, in °C.
    pub temperature: f64,
    /// Whether a move or turn is under way.
    pub moving: bool,
    /// The obstacles present now.
    pub obstacles: Vec<Obstacle>,
    /// The blockages on the robot's map now.
    pub known_blockages: Vec<Point>,
    /// The rooms whose letter is still on the tray, ascending.
    pub tray: Vec<u32>,
    /// The letters taken, in the order they were taken.
    pub delivered: Vec<Delivery>,
    /// Everything said, in order.
    pub utterances: Vec<Utterance>,
    /// How far the robot has driven, in metres.
    pub distance_travelled: f64,
}

/// What a run achieved, for the end of a demo.
#[derive(Clone, Debug, PartialEq)]
pub struct Summary {
    /// The rooms whose letter was taken, in the order they were taken.
    pub delivered: Vec<u32>,
    /// How many utterances the robot made.
    pub utterances: usize,
    /// How far the robot drove, in metres.
    pub distance_travelled: f64,
    /// World time at the end.
    pub time: Duration,
}

impl fmt::Display for Summary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let rooms: Vec<String> = self.delivered.iter().map(u32::to_string).collect();
        write!(
            f,
            "delivered to rooms [{}], {} utterances, {:.1} m driven, {:.1} s simulated",
            rooms.join(", "),
            self.utterances,
            self.distance_travelled,
            self.time.as_secs_f64()
        )
    }
}

/// The simulated office, its robot and its people. See the crate documentation for the map.
#[derive(Clone, Debug)]
pub struct World {
    floor: Floor,
    heat_rate: f64,
    /// Invariant: the sum of every step taken; never decreases.
    clock: Duration,
    pose: Pose,
    temperature: f64,
    distance_travelled: f64,
    /// Invariant: at most one motion at a time (one drive).
    motion: Option<Motion>,
    /// How finished motions ended, until the command waiting on each collects its result.
    ended: BTreeMap<MotionId, Result<(), RobotError>>,
    next_motion: u64,
    /// Invariant: sorted by `appears`.
    obstacles: Vec<Obstacle>,
    /// Blockages on the robot's map, each with when it is forgotten (`None`: never).
    known: Vec<(Point, Option<Duration>)>,
    mail: BTreeMap<u32, Mailbox>,
    utterances: Vec<Utterance>,
    sensor_rng: ChaCha8Rng,
}

impl World {
    /// A world for `seed` set up as `scenario` says.
    pub fn new(seed: u64, scenario: Scenario) -> World {
        World::with_config(seed, scenario.config())
    }

    /// A world for `seed` with explicit settings.
    pub fn with_config(seed: u64, config: Config) -> World {
        let floor = Floor::office();
        let mut obstacles = config.obstacles;
        if config.traffic {
            obstacles.extend(traffic(&floor, seed));
        }
        obstacles.sort_by_key(|o| o.appears);
        let known = obstacles
            .iter()
            .filter(|o| o.on_map)
            .map(|o| (o.at, None))
            .collect();
        let mut mail_rng = rng(seed, stream::MAIL);
        let mut door_rng = rng(seed, stream::DOORS);
        let mail = floor
            .rooms()
            .iter()
            .map(|r| {
                let magnitude = 0.3 + 0.6 * unit(&mut door_rng);
                let sign = if unit(&mut door_rng) < 0.5 { -1.0 } else { 1.0 };
                let mailbox = Mailbox {
                    door_error: sign * magnitude,
                    pickup_delay: millis_between(&mut mail_rng, 3_000, 15_000),
                    announced: None,
                };
                (r.number, mailbox)
            })
            .collect();
        World {
            floor,
            heat_rate: config.heat_rate,
            clock: Duration::ZERO,
            pose: config.start,
            temperature: AMBIENT_C,
            distance_travelled: 0.0,
            motion: None,
            ended: BTreeMap::new(),
            next_motion: 0,
            obstacles,
            known,
            mail,
            utterances: Vec::new(),
            sensor_rng: rng(seed, stream::SENSOR),
        }
    }

    /// The floor plan.
    pub fn floor(&self) -> &Floor {
        &self.floor
    }

    /// World time: the sum of every step so far.
    pub fn clock(&self) -> Duration {
        self.clock
    }

    /// The robot's pose.
    pub fn pose(&self) -> Pose {
        self.pose
    }

    /// The motor temperature, in °C.
    pub fn temperature(&self) -> f64 {
        self.temperature
    }

    /// Every obstacle of the run, present or not, in order of appearance (the seeded schedule).
    pub fn obstacles(&self) -> &[Obstacle] {
        &self.obstacles
    }

    /// Adds an obstacle (for tests and custom scenarios).
    pub fn place(&mut self, obstacle: Obstacle) {
        if obstacle.on_map {
            self.known.push((obstacle.at, None));
        }
        let at = self
            .obstacles
            .partition_point(|o| o.appears <= obstacle.appears);
        self.obstacles.insert(at, obstacle);
    }

    /// How long after the robot announces itself the letter for `room` is taken (seeded).
    pub fn pickup_delay(&self, room: u32) -> Result<Duration, UnknownRoom> {
        Ok(self.mailbox(room)?.pickup_delay)
    }

    /// Where the door of `room` really is (the map's position is off by a seeded error).
    pub fn true_door(&self, room: u32) -> Result<Point, UnknownRoom> {
        let r = self.floor.room(room)?;
        let error = self.mailbox(room)?.door_error;
        Ok(self.floor.corridors()[r.corridor].point_at(r.station + error))
    }

    fn mailbox(&self, room: u32) -> Result<&Mailbox, UnknownRoom> {
        self.mail.get(&room).ok_or(UnknownRoom { room })
    }

    /// The blockages on the robot's map now.
    pub fn known_blockages(&self) -> Vec<Point> {
        let t = self.clock;
        self.known
            .iter()
            .filter(|(_, until)| until.is_none_or(|u| t < u))
            .map(|(p, _)| *p)
            .collect()
    }

    /// Advances time by `dt`, in steps of at most [`TICK`].
    pub fn advance(&mut self, dt: Duration) {
        self.advance_to(self.clock + dt);
    }

    /// Advances time to `t`; does nothing if `t` is not after the clock. Costs one step per
    /// [`TICK`] of simulated time.
    pub fn advance_to(&mut self, t: Duration) {
        while self.clock < t {
            self.step((t - self.clock).min(TICK));
        }
    }

    /// One step: the motion, then the motor temperature.
    fn step(&mut self, dt: Duration) {
        let start = self.clock;
        self.clock += dt;
        let secs = dt.as_secs_f64();
        let activity = match self.motion.take() {
            Some(m) => self.drive(m, start, secs),
            None => 0.0,
        };
        let cooling = COOLING_RATE * (self.temperature - AMBIENT_C);
        self.temperature += (self.heat_rate * activity - cooling) * secs;
    }

    /// Carries `motion` on for `secs` from world time `start`; puts it back unless it ended.
    /// Returns how hard the motor worked, from 0 (idle) to 1 (full speed).
    fn drive(&mut self, motion: Motion, start: Duration, secs: f64) -> f64 {
        if self.temperature >= MOTOR_CUTOFF_C {
            let temperature = self.temperature;
            self.end(motion.id(), Err(Overheating { temperature }.into()));
            return 0.0;
        }
        match motion {
            Motion::Move {
                id,
                remaining,
                sign,
                stopped_since,
            } => self.drive_move(id, remaining, sign, stopped_since, start, secs),
            Motion::Turn {
                id,
                remaining,
                target,
            } => self.drive_turn(id, remaining, target, secs),
        }
    }

    /// One step of a guarded move: drive as far as the speed, the walls and
    /// [`SAFETY_DISTANCE`] to the nearest obstacle ahead allow. Stopped short by a wall, the move
    /// fails at once; stopped before an obstacle, it waits up to [`PATIENCE`] for it to leave.
    fn drive_move(
        &mut self,
        id: MotionId,
        remaining: f64,
        sign: f64,
        mut stopped_since: Option<Duration>,
        start: Duration,
        secs: f64,
    ) -> f64 {
        let (fx, fy) = self.pose.facing();
        let dir = (fx * sign, fy * sign);
        let want = (SPEED * secs).min(remaining);
        let wall = self.floor.free_distance(self.pose.position(), dir);
        let ahead = self.nearest_ahead(dir, start);
        let clear = ahead.map_or(f64::INFINITY, |(d, _)| (d - SAFETY_DISTANCE).max(0.0));
        let step = want.min(wall).min(clear);
        self.pose.x += dir.0 * step;
        self.pose.y += dir.1 * step;
        self.distance_travelled += step;
        let remaining = remaining - step;

        let blocked = |obstacle| -> Result<(), RobotError> {
            Err(Blocked {
                distance_left: remaining,
                obstacle,
            }
            .into())
        };
        let outcome = if remaining <= EPS {
            Some(Ok(()))
        } else if step >= want - EPS {
            stopped_since = None;
            None
        } else {
            match ahead {
                Some((_, kind)) if clear < wall => {
                    let since = *stopped_since.get_or_insert(start);
                    if self.clock - since >= PATIENCE {
                        self.remember_blockage(dir);
                        Some(blocked(kind))
                    } else {
                        None
                    }
                }
                _ => Some(blocked(ObstacleKind::Wall)),
            }
        };
        match outcome {
            Some(res) => self.end(id, res),
            None => {
                self.motion = Some(Motion::Move {
                    id,
                    remaining,
                    sign,
                    stopped_since,
                });
            }
        }
        step / (SPEED * secs)
    }

    /// One step of a turn in place; the motor works half as hard as when driving.
    fn drive_turn(&mut self, id: MotionId, remaining: f64, target: f64, secs: f64) -> f64 {
        let step = (TURN_RATE * secs).min(remaining.abs()) * remaining.signum();
        let remaining = remaining - step;
        if remaining.abs() <= EPS {
            self.pose.heading = target;
            self.end(id, Ok(()));
        } else {
            self.pose.heading = normalize(self.pose.heading + step);
            self.motion = Some(Motion::Turn {
                id,
                remaining,
                target,
            });
        }
        0.5 * step.abs() / (TURN_RATE * secs)
    }

    /// The nearest obstacle in the robot's path along `dir` at time `t`: its distance and kind.
    fn nearest_ahead(&self, dir: (f64, f64), t: Duration) -> Option<(f64, ObstacleKind)> {
        let p = self.pose.position();
        self.obstacles
            .iter()
            .filter(|o| o.present(t))
            .filter_map(|o| {
                let (rx, ry) = (o.at.x - p.x, o.at.y - p.y);
                let along = rx * dir.0 + ry * dir.1;
                let across = (rx * dir.1 - ry * dir.0).abs();
                (along > 0.0 && across < CORRIDOR_HALF_WIDTH).then_some((along, o.kind))
            })
            .min_by(|a, b| a.0.total_cmp(&b.0))
    }

    /// Puts the obstacle that stopped the robot on its map for [`BLOCKAGE_MEMORY`].
    fn remember_blockage(&mut self, dir: (f64, f64)) {
        if let Some((d, _)) = self.nearest_ahead(dir, self.clock) {
            let p = self.pose.position();
            let at = Point::new(p.x + dir.0 * d, p.y + dir.1 * d);
            self.known.push((at, Some(self.clock + BLOCKAGE_MEMORY)));
        }
    }

    fn end(&mut self, id: MotionId, result: Result<(), RobotError>) {
        self.motion = None;
        self.ended.insert(id, result);
    }

    fn new_motion(&mut self) -> Result<MotionId, RobotError> {
        if self.motion.is_some() {
            return Err(MotorBusy.into());
        }
        if self.temperature >= MOTOR_CUTOFF_C {
            return Err(Overheating {
                temperature: self.temperature,
            }
            .into());
        }
        self.next_motion += 1;
        Ok(MotionId(self.next_motion))
    }

    /// Starts driving `dist` metres along the heading (backwards if negative); the motion goes on
    /// in [`World::advance`]. Ask [`World::take_motion_result`] how it ended.
    pub fn begin_move(&mut self, dist: f64) -> Result<MotionId, RobotError> {
        if !dist.is_finite() {
            return Err(BadArgument(format!("move distance {dist} is not finite")).into());
        }
        let id = self.new_motion()?;
        if dist.abs() <= EPS {
            self.end(id, Ok(()));
        } else {
            self.motion = Some(Motion::Move {
                id,
                remaining: dist.abs(),
                sign: dist.signum(),
                stopped_since: None,
            });
        }
        Ok(id)
    }

    /// Starts turning in place by `angle` radians (counter-clockwise positive).
    pub fn begin_turn(&mut self, angle: f64) -> Result<MotionId, RobotError> {
        if !angle.is_finite() {
            return Err(BadArgument(format!("turn angle {angle} is not finite")).into());
        }
        let id = self.new_motion()?;
        let target = normalize(self.pose.heading + angle);
        if angle.abs() <= EPS {
            self.end(id, Ok(()));
        } else {
            self.motion = Some(Motion::Turn {
                id,
                remaining: angle,
                target,
            });
        }
        Ok(id)
    }

    /// Collects how motion `id` ended; `None` while it goes on. A result is handed out once;
    /// asking again (or about an unknown id) gives `Ok(())`.
    pub fn take_motion_result(&mut self, id: MotionId) -> Option<Result<(), RobotError>> {
        if self.motion.as_ref().is_some_and(|m| m.id() == id) {
            return None;
        }
        Some(self.ended.remove(&id).unwrap_or(Ok(())))
    }

    /// Stops motion `id` where the robot is, if it is still going, and forgets its result (the
    /// command that started it was terminated, so nobody will collect it).
    pub fn halt(&mut self, id: MotionId) {
        if self.motion.as_ref().is_some_and(|m| m.id() == id) {
            self.motion = None;
        }
        self.ended.remove(&id);
    }

    /// The shortest path to `room`'s door (as the map has it) avoiding the blockages the map
    /// knows now. See [`Floor::plan`].
    pub fn plan(&self, room: u32) -> Result<Vec<Waypoint>, RobotError> {
        self.floor
            .plan(self.pose.position(), room, &self.known_blockages())
    }

    /// The door sensor: -1 when `room`'s door is behind the robot's centre (the paper's "left"),
    /// 1 when ahead ("right"), 0 when centred within [`DOOR_TOLERANCE`]; the reading is noisy.
    /// Moving `side * CENTRING_STEP` corrects. Fails when the door is out of sensor range.
    pub fn look_for_door(&mut self, room: u32) -> Result<i32, RobotError> {
        let door = self.true_door(room)?;
        let p = self.pose.position();
        let distance = p.distance(door);
        if distance > DOOR_SENSOR_RANGE {
            return Err(DoorNotFound { room, distance }.into());
        }
        let (fx, fy) = self.pose.facing();
        let along = (door.x - p.x) * fx + (door.y - p.y) * fy;
        let reading = along + DOOR_NOISE * (2.0 * unit(&mut self.sensor_rng) - 1.0);
        Ok(if reading.abs() <= DOOR_TOLERANCE {
            0
        } else if reading > 0.0 {
            1
        } else {
            -1
        })
    }

    /// Records an utterance; people behind doors within [`ANNOUNCE_RANGE`] hear it and come for
    /// their letter after their pickup delay. Returns the rooms that heard it.
    pub fn speak(&mut self, text: &str) -> Vec<u32> {
        self.utterances.push(Utterance {
            at: self.clock,
            text: text.to_string(),
        });
        let p = self.pose.position();
        let near: Vec<u32> = self
            .mail
            .keys()
            .copied()
            .filter(|&room| {
                self.true_door(room)
                    .is_ok_and(|d| d.distance(p) <= ANNOUNCE_RANGE)
            })
            .collect();
        for room in &near {
            if let Some(m) = self.mail.get_mut(room) {
                m.announced.get_or_insert(self.clock);
            }
        }
        near
    }

    /// The mail-gone sensor: whether `room`'s letter has been taken from the tray.
    pub fn mail_gone(&self, room: u32) -> Result<bool, UnknownRoom> {
        Ok(self.taken_at(self.mailbox(room)?).is_some())
    }

    fn taken_at(&self, m: &Mailbox) -> Option<Duration> {
        m.announced
            .map(|a| a + m.pickup_delay)
            .filter(|&t| t <= self.clock)
    }

    /// The letters taken so far, in the order they were taken.
    pub fn delivered(&self) -> Vec<Delivery> {
        let mut out: Vec<Delivery> = self
            .mail
            .iter()
            .filter_map(|(&room, m)| self.taken_at(m).map(|at| Delivery { room, at }))
            .collect();
        out.sort_by_key(|d| (d.at, d.room));
        out
    }

    /// Everything said so far.
    pub fn utterances(&self) -> &[Utterance] {
        &self.utterances
    }

    /// The world now, for tests and displays.
    pub fn snapshot(&self) -> Snapshot {
        Snapshot {
            time: self.clock,
            pose: self.pose,
            temperature: self.temperature,
            moving: self.motion.is_some(),
            obstacles: self
                .obstacles
                .iter()
                .filter(|o| o.present(self.clock))
                .cloned()
                .collect(),
            known_blockages: self.known_blockages(),
            tray: self
                .mail
                .iter()
                .filter(|(_, m)| self.taken_at(m).is_none())
                .map(|(&room, _)| room)
                .collect(),
            delivered: self.delivered(),
            utterances: self.utterances.clone(),
            distance_travelled: self.distance_travelled,
        }
    }

    /// What the run achieved so far.
    pub fn summary(&self) -> Summary {
        Summary {
            delivered: self.delivered().iter().map(|d| d.room).collect(),
            utterances: self.utterances.len(),
            distance_travelled: self.distance_travelled,
            time: self.clock,
        }
    }
}

#[cfg(test)]
mod tests;
