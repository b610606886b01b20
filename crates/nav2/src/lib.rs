//! Nav2's navigate-to-pose with replanning and recovery (the behaviour of its default navigation
//! tree), written in TDL with the recovery patterns of `tdl::patterns`, against simulated
//! planner, controller and recovery servers on virtual time.
//!
//! - `src/navigate.tdl`: the navigation (its header comment draws the task tree).
//! - [`servers`]: the simulated servers and the world they share, with scripted faults.
//!
//! ```
//! use nav2::servers::Nav;
//!
//! let nav = Nav::new(5.0);
//! let report = tdl::block_on_virtual(tdl::Runtime::new().run(nav2::navigate_to_pose(nav.clone(), nav.recoveries())))?;
//! assert_eq!(report.outcome, tdl::RunOutcome::Completed);
//! assert!(nav.log().iter().any(|e| e.what == "reached 5.0"));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![deny(warnings)]

pub mod servers;

/// Generated from `src/navigate.tdl`.
mod navigate {
    use crate::servers::*;
    use tdl::Ended;
    use tdl::patterns::{InTurn, Recovered};
    include!(concat!(env!("OUT_DIR"), "/navigate.rs"));
}

pub use navigate::*;
