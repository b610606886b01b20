//! Compiles `src/day.tdl` into `$OUT_DIR/day.rs`, which `src/lib.rs` includes.

fn main() {
    tdl_build::compile_all(["src/day.tdl"]);
}
