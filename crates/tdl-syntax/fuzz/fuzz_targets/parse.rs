//! Fuzz target for the TDL front end: arbitrary bytes, read as UTF-8 lossily, go through
//! `parse_str` (which must never panic, whatever the input) and the rendering of its diagnostics;
//! when the parse has no errors, the tree also goes through the tree dump and the code generator,
//! whose output is pretty-printed as `tdl expand` does.

#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let src = String::from_utf8_lossy(data);
    let parse = tdl_syntax::parse_str("fuzz.tdl", &src);
    let _ = parse.render("fuzz.tdl", Some(&src));
    if parse.has_errors() {
        return;
    }
    let _ = tdl_syntax::dump(&parse.file);
    let generated = tdl_syntax::generate(&parse.file);
    let _ = tdl_syntax::pretty(&generated.tokens);
    let _ = tdl_syntax::stubs(&parse.file);
});
