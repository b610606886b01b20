//! Resuming from a journal (issue 46): a recorded run of W2's flat goal, read back and replayed
//! to its end (`tcm-bench --layer journal`).

use std::time::Instant;
use tcm::{Runtime, Task};

/// W2's flat goal of `n` commands, the commands' bodies empty.
pub(crate) fn flat_goal(n: usize) -> Task {
    Task::goal("top", move |ctx| async move {
        for _ in 0..n {
            ctx.spawn(Task::command("noop", |_| async { Ok(()) }))
                .start()?;
        }
        Ok(())
    })
}

/// Resuming from a journal (`Runtime::replay` of a recorded run: the journal read back, checked,
/// and replayed to its end, the goal's body run again, each command's end given from the journal):
/// the journal's records, and the seconds from opening the file to the replayed run's end.
pub(crate) fn resume_from_journal(n: usize) -> (usize, f64) {
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_time()
        .build()
        .expect("tokio runtime");
    let path =
        std::env::temp_dir().join(format!("tcm-bench-resume-{}.journal", std::process::id()));
    let _ = std::fs::remove_file(&path);
    let writer = tcm_journal::Writer::create(
        &path,
        "bench",
        tcm_journal::Durability::Group(std::time::Duration::from_millis(10)),
    )
    .expect("a journal");
    let recorded = rt
        .block_on(Runtime::new().journal(writer).run(flat_goal(n)))
        .expect("run");
    assert_eq!(recorded.outcome, tcm::RunOutcome::Completed);
    let start = Instant::now();
    let journal = tcm_journal::read(&path, Some("bench")).expect("the journal reads back");
    let records = journal.entries.len();
    let replayed = rt
        .block_on(Runtime::new().replay(journal).run(flat_goal(n)))
        .expect("replay");
    let secs = start.elapsed().as_secs_f64();
    assert_eq!(replayed.outcome, tcm::RunOutcome::Completed, "{replayed}");
    let _ = std::fs::remove_file(&path);
    (records, secs)
}
