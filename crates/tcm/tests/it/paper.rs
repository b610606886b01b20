//! The paper's Figure 4 program, on virtual time.

use crate::fig4;
use crate::util::{assert_order, only, run_checked, story};
use tcm::{RunOutcome, Runtime};

#[tokio::test(start_paused = true)]
async fn deliver_mail_runs_in_the_papers_order() {
    let (report, trace) = run_checked(
        Runtime::new(),
        fig4::deliver_mail(7, fig4::World::nominal()),
    )
    .await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let st = story(&trace);
    // Navigation: three legs in sequence (0-6 s). Then centring: look, move, look, move, look,
    // each expansion of centerOnDoor only after the previous move (delay expansion + disable
    // execution until previous execution completed). Then speak and monitorPickup together; speak is
    // terminated when monitorPickup completes.
    assert_order(
        &st,
        &[
            "0 navigateToLocn handling active",
            "6 navigateToLocn execution completed",
            "6 centerOnDoor handling active",
            "6 lookForDoor handling active",
            "7 lookForDoor handling completed",
            "7 move handling active",
            "8 move execution completed",
            "8 centerOnDoor handling active",
            "9 move handling active",
            "10 centerOnDoor handling active",
            "11 lookForDoor handling completed",
            "11 centerOnDoor execution completed",
            "11 speak handling active",
            "11 monitorPickup handling active",
            "16 monitorPickup execution completed",
            "16 speak terminating",
            "16 speak terminated",
            "16 deliverMail execution completed",
        ],
    );
    let centring = only(&st, &["centerOnDoor handling active"]);
    assert_eq!(
        centring,
        [
            "6 centerOnDoor handling active",
            "8 centerOnDoor handling active",
            "10 centerOnDoor handling active"
        ]
    );
    assert!(
        !st.iter().any(|l| l.contains("centerOnDoor terminating")),
        "the 30 s timeout must not fire when centring converges"
    );
}

#[tokio::test(start_paused = true)]
async fn the_30s_timeout_cuts_a_door_search_that_never_converges() {
    let (report, trace) = run_checked(
        Runtime::new(),
        fig4::deliver_mail(7, fig4::World::never_centred()),
    )
    .await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let st = story(&trace);
    // centerOnDoor was spawned at 0 with `terminate in 30s`: at 30 s its whole recursion is
    // terminated; speak and monitorPickup, sequential on it, then proceed.
    assert_order(
        &st,
        &[
            "6 centerOnDoor handling active",
            "30 centerOnDoor terminating",
            "30 centerOnDoor terminated",
            "30 speak handling active",
            "30 monitorPickup handling active",
            "35 speak terminating",
            "35 deliverMail execution completed",
        ],
    );
    assert!(
        only(&st, &["lookForDoor handling active"]).len() >= 10,
        "the search kept going until the timeout"
    );
}

#[tokio::test(start_paused = true)]
async fn the_same_program_gives_the_same_trace_every_time() {
    let (_, a) = run_checked(
        Runtime::new(),
        fig4::deliver_mail(7, fig4::World::never_centred()),
    )
    .await;
    let (_, b) = run_checked(
        Runtime::new(),
        fig4::deliver_mail(7, fig4::World::never_centred()),
    )
    .await;
    let lines = |t: &[tcm::TraceEvent]| -> Vec<String> {
        // Run numbers differ between runs; everything else must be identical.
        t.iter().skip(1).map(tcm_trace::to_line).collect()
    };
    assert!(a.len() > 100);
    assert_eq!(lines(&a), lines(&b));
}
