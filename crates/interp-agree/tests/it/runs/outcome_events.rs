//! `outcome_events.tdl`: `succeeded`, `failed` and `terminated` beside `completed`, for a
//! fallback and a watchdog. Every task is declared in the file.

use tdl::Task;
use tdl_interp::Registry;

use crate::util::Case;

include!(concat!(env!("OUT_DIR"), "/outcome_events.rs"));

#[tokio::test(start_paused = true)]
async fn a_fallback_on_outcome_events_runs_alike() {
    let case = Case::new(&["outcome_events"], &Registry::new());
    case.alike(fallback(), "fallback", vec![]).await;
    for (compiled, name) in [
        (plan as fn() -> Task, "plan"),
        (backup, "backup"),
        (give_up, "give_up"),
        (watchdog, "watchdog"),
    ] {
        case.alike(compiled(), name, vec![]).await;
    }
}
