//! Blocking commands in TDL (docs/semantics.md, "Blocking actions"): a `blocking command`'s body
//! is plain Rust run on a blocking thread; its value goes to the goal that waits for it, its
//! failure to the goal's handler, and a terminated one is signalled and its node terminated once
//! the body returned. Every run's trace goes through the checker.

use crate::util::{run_checked, story};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};
use tdl::{RunOutcome, Runtime};

static SAW_CANCEL: AtomicBool = AtomicBool::new(false);

tdl::tdl! {
    exception NoPath { room: u32 }

    /// The sum of the first `n` steps, computed on a blocking thread.
    blocking command plan_path(n: u64) -> u64 {
        if n == 0 {
            fail NoPath { room: 0 };
        }
        (1..=n).sum::<u64>()
    }

    /// Works until it is cancelled (at most 10 s of real time, were the signal lost).
    blocking command survey() {
        let give_up = Instant::now() + Duration::from_secs(10);
        while Instant::now() < give_up {
            if ctx.is_cancelled() {
                SAW_CANCEL.store(true, Ordering::SeqCst);
                succeed;
            }
            std::thread::sleep(Duration::from_millis(1));
        }
    }

    command stop_survey(survey: tdl::NodeId) {
        ctx.terminate(survey)?;
    }

    handler give_up() handles NoPath {}

    goal deliver() with exception handler give_up() {
        let cost = spawn plan_path(100) with wait;
        if cost != 5050 {
            fail NoPath { room: 1 };
        }
        spawn plan_path(0);
    }

    goal survey_then_stop() {
        s: spawn survey();
        spawn stop_survey(node!(s));
    }
}

#[tdl::tokio::test(crate = "tdl::tokio", start_paused = true)]
async fn a_blocking_command_gives_its_value_and_its_failure() {
    let (report, trace) = run_checked(Runtime::new(), deliver()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(report.failures, 1, "plan_path(0) failed, and was handled");
    let s = story(&trace);
    assert!(s.iter().any(|l| l.contains("give_up")), "{s:#?}");
}

#[tdl::tokio::test(crate = "tdl::tokio", start_paused = true)]
async fn a_terminated_blocking_command_is_signalled_and_terminated_once_it_returned() {
    let (report, trace) = run_checked(Runtime::new(), survey_then_stop()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert!(
        SAW_CANCEL.load(Ordering::SeqCst),
        "the body saw its cancellation"
    );
    assert!(story(&trace).iter().any(|l| l == "0 survey terminated"));
}
