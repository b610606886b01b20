//! Helpers: the runtime's own testing module (run with a recorder, check, story), and a session
//! whose trace is recorded.

pub(crate) use tcm::testing::{assert_order, only, run_checked, story};

/// A session on a new runtime whose trace goes to the recorder returned with it.
pub(crate) fn recorded_session() -> (tcm::Session, tcm::Recorder) {
    let rec = tcm::Recorder::new();
    let session = tcm::Runtime::new()
        .with_sink(rec.clone())
        .start()
        .expect("inside a tokio runtime");
    (session, rec)
}
