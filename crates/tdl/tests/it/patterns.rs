//! The recovery patterns of `tdl::patterns` (issue 17, point 4), each in a story: alternatives,
//! recoveries in turn, retries around a subtree, preemption. Replanning at a bounded rate is a
//! monitor with a period; crates/nav2 tests it beside a follower.

use crate::util::{run_checked, story};
use std::cell::RefCell;
use std::time::Duration;
use tdl::patterns::{InTurn, Preemption, alternatives, retry_around};
use tdl::{Ended, RunOutcome, Runtime};

thread_local! {
    static LOG: RefCell<Vec<String>> = const { RefCell::new(Vec::new()) };
}

fn log(s: impl Into<String>) {
    LOG.with(|l| l.borrow_mut().push(s.into()));
}

fn take() -> Vec<String> {
    LOG.with(|l| std::mem::take(&mut *l.borrow_mut()))
}

fn attempts(prefix: &str) -> usize {
    LOG.with(|l| l.borrow().iter().filter(|s| s.starts_with(prefix)).count())
}

tdl::tdl! {
    exception Stuck;
    exception Broken;

    command try_it(name: &'static str, works: bool) -> &'static str {
        tdl::tokio::time::sleep(Duration::from_secs(1)).await;
        log(format!("try {name}"));
        if !works {
            fail Stuck;
        }
        name
    }

    command recovery(name: &'static str, secs: u64) {
        log(format!("recovery {name}"));
        tdl::tokio::time::sleep(Duration::from_secs(secs)).await;
    }

    // Fails with `Stuck` the first `stuck` times, then with `Broken` if `broken`, then works.
    command body(stuck: usize, broken: bool) {
        let n = attempts("body");
        log(format!("body {n}"));
        if n < stuck {
            fail Stuck;
        }
        if broken {
            fail Broken;
        }
    }

    goal fallback(works: [bool; 3]) {
        let o = alternatives::<&'static str>(&ctx, [
            try_it("a", works[0]),
            try_it("b", works[1]),
            try_it("c", works[2]),
        ]).await?;
        match o {
            Ended::Succeeded(name) => log(format!("chose {name}")),
            Ended::Failed(f) => log(format!("all failed {}", f.exception)),
            Ended::Terminated => log("terminated"),
            Ended::Skipped => log("skipped"),
        }
    }

    goal around(stuck: usize, broken: bool, turn: InTurn) {
        let o = retry_around::<()>(&ctx, 3, |_| body(stuck, broken), &turn, |f| f.is_a("Stuck")).await?;
        match o {
            Ended::Succeeded(()) => log("succeeded"),
            Ended::Failed(f) => log(format!("failed {}", f.exception)),
            Ended::Terminated => log("terminated"),
            Ended::Skipped => log("skipped"),
        }
    }

    goal preempted(turn: InTurn, p: Preemption) {
        spawn preempt_in_2s(p);
        let r = turn.recover(&ctx).await?;
        log(format!("{r:?}"));
    }

    command preempt_in_2s(p: Preemption) {
        tdl::tokio::time::sleep(Duration::from_secs(2)).await;
        p.preempt(|n| ctx.raise(n))?;
    }
}

fn recoveries() -> InTurn {
    InTurn::new(3, |i| match i {
        0 => recovery("clear", 1),
        1 => recovery("spin", 1),
        _ => recovery("wait", 5),
    })
}

#[tokio::test(start_paused = true)]
async fn alternatives_try_each_until_one_succeeds() {
    take();
    let (report, _) = run_checked(Runtime::new(), fallback([false, true, true])).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert!(report.is_clean(), "{report}");
    assert_eq!(take(), ["try a", "try b", "chose b"]);

    let (report, _) = run_checked(Runtime::new(), fallback([false, false, false])).await;
    assert!(report.is_clean(), "{report}");
    assert_eq!(take(), ["try a", "try b", "try c", "all failed Stuck"]);
}

#[tokio::test(start_paused = true)]
async fn retries_around_a_subtree_with_recoveries_in_turn_reset_on_success() {
    take();
    let turn = recoveries();
    let (report, _) = run_checked(Runtime::new(), around(2, false, turn.clone())).await;
    assert!(report.is_clean(), "{report}");
    assert_eq!(
        take(),
        [
            "body 0",
            "recovery clear",
            "body 1",
            "recovery spin",
            "body 2",
            "succeeded"
        ]
    );
    // The success reset the turn.
    assert_eq!(turn.next_index(), 0);

    // Bounded: three retries at most, the recoveries going round.
    let (report, _) = run_checked(Runtime::new(), around(9, false, turn.clone())).await;
    assert!(report.is_clean(), "{report}");
    let log = take();
    assert_eq!(log.iter().filter(|s| s.starts_with("body")).count(), 4);
    assert_eq!(
        log.iter()
            .filter(|s| s.starts_with("recovery"))
            .cloned()
            .collect::<Vec<_>>(),
        ["recovery clear", "recovery spin", "recovery wait"]
    );
    assert_eq!(log.last().map(String::as_str), Some("failed Stuck"));
    assert_eq!(turn.next_index(), 0, "went round once: back at the first");

    // A failure recovery cannot help ends it at once.
    let (report, _) = run_checked(Runtime::new(), around(0, true, recoveries())).await;
    assert!(report.is_clean(), "{report}");
    assert_eq!(take(), ["body 0", "failed Broken"]);
}

#[tokio::test(start_paused = true)]
async fn a_preemption_ends_the_running_recovery_at_that_instant() {
    take();
    // One recovery, `wait` (5 s): the preemption at 2 s ends it.
    let turn = InTurn::new(1, |_| recovery("wait", 5));
    let p = Preemption::new("goal");
    let (report, trace) = run_checked(
        Runtime::new(),
        preempted(turn.clone().preempted_by(p.clone()), p.clone()),
    )
    .await;
    assert!(report.is_clean(), "{report}");
    assert_eq!(take(), ["recovery wait", "Preempted"]);
    assert_eq!(p.count(), 1);
    let st = story(&trace);
    assert!(
        st.iter().any(|l| l == "2 recovery terminated"),
        "{}",
        st.join("\n")
    );
    // A recovery spawned after the preemption waits for the next one: it is not ended at once.
    assert_eq!(p.next_event(), "goal#1");
}
