//! Activation data: a monitor activated with data (TCM's `TCM_Activate(monitor, data)`), by a
//! trigger that carries data (`TCM_ActivateAt(monitor, event, data)`, `TCM_ActivateIn`), or by an
//! external event raised with data, hands it to that activation's body, and to no other.

use crate::util::{only, run_checked, story};
use std::sync::{Arc, Mutex};
use tcm::{Monitor, RunOutcome, Runtime, Task};

#[derive(Debug, PartialEq)]
struct Bump {
    side: &'static str,
}

/// What each activation saw: its number, its data, and whether data of another type read as some.
type Seen = Arc<Mutex<Vec<(u32, Option<&'static str>, bool)>>>;

/// A monitor of at most `max` activations, each noting its number, its `Bump` and whether data
/// of another type (a `u32`) read as some.
fn bumper(seen: &Seen, max: u32) -> Task {
    let s = seen.clone();
    let params = Monitor {
        max_activations: Some(max),
        ..Monitor::default()
    };
    Task::monitor("bumper", params, move |ctx| {
        let s = s.clone();
        async move {
            let (n, _) = ctx.activation().unwrap_or_default();
            let bump = ctx.activation_data::<Bump>().map(|b| b.side);
            let wrong = ctx.activation_data::<u32>().is_some();
            s.lock().expect("seen").push((n, bump, wrong));
            Ok(())
        }
    })
}

#[tokio::test(start_paused = true)]
async fn each_activation_reads_the_data_it_was_activated_with() {
    let seen: Seen = Arc::default();
    let monitor = bumper(&seen, 3);
    let task = Task::goal("g", move |ctx| async move {
        // The monitor must be active before it is activated: start it at once.
        ctx.hold_children(false)?;
        let bumper = ctx.spawn(monitor).start()?;
        let first = ctx.activate_with(bumper, Bump { side: "left" })?;
        assert!(first.is_some());
        ctx.activate(bumper)?;
        ctx.activate_with(bumper, Bump { side: "right" })?;
        // Past the maximum: no activation, and the data is dropped.
        assert_eq!(ctx.activate_with(bumper, Bump { side: "front" }).ok(), None);
        Ok(())
    });
    let (report, trace) = run_checked(Runtime::new(), task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(
        *seen.lock().expect("seen"),
        [
            (1, Some("left"), false),
            (2, None, false),
            (3, Some("right"), false)
        ]
    );
    assert_eq!(
        only(&story(&trace), &["ACT-bumper handling completed"]).len(),
        3
    );
}

#[tokio::test(start_paused = true)]
async fn data_outside_an_activation_reads_as_none() {
    let task = Task::goal("g", |ctx| async move {
        assert!(ctx.activation_data::<Bump>().is_none());
        Ok(())
    });
    let (report, _) = run_checked(Runtime::new(), task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
}

/// An external event raised with data (`EventHandle::raise_with`) hands it to the activation it
/// makes; one raised without data makes an activation without.
#[tokio::test(start_paused = true)]
async fn an_external_event_raised_with_data_hands_it_to_its_activation() {
    let seen: Seen = Arc::default();
    let monitor = bumper(&seen, 2);
    let rt = Runtime::new();
    let events = rt.events();
    let task = Task::goal("g", move |ctx| async move {
        let bump = ctx.external("bump")?;
        ctx.spawn(monitor)
            .activate(tcm::When::External(bump))
            .start()?;
        Ok(())
    });
    tokio::spawn(async move {
        tokio::time::sleep(std::time::Duration::from_secs(1)).await;
        events
            .raise_with("bump", Bump { side: "rear" })
            .expect("raise");
        tokio::time::sleep(std::time::Duration::from_secs(1)).await;
        events.raise("bump").expect("raise");
    });
    let (report, _) = run_checked(rt, task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(
        *seen.lock().expect("seen"),
        [(1, Some("rear"), false), (2, None, false)]
    );
}

/// Triggers that carry data (`Ctx::activate_when`, TCM's `TCM_ActivateAt(monitor, event, data)`
/// and `TCM_ActivateIn(monitor, delay, data)`): each activation a trigger makes reads that
/// trigger's data, in the order the triggers fire, not the order they were given; a plain
/// `activate at` trigger makes one without; a trigger past the maximum makes none. Forms that make
/// activations of their own (a condition, an external event) are refused, and so is a node that is
/// not a monitor.
#[tokio::test(start_paused = true)]
async fn each_trigger_hands_its_own_data_to_the_activation_it_makes() {
    use std::time::Duration;
    use tcm::{Event, Point, When};
    let seen: Seen = Arc::default();
    let monitor = bumper(&seen, 3);
    let task = Task::goal("g", move |ctx| async move {
        let bumper = ctx.spawn(monitor).start()?;
        let drive = ctx
            .spawn(Task::command("drive", |ctx| async move {
                ctx.sleep(Duration::from_secs(2)).await;
                Ok(())
            }))
            .start()?;
        // Given first, fires last (at 5 s): past the maximum of 3, no activation.
        ctx.activate_when(
            bumper,
            When::In(Duration::from_secs(5)),
            Bump { side: "late" },
        )?;
        // At 1 s, then at drive's end (2 s), then a plain trigger at 3 s.
        ctx.activate_when(
            bumper,
            When::Event(Event::new(drive, Point::Completed)),
            Bump { side: "rear" },
        )?;
        ctx.activate_when(
            bumper,
            When::In(Duration::from_secs(1)),
            Bump { side: "left" },
        )?;
        ctx.constrain(
            bumper,
            tcm::Constraint::activate(When::In(Duration::from_secs(3))),
        )?;
        // Refused: forms with activations of their own, and a node that is no monitor.
        let ext = ctx.external("bump")?;
        let refused = ctx.activate_when(bumper, When::External(ext), Bump { side: "x" });
        assert!(
            refused
                .as_ref()
                .is_err_and(|e| e.to_string().contains("carries no data")),
            "{refused:?}"
        );
        let not_a_monitor = ctx.activate_when(drive, When::Now, Bump { side: "x" });
        assert!(
            not_a_monitor
                .as_ref()
                .is_err_and(|e| e.to_string().contains("not a monitor")),
            "{not_a_monitor:?}"
        );
        Ok(())
    });
    let (report, trace) = run_checked(Runtime::new(), task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(
        *seen.lock().expect("seen"),
        [
            (1, Some("left"), false),
            (2, Some("rear"), false),
            (3, None, false)
        ]
    );
    assert_eq!(
        only(&story(&trace), &["ACT-bumper handling completed"]).len(),
        3
    );
}
