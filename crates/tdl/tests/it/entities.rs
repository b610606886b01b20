//! Constraints naming an *entity* (a `with` group, `previous` after a group) or a missing one
//! (`previous` before anything): `terminate` and `activate` at a group's event happen once every
//! member reached it, at once for a group none of whose spawns ran; a missing or empty `previous`
//! drops the `after` part of a delay and keeps the delay (docs/semantics.md, "Tags and forward
//! references").

use crate::util::{assert_order, only, run_checked, story};
use tdl::{RunOutcome, Runtime};

async fn sleep_s(s: u64) {
    tokio::time::sleep(std::time::Duration::from_secs(s)).await;
}

tdl::tdl! {
    command quick() { sleep_s(1).await; }
    command slow() { sleep_s(3).await; }
    command guard() { std::future::pending::<()>().await; }
    command step() { sleep_s(1).await; }
    monitor beacon() with maximum activate 1 { trigger; }

    // (6) The first spawn of a body has no `previous`: each `… after previous` keeps its delay.
    goal first_spawns() {
        spawn step() with disable for 2s after previous completed;
    }
    goal first_terminates() {
        spawn guard() with terminate in 3s after previous completed;
    }
    goal first_activates() {
        spawn beacon() with activate in 1s after previous completed;
    }
    // Without `after`, `terminate at previous` with nothing before is void.
    goal first_terminate_at() {
        spawn step() with terminate at previous completed;
    }

    // (5) `terminate at` / `activate at` a group: when its last member gets there.
    goal whole_group() {
        grp: with (parallel) { spawn quick(); spawn slow(); }
        spawn guard() with terminate at grp completed;
        spawn beacon() with activate at grp completed;
    }
    goal previous_group() {
        with (parallel) { spawn quick(); spawn slow(); }
        spawn guard() with terminate in 1s after previous completed;
    }
    // A group none of whose spawns ran is a dead reference.
    goal empty_group(go: bool) {
        grp: with (parallel) { if go { spawn quick(); } }
        spawn step() with disable for 2s after previous completed;
        spawn guard() with terminate at grp completed;
        spawn beacon() with activate in 1s after grp completed;
    }
}

#[tokio::test(start_paused = true)]
async fn a_missing_previous_drops_the_after_part_and_keeps_the_delay() {
    let (report, trace) = run_checked(Runtime::new(), first_spawns()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_order(
        &story(&trace),
        &[
            "2 step handling active",
            "3 first_spawns execution completed",
        ],
    );

    let (report, trace) = run_checked(Runtime::new(), first_terminates()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_order(
        &story(&trace),
        &[
            "0 guard handling active",
            "3 guard terminating",
            "3 first_terminates execution completed",
        ],
    );

    let (report, trace) = run_checked(Runtime::new(), first_activates()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_order(
        &story(&trace),
        &[
            "0 beacon handling active",
            "1 ACT-beacon handling active",
            "1 first_activates execution completed",
        ],
    );

    let (report, trace) = run_checked(Runtime::new(), first_terminate_at()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let st = story(&trace);
    assert_order(
        &st,
        &["0 step handling active", "1 step execution completed"],
    );
    assert!(!st.iter().any(|l| l.contains("step terminat")), "{st:#?}");
}

#[tokio::test(start_paused = true)]
async fn terminate_and_activate_at_a_group_wait_for_every_member() {
    let (report, trace) = run_checked(Runtime::new(), whole_group()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    // `quick` completes at 1, `slow` at 3: the group completes at 3, not at 1.
    assert_eq!(
        only(
            &story(&trace),
            &["guard terminating", "ACT-beacon handling active"]
        ),
        ["3 guard terminating", "3 ACT-beacon handling active"]
    );

    let (report, trace) = run_checked(Runtime::new(), previous_group()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(
        only(&story(&trace), &["guard terminating"]),
        ["4 guard terminating"]
    );
}

#[tokio::test(start_paused = true)]
async fn a_group_none_of_whose_spawns_ran_is_a_dead_reference() {
    let (report, trace) = run_checked(Runtime::new(), empty_group(false)).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    // `terminate at` it fires at once; the `after` parts are dropped and the delays kept.
    assert_eq!(
        only(
            &story(&trace),
            &[
                "guard terminating",
                "step handling active",
                "ACT-beacon handling active"
            ]
        ),
        [
            "0 guard terminating",
            "1 ACT-beacon handling active",
            "2 step handling active"
        ]
    );

    let (report, trace) = run_checked(Runtime::new(), empty_group(true)).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(
        only(
            &story(&trace),
            &[
                "guard terminating",
                "step handling active",
                "ACT-beacon handling active"
            ]
        ),
        [
            "1 guard terminating",
            "2 ACT-beacon handling active",
            "3 step handling active"
        ]
    );
}
