//! Compiles the mission, `src/mission.tdl`, into `$OUT_DIR/mission.rs` with `tdl-build`; `src/mission.rs`
//! includes it.

fn main() {
    tdl_build::compile("src/mission.tdl");
}
