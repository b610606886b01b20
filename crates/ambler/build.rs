//! Compiles the two TDL files into `$OUT_DIR/terrain.rs` and `$OUT_DIR/walk.rs`; `src/lib.rs`
//! includes them. `terrain.tdl` declares the exception and the leg and terrain commands,
//! `walk.tdl` the walking goals and the recovery handlers, which name them.

fn main() {
    tdl_build::compile("src/terrain.tdl");
    tdl_build::compile("src/walk.tdl");
}
