//! The interpreter's tests: each program is compiled with `tdl!` and loaded at run time from
//! the same text, both run on virtual time, and their traces must be the same, record for
//! record (`differential.rs`); what the subset refuses is refused with located diagnostics
//! (`refused.rs`).

mod budget;
mod differential;
mod refused;
mod util;
mod versions;
