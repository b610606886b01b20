//! Compiles the `.tdl` files the integration tests include (`tests/data/*.tdl`) through
//! `tdl-build`, exactly as a user's build script would.

fn main() {
    tdl_build::compile("tests/data/patrol.tdl");
}
