//! Each scenario with fixed seeds on virtual time, asserted on the trace (every run also passes
//! the trace checker, in `run_checked`).

use crate::util::{Story, lines, log_of, run_checked, setup};
use std::time::Duration;
use tdl::{RunOutcome, TraceKind};
use xavier_world::Scenario;

#[test]
fn nominal_delivers_every_room() {
    for seed in [1, 2, 3] {
        let s = setup(seed, Scenario::Nominal, &[3, 7, 12]);
        let (summary, trace, done) = run_checked(&s);
        let log = log_of(&trace);
        assert_eq!(summary.outcome, RunOutcome::Completed, "{log}");
        let mut delivered = summary.delivered.clone();
        delivered.sort_unstable();
        assert_eq!(delivered, [3, 7, 12], "seed {seed}:\n{summary}\n{log}");
        assert_eq!(done.mission.notifications(), [3, 7, 12], "seed {seed}");
        assert!(summary.undeliverable.is_empty(), "seed {seed}:\n{summary}");
        let story = Story::new(&trace);
        assert!(story.failures().is_empty(), "seed {seed}:\n{log}");
        // Figure 6: one pickup monitor per room, each triggered once.
        assert_eq!(story.triggers("monitor_pickup"), 3, "seed {seed}:\n{log}");
        assert!(story.reservations("base").is_empty(), "seed {seed}:\n{log}");
    }
}

#[test]
fn blocked_corridor_detours_round_the_cart_and_delivers() {
    for seed in [1, 2] {
        let s = setup(seed, Scenario::BlockedCorridor, &[3, 7, 12]);
        let (summary, trace, _) = run_checked(&s);
        let log = log_of(&trace);
        let story = Story::new(&trace);
        // The guarded move towards room 7 runs into the cart and raises `Blocked`...
        let failures = story.failures();
        assert_eq!(failures.len(), 1, "seed {seed}:\n{log}");
        let (failing, name, exception) = failures[0].clone();
        assert_eq!(
            (name.as_str(), exception.as_str()),
            ("guardedMove", "Blocked")
        );
        // ...the detour handler, attached to the navigation, takes it...
        let handlers = story.handlers_for(failing);
        assert_eq!(handlers.len(), 1, "seed {seed}:\n{log}");
        let (handler, handler_name, attached) = handlers[0].clone();
        assert_eq!(handler_name, "detour");
        assert_eq!(story.name(attached), "navigate_to_locn");
        // ...and completes (it navigates round the loop), and room 7 gets its letter.
        assert!(story.completed(handler), "seed {seed}:\n{log}");
        assert!(!story.terminated(handler), "seed {seed}:\n{log}");
        assert!(summary.undeliverable.is_empty(), "seed {seed}:\n{summary}");
        let mut delivered = summary.delivered.clone();
        delivered.sort_unstable();
        assert_eq!(delivered, [3, 7, 12], "seed {seed}:\n{summary}");
        assert_eq!(summary.exceptions[0].handler(), Some("detour"));
        assert_eq!(summary.exceptions[0].room, Some(7));
        // The detour goes round the loop: far more than the 34 m straight along the south corridor.
        assert!(summary.distance > 100.0, "seed {seed}:\n{summary}");
    }
}

#[test]
fn no_path_gives_up_on_room_12_and_delivers_the_others() {
    let s = setup(1, Scenario::NoPath, &[3, 12, 7]);
    let (summary, trace, _) = run_checked(&s);
    let log = log_of(&trace);
    let story = Story::new(&trace);
    let failures = story.failures();
    // planPath fails; no handler on it takes the failure, so it goes to navigate_to_locn, whose
    // body waits for the path (a waited value): the waiter fails with the same exception, once.
    assert_eq!(failures.len(), 2, "{log}");
    let (_, name, exception) = failures[0].clone();
    assert_eq!((name.as_str(), exception.as_str()), ("planPath", "NoPath"));
    let (failing, name, exception) = failures[1].clone();
    assert_eq!(
        (name.as_str(), exception.as_str()),
        ("navigate_to_locn", "NoPath")
    );
    let handlers = story.handlers_for(failing);
    assert_eq!(handlers.len(), 1, "{log}");
    assert_eq!(handlers[0].1, "give_up_no_path");
    assert_eq!(story.name(handlers[0].2), "deliver_mail");
    // Room 12 is recorded as undeliverable, its delivery terminated; the round goes on.
    assert_eq!(summary.undeliverable.len(), 1, "{summary}");
    assert_eq!(summary.undeliverable[0].room, 12);
    assert_eq!(summary.undeliverable[0].exception, "NoPath");
    assert!(story.terminated(handlers[0].2), "{log}");
    assert_eq!(summary.delivered, [3, 7], "{summary}");
    assert_eq!(summary.outcome, RunOutcome::Completed);
    // Nothing was said at room 12's door: the delivery stopped before centring.
    assert_eq!(story.triggers("monitor_pickup"), 2, "{log}");
}

