//! The lander's world: what its camera and arm do, and the telemetry the outside sends.

use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;
use tdl::{EventHandle, StateValue};

/// The world the lander's commands act on: the range its camera finds, how each try at clearing
/// the arm goes, and what the commands noted.
#[derive(Clone, Debug, Default)]
pub struct World(Arc<Mutex<Inner>>);

#[derive(Debug, Default)]
struct Inner {
    range: Option<f64>,
    resets: Vec<(u64, bool)>,
    notes: Vec<String>,
}

impl World {
    /// A world whose camera finds `range` (or nothing), and whose arm resets go as `resets`
    /// says, in order: how many seconds each takes and whether it clears the fault.
    pub fn new(range: Option<f64>, resets: Vec<(u64, bool)>) -> World {
        World(Arc::new(Mutex::new(Inner {
            range,
            resets,
            notes: Vec::new(),
        })))
    }

    fn with<T>(&self, f: impl FnOnce(&mut Inner) -> T) -> T {
        f(&mut self.0.lock().unwrap_or_else(PoisonError::into_inner))
    }

    /// What the camera ranges.
    pub fn range(&self) -> Option<f64> {
        self.with(|w| w.range)
    }

    /// The next try at clearing the arm: its duration and whether it works (a quick success once
    /// the script is used up).
    pub fn reset(&self) -> (u64, bool) {
        self.with(|w| {
            if w.resets.is_empty() {
                (1, true)
            } else {
                w.resets.remove(0)
            }
        })
    }

    /// Notes what happened, for the tests.
    pub fn note(&self, what: &str) {
        self.with(|w| w.notes.push(what.to_string()));
    }

    /// What the commands and monitors noted, in order.
    pub fn notes(&self) -> Vec<String> {
        self.with(|w| w.notes.clone())
    }
}

/// Telemetry from outside the plan: at each time (seconds from the start), a state variable takes
/// a value.
#[derive(Clone, Debug, Default)]
pub struct Telemetry(Vec<(u64, &'static str, StateValue)>);

impl Telemetry {
    /// None: nothing changes by itself.
    pub fn none() -> Telemetry {
        Telemetry::default()
    }

    /// Adds `var = value` at `secs`.
    pub fn at(mut self, secs: u64, var: &'static str, value: impl Into<StateValue>) -> Telemetry {
        self.0.push((secs, var, value.into()));
        self
    }

    /// Plays it on the run's clock through `events`, from a task of its own.
    pub fn play(self, events: EventHandle) -> tokio::task::JoinHandle<()> {
        let mut script = self.0;
        script.sort_by_key(|s| s.0);
        tokio::spawn(async move {
            let start = tokio::time::Instant::now();
            for (secs, var, value) in script {
                tokio::time::sleep_until(start + Duration::from_secs(secs)).await;
                if let Err(e) = events.set_state(var, value) {
                    panic!("telemetry {var}: {e}");
                }
            }
        })
    }
}
