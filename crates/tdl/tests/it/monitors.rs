//! Monitors written in TDL: the paper's Figure 6 under `deliver_mail`, maximum activations,
//! spawn-level overrides, `activate` statements, and persistent state shared by activations.

use crate::util::{assert_order, only, run_checked, story};
use std::cell::RefCell;
use tdl::{RunOutcome, Runtime, TraceEvent, TraceKind};

thread_local! {
    // Per test thread: tokio's test runtime runs every action on the test's thread.
    static SAID: RefCell<Vec<String>> = const { RefCell::new(Vec::new()) };
    static SEEN: RefCell<Vec<(u32, u32, u32)>> = const { RefCell::new(Vec::new()) };
}

async fn sleep_ms(ms: u64) {
    tokio::time::sleep(std::time::Duration::from_millis(ms)).await;
}

/// The simulated mail: taken 10 s into the run.
fn mail_is_gone(now: std::time::Duration) -> bool {
    now >= std::time::Duration::from_secs(10)
}

tdl::tdl! {
    goal deliver_mail(room: u32) {
        spawn navigate_to_locn(room);
        spawn center_on_door() with sequential execution previous, terminate in 30s;
        spawn speak("Xavier here with your mail")
            with sequential execution center_on_door, terminate at monitor_pickup completed;
        spawn monitor_pickup() with sequential execution center_on_door;
    }

    // Figure 6.
    monitor monitor_pickup() with maximum trigger 1, maximum activate 15, period 1.5s {
        if mail_is_gone(ctx.now()) {
            trigger;
            with (parallel) {
                spawn speak("Thank you") with name "thank_you";
                spawn notify_sender();
            }
        }
    }

    command navigate_to_locn(room: u32) { assert!(room > 0); sleep_ms(3000).await; }
    command center_on_door() { sleep_ms(2000).await; }
    command notify_sender() { sleep_ms(500).await; }

    command speak(text: &'static str) {
        SAID.with(|s| s.borrow_mut().push(text.to_owned()));
        if text.starts_with("Xavier") {
            // Repeats its announcement until terminated.
            std::future::pending::<()>().await;
        }
        sleep_ms(1000).await;
    }

    // Never triggers: completes after its maximum activations. Its persistent counter is shared
    // by the activations; `ctx.activation()` gives this activation's number and the triggers.
    monitor poll(label: u32) with maximum activate 3, period 1s, persistent calls: u32 = 0 {
        calls += 1;
        let (number, triggers) = ctx.activation().unwrap_or_default();
        SEEN.with(|s| s.borrow_mut().push((label + calls, number, triggers)));
    }

    goal polling() {
        spawn poll(100);
    }

    goal polling_overridden() {
        p: spawn poll(200) with maximum activate 2, period 10s;
        // After the spawn: the monitor starts when this body ends, then this activates it.
        p activate;
    }
}

fn activations(trace: &[TraceEvent]) -> Vec<(u64, u32)> {
    trace
        .iter()
        .filter_map(|e| match &e.kind {
            TraceKind::Activated { number, .. } => Some((e.t / 1_000_000, *number)),
            _ => None,
        })
        .collect()
}

#[tokio::test(start_paused = true)]
async fn figure_6_monitor_triggers_once_and_ends_the_waiting_speak() {
    SAID.with(|s| s.borrow_mut().clear());
    let (report, trace) = run_checked(Runtime::new(), deliver_mail(7)).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    // Period 1.5 s from 5 s: 5, 6.5, 8, 9.5, then 11 sees the mail gone and triggers.
    assert_eq!(
        activations(&trace),
        [(5000, 1), (6500, 2), (8000, 3), (9500, 4), (11000, 5)]
    );
    let triggers = trace
        .iter()
        .filter(|e| matches!(e.kind, TraceKind::Triggered { .. }))
        .count();
    assert_eq!(triggers, 1);
    let st = story(&trace);
    assert_order(
        &only(
            &st,
            &[
                "monitor_pickup",
                "speak",
                "thank_you",
                "notify_sender",
                "deliver_mail",
            ],
        ),
        &[
            "5 speak handling active",
            "5 monitor_pickup handling active",
            // The trigger reaches the maximum: the monitor's handling completes at once...
            "11 monitor_pickup handling completed",
            // ...and the last activation's children start when its body ends, in parallel.
            "11 thank_you handling active",
            "11 notify_sender handling active",
            "11.5 notify_sender execution completed",
            "12 thank_you execution completed",
            // The monitor's execution completes with its activations' subtrees; the waiting
            // speak is terminated then.
            "12 monitor_pickup execution completed",
            "12 speak terminated",
            "12 deliver_mail execution completed",
        ],
    );
    assert_eq!(
        SAID.with(|s| s.borrow().clone()),
        ["Xavier here with your mail", "Thank you"]
    );
}

#[tokio::test(start_paused = true)]
async fn a_monitor_completes_at_its_maximum_activations() {
    SEEN.with(|s| s.borrow_mut().clear());
    let (report, trace) = run_checked(Runtime::new(), polling()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(activations(&trace), [(0, 1), (1000, 2), (2000, 3)]);
    // The persistent counter carries over from one activation to the next.
    assert_eq!(
        SEEN.with(|s| s.borrow().clone()),
        [(101, 1, 0), (102, 2, 0), (103, 3, 0)]
    );
    assert_order(
        &story(&trace),
        &[
            "0 poll handling active",
            "2 poll handling completed",
            "2 poll execution completed",
            "2 polling execution completed",
        ],
    );
}

#[tokio::test(start_paused = true)]
async fn spawn_overrides_and_activate_statements() {
    SEEN.with(|s| s.borrow_mut().clear());
    let (report, trace) = run_checked(Runtime::new(), polling_overridden()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    // The period's activation at 0 and `p activate` at 0: the overridden maximum (2) is reached.
    assert_eq!(activations(&trace), [(0, 1), (0, 2)]);
    assert_eq!(SEEN.with(|s| s.borrow().len()), 2);
    assert_order(&story(&trace), &["0 poll handling completed"]);
}
