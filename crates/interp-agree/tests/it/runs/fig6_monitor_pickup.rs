//! `fig6_monitor_pickup.tdl`: the TDL paper's Figure 6, a polling monitor with limits, in Rust's
//! spelling and in the paper's. The file has only monitors, which do not run by themselves:
//! `drivers/fig6_monitor_pickup_driver.tdl` spawns each from a goal, compiled and loaded with
//! it. `mail_is_gone` says yes from its fourth reading on; `speak` and `notify_sender` are
//! commands built in Rust.

use tdl::Task;
use tdl_interp::Registry;

use crate::util::{Case, command, tick};

include!(concat!(env!("OUT_DIR"), "/fig6_monitor_pickup.rs"));
include!(concat!(env!("OUT_DIR"), "/fig6_monitor_pickup_driver.rs"));

fn mail_is_gone() -> bool {
    tick("mail") >= 3
}

fn speak(_text: &str) -> Task {
    command("speak", 800)
}

fn notify_sender() -> Task {
    command("notify_sender", 1200)
}

fn case() -> Case {
    let mut registry = Registry::new();
    registry
        .function("mail_is_gone", mail_is_gone)
        .task("speak", |text: String| speak(&text))
        .task("notify_sender", notify_sender);
    Case::new(
        &["fig6_monitor_pickup", "fig6_monitor_pickup_driver"],
        &registry,
    )
}

#[tokio::test(start_paused = true)]
async fn the_monitor_in_rust_spelling_runs_alike() {
    case().alike(watch_mail(), "watch_mail", vec![]).await;
}

#[tokio::test(start_paused = true)]
async fn the_monitor_in_the_papers_words_runs_alike() {
    case()
        .alike(watch_mail_paper(), "watch_mail_paper", vec![])
        .await;
}
