//! The simulated world: the terrain (arcs, steps, obstacles under footfalls, fixed by a seed) and
//! the walker's state, shared by the tasks, the handlers and the wiretaps.
//!
//! A leg move hits the obstacle under its footfall when the obstacle is higher than the leg's
//! lift. The three recoveries change what the next attempt meets: raising the leg lifts it to
//! [`RAISED_LIFT`], replanning moves the footfall to the step's alternate foothold, shuffling the
//! feet into the standard configuration lifts it to [`SHUFFLED_LIFT`].

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Duration;
use tdl::Failure;

/// How high a leg swings normally (metres).
pub const NOMINAL_LIFT: f64 = 0.15;
/// How high a leg swings once its trajectory was raised.
pub const RAISED_LIFT: f64 = 0.45;
/// How high a leg swings from the standard configuration, after the feet were shuffled.
pub const SHUFFLED_LIFT: f64 = 0.9;
/// The steepest ground the Ambler walks on (degrees).
pub const MAX_TILT: f64 = 20.0;
/// Time to plan an arc.
pub const ARC_PLANNING: Duration = Duration::from_secs(4);
/// Time to plan a step (choose the leg's footfall and the body's move).
pub const STEP_PLANNING: Duration = Duration::from_secs(2);
/// Time of a leg move.
pub const LEG_MOVE: Duration = Duration::from_secs(3);
/// Time of a body move.
pub const BODY_MOVE: Duration = Duration::from_secs(3);
/// Time to shuffle the feet into the standard configuration.
pub const SHUFFLE: Duration = Duration::from_secs(6);

/// What lies under one footfall: the obstacle's height at the planned foothold and at the
/// alternate one a replanning chooses (0 for none).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Obstacle {
    /// Height at the planned foothold (metres).
    pub primary: f64,
    /// Height at the alternate foothold.
    pub alternate: f64,
}

impl Obstacle {
    /// Cleared by raising the leg.
    pub const ROCK: Obstacle = Obstacle {
        primary: 0.3,
        alternate: 0.0,
    };
    /// Too high for a raised leg at the planned foothold; the alternate one is lower.
    pub const BOULDER: Obstacle = Obstacle {
        primary: 0.6,
        alternate: 0.3,
    };
    /// Too high for a raised leg at either foothold: only the standard configuration clears it.
    pub const RIDGE: Obstacle = Obstacle {
        primary: 0.7,
        alternate: 0.7,
    };
}

/// The terrain: how many steps each arc takes, and the obstacles under some footfalls.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Terrain {
    /// Steps per arc, in walking order.
    pub arcs: Vec<u32>,
    /// Obstacles by (arc, step).
    pub obstacles: BTreeMap<(u32, u32), Obstacle>,
    /// The ground's tilt by arc (degrees; 0 when not given).
    pub tilts: BTreeMap<u32, f64>,
}

impl Terrain {
    /// Flat terrain: `arcs` arcs of `steps` steps each, no obstacle.
    pub fn flat(arcs: u32, steps: u32) -> Terrain {
        Terrain {
            arcs: vec![steps; arcs as usize],
            obstacles: BTreeMap::new(),
            tilts: BTreeMap::new(),
        }
    }

    /// This terrain with `obstacle` under the footfall of `step` of `arc`.
    pub fn with_obstacle(mut self, arc: u32, step: u32, obstacle: Obstacle) -> Terrain {
        self.obstacles.insert((arc, step), obstacle);
        self
    }

    /// This terrain with the ground of `arc` tilted by `degrees`.
    pub fn with_tilt(mut self, arc: u32, degrees: f64) -> Terrain {
        self.tilts.insert(arc, degrees);
        self
    }

