//! Held children by default (issue 11, point 18): a hand-written action holds the children it
//! spawns until it returns or waits, as generated TDL does, so a constraint statement after a
//! spawn is always in time; `ctx.hold_children(false)` opts out (docs/semantics.md, "Bodies and
//! children").

use crate::util::{only, run_checked, story};
use std::time::Duration;
use tcm::{Constraint, Handler, Monitor, RunOutcome, Runtime, Task};

fn secs(s: u64) -> Duration {
    Duration::from_secs(s)
}

fn sleeper(name: &'static str, d: u64) -> Task {
    Task::command(name, move |_| async move {
        tokio::time::sleep(secs(d)).await;
        Ok(())
    })
}

fn starts(trace: &[tcm::TraceEvent]) -> Vec<String> {
    only(&story(trace), &["handling active"])
}

#[tokio::test(start_paused = true)]
async fn children_start_when_the_body_returns_not_at_a_plain_await() {
    let task = Task::goal("g", |ctx| async move {
        let a = ctx.spawn(sleeper("a", 1)).start()?;
        let b = ctx.spawn(sleeper("b", 1)).start()?;
        // A plain `.await` does not release the children: they have not started.
        tokio::time::sleep(secs(2)).await;
        // So a constraint statement after the spawn is still in time.
        ctx.constrain(b, Constraint::Serial(a.into()))?;
        Ok(())
    });
    let (report, trace) = run_checked(Runtime::new(), task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(
        starts(&trace),
        [
            "0 g handling active",
            "2 a handling active",
            "3 b handling active"
        ]
    );
}

#[tokio::test(start_paused = true)]
async fn hold_children_false_starts_them_at_once() {
    let task = Task::goal("g", |ctx| async move {
        ctx.hold_children(false)?;
        let a = ctx.spawn(sleeper("a", 1)).start()?;
        let b = ctx.spawn(sleeper("b", 1)).start()?;
        tokio::time::sleep(secs(2)).await;
        // Too late: `b` started at once.
        assert!(
            ctx.constrain(b, Constraint::Serial(a.into())).is_err(),
            "b already started"
        );
        Ok(())
    });
    let (report, trace) = run_checked(Runtime::new(), task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(
        starts(&trace),
        [
            "0 g handling active",
            "0 a handling active",
            "0 b handling active"
        ]
    );
}

#[tokio::test(start_paused = true)]
async fn a_wait_releases_the_children_and_holds_again_after() {
    let task = Task::goal("g", |ctx| async move {
        ctx.spawn(sleeper("a", 3)).start()?;
        // `b` and `a` start while the body waits for `b`.
        ctx.spawn(sleeper("b", 1)).wait().await?;
        ctx.spawn(sleeper("c", 1)).start()?;
        tokio::time::sleep(secs(1)).await;
        Ok(())
    });
    let (report, trace) = run_checked(Runtime::new(), task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(
        starts(&trace),
        [
            "0 g handling active",
            "0 a handling active",
            "0 b handling active",
            "2 c handling active"
        ]
    );
}

#[tokio::test(start_paused = true)]
async fn monitor_activations_and_handlers_hold_their_children_too() {
    let params = Monitor {
        max_activations: Some(1),
        ..Monitor::default()
    };
    let task = Task::goal("g", move |ctx| async move {
        ctx.spawn(
            Task::monitor("m", params, |ctx| async move {
                ctx.spawn(sleeper("from_activation", 1)).start()?;
                tokio::time::sleep(secs(1)).await;
                Ok(())
            })
            .with(Constraint::activate(tcm::When::Now)),
        )
        .start()?;
        ctx.spawn(Task::command("bad", |_| async {
            Err::<(), _>(tcm::Failure::new("Oops", "no"))
        }))
        .handler(Handler::new("fix", "Oops", |ctx| async move {
            ctx.spawn(sleeper("from_handler", 1)).start()?;
            tokio::time::sleep(secs(2)).await;
            Ok(())
        }))
        .start()?;
        Ok(())
    });
    let (report, trace) = run_checked(Runtime::new(), task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let st = starts(&trace);
    assert!(
        st.contains(&"1 from_activation handling active".to_string()),
        "{st:?}"
    );
    assert!(
        st.contains(&"2 from_handler handling active".to_string()),
        "{st:?}"
    );
}
