//! What a run contains: the obstacles (placed by a scenario, or random passers-by on a seeded
//! schedule), the scenarios and their settings. `world.rs` makes them move; the crate
//! documentation says what each scenario is for.

use crate::floor::{Floor, Point};
use crate::random::{millis_between, rng, stream, unit};
use crate::world::Pose;
use std::fmt;
use std::str::FromStr;
use std::time::Duration;

/// Motor heating while driving at full speed, in °C per second, in the normal scenarios; the
/// steady state, ambient plus `heat / COOLING_RATE` = 45 °C, stays below the warning.
pub const NOMINAL_HEAT_RATE: f64 = 0.5;
/// Motor heating in the overheat scenario: steady state 120 °C; the warning is crossed after
/// about 26 s of driving, the cutoff after about 60 s.
pub const OVERHEAT_HEAT_RATE: f64 = 2.0;

/// Random traffic is scheduled up to this time.
pub const TRAFFIC_HORIZON: Duration = Duration::from_secs(3600);

/// What stands in the robot's way.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum ObstacleKind {
    /// Someone walking by; leaves within seconds.
    Person,
    /// A mail or cleaning cart; random ones leave within seconds, a scenario's may stay minutes.
    Cart,
    /// A closed fire door or a barrier; stays, and is on the robot's map from the start.
    Barrier,
    /// The end of a corridor, or its side.
    Wall,
}

impl fmt::Display for ObstacleKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ObstacleKind::Person => "a person",
            ObstacleKind::Cart => "a cart",
            ObstacleKind::Barrier => "a barrier",
            ObstacleKind::Wall => "a wall",
        })
    }
}

/// An obstacle on a corridor's centreline, present from `appears` until `leaves`.
#[derive(Clone, Debug, PartialEq)]
pub struct Obstacle {
    /// What it is.
    pub kind: ObstacleKind,
    /// Where it stands.
    pub at: Point,
    /// When it appears, in world time.
    pub appears: Duration,
    /// When it leaves, in world time; `None` if it stays.
    pub leaves: Option<Duration>,
    /// Whether the robot's map knows it from the start, so the planner avoids it at once.
    pub on_map: bool,
}

impl Obstacle {
    /// Whether it is there at world time `t`.
    pub fn present(&self, t: Duration) -> bool {
        self.appears <= t && self.leaves.is_none_or(|l| t < l)
    }
}

/// What is special about a run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Scenario {
    /// Random passers-by only.
    Nominal,
    /// A cart blocks the south corridor at x = 30 m (between rooms 5 and 7) for the first 300 s;
    /// the robot's map does not know it until a guarded move runs into it.
    BlockedCorridor,
    /// Closed fire doors on the east corridor at y = 3 m and y = 17 m, known to the map: room 12
    /// cannot be reached, every other room can.
    NoPath,
    /// The motor heats four times as fast ([`OVERHEAT_HEAT_RATE`]): a long trip crosses
    /// [`crate::OVERHEAT_WARNING_C`].
    Overheat,
}

impl Scenario {
    /// Every scenario.
    pub const ALL: [Scenario; 4] = [
        Scenario::Nominal,
        Scenario::BlockedCorridor,
        Scenario::NoPath,
        Scenario::Overheat,
    ];

    /// Its name on a command line: `nominal`, `blocked-corridor`, `no-path`, `overheat`.
    pub fn name(self) -> &'static str {
        match self {
            Scenario::Nominal => "nominal",
            Scenario::BlockedCorridor => "blocked-corridor",
            Scenario::NoPath => "no-path",
            Scenario::Overheat => "overheat",
        }
    }

    /// The world's settings for this scenario.
    pub fn config(self) -> Config {
        let mut config = Config::default();
        match self {
            Scenario::Nominal => {}
            Scenario::BlockedCorridor => config.obstacles.push(Obstacle {
                kind: ObstacleKind::Cart,
                at: Point::new(30.0, 0.0),
                appears: Duration::ZERO,
                leaves: Some(Duration::from_secs(300)),
                on_map: false,
            }),
            Scenario::NoPath => {
                for y in [3.0, 17.0] {
                    config.obstacles.push(Obstacle {
                        kind: ObstacleKind::Barrier,
                        at: Point::new(40.0, y),
                        appears: Duration::ZERO,
                        leaves: None,
                        on_map: true,
                    });
                }
            }
            Scenario::Overheat => config.heat_rate = OVERHEAT_HEAT_RATE,
        }
        config
    }
}

impl fmt::Display for Scenario {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A scenario name that is not one of [`Scenario::ALL`].
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown scenario `{0}`; expected nominal, blocked-corridor, no-path or overheat")]
pub struct UnknownScenario(pub String);

impl FromStr for Scenario {
    type Err = UnknownScenario;

    fn from_str(s: &str) -> Result<Scenario, UnknownScenario> {
        Scenario::ALL
            .into_iter()
            .find(|sc| sc.name() == s)
            .ok_or_else(|| UnknownScenario(s.to_string()))
    }
}

/// The world's settings; [`Scenario::config`] gives the standard ones.
#[derive(Clone, Debug, PartialEq)]
pub struct Config {
    /// Motor heating while driving at full speed, in °C per second (half of it while turning).
    pub heat_rate: f64,
    /// Whether people and carts pass by at random (seeded) times and places.
    pub traffic: bool,
    /// Obstacles placed by the scenario, besides the random traffic.
    pub obstacles: Vec<Obstacle>,
    /// Where the robot starts.
    pub start: Pose,
}

impl Default for Config {
    /// The nominal settings: traffic on, the robot at junction A facing east.
    fn default() -> Config {
        Config {
            heat_rate: NOMINAL_HEAT_RATE,
            traffic: true,
            obstacles: Vec::new(),
            start: Pose {
                x: 0.0,
                y: 0.0,
                heading: 0.0,
            },
        }
    }
}

/// The seeded schedule of passers-by: one every 10 to 40 s, people (70 %) staying 1 to 4 s and
/// carts 2 to 5 s, each at a random place on a random corridor, away from its ends.
pub(crate) fn traffic(floor: &Floor, seed: u64) -> Vec<Obstacle> {
    let mut rng = rng(seed, stream::TRAFFIC);
    let corridors = floor.corridors();
    let mut out = Vec::new();
    let mut t = Duration::ZERO;
    // Each round adds at least 10 s, so the loop ends after at most HORIZON / 10 s rounds.
    loop {
        t += millis_between(&mut rng, 10_000, 40_000);
        if t > TRAFFIC_HORIZON {
            break;
        }
        let person = unit(&mut rng) < 0.7;
        let pick = (unit(&mut rng) * corridors.len() as f64) as usize;
        let Some(corridor) = corridors.get(pick) else {
            break;
        };
        let station = 1.0 + unit(&mut rng) * (corridor.length() - 2.0);
        let stay = if person {
            millis_between(&mut rng, 1_000, 4_000)
        } else {
            millis_between(&mut rng, 2_000, 5_000)
        };
        out.push(Obstacle {
            kind: if person {
                ObstacleKind::Person
            } else {
                ObstacleKind::Cart
            },
            at: corridor.point_at(station),
            appears: t,
            leaves: Some(t + stay),
            on_map: false,
        });
    }
    out
}

#[cfg(test)]
mod tests;
