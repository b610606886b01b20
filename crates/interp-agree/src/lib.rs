//! The interpreter (`tdl-interp`) held to the compiler (`tdl-build`) on every program of
//! `tdl-syntax`'s `test_data/ok`: each program that the interpreted subset accepts runs compiled
//! and interpreted on virtual time with the same trace, record for record; each it refuses is
//! refused when loaded with a located diagnostic naming the construct, snapshotted. The crate has
//! no code of its own: its tests (`tests/it`) and its build script are all there is.
