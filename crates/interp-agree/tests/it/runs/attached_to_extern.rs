//! `attached_to_extern.tdl`: a program of recovery alone, its handlers attached with `for` to
//! `bump`, a task it only declares `extern` (a Rust command here, blocked for odd numbers).
//! `drivers/attached_to_extern_driver.tdl` spawns three bumps; the first handler attached,
//! `back_off`, takes each blocked one, and the wiretap `steady` checks each before it starts.

use std::time::Duration;

use tdl::{NodeKind, Task};
use tdl_interp::Registry;

use crate::util::Case;

include!(concat!(env!("OUT_DIR"), "/attached_to_extern.rs"));
include!(concat!(env!("OUT_DIR"), "/attached_to_extern_driver.rs"));

fn bump(i: i64) -> Task {
    Task::new(NodeKind::Command, "bump", move |_ctx| async move {
        tokio::time::sleep(Duration::from_millis(100)).await;
        if i % 2 == 1 {
            Err(tdl::Failure::new("Blocked", format!("bump {i} is blocked")))
        } else {
            Ok(())
        }
    })
}

fn case() -> Case {
    let mut registry = Registry::new();
    registry.task("bump", bump);
    Case::new(
        &["attached_to_extern", "attached_to_extern_driver"],
        &registry,
    )
    .attached(|| vec![back_off(), retry_higher()])
    .taps(|| vec![steady()])
}

#[tokio::test(start_paused = true)]
async fn recovery_attached_to_an_extern_task_runs_alike() {
    case().alike(bumps(), "bumps", vec![]).await;
}

#[tokio::test(start_paused = true)]
async fn the_wiretap_checks_every_bump() {
    let rec = tdl::Recorder::new();
    tdl::Runtime::new()
        .tap(steady())
        .attach(back_off())
        .with_sink(rec.clone())
        .run(bumps())
        .await
        .expect("the run ends");
    let tapped = rec
        .events()
        .iter()
        .filter(|e| matches!(&e.kind, tdl::TraceKind::Tapped { when, .. } if when == "before"))
        .count();
    assert_eq!(tapped, 3);
}