    /// A terrain drawn from `seed`: `arcs` arcs of 3 to 6 steps; about one footfall in six has a
    /// rock, one in twelve a boulder, one in twenty a ridge. The same seed gives the same terrain.
    pub fn generate(seed: u64, arcs: u32) -> Terrain {
        let mut rng = SplitMix(seed);
        let mut terrain = Terrain::default();
        for arc in 0..arcs {
            let steps = 3 + (rng.next() % 4) as u32;
            terrain.arcs.push(steps);
            terrain.tilts.insert(arc, (rng.next() % 15) as f64);
            for step in 0..steps {
                let obstacle = match rng.next() % 120 {
                    0..20 => Some(Obstacle::ROCK),
                    20..30 => Some(Obstacle::BOULDER),
                    30..36 => Some(Obstacle::RIDGE),
                    _ => None,
                };
                if let Some(o) = obstacle {
                    terrain.obstacles.insert((arc, step), o);
                }
            }
        }
        terrain
    }

    /// The number of steps of the whole walk.
    pub fn steps(&self) -> u32 {
        self.arcs.iter().sum()
    }
}

/// SplitMix64: a small deterministic generator, enough for terrain.
struct SplitMix(u64);

impl SplitMix {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
}

/// A recovery strategy, in the order they are tried.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Recovery {
    /// The leg's trajectory raised, the leg move retried (handler on the leg move).
    RaiseLeg,
    /// The step's footfall replanned, the leg move retried (handler on the step).
    Replan,
    /// The feet shuffled into the standard configuration, the leg move retried (handler on the
    /// arc).
    Shuffle,
}

/// How one footfall is to be made now.
#[derive(Clone, Copy, Debug, Default)]
struct Footfall {
    alternate: bool,
    shuffled: bool,
}

#[derive(Debug, Default)]
struct State {
    terrain: Terrain,
    footfalls: BTreeMap<(u32, u32), Footfall>,
    /// The steps whose body moved, the last step of the walk done.
    done: Vec<(u32, u32)>,
    planned: Vec<(u32, u32)>,
    leg_moves: u32,
    lifts_mm: Vec<(u32, u32, u32)>,
    body_moves: u32,
    contacts: Vec<(u32, u32)>,
    recoveries: Vec<(u32, u32, Recovery)>,
    stability_checks: u32,
    footfall_checks: u32,
}

/// The walker: the terrain and what the walk did so far. Cheap to clone (shared state).
#[derive(Clone, Debug, Default)]
pub struct Walker {
    state: Arc<Mutex<State>>,
}

impl Walker {
    /// A walker at the start of `terrain`.
    pub fn new(terrain: Terrain) -> Walker {
        Walker {
            state: Arc::new(Mutex::new(State {
                terrain,
                ..State::default()
            })),
        }
    }

    fn state(&self) -> MutexGuard<'_, State> {
        // Plain data changed in non-panicking steps: a poisoned lock still guards it.
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// The number of arcs to walk.
    pub fn arcs(&self) -> u32 {
        self.state().terrain.arcs.len() as u32
    }

    /// Plans `arc`: its number of steps (0 for an arc the terrain does not have).
    pub fn plan_arc(&self, arc: u32) -> u32 {
        let st = self.state();
        st.terrain.arcs.get(arc as usize).copied().unwrap_or(0)
    }

    /// Plans a step: the footfall starts at the planned foothold with the nominal lift.
    pub fn plan_step(&self, arc: u32, step: u32) {
        let mut st = self.state();
        st.planned.push((arc, step));
        st.footfalls.insert((arc, step), Footfall::default());
    }

    /// Swings the leg of `step` of `arc` to its footfall on a trajectory `lift` metres high (the
    /// feet in the standard configuration lift it higher): `Some(height)` of the obstacle it hit,
    /// `None` when the foot landed.
    pub fn swing_leg(&self, arc: u32, step: u32, lift: f64) -> Option<f64> {
        let mut st = self.state();
        st.leg_moves += 1;
        // Whole millimetres: the log compares exactly.
        st.lifts_mm
            .push((arc, step, (lift * 1000.0).round() as u32));
        let f = st.footfalls.get(&(arc, step)).copied().unwrap_or_default();
        let obstacle = st.terrain.obstacles.get(&(arc, step)).copied()?;
        let height = if f.alternate {
            obstacle.alternate
        } else {
            obstacle.primary
        };
        let lift = if f.shuffled {
            SHUFFLED_LIFT.max(lift)
        } else {
            lift
        };
        if height > lift {
            st.contacts.push((arc, step));
            Some(height)
        } else {
            None
        }
    }