#[test]
fn overheat_keeps_the_base_still_until_the_motor_cools_then_motion_resumes() {
    let s = setup(1, Scenario::Overheat, &[3, 7, 12]);
    let (summary, trace, _) = run_checked(&s);
    let log = log_of(&trace);
    let story = Story::new(&trace);
    // The motor monitor reserved the base for itself, then gave it back.
    let spans = story.reservations("base");
    assert!(!spans.is_empty(), "{log}");
    for &(holder, from, until) in &spans {
        assert_eq!(story.name(holder), "watch_motor", "{log}");
        let until = until.unwrap_or_else(|| panic!("the base stayed reserved:\n{log}"));
        // While reserved, no motion starts (the stretch under way may finish)...
        let started = story.motions_started_between(from, until);
        assert!(
            started.is_empty(),
            "motions started while the base was reserved: {started:?}\n{log}"
        );
        // ...and the robot stood long enough to cool from the warning to MOTOR_COOL_C.
        assert!(until - from >= Duration::from_secs(20), "{log}");
        // Motion resumes after it.
        assert!(
            !story
                .motions_started_between(until, Duration::MAX)
                .is_empty(),
            "{log}"
        );
    }
    assert!(story.triggers("watch_motor") >= 1);
    // The summary names the motion that waited for the base, and why.
    let wait = summary
        .resource_waits
        .iter()
        .find(|w| w.uses == "base")
        .unwrap_or_else(|| panic!("no wait for the base:\n{summary}"));
    assert!(wait.why.contains("reserved for watch_motor"), "{summary}");
    assert!(
        summary.to_string().contains("resource waits:  1"),
        "{summary}"
    );
    let mut delivered = summary.delivered.clone();
    delivered.sort_unstable();
    assert_eq!(delivered, [3, 7, 12], "{summary}");
    assert_eq!(summary.outcome, RunOutcome::Completed);
}

#[test]
fn the_same_seed_gives_the_same_trace_twice() {
    for sc in Scenario::ALL {
        let s = setup(7, sc, &[3, 7, 12]);
        let (_, a, _) = run_checked(&s);
        let (_, b, _) = run_checked(&s);
        assert!(a.len() > 500, "{sc}: {} records", a.len());
        assert_eq!(lines(&a), lines(&b), "{sc}");
    }
    // And a different seed gives a different run.
    let (_, a, _) = run_checked(&setup(7, Scenario::Nominal, &[3]));
    let (_, b, _) = run_checked(&setup(8, Scenario::Nominal, &[3]));
    assert_ne!(lines(&a), lines(&b));
}

#[test]
fn the_summary_names_exceptions_and_handlers() {
    let s = setup(1, Scenario::NoPath, &[12, 3]);
    let (summary, trace, _) = run_checked(&s);
    let text = summary.to_string();
    assert!(text.contains("delivered:       3"), "{text}");
    assert!(text.contains("room 12: NoPath"), "{text}");
    // Failures and warnings are counted; every failure of this scenario has a handler.
    let failures = summary.failures;
    assert!(failures >= 1, "{text}");
    assert!(
        text.contains(&format!(
            "failures:        {failures} (0 unhandled), 0 warning(s)"
        )),
        "{text}"
    );
    assert!(
        text.contains("-> handler give_up_no_path"),
        "{text}\n{}",
        log_of(&trace)
    );
    assert!(matches!(trace[0].kind, TraceKind::RunStarted { .. }));
}
