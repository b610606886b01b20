//! Integration tests of the simulated world and its commands: small `tcm` programs on virtual time
//! that plan, drive, centre on doors and deliver mail, each checked by the trace checker.

mod mission;
mod util;
