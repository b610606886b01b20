//! `handlers_retry.tdl`: a handler that retries the failed task, reads the exception's data and
//! the nodes involved, and counts its uses. `move_to` is a command built in Rust here: blocked
//! by a cart twice, then through. It raises the program's exception `Blocked`: the compiled
//! program's Rust type, or for the interpreted program the same failure (name, message) carrying
//! the fields as a record, as the interpreter's own `fail` does. `log` writes a note; the
//! handler's notes print `failing` and `attached`, the nodes involved, the same in both.

use std::sync::Arc;
use std::time::Duration;

use tdl::{Exception as _, Failure, NodeKind, Task};
use tdl_interp::{Record, Registry, Value};

use crate::util::{Case, Compare, command, note, tick};

include!(concat!(env!("OUT_DIR"), "/handlers_retry.rs"));

fn log(text: String) {
    note(text);
}

/// `move_to`, raising `Blocked { by }` as `blocked` makes it.
fn move_to_raising(_x: f64, blocked: fn(String) -> Failure) -> Task {
    Task::retryable(NodeKind::Command, "move_to", move |_ctx| async move {
        tokio::time::sleep(Duration::from_millis(700)).await;
        if tick("move") < 2 {
            return Err(blocked("a cart".into()));
        }
        Ok(())
    })
}

fn move_to(x: f64) -> Task {
    move_to_raising(x, |by| Blocked { by }.raise())
}

/// `Blocked { by }` as the interpreter raises a declared exception: its `Debug` the message,
/// its fields a record.
fn blocked_record(by: String) -> Failure {
    let message = format!("{:?}", Blocked { by: by.clone() });
    let mut failure = Failure::new("Blocked", message);
    failure.data = Some(Arc::new(Value::Record(Arc::new(Record {
        name: Arc::from("Blocked"),
        fields: vec![(Arc::from("by"), Value::str(by))],
    }))));
    failure
}

fn say_done() -> Task {
    command("say_done", 300)
}

fn case() -> Case {
    let mut registry = Registry::new();
    registry
        .function("log", log)
        .task("move_to", |x: f64| move_to_raising(x, blocked_record))
        .task("say_done", say_done);
    Case::new(&["handlers_retry"], &registry)
}

#[tokio::test(start_paused = true)]
async fn a_move_retried_by_its_handler_traces_alike() {
    case()
        .compare(Compare::TraceOnly)
        .alike(deliver(), "deliver", vec![])
        .await;
}

#[tokio::test(start_paused = true)]
async fn a_move_retried_by_its_handler_runs_alike() {
    case().alike(deliver(), "deliver", vec![]).await;
}
