//! The one integration-test binary of `tdl-syntax` (house style: `tests/it/main.rs`).
//!
//! `data` runs the parser over `test_data/{ok,err}/*.tdl` and snapshots the tree or the
//! diagnostics beside each file; `props` feeds random token streams to the front end; `api`
//! checks the public entry points and the diagnostic rendering.

mod api;
mod data;
mod props;
