//! Integration tests of the engine through its public API: random programs checked by the trace
//! checker.

mod random_trees;
