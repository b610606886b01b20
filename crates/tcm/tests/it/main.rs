//! Integration tests of the `tcm` runtime: story tests on virtual time, each checked by the trace
//! checker, plus a few real-time tests of true concurrency.

#[path = "../../examples/paper/fig4.rs"]
mod fig4;

mod exceptions;
mod monitors;
mod paper;
mod runtime;
mod util;
