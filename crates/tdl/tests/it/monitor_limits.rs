//! Monitor limits wherever TDL takes monitor constraints: a `with` group's value, overridden by
//! the spawn's own, and set again by a constraint statement, before the monitor starts or while it
//! runs (docs/semantics.md, "Monitors"; catalogue 1.4: the last one given wins).

use crate::util::{only, run_checked, story};
use tdl::{RunOutcome, Runtime, TraceKind};

async fn sleep_ms(ms: u64) {
    tokio::time::sleep(std::time::Duration::from_millis(ms)).await;
}

tdl::tdl! {
    monitor ping() { sleep_ms(100).await; }
    command pause() { sleep_ms(2500).await; }

    // The group says 10 every 2 s, the spawn 6 every 1 s, the statement 3: three, a second apart.
    goal layered() {
        with (maximum activate 10, period 2s) { m: spawn ping() with maximum activate 6, period 1s; }
        m maximum activate 3;
    }

    // Only the group's values.
    goal from_group() {
        with (maximum activate 2, period 1s) { spawn ping(); }
    }

    // While the monitor runs: at 2.5 s it made 3 activations (0, 1, 2), so a maximum of 3
    // completes it at once.
    goal lowered_later() {
        m: spawn ping() with period 1s;
        spawn pause() with wait;
        m maximum activate 3;
    }

    // A new period from the poll already due: polls at 0, 1, 2, then 3 (due), 3.5, 4.
    goal faster_later() {
        m: spawn ping() with period 1s, maximum activate 6;
        spawn pause() with wait;
        m period 500ms;
    }

    // A maximum of triggers set while it runs: every activation triggers; 3 triggers by 2.5 s.
    monitor beat() with period 1s { trigger; }
    goal triggers_later() {
        b: spawn beat();
        spawn pause() with wait;
        b maximum trigger 3;
    }
}

fn activations(trace: &[tdl::TraceEvent], name: &str) -> Vec<String> {
    only(
        &story(trace),
        &[
            &format!("ACT-{name} handling active"),
            &format!(" {name} handling completed"),
        ],
    )
}

#[tokio::test(start_paused = true)]
async fn the_last_limit_given_wins() {
    let (report, trace) = run_checked(Runtime::new(), layered()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(
        activations(&trace, "ping"),
        [
            "0 ACT-ping handling active",
            "1 ACT-ping handling active",
            "2 ping handling completed",
            "2 ACT-ping handling active",
        ]
    );
    let params: Vec<Option<u32>> = trace
        .iter()
        .filter_map(|ev| match ev.kind {
            TraceKind::MonitorParams {
                max_activations, ..
            } => Some(max_activations),
            _ => None,
        })
        .collect();
    assert_eq!(params, [Some(6), Some(3)]);

    let (report, trace) = run_checked(Runtime::new(), from_group()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(
        activations(&trace, "ping"),
        [
            "0 ACT-ping handling active",
            "1 ping handling completed",
            "1 ACT-ping handling active",
        ]
    );
}

#[tokio::test(start_paused = true)]
async fn limits_set_while_the_monitor_runs() {
    let (report, trace) = run_checked(Runtime::new(), lowered_later()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(
        activations(&trace, "ping"),
        [
            "0 ACT-ping handling active",
            "1 ACT-ping handling active",
            "2 ACT-ping handling active",
            "2.5 ping handling completed",
        ]
    );

    let (report, trace) = run_checked(Runtime::new(), faster_later()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(
        activations(&trace, "ping"),
        [
            "0 ACT-ping handling active",
            "1 ACT-ping handling active",
            "2 ACT-ping handling active",
            "3 ACT-ping handling active",
            "3.5 ACT-ping handling active",
            "4 ping handling completed",
            "4 ACT-ping handling active",
        ]
    );

    let (report, trace) = run_checked(Runtime::new(), triggers_later()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(
        activations(&trace, "beat"),
        [
            "0 ACT-beat handling active",
            "1 ACT-beat handling active",
            "2 ACT-beat handling active",
            "2.5 beat handling completed",
        ]
    );
}
