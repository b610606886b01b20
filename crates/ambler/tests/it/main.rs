//! The Ambler's walk on virtual time, checked by the trace checker (`tdl::testing::run_checked`),
//! and asserted on its trace.

mod interpreted;
mod recovery;
mod util;
mod walking;
