//! Compiles `src/navigate.tdl` into `$OUT_DIR/navigate.rs`; `src/lib.rs` includes it.

fn main() {
    tdl_build::compile("src/navigate.tdl");
}
