//! The canonical spelling reads back as itself: each constraint below, parsed on a spawn and
//! printed, is the text it came from.

use crate::ast::{Item, Stmt};

/// The constraints of the first spawn of `src`, printed.
fn printed(with: &str) -> Vec<String> {
    let src = format!(
        "exception E; handler h(n: u32) handles E {{ bypass; }} \
         goal g(n: u32) {{ a: spawn t(); spawn u(n) with {with}; }}"
    );
    let parse = crate::parse_str("p.tdl", &src);
    assert!(!parse.has_errors(), "{with}: {:?}", parse.diagnostics);
    let Some(Item::Task(task)) = parse
        .file
        .items
        .iter()
        .find(|it| matches!(it, Item::Task(t) if t.name == "g"))
    else {
        panic!("no goal g");
    };
    let Stmt::Spawn(spawn) = &task.body.stmts[1] else {
        panic!("no second spawn");
    };
    spawn
        .constraints
        .iter()
        .map(|c| {
            let mut out = String::new();
            super::constraint(&c.kind, &mut out);
            out
        })
        .collect()
}

#[test]
fn constraints_print_as_they_are_written() {
    for written in [
        "sequential execution a",
        "sequential expansion",
        "serial a",
        "serial",
        "wait",
        "terminate in 30s",
        "terminate in 2s after a execution completed",
        "terminate at a completed",
        "disable until 09:00:00",
        "disable execution until 13:05:07.25",
        "disable for 200ms",
        "disable until a handling active",
        "disable until external \"door open\"",
        "disable until external (format!(\"door {n}\"))",
        "activate in (n as f64 * 0.5)",
        "maximum activate 3",
        "maximum trigger (n + 1)",
        "period 1500ms",
        "exception handler h(n + 1) maximum activate 2",
        "on terminate t()",
        "on terminate l: spawn t()",
        "name format!(\"u{n}\")",
        "deny if busy",
        "priority (n as i32)",
    ] {
        assert_eq!(printed(written), [written], "{written}");
    }
}

#[test]
fn times_of_day_and_durations_have_one_spelling() {
    assert_eq!(
        printed("disable until 9:00:00, terminate in 0:0:30.0"),
        ["disable until 09:00:00", "terminate in 30s"]
    );
}
