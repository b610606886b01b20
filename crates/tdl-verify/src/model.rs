//! The hook that replaces the checker's choices for a command by a model the user writes in Rust.
//!
//! By default a command is a choice: it may succeed, fail with each exception it may raise, or run
//! until it is terminated, ending at any time within the duration bound. A [`CommandModel`] says
//! instead, per command and arguments, which endings are possible and after how long; the checker
//! then explores only those, each ending exactly when its duration has passed (a world simulation
//! such as `xavier-world` could answer from its map).

use std::time::Duration;

/// A command's argument as the checker knows it: a literal it could evaluate, or unknown.
#[derive(Clone, Debug, PartialEq)]
pub enum Arg {
    /// Not known to the checker.
    Unknown,
    /// An integer.
    Int(i64),
    /// A boolean.
    Bool(bool),
    /// A string.
    Str(String),
    /// A floating-point number.
    Float(f64),
}

/// One way a modelled command may end.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub enum Ending {
    /// It succeeds after this long.
    Succeeds(Duration),
    /// It fails with the exception of this name after this long.
    Fails(String, Duration),
    /// It runs until it is terminated.
    Never,
}

impl Ending {
    /// How long it runs.
    pub fn after(&self) -> Duration {
        match self {
            Ending::Succeeds(d) | Ending::Fails(_, d) => *d,
            Ending::Never => Duration::MAX,
        }
    }
}

/// A model of the program's commands (and of the tasks written in Rust it spawns).
pub trait CommandModel: Send + Sync {
    /// The ways the command `task`, called with `args`, may end; `None` leaves it to the
    /// checker's choices.
    fn endings(&self, task: &str, args: &[Arg]) -> Option<Vec<Ending>>;
}
