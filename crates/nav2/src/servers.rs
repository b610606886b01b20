//! The simulated servers (planner, controller, recoveries) and the world they share: a robot on a
//! line, a goal, the latest path, and scripted faults. Every server takes virtual time (tokio's
//! clock), so a run is the same every time.
//!
//! - The planner takes [`PLANNING`] and returns a path to the current goal (numbered from 1).
//! - The controller follows the latest path at [`SPEED`], in steps of [`TICK`], taking up a new
//!   path at its next step; it succeeds when the robot is at the path's goal.
//! - A recovery takes its own time ([`Nav::recovery`]) and succeeds unless made to fail.
//! - Faults are scripted: the next runs of the planner or the controller fail with the given
//!   errors, in order ([`Nav::fail_planner`], [`Nav::fail_controller`]); a failing controller run
//!   is blocked (the robot does not move) and fails after [`FOLLOWED_BEFORE_FAILING`].

use crate::{back_up, clearing_actions, spin, wait_a_while};
use std::collections::{HashSet, VecDeque};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Duration;
use tdl::patterns::{InTurn, Preemption};
use tdl::tokio::sync::watch;
use tdl::tokio::time::{Instant, sleep};
use tdl::{Ended, Failure, Task};

/// Time to compute a path.
pub const PLANNING: Duration = Duration::from_millis(100);
/// The controller's step.
pub const TICK: Duration = Duration::from_millis(100);
/// The robot's speed (metres per second).
pub const SPEED: f64 = 1.0;
/// How long a controller run that is scripted to fail follows before it fails.
pub const FOLLOWED_BEFORE_FAILING: Duration = Duration::from_secs(2);

/// Why a server failed, as Nav2's error codes say it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NavError {
    /// Planner: no path to the goal (a cleared costmap may open one).
    NoValidPath,
    /// Planner: the goal is outside the map (nothing recovers that).
    GoalOutsideMap,
    /// Controller: the robot does not move (an obstacle a recovery may clear).
    FailedToMakeProgress,
    /// Controller: blocked for too long.
    PatienceExceeded,
    /// Controller: the path cannot be followed (nothing recovers that).
    InvalidPath,
}

impl NavError {
    /// Would a recovery help (Nav2's `WouldAPlannerRecoveryHelp`, `WouldAControllerRecoveryHelp`)?
    pub fn recovery_helps(self) -> bool {
        matches!(
            self,
            NavError::NoValidPath | NavError::FailedToMakeProgress | NavError::PatienceExceeded
        )
    }
}

/// Which costmap to clear.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Costmap {
    /// The controller's.
    Local,
    /// The planner's.
    Global,
}

impl Costmap {
    /// The recovery's name in the log.
    pub fn name(self) -> &'static str {
        match self {
            Costmap::Local => "clear_local",
            Costmap::Global => "clear_global",
        }
    }
}

/// A path from the planner.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Path {
    /// Its number: the planner's runs that succeeded, from 1.
    pub number: u32,
    /// Where it leads.
    pub goal: f64,
}

/// One line of the world's log.
#[derive(Clone, Debug, PartialEq)]
pub struct Entry {
    /// Virtual time since the first server call.
    pub at: Duration,
    /// What happened: `plan N to G`, `follow`, `following path N`, `reached G`, `controller
    /// failed E`, `planner failed E`, `recovery NAME`, `recovery NAME failed`, `goal G`,
    /// `navigation succeeded|failed E|terminated`.
    pub what: String,
}

#[derive(Default)]
struct World {
    start: Option<Instant>,
    goal: f64,
    position: f64,
    plans: u32,
    planner_faults: VecDeque<NavError>,
    controller_faults: VecDeque<NavError>,
    failing_recoveries: HashSet<&'static str>,
    log: Vec<Entry>,
}

impl World {
    fn note(&mut self, what: String) {
        let start = *self.start.get_or_insert_with(Instant::now);
        self.log.push(Entry {
            at: Instant::now() - start,
            what,
        });
    }
}

/// The world shared by the tasks: cloning shares it.
#[derive(Clone)]
pub struct Nav {
    world: Arc<Mutex<World>>,
    path: Arc<watch::Sender<Option<Path>>>,
    preemption: Preemption,
}

impl Nav {
    /// A robot at 0 with its goal at `goal` (metres).
    pub fn new(goal: f64) -> Nav {
        Nav {
            world: Arc::new(Mutex::new(World {
                goal,
                ..World::default()
            })),
            path: Arc::new(watch::Sender::new(None)),
            preemption: Preemption::new("goal_updated"),
        }
    }

