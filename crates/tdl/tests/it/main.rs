//! The one integration-test binary of `tdl` (house style: `tests/it/main.rs`): TDL programs
//! written with `tdl!` (or compiled from `.tdl` files by `tdl-build`) run on virtual time, and
//! each test asserts on the trace, which the trace checker also validates.

mod args_shown;
mod blocking;
mod build;
mod by_value;
mod entities;
mod exceptions;
mod external;
mod facade;
mod groups;
mod logging;
mod loops;
mod monitor_limits;
mod monitors;
mod node_refs;
mod on_terminate;
mod outcomes;
mod paper;
mod patterns;
mod placement;
mod porting;
mod propagation;
mod refs;
mod resources;
mod state;
mod ui;
mod util;
mod warnings;
