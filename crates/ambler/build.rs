//! Compiles the two TDL files, as one program, into `$OUT_DIR/terrain.rs` and `$OUT_DIR/walk.rs`;
//! `src/lib.rs` includes them. `terrain.tdl` declares the exception and the leg and terrain
//! commands, `walk.tdl` the walking goals and the recovery handlers, which name them: a name
//! misspelt in one file is an error here, not a handler that never fires.

fn main() {
    tdl_build::compile_all(["src/terrain.tdl", "src/walk.tdl"]);
}
