//! Helpers: the runtime's testing module (run with a recorder, check the trace, stories).

pub(crate) use tdl::testing::{assert_order, only, run_checked, story};
