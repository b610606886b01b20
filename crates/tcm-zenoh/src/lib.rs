//! Distributed task trees over zenoh, built on the public `tcm` API (docs/distributed.md).
//!
//! A system is a set of processes that share a name (the key prefix `tdl/<system>/`). The
//! [`Executive`] owns the one task tree, and so the one trace. An [`Agent`] joins the system and
//! offers tasks by name, holding a liveliness token `tdl/<system>/agents/<agent>` (and one per
//! offered task). A remote task ([`Executive::remote`]) is a node of the executive's tree whose
//! action an agent carries out: its constraints, waits, termination and handlers are the tree's,
//! as for any node. Its value comes back as JSON and its failure typed, so handler search by type
//! works across processes; terminating it cancels the body on the agent, which runs its cleanup
//! and confirms; a remote goal's body spawns children in the tree through calls to the executive.
//!
//! Every message carries its task's id and a sequence number: each is applied once, in order
//! (numbered one more than the last of its task and direction), and duplicates, messages out of
//! order and late messages are counted ([`Stats`], [`AgentStats`]) and logged through `tracing`;
//! a `cancelled` the executive never asked for fails the node with [`RemoteCancelled`]. A lost
//! agent (its token deleted: its process died, or its link broke) fails each task it ran with
//! [`AgentLost`] as soon as the executive sees it; timeouts in the style of durable workflows
//! (schedule-to-start, start-to-close, heartbeat; [`RemoteOptions`]) fail it with
//! [`RemoteTimeout`]. Nothing waits silently for ever.
//!
//! Executives and agents need a multi-thread tokio runtime (zenoh does not support tokio's
//! current-thread scheduler), and so run on real time.
//!
//! ```no_run
//! # async fn demo() -> Result<(), Box<dyn std::error::Error>> {
//! use tcm_zenoh::{Agent, At, Executive, RemoteCtx, RemoteFailure};
//! let (exec, port) = Executive::open_loopback("robot").await?;
//! let _arm = Agent::builder("robot", "arm")
//!     .command("grasp", |_ctx: RemoteCtx, force: f64| async move {
//!         Ok::<_, RemoteFailure>(force > 0.0)
//!     })
//!     .start(tcm_zenoh::config::loopback_connect(port)?)
//!     .await?;
//! exec.wait_for("arm", Some("grasp"), std::time::Duration::from_secs(5)).await?;
//! let report = tcm::Runtime::new().run(exec.remote(At::agent("arm"), "grasp", 2.0).task()).await?;
//! assert_eq!(report.outcome, tcm::RunOutcome::Completed);
//! # Ok(())
//! # }
//! ```
#![warn(missing_docs)]

mod agent;
mod body;
pub mod config;
mod executive;
mod failure;
mod noise;
mod remote;
mod sequence;
mod wire;

pub use agent::{Agent, AgentBuilder, AgentStats, Limits};
pub use body::{Child, ChildId, RemoteCtx, RemoteSpawn};
pub use executive::{Executive, Placement};
pub use failure::{
    AgentLost, RemoteCancelled, RemoteError, RemoteFailure, RemoteRefused, RemoteTimeout,
    TimeoutKind, caught,
};
pub use remote::{At, Remote, RemoteOptions};
pub use wire::{ChildEnded, ChildRef, Json, Kind};

/// For the fuzz target (`fuzz/fuzz_targets/wire.rs`) only, with the feature `fuzzing`: the
/// decoders the executive and the agents read messages with, and the rule they number them by.
/// Not a stable API.
#[cfg(feature = "fuzzing")]
#[doc(hidden)]
pub mod fuzzing {
    pub use crate::sequence::{Known, Verdict, start_verdict, verdict};

    /// A message to an executive as it reads it: its task, number and kind, and whether it ends
    /// the task (`done`, `cancelled`), encoded again; `None` when it does not read.
    pub fn decode_to_exec(bytes: &[u8]) -> Option<(u64, u64, &'static str, bool, Vec<u8>)> {
        let m = crate::wire::decode_to_exec(bytes).ok()?;
        let ends = matches!(
            m.body,
            crate::wire::ToExec::Done { .. } | crate::wire::ToExec::Cancelled
        );
        Some((m.task, m.seq, m.body.name(), ends, m.encode()))
    }