    fn world(&self) -> MutexGuard<'_, World> {
        self.world.lock().unwrap_or_else(PoisonError::into_inner)
    }

    fn note(&self, what: String) {
        self.world().note(what);
    }

    /// The recoveries, in turn: clear both costmaps, spin, wait, back up; a new goal
    /// ([`Nav::new_goal`]) ends the one running.
    pub fn recoveries(&self) -> InTurn {
        let nav = self.clone();
        self.recoveries_with(move |i| match i {
            0 => clearing_actions(nav.clone()),
            1 => spin(nav.clone()),
            2 => wait_a_while(nav.clone()),
            _ => back_up(nav.clone()),
        })
    }

    /// The four recoveries, in turn, built by `make` from their place (0: clear both costmaps,
    /// 1: spin, 2: wait, 3: back up), preempted by a new goal: for the same recoveries of
    /// another build of the program (its tasks loaded at run time).
    pub fn recoveries_with(&self, make: impl Fn(usize) -> Task + Send + Sync + 'static) -> InTurn {
        InTurn::new(4, make).preempted_by(self.preemption.clone())
    }

    /// The next runs of the planner fail with `errors`, in order.
    pub fn fail_planner(&self, errors: impl IntoIterator<Item = NavError>) {
        self.world().planner_faults.extend(errors);
    }

    /// The next runs of the controller fail with `errors`, in order.
    pub fn fail_controller(&self, errors: impl IntoIterator<Item = NavError>) {
        self.world().controller_faults.extend(errors);
    }

    /// The recovery named `name` fails from now on.
    pub fn fail_recovery(&self, name: &'static str) {
        self.world().failing_recoveries.insert(name);
    }

    /// A new goal: the planner plans to it from its next run, and the recovery that runs, if any,
    /// is ended at once. `raise` raises the preemption's external event (`|n| events.raise(n)`
    /// with the run's `EventHandle`, or `|n| ctx.raise(n)` in a body).
    pub fn new_goal(
        &self,
        goal: f64,
        raise: impl FnOnce(&str) -> Result<(), tdl::Error>,
    ) -> Result<(), tdl::Error> {
        {
            let mut w = self.world();
            w.goal = goal;
            w.note(format!("goal {goal:.1}"));
        }
        self.preemption.preempt(raise)
    }

    /// The planner: a path to the current goal, after [`PLANNING`].
    pub async fn compute_path(&self) -> Result<Path, NavError> {
        sleep(PLANNING).await;
        let mut w = self.world();
        if let Some(e) = w.planner_faults.pop_front() {
            w.note(format!("planner failed {e:?}"));
            return Err(e);
        }
        w.plans += 1;
        let path = Path {
            number: w.plans,
            goal: w.goal,
        };
        w.note(format!("plan {} to {:.1}", path.number, path.goal));
        Ok(path)
    }

    /// Makes `path` the one the controller follows.
    pub fn publish(&self, path: Path) {
        self.path.send_replace(Some(path));
    }

    /// The controller: follows the latest path until the robot is at its goal, taking up each new
    /// path at its next step.
    pub async fn follow_path(&self) -> Result<(), NavError> {
        let fault = {
            let mut w = self.world();
            w.note("follow".to_owned());
            w.controller_faults.pop_front()
        };
        let mut paths = self.path.subscribe();
        let mut current = 0;
        let mut followed = Duration::ZERO;
        loop {
            let Some(path) = *paths.borrow_and_update() else {
                // No path yet: wait for the first.
                if paths.changed().await.is_err() {
                    return Err(NavError::InvalidPath);
                }
                continue;
            };
            if path.number != current {
                current = path.number;
                self.note(format!("following path {current}"));
            }
            if let Some(e) = fault.filter(|_| followed >= FOLLOWED_BEFORE_FAILING) {
                self.note(format!("controller failed {e:?}"));
                return Err(e);
            }
            // A run scripted to fail is blocked: the robot does not move.
            if fault.is_none() {
                let mut w = self.world();
                let step = SPEED * TICK.as_secs_f64();
                let left = path.goal - w.position;
                if left.abs() <= step / 2.0 {
                    w.position = path.goal;
                    w.note(format!("reached {:.1}", path.goal));
                    return Ok(());
                }
                w.position += step.min(left.abs()) * left.signum();
            }
            sleep(TICK).await;
            followed += TICK;
        }
    }

    /// A recovery: `clear_local` and `clear_global` take 200 ms, `spin` 2 s, `wait` 5 s,
    /// `back_up` 1 s.
    pub async fn recovery(&self, name: &'static str) -> Result<(), Failure> {
        self.note(format!("recovery {name}"));
        let took = match name {
            "spin" => Duration::from_secs(2),
            "wait" => Duration::from_secs(5),
            "back_up" => Duration::from_secs(1),
            _ => Duration::from_millis(200),
        };
        sleep(took).await;
        if self.world().failing_recoveries.contains(name) {
            self.note(format!("recovery {name} failed"));
            return Err(Failure::new("RecoveryFailed", format!("{name} failed")));
        }
        Ok(())
    }

    /// Logs how a navigation ended.
    pub fn finished(&self, o: &Ended<()>) {
        let what = match o {
            Ended::Succeeded(()) => "navigation succeeded".to_owned(),
            Ended::Failed(f) => format!("navigation failed {}", f.exception),
            Ended::Terminated => "navigation terminated".to_owned(),
            Ended::Skipped => "navigation skipped".to_owned(),
        };
        self.note(what);
    }

    /// Where the robot is.
    pub fn position(&self) -> f64 {
        self.world().position
    }

    /// The log so far.
    pub fn log(&self) -> Vec<Entry> {
        self.world().log.clone()
    }
}
