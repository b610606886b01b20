//! The trace reader and checker (`tdl trace check`) on arbitrary bytes: reading never panics and
//! every refusal names its line; whatever reads as a trace goes through the checker without panic.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    match tcm_trace::read_jsonl(data) {
        Ok(events) => {
            let _ = tcm_trace::check(&events);
        }
        Err(e) => {
            let text = e.to_string();
            assert!(text.starts_with("line "), "an error without its line: {text}");
        }
    }
});
