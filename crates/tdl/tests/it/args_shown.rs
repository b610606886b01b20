//! A node's arguments in its `spawned` record (issue 48, item 12; docs/trace-format.md): each
//! goal's and command's node tells the arguments it was spawned with, `name = value, …`, as
//! `tdl::ShowArg` shows them, so the viewer can show them in the node's details. A type that is no
//! `ShowArg` shows as `…`; a program shows its own types by implementing it.

use crate::util::run_checked;
use std::collections::HashMap;
use std::fmt::Write as _;
use tdl::{RunOutcome, Runtime, ShowArg, TraceKind};

/// A room, shown by its name.
#[derive(Clone)]
pub(crate) struct Room(&'static str);

impl ShowArg for Room {
    fn show_arg(&self, out: &mut String) {
        let _ = write!(out, "room {}", self.0);
    }
}

/// Not shown: its contents would change between runs.
#[derive(Clone, Default)]
pub(crate) struct Counts(HashMap<String, u32>);

tdl::tdl! {
    command visit(room: Room, tries: u32, note: Option<String>, counts: Counts) {
        let _ = (room, tries, note, counts.0.len());
    }

    command idle() {}

    goal round(rooms: Vec<&'static str>, speed: f64) {
        for name in rooms {
            spawn visit(Room(name), 3, Some(format!("to {name}")), Counts::default());
        }
        spawn idle();
        let _ = speed;
    }
}

#[tokio::test(start_paused = true)]
async fn a_nodes_spawned_record_tells_the_arguments_it_was_given() {
    let rooms: Vec<&'static str> = (0..10).map(|i| ["lab", "hall"][i % 2]).collect();
    let (report, trace) = run_checked(Runtime::new(), round(rooms, 0.5)).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let args: Vec<(String, Option<String>)> = trace
        .iter()
        .filter_map(|e| match &e.kind {
            TraceKind::Spawned { name, args, .. } => Some((name.clone(), args.clone())),
            _ => None,
        })
        .collect();
    let shown = |name: &str| -> Vec<Option<&str>> {
        args.iter()
            .filter(|(n, _)| n == name)
            .map(|(_, a)| a.as_deref())
            .collect()
    };
    // A list is cut after eight items.
    assert_eq!(
        shown("round"),
        [Some(
            r#"rooms = ["lab", "hall", "lab", "hall", "lab", "hall", "lab", "hall", …], speed = 0.5"#
        )]
    );
    assert_eq!(
        shown("visit")[..2],
        [
            Some(r#"room = room lab, tries = 3, note = Some("to lab"), counts = …"#),
            Some(r#"room = room hall, tries = 3, note = Some("to hall"), counts = …"#),
        ]
    );
    // A task without arguments tells none.
    assert_eq!(shown("idle"), [None]);
}
