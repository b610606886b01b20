//! Task arguments are passed by value, as TDL copies them: a variable given to a spawn, a
//! handler, an `on terminate` or a `retry with` is cloned, so a program uses it again without
//! writing `.clone()` (issue 48, item 5). Before, each of these reuses was a "use of moved value".

use crate::util::run_checked;
use std::sync::{Arc, Mutex};
use tdl::{RunOutcome, Runtime};

/// What the tasks did, shared: `Clone`, not `Copy`.
#[derive(Clone, Default)]
pub(crate) struct Log(Arc<Mutex<Vec<String>>>);

impl Log {
    fn note(&self, what: String) {
        self.0.lock().expect("log").push(what);
    }
    fn lines(&self) -> Vec<String> {
        self.0.lock().expect("log").clone()
    }
}

tdl::tdl! {
    exception Jammed;

    command visit(log: Log, room: u32) {
        log.note(format!("visit {room}"));
    }

    command jam(log: Log, tries: u32) {
        log.note(format!("jam {tries}"));
        if tries < 1 { fail Jammed; }
    }

    command tidy(log: Log) {
        log.note("tidy".to_string());
    }

    command forever(log: Log) {
        log.note("forever".to_string());
        std::future::pending::<()>().await;
    }

    handler again(log: Log, tries: u32) handles Jammed with maximum activate 3 {
        log.note(format!("again {tries}"));
        retry with (log, tries + 1);
    }

    goal tour(log: Log, rooms: Vec<u32>) {
        for room in rooms {
            spawn visit(log, room) with serial previous;
        }
        spawn jam(log, 0) with serial previous, exception handler again(log, 0);
        spawn forever(log) with on terminate spawn tidy(log), terminate in 1s;
        log.note("spawned".to_string());
    }
}

#[tokio::test(start_paused = true)]
async fn a_variable_given_as_an_argument_stays_usable_after_the_spawn() {
    let log = Log::default();
    let (report, _) = run_checked(Runtime::new(), tour(log.clone(), vec![1, 2, 3])).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(
        log.lines(),
        [
            "spawned", "visit 1", "forever", "visit 2", "visit 3", "jam 0", "again 0", "jam 1",
            "tidy",
        ],
    );
}
