//! Stuck runs whose actions are suspended in an await on the engine (issue 11, point 10): the run
//! ends `Stuck` on virtual time, with a report naming every waiting node and what each parked
//! action awaits (docs/semantics.md, "Run outcome").

use crate::util::{assert_order, run_checked, story};
use std::time::Duration;
use tcm::{Monitor, RunOutcome, Runtime, Task};

/// Longer than any of these runs: a run that does not end by itself fails its test instead of
/// hanging `cargo test` (the paused clock jumps to this timeout when every task waits).
const NEVER: Duration = Duration::from_secs(24 * 3600);

async fn stuck(task: Task) -> (Vec<String>, Vec<tcm::TraceEvent>) {
    let run = run_checked(Runtime::new(), task);
    let (report, trace) = tokio::time::timeout(NEVER, run)
        .await
        .expect("the run ends by itself");
    let RunOutcome::Stuck(blocked) = report.outcome else {
        panic!("expected stuck, got {:?}", report.outcome);
    };
    assert_eq!(report.elapsed, Duration::ZERO, "stuck as soon as it is");
    (blocked.iter().map(ToString::to_string).collect(), trace)
}

#[tokio::test(start_paused = true)]
async fn a_goal_called_functionally_in_an_expand_first_body_is_stuck_not_hung() {
    // `plan` expands first: its execution waits for its expansion, which waits for its body, which
    // awaits `measure`, whose execution waits for `plan`'s execution.
    let task = Task::goal("top", |ctx| async move {
        ctx.spawn(Task::goal("plan", |ctx| async move {
            let _: u32 = ctx
                .spawn(Task::command("measure", |_| async { Ok(3u32) }))
                .wait_value()
                .await?;
            Ok(())
        }))
        .expand_first()
        .start()?;
        Ok(())
    });
    let (report, trace) = stuck(task).await;
    assert_eq!(
        report,
        [
            "plan {2} handling is active and waits for its action, which awaits measure {3} \
             execution completed",
            "plan {2} execution waits for its own expansion (expand first)",
            "measure {3} execution waits for its parent plan {2} execution enabled",
        ]
    );
    let st = story(&trace);
    assert_order(&st, &["0 top handling completed", "0 plan handling active"]);
    assert!(!st.iter().any(|l| l.contains("measure handling")), "{st:?}");
}

#[tokio::test(start_paused = true)]
async fn an_action_awaiting_its_own_parent_is_named_in_the_report() {
    // Every facet is enabled or active: before the parked actions were counted, this run hung, and
    // its report, had it ended, would have been empty.
    let task = Task::goal("g", |ctx| async move {
        let me = ctx.node();
        ctx.spawn(Task::command("c", move |ctx| async move {
            ctx.wait(me).await?;
            Ok(())
        }))
        .start()?;
        Ok(())
    });
    let (report, _) = stuck(task).await;
    assert_eq!(
        report,
        [
            "c {2} handling is active and waits for its action, which awaits g {1} execution completed"
        ]
    );
}

#[tokio::test(start_paused = true)]
async fn two_actions_awaiting_each_other_are_both_named() {
    let task = Task::goal("g", |ctx| async move {
        ctx.hold_children(false)?;
        let b = ctx.reserve("b")?;
        let a = ctx
            .spawn(Task::command("a", move |ctx| async move {
                ctx.wait(b).await?;
                Ok(())
            }))
            .start()?;
        ctx.spawn(Task::command("b", move |ctx| async move {
            ctx.wait(a).await?;
            Ok(())
        }))
        .fulfils(b)
        .start()?;
        Ok(())
    });
    let (report, _) = stuck(task).await;
    assert_eq!(
        report,
        [
            "b {2} handling is active and waits for its action, which awaits a {3} execution \
             completed",
            "a {3} handling is active and waits for its action, which awaits b {2} execution \
             completed",
        ]
    );
}

#[tokio::test(start_paused = true)]
async fn an_enabled_node_left_suspended_is_named() {
    // Its handling is enabled, not disabled: the report used to leave it out, and was empty.
    let task = Task::goal("g", |ctx| async move {
        let w = ctx
            .spawn(Task::command("w", |_| async { Ok(()) }))
            .start()?;
        ctx.suspend(w)?;
        Ok(())
    });
    let (report, _) = stuck(task).await;
    assert_eq!(
        report,
        ["w {2} handling is enabled and waits for being unsuspended"]
    );
}

#[tokio::test(start_paused = true)]
async fn a_monitor_nothing_can_activate_is_named() {
    let task = Task::monitor(
        "watch",
        Monitor {
            max_activations: Some(1),
            ..Monitor::default()
        },
        |_| async { Ok(()) },
    );
    let (report, _) = stuck(task).await;
    assert_eq!(
        report,
        ["watch {1} handling is active and waits for an activation, and none is armed"]
    );
}

#[tokio::test(start_paused = true)]
async fn a_parked_action_beside_a_running_one_is_not_stuck() {
    // `waiter` is parked on `slow`, which runs for 3 s on a timer of its own: the run goes on.
    let task = Task::goal("g", |ctx| async move {
        ctx.hold_children(false)?;
        let slow = ctx
            .spawn(Task::command("slow", |_| async {
                tokio::time::sleep(Duration::from_secs(3)).await;
                Ok(())
            }))
            .start()?;
        ctx.spawn(Task::command("waiter", move |ctx| async move {
            ctx.wait(slow).await?;
            Ok(())
        }))
        .start()?;
        Ok(())
    });
    let (report, trace) = tokio::time::timeout(NEVER, run_checked(Runtime::new(), task))
        .await
        .expect("the run ends by itself");
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_order(
        &story(&trace),
        &[
            "3 slow handling completed",
            "3 waiter handling completed",
            "3 g execution completed",
        ],
    );
}

#[tokio::test(start_paused = true)]
async fn a_timeout_for_a_wait_belongs_in_the_engine() {
    // The limit of the rule: an action racing an engine wait against a private timer (a
    // `tokio::select!` with a sleep) counts as parked, and the run below would end stuck at once.
    // Put the timeout in the engine instead, where the run can see it: here `terminate in`.
    let task = Task::goal("g", |ctx| async move {
        let me = ctx.node();
        let out = ctx
            .spawn(Task::command("c", move |ctx| async move {
                ctx.wait(me).await?;
                Ok(())
            }))
            .terminate_in(Duration::from_secs(5))
            .wait()
            .await?;
        assert_eq!(out, tcm::WatchOutcome::Terminated);
        Ok(())
    });
    let (report, trace) = tokio::time::timeout(NEVER, run_checked(Runtime::new(), task))
        .await
        .expect("the run ends by itself");
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_order(
        &story(&trace),
        &["5 c terminating", "5 g handling completed"],
    );
}

#[tokio::test(start_paused = true)]
async fn a_private_timer_raced_against_a_wait_counts_as_parked() {
    // The documented limit, shown: the sleep would end the wait at 5 s, but the run sees only the
    // parked wait and ends stuck at 0 s. The test above shows what to write instead.
    let task = Task::goal("g", |ctx| async move {
        let me = ctx.node();
        ctx.spawn(Task::command("c", move |ctx| async move {
            tokio::select! {
                res = ctx.wait(me) => { res?; }
                () = tokio::time::sleep(Duration::from_secs(5)) => {}
            }
            Ok(())
        }))
        .start()?;
        Ok(())
    });
    let (report, _) = stuck(task).await;
    assert_eq!(
        report,
        [
            "c {2} handling is active and waits for its action, which awaits g {1} execution completed"
        ]
    );
}
