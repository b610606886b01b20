//! The Ambler walking rover of the TCA paper (its Figure 1) in TDL, walking simulated terrain on
//! virtual time.
//!
//! - `src/terrain.tdl`: the `TerrainContact` exception and the leg and terrain commands.
//! - `src/walk.tdl`: the walking goals (arcs, steps planned one ahead of execution) and the three
//!   recoveries from a terrain contact.
//! - [`world`]: the terrain (from a seed) and the walker's shared state.
//! - [`monitored`]: a runtime with the stability and footfall monitors wiretapped on the moves,
//!   from outside the task code.
//!
//! ```
//! use ambler::world::{Terrain, Walker};
//!
//! let walker = Walker::new(Terrain::flat(1, 3));
//! let report = tdl::block_on_virtual(ambler::monitored(&walker).run(ambler::walk(walker.clone())))?;
//! assert_eq!(report.outcome, tdl::RunOutcome::Completed);
//! assert_eq!(walker.log().body_moves, 3);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![deny(warnings)]

pub mod world;

use tdl::{Ctx, Failure, Runtime, TapWhen};
use world::Walker;

/// Generated from `src/terrain.tdl`.
mod terrain {
    use crate::world::*;
    include!(concat!(env!("OUT_DIR"), "/terrain.rs"));
}

/// Generated from `src/walk.tdl`.
mod walk {
    use crate::terrain::*;
    use crate::world::*;
    include!(concat!(env!("OUT_DIR"), "/walk.rs"));
}

pub use terrain::*;
pub use walk::*;

/// A runtime with the Ambler's execution monitors wiretapped on the moves (TCA's wiretaps: added
/// from outside, the task code does not know them): the stability monitor before every leg and
/// body move, the footfall monitor after every leg move; and the arc-level recovery
/// ([`shuffle_and_retry`]) attached to every arc, likewise from outside.
pub fn monitored(_walker: &Walker) -> Runtime {
    // A check reads the tapped move's arguments, `(w, arc, step[, lift])` (TCA's monitors saw the
    // message's data); the moves run in order, but the check need not guess which step is next.
    let unknown = || Err(Failure::new("Unstable", "a move without its arguments"));
    Runtime::new()
        .attach(shuffle_and_retry())
        .wiretap("move_leg", TapWhen::Before, move |ctx: Ctx| async move {
            match ctx.tapped_args::<(Walker, u32, u32, f64)>() {
                Some(args) => args.0.check_stability(args.1, args.2),
                None => unknown(),
            }
        })
        .wiretap("move_body", TapWhen::Before, move |ctx: Ctx| async move {
            match ctx.tapped_args::<(Walker, u32, u32)>() {
                Some(args) => args.0.check_stability(args.1, args.2),
                None => unknown(),
            }
        })
        .wiretap("move_leg", TapWhen::After, |ctx: Ctx| async move {
            match ctx.tapped_args::<(Walker, u32, u32, f64)>() {
                Some(args) => {
                    let (w, arc, step, _) = &*args;
                    w.check_footfall(*arc, *step)
                }
                None => Err(Failure::new(
                    "BadFoothold",
                    "a leg move without its arguments",
                )),
            }
        })
}
