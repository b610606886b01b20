//! Same program, same inputs, virtual time: the same trace, byte for byte (docs/semantics.md,
//! "Determinism"), also when the `Runtime` is made before the tokio runtime that drives it.

use std::time::Duration;
use tcm::testing::{lines, run_checked};
use tcm::{NodeRef, Runtime, Task};

fn program() -> Task {
    Task::goal("g", |ctx| async move {
        for _ in 0..3 {
            ctx.spawn(Task::command("step", |_| async {
                tokio::time::sleep(Duration::from_millis(1500)).await;
                Ok(())
            }))
            .serial(NodeRef::Previous)
            .start()?;
        }
        Ok(())
    })
}

#[test]
fn two_virtual_runs_of_one_program_give_the_same_lines() {
    let run = || {
        // Made outside the tokio runtime, as `block_on_virtual(run_checked(Runtime::new(), …))`
        // does: its time zero must still be taken inside it.
        let rt = Runtime::new();
        std::thread::sleep(Duration::from_millis(2));
        let run = async { Ok::<_, tcm::Error>(run_checked(rt, program()).await) };
        tcm::block_on_virtual(run).expect("a tokio runtime")
    };
    let (a, ta) = run();
    let (b, tb) = run();
    assert_eq!(a.elapsed, Duration::from_millis(4500));
    assert_eq!(b.elapsed, a.elapsed);
    assert_eq!(lines(&ta), lines(&tb));
    assert_eq!(ta.last().map(|r| r.t), Some(4_500_000_000));
}