    /// A message to an agent as it reads it: its task, number and kind, encoded again; `None`
    /// when it does not read.
    pub fn decode_to_agent(bytes: &[u8]) -> Option<(u64, u64, &'static str, Vec<u8>)> {
        let m = crate::wire::decode_to_agent(bytes).ok()?;
        Some((m.task, m.seq, m.body.name(), m.encode()))
    }
}

/// Sends the log of `tracing` (this crate's warnings: messages ignored or refused, a peer not
/// reached) to stderr, filtered by `RUST_LOG`, `warn` by default: for a program that runs an
/// executive or an agent. Does nothing when the process has a subscriber already.
pub fn log_to_stderr() {
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn"));
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(false)
        .try_init();
}

/// Errors of the distribution layer's API (a remote task's own failures are `tcm` failures).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// Zenoh refused: a bad configuration, a session that cannot open, a declaration that failed.
    #[error("zenoh: {0}")]
    Zenoh(String),
    /// A system, agent or task name that cannot be one chunk of a key expression (use ASCII
    /// letters, digits, `_`, `-`, `.`).
    #[error("bad name {0:?}: use ASCII letters, digits, `_`, `-` and `.`")]
    BadName(String),
    /// Something awaited did not happen in time.
    #[error("timed out: {0}")]
    Timeout(String),
}

impl Error {
    pub(crate) fn zenoh(e: impl std::fmt::Display) -> Error {
        Error::Zenoh(e.to_string())
    }
}

/// How long a sender waits for the first subscriber of a key it publishes to: a subscriber's
/// declaration follows its peer's token within milliseconds on a working link; well under the
/// default schedule-to-start (10 s), so that a start held for the whole wait is still in time.
const REACH: std::time::Duration = std::time::Duration::from_secs(3);

/// Waits until this session knows a subscriber matching `publisher`'s key, at most [`REACH`];
/// whether it does. Zenoh drops a publication that matches no subscriber the session knows of,
/// and a peer's liveliness token can reach a session before its subscriber's declaration
/// (docs/distributed.md, "Messages"): the first message to a peer waits for this.
pub(crate) async fn matched(publisher: &zenoh::pubsub::Publisher<'_>) -> Result<bool, Error> {
    let now = || async {
        publisher
            .matching_status()
            .await
            .map(|s| s.matching())
            .map_err(Error::zenoh)
    };
    if now().await? {
        return Ok(true);
    }
    let listener = publisher.matching_listener().await.map_err(Error::zenoh)?;
    // A declaration may have come between the first look and the listener.
    if now().await? {
        return Ok(true);
    }
    let wait = async {
        while let Ok(status) = listener.recv_async().await {
            if status.matching() {
                return true;
            }
        }
        false
    };
    Ok(tokio::time::timeout(REACH, wait).await.unwrap_or(false))
}

/// The counters of an executive.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Stats {
    /// Remote tasks placed on an agent (a start sent).
    pub placed: u64,
    /// Remote tasks whose body returned a value.
    pub succeeded: u64,
    /// Remote tasks whose body failed.
    pub failed: u64,
    /// Cancels sent to agents (a node terminated, or its action dropped).
    pub cancels: u64,
    /// Cancels the agent confirmed.
    pub cancelled: u64,
    /// Remote tasks failed with `AgentLost`.
    pub agent_lost: u64,
    /// Remote tasks failed with `RemoteTimeout`.
    pub timeouts: u64,
    /// Messages received twice, ignored.
    pub duplicates: u64,
    /// Messages of a running task numbered past the next one expected (a gap, a forged
    /// sequence number), refused.
    pub refused: u64,
    /// Messages of a task that had ended (or that this executive never had), ignored.
    pub late: u64,
    /// Messages that could not be read, ignored.
    pub malformed: u64,
    /// Messages about a task from another agent than the one it was placed on, refused.
    pub strangers: u64,
}
