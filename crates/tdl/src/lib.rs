//! TDL for Rust: task-level control of robots after Simmons & Apfelbaum's Task Description
//! Language (1998). This is the crate users depend on.
//!
//! - [`tdl!`] compiles TDL task definitions (`goal`, `command`, `monitor`, `handler`,
//!   `exception`, `spawn ... with ...`, `with (...) { ... }` groups, constraint statements,
//!   `bind`, `node!(tag)`, `fail`, `trigger`, `bypass`, `retry`) into Rust items: per task a
//!   struct with its arguments and a constructor function returning a [`Task`] (a [`Handler`] for
//!   handlers). Generated bodies hold their children until they end or wait, as in TDL.
//! - Everything else is the `tcm` runtime, re-exported: [`Runtime`] runs a task tree, [`Ctx`] is
//!   what a body sees, [`Constraint`] and friends are what the generated code builds,
//!   [`block_on_virtual`] runs a simulation on virtual time, and [`tokio`] is the tokio it all
//!   runs on. A program depends on `tdl` alone: bodies write `tdl::tokio::time::sleep(..)`, and
//!   tests `#[tdl::tokio::test(crate = "tdl::tokio", start_paused = true)]`.
//! - `.tdl` files can also be compiled from `build.rs` with the `tdl-build` crate, and checked or
//!   expanded with the `tdl` command-line tool.
//!
//! ```
//! tdl::tdl! {
//!     command beep() {
//!         tdl::tokio::time::sleep(std::time::Duration::from_millis(10)).await;
//!     }
//!     goal beep_twice() {
//!         spawn beep();
//!         spawn beep() with sequential execution previous;
//!     }
//! }
//! # let report = tdl::block_on_virtual(tdl::Runtime::new().run(beep_twice())).unwrap();
//! # assert_eq!(report.outcome, tdl::RunOutcome::Completed);
//! ```
//!
//! The language reference and the mapping of each construct to `tcm` are in
//! `docs/language.md`.

#![warn(missing_docs)]

extern crate self as tdl;

pub use tcm::*;
pub use tdl_macros::tdl;

mod caught;
#[doc(hidden)]
pub mod codegen;
mod show;

pub use caught::Caught;
pub use show::{SHOWN_ITEMS, ShowArg};

/// The runtime crate, for paths the re-exports do not cover.
pub use tcm;