    /// Moves the body over the feet of `step` of `arc`.
    pub fn move_body(&self, arc: u32, step: u32) {
        let mut st = self.state();
        st.body_moves += 1;
        st.done.push((arc, step));
    }

    /// Recovery 1: the leg's trajectory for `step` of `arc` is raised (the retried leg move gets
    /// [`RAISED_LIFT`] as its argument); this records it.
    pub fn raise_leg(&self, arc: u32, step: u32) {
        self.recover(arc, step, Recovery::RaiseLeg, |_| {});
    }

    /// Recovery 2: replans the step's footfall onto the alternate foothold.
    pub fn replan_footfall(&self, arc: u32, step: u32) {
        self.recover(arc, step, Recovery::Replan, |f| f.alternate = true);
    }

    /// Recovery 3: the feet are in the standard configuration, from which the leg lifts highest.
    pub fn shuffle_feet(&self, arc: u32, step: u32) {
        self.recover(arc, step, Recovery::Shuffle, |f| f.shuffled = true);
    }

    fn recover(&self, arc: u32, step: u32, how: Recovery, change: impl FnOnce(&mut Footfall)) {
        let mut st = self.state();
        st.recoveries.push((arc, step, how));
        change(st.footfalls.entry((arc, step)).or_default());
    }

    /// The stability monitor (a wiretap before every leg and body move, reading the tapped move's
    /// arc and step from its arguments): fails with `Unstable` when the ground under the move is
    /// steeper than [`MAX_TILT`].
    pub fn check_stability(&self, arc: u32, step: u32) -> Result<(), Failure> {
        let mut st = self.state();
        st.stability_checks += 1;
        let tilt = st.terrain.tilts.get(&arc).copied().unwrap_or(0.0);
        if tilt > MAX_TILT {
            return Err(Failure::new(
                "Unstable",
                format!("step {step} of arc {arc}: the ground tilts {tilt} degrees"),
            ));
        }
        Ok(())
    }

    /// The footfall monitor (a wiretap after every leg move that landed, reading the move's arc and
    /// step from its arguments): the foot's force sensors must show it on a foothold the walker
    /// planned.
    pub fn check_footfall(&self, arc: u32, step: u32) -> Result<(), Failure> {
        let mut st = self.state();
        st.footfall_checks += 1;
        match st.footfalls.contains_key(&(arc, step)) {
            true => Ok(()),
            false => Err(Failure::new(
                "BadFoothold",
                "a foot landed off any planned foothold",
            )),
        }
    }

    /// What the walk did so far.
    pub fn log(&self) -> WalkLog {
        let st = self.state();
        WalkLog {
            planned: st.planned.clone(),
            leg_moves: st.leg_moves,
            lifts_mm: st.lifts_mm.clone(),
            body_moves: st.body_moves,
            contacts: st.contacts.clone(),
            recoveries: st.recoveries.clone(),
            stability_checks: st.stability_checks,
            footfall_checks: st.footfall_checks,
        }
    }
}

/// What a walk did, read from the walker.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct WalkLog {
    /// The steps planned, (arc, step), in order.
    pub planned: Vec<(u32, u32)>,
    /// Leg moves attempted (retries included).
    pub leg_moves: u32,
    /// Each leg move's (arc, step, trajectory height in millimetres), in order.
    pub lifts_mm: Vec<(u32, u32, u32)>,
    /// Body moves made.
    pub body_moves: u32,
    /// The leg moves that hit an obstacle, (arc, step).
    pub contacts: Vec<(u32, u32)>,
    /// The recoveries used, in order.
    pub recoveries: Vec<(u32, u32, Recovery)>,
    /// Checks made by the stability monitor.
    pub stability_checks: u32,
    /// Checks made by the footfall monitor.
    pub footfall_checks: u32,
}
