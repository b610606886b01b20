//! Unit tests for `textlog.rs`: exact TCM lines, column for column, from hand-made traces.

use super::{TextLog, TextLogOptions, time_suffix};
use crate::event::TraceKind;
use crate::state::NodeKind;
use crate::test_util::*;

const PLAIN: TextLogOptions = TextLogOptions {
    time: false,
    trace: false,
};

#[test]
fn standard_lines_of_a_small_run() {
    let text = TextLog::render(PLAIN, &small_run());
    assert_eq!(
        text,
        "\
Goal              deliver {1}:        TCM {0} --> ON HOLD         (Inactive)
Goal              deliver {1}:  ON HOLD  --> TCM             (Sent)
Command             speak {2}:        TCM {1} --> ON HOLD         (Inactive)
  Success         deliver {1}:
Command             speak {2}:  ON HOLD  --> TCM             (Sent)
  Success           speak {2}:
"
    );
}

#[test]
fn tcm_log_examples_column_for_column() {
    let mut b = Tb::new();
    b.goal(1, 0, "A")
        .start_goal(1)
        .command(2, 1, "B")
        .tr(1, H, A, C);
    b.spawn(5, 0, NodeKind::Monitor, "monitor")
        .start_command(5)
        .tr(5, H, A, C);
    let text = TextLog::render(PLAIN, &b.build());
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(
        lines[0],
        "Goal                    A {1}:        TCM {0} --> ON HOLD         (Inactive)"
    );
    assert_eq!(
        lines[1],
        "Goal                    A {1}:  ON HOLD  --> TCM             (Sent)"
    );
    assert_eq!(
        lines[2],
        "Command                 B {2}:        TCM {1} --> ON HOLD         (Inactive)"
    );
    assert_eq!(lines[3], "  Success               A {1}:");
    assert_eq!(
        lines[4],
        "Monitor           monitor {5}:        TCM {0} --> ON HOLD         (Inactive)"
    );
    assert_eq!(
        lines[5],
        "Monitor           monitor {5}:  ON HOLD  --> TCM             (Sent)"
    );
    assert_eq!(lines[6], " Complete         monitor {5}:");
    assert_eq!(lines.len(), 7);
}

#[test]
fn long_names_overflow_and_failures_and_warnings() {
    let mut b = Tb::new();
    b.command(2, 0, "ACT-foo-auto,wait").start_command(2);
    b.push(TraceKind::Failed {
        node: 2,
        exception: "Stuck".into(),
        message: "no door".into(),
    });
    b.push(TraceKind::Warning {
        node: Some(2),
        message: "No exception handler found for exception type \"Stuck\"".into(),
    });
    b.tr(2, H, A, C);
    let text = TextLog::render(PLAIN, &b.build());
    assert_eq!(
        text,
        "\
Command   ACT-foo-auto,wait {2}:        TCM {0} --> ON HOLD         (Inactive)
Command   ACT-foo-auto,wait {2}:  ON HOLD  --> TCM             (Sent)
WARNING: No exception handler found for exception type \"Stuck\"
  Failure ACT-foo-auto,wait {2}:
"
    );
}

#[test]
fn termination_suppresses_handling_lines() {
    let mut b = Tb::new();
    b.goal(1, 0, "a")
        .start_goal(1)
        .command(2, 1, "c")
        .tr(1, H, A, C)
        .tr(1, P, A, C);
    b.push(TraceKind::Suspended { node: 2 })
        .push(TraceKind::Unsuspended { node: 2 });
    b.push(TraceKind::Terminating { node: 1 })
        .push(TraceKind::Terminating { node: 2 });
    b.tr(2, H, D, C).tr(2, X, D, C);
    b.push(TraceKind::Terminated { node: 2 });
    let text = TextLog::render(PLAIN, &b.build());
    assert_eq!(
        text,
        "\
Goal                    a {1}:        TCM {0} --> ON HOLD         (Inactive)
Goal                    a {1}:  ON HOLD  --> TCM             (Sent)
Command                 c {2}:        TCM {1} --> ON HOLD         (Inactive)
  Success               a {1}:
Suspended c {2}
Unsuspended c {2}
Will Terminate a {1} when all references to it are released
Will Terminate c {2} when all references to it are released
Terminated c {2}
"
    );
}

#[test]
fn time_suffix_is_hours_minutes_seconds_hundredths() {
    assert_eq!(time_suffix(0), "   0:00:00.00");
    assert_eq!(time_suffix(3_723 * S + 456_000_000), "   1:02:03.45");
    assert_eq!(time_suffix(100 * 3_600 * S), " 100:00:00.00");
    let mut b = Tb::new();
    b.at(90 * S + S / 4).goal(1, 0, "A");
    let text = TextLog::render(
        TextLogOptions {
            time: true,
            trace: false,
        },
        &b.build(),
    );
    assert_eq!(
        text,
        "Goal                    A {1}:        TCM {0} --> ON HOLD         (Inactive)   0:01:30.25\n"
    );
}

#[test]
fn trace_mode_adds_transition_lines() {
    let mut b = Tb::new();
    b.goal(1, 0, "centerOnDoor")
        .start_goal(1)
        .tr(1, X, D, E)
        .tr(1, H, A, C);
    b.push(TraceKind::Terminating { node: 1 })
        .tr(1, P, A, C)
        .tr(1, X, E, C);
    b.push(TraceKind::Terminated { node: 1 })
        .push(TraceKind::Reclaimed { node: 1 });
    let mut log = TextLog::new(TextLogOptions {
        time: false,
        trace: true,
    });
    let mut out = Vec::new();
    for ev in b.build() {
        assert!(log.write(&ev, &mut out).is_ok());
    }
    assert_eq!(
        String::from_utf8(out).unwrap_or_default(),
        "\
Goal         centerOnDoor {1}:        TCM {0} --> ON HOLD         (Inactive)
centerOnDoor transitioning from Unhandled to Handling
Goal         centerOnDoor {1}:  ON HOLD  --> TCM             (Sent)
centerOnDoor transitioning from Unplanned to Planning
centerOnDoor transitioning from Handling to Handled
  Success    centerOnDoor {1}:
centerOnDoor transitioning from Alive to Terminating
Will Terminate centerOnDoor {1} when all references to it are released
centerOnDoor transitioning from Planning to Planned
centerOnDoor transitioning from Unachieved to Achieved
centerOnDoor transitioning from Terminating to Terminated
Terminated centerOnDoor {1}
Deleting centerOnDoor
"
    );
}
