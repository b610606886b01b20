//! The TDL front end on arbitrary text: parsing, the static checks and code generation never
//! panic, and every diagnostic points into the input (a line and column that exist).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(src) = std::str::from_utf8(data) else {
        return;
    };
    let (_, diagnostics) = tdl_syntax::compile_str("fuzz.tdl", src);
    let lines = src.lines().count().max(1);
    for d in &diagnostics {
        assert!(
            d.line() >= 1 && d.line() <= lines + 1 && d.column() >= 1,
            "diagnostic outside the input: {}:{} ({} lines): {}",
            d.line(),
            d.column(),
            lines,
            d.message()
        );
    }
});
