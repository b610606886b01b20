//! A serving executive (docs/distributed.md, "A serving executive"): a long-lived process that
//! holds TDL programs loaded at run time and runs their tasks, each run with its own trace, while
//! clients load new programs and versions, start, stop and raise events in runs, and add recovery
//! (handlers declared `for` a task) to the runs under way, as TCA's modules extended a running
//! system.
//!
//! - [`Server`]: the programs, the runs and the operations on them (its module gives the rules).
//! - [`serve`]: answers [`Request`]s over zenoh, on `tdl/<system>/serve/<executive>/<client>`.
//! - [`Client`]: sends them (`tdl load`, `tdl start`, `tdl stop`, `tdl status`, `tdl raise`).
//! - [`register_offers`]: the agents' tasks registered for a program (shared with `tdl run`);
//!   [`outside`] and [`default_task`] (from `tdl_interp`): what it needs from agents, and which
//!   task runs by default.
#![warn(missing_docs)]

mod program;
pub mod proto;
mod serve;
mod server;

pub use program::register_offers;
pub use proto::{File, ProgramInfo, Reply, Request, Response, RunInfo, Swap, Verify};
pub use serve::{Client, DEFAULT_TIMEOUT, Serving, serve};
pub use server::Server;
pub use tdl_interp::{default_task, outside};

/// Errors of serving and of clients (a refused request is a [`Response::Refused`], not an error).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// Zenoh failed.
    #[error("zenoh: {0}")]
    Zenoh(String),
    /// A message did not read.
    #[error("protocol: {0}")]
    Protocol(String),
    /// No executive answered.
    #[error(
        "no executive `{executive}` of system `{system}` answered within {waited:?}: is `tdl serve` running there, and may this client speak to it?"
    )]
    NoAnswer {
        /// The executive asked.
        executive: String,
        /// Its system.
        system: String,
        /// How long the client waited.
        waited: std::time::Duration,
    },
    /// A client name that cannot be a key segment.
    #[error("`{0}` cannot name a client: use letters, digits, `-` and `_`")]
    Name(String),
}
