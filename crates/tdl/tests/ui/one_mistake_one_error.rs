// The mistake is in `deliver`'s body; `main` still uses both tasks and type-checks against the
// stubs, so the only error is the real one.
tdl::tdl! {
    goal deliver(room: u32) {
        spawn speak(room) with sequential execution nowhere;
    }
    command speak(room: u32) {
        assert!(room > 0);
    }
}

fn main() {
    let _task: tdl::Task = deliver(7);
    let _other: tdl::Task = speak(7);
}
