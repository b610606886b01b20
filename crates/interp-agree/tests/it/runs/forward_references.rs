//! `forward_references.tdl`: constraint statements on earlier and later spawns, labels as tags,
//! `self` and `parent` in events. The tasks it spawns without declaring them are commands built
//! in Rust here, of different lengths; `mail_is_gone` says yes from its second reading on.

use tdl::Task;
use tdl_interp::Registry;

use crate::util::{Case, command, tick};

include!(concat!(env!("OUT_DIR"), "/forward_references.rs"));

fn mail_is_gone() -> bool {
    tick("mail") >= 1
}

fn fetch_part(n: u32) -> Task {
    command("fetch_part", 400 * u64::from(n))
}

fn stop_all() -> Task {
    command("stop_all", 100)
}

fn tidy() -> Task {
    command("tidy", 5000)
}

fn a(n: u32) -> Task {
    command("a", 300 * u64::from(n))
}

fn b(n: u32) -> Task {
    command("b", 200 * u64::from(n))
}

#[tokio::test(start_paused = true)]
async fn forward_references_run_alike() {
    let mut registry = Registry::new();
    registry
        .function("mail_is_gone", mail_is_gone)
        .task("fetch_part", fetch_part)
        .task("stop_all", stop_all)
        .task("tidy", tidy)
        .task("a", a)
        .task("b", b);
    Case::new(&["forward_references"], &registry)
        .alike(fetch(), "fetch", vec![])
        .await;
}
