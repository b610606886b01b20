//! Macro UI tests: each `tests/ui/*.rs` holds one mistake; its `.stderr` shows the spanned error.

#[test]
fn ui() {
    let t = trybuild::TestCases::new();
    t.compile_fail("tests/ui/*.rs");
}
