//! Integration tests of the `tcm` runtime: story tests on virtual time, each checked by the trace
//! checker, plus a few real-time tests of true concurrency.

#[path = "../../examples/paper/fig4.rs"]
mod fig4;

mod activation_data;
mod beside;
mod blocking;
mod callbacks;
mod cancel;
mod control;
mod determinism;
mod exceptions;
mod held_children;
mod introspection;
mod journal;
mod loud;
mod monitors;
mod now;
mod panics;
mod paper;
mod patterns;
mod replay;
mod resources;
mod runtime;
mod session;
mod state;
mod steering;
mod stuck;
mod util;
