//! Compiles the `.tdl` files the integration tests include (`tests/data/*.tdl`) through
//! `tdl-build`, exactly as a user's build script would: the patrol program is two files.

fn main() {
    tdl_build::compile_all(["tests/data/patrol.tdl", "tests/data/patrol_faults.tdl"]);
}
