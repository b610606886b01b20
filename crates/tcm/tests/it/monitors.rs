//! Monitors through the async runtime: the paper's Figure 6 under deliverMail, and monitors
//! activated from events and handles.

use crate::fig4;
use crate::util::{assert_order, only, run_checked, story};
use std::sync::Arc;
use std::time::Duration;
use tcm::{Monitor, RunOutcome, Runtime, Task, When};

#[tokio::test(start_paused = true)]
async fn figure_6_monitor_under_deliver_mail() {
    // Centring ends at 11 s; the mail is taken at 16 s. The monitor polls every 1.5 s from 11 s:
    // 11, 12.5, 14, 15.5, 17 -> it triggers at 17 s, says thank you and notifies the sender in
    // parallel, completes, and the "Xavier here" speak waiting on it is terminated.
    let world = Arc::new(fig4::World {
        door_readings: std::sync::Mutex::new([-1, 1].into()),
        forever: 0,
        pickup_after: Duration::from_secs(16),
        said: std::sync::Mutex::new(Vec::new()),
    });
    let (report, trace) =
        run_checked(Runtime::new(), fig4::deliver_mail_fig6(7, world.clone())).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let st = story(&trace);
    assert_eq!(
        only(&st, &["ACT-monitorPickup handling active"]),
        [
            "11 ACT-monitorPickup handling active",
            "12.5 ACT-monitorPickup handling active",
            "14 ACT-monitorPickup handling active",
            "15.5 ACT-monitorPickup handling active",
            "17 ACT-monitorPickup handling active",
        ]
    );
    assert_order(
        &st,
        &[
            "11 speak handling active",
            "17 monitorPickup handling completed",
            "17 notifySender handling active",
            "17.5 notifySender handling completed",
            "18 monitorPickup execution completed",
            "18 speak terminating",
            "18 deliverMail execution completed",
        ],
    );
    assert_eq!(*world.said.lock().expect("said"), ["Thank you"]);
}

#[tokio::test(start_paused = true)]
async fn a_monitor_activated_by_an_external_event_each_time() {
    let rt = Runtime::new();
    let events = rt.events();
    let task = Task::goal("g", |ctx| async move {
        let bump = ctx.external("bump")?;
        let params = Monitor {
            max_activations: Some(3),
            ..Monitor::default()
        };
        ctx.spawn(Task::monitor("bumper", params, |ctx| async move {
            let (n, _) = ctx.activation().unwrap_or_default();
            tokio::time::sleep(Duration::from_millis(100 * u64::from(n))).await;
            Ok(())
        }))
        .activate(When::External(bump))
        .start()?;
        Ok(())
    });
    tokio::spawn(async move {
        for _ in 0..3 {
            tokio::time::sleep(Duration::from_secs(2)).await;
            events.raise("bump").expect("raise");
        }
    });
    let (report, trace) = run_checked(rt, task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let st = story(&trace);
    assert_eq!(
        only(&st, &["ACT-bumper handling completed"]),
        [
            "2.1 ACT-bumper handling completed",
            "4.2 ACT-bumper handling completed",
            "6.3 ACT-bumper handling completed"
        ]
    );
}

/// A rate-limited check through the runtime: period 100 ms from 100 ms, `serial`, five
/// activations, the first taking 350 ms, under `overrun`; the instants the activations start.
async fn overrun_starts(overrun: tcm::Overrun) -> Vec<String> {
    let params = Monitor {
        max_activations: Some(5),
        period: Some(Duration::from_millis(100)),
        initial_wait: true,
        each: tcm::EachActivation {
            serial: true,
            ..Default::default()
        },
        overrun,
        ..Monitor::default()
    };
    let task = Task::monitor("tick", params, |ctx| async move {
        if ctx.activation().unwrap_or_default().0 == 1 {
            ctx.sleep(Duration::from_millis(350)).await;
        }
        Ok(())
    });
    let (report, trace) = run_checked(Runtime::new(), task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    only(&story(&trace), &["ACT-tick handling active"])
}

#[tokio::test(start_paused = true)]
async fn a_monitor_s_overrun_policy_chooses_what_the_polls_missed_do() {
    let starts = |ts: &[&str]| -> Vec<String> {
        ts.iter()
            .map(|t| format!("{t} ACT-tick handling active"))
            .collect()
    };
    // The default catches up at one instant; skip keeps the schedule; delay restarts it.
    assert_eq!(
        overrun_starts(tcm::Overrun::Burst).await,
        starts(&["0.1", "0.45", "0.45", "0.45", "0.5"])
    );
    assert_eq!(
        overrun_starts(tcm::Overrun::Skip).await,
        starts(&["0.1", "0.5", "0.6", "0.7", "0.8"])
    );
    assert_eq!(
        overrun_starts(tcm::Overrun::Delay).await,
        starts(&["0.1", "0.45", "0.55", "0.65", "0.75"])
    );
}
