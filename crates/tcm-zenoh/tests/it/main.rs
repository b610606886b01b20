//! Integration tests of distributed task trees: an executive and its agents on 127.0.0.1 (peer
//! mode, multicast scouting off), in one process with a zenoh session each, or with an agent in a
//! process of its own. Every test is bounded in time, and every run's trace is checked.

mod adversary;
mod agent_loss;
mod bounds;
mod exactly_once;
mod exceptions;
mod forgery;
mod goals;
mod identity;
mod python;
mod reach;
mod remote_command;
mod repeats;
mod resume;
mod state;
mod suspension;
mod tdl;
mod termination;
mod timeouts;
mod tls;
mod typed;
mod util;
