//! Helpers: the runtime's own testing module (run with a recorder, check, story).

pub(crate) use tcm::testing::{assert_order, only, run_checked, story};
