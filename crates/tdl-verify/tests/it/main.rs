//! `tdl-verify` on the Xavier mission and on copies of it with one seeded bug each
//! (`test_data/`): each bug is found, with a counterexample as short as any (breadth-first), a
//! trace the trace checker accepts and `tdl trace story` can replay; the mission itself passes.
//!
//! The bounds are smaller than the defaults (one loop iteration where two are not needed, no
//! command left running forever, no command outlasting a deadline) so that the tests run in
//! seconds in a debug build; `docs/verification.md` has the run with the default bounds.

mod agents;
mod approvals;
mod mission;
mod sim;
mod state;
mod status;
