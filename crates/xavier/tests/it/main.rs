//! Integration tests of the xavier crate: the mission on every scenario with fixed seeds on
//! virtual time, asserted on the trace, and the `xavier` binary.

mod binary;
mod crash;
mod distributed;
mod interpreted;
mod scenarios;
mod served;
mod steer;
mod util;
mod viewer;
mod watched;
