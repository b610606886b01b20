//! Forward references (constraint statements on spawns further down) and dead references (tags
//! of spawns that never ran: enablement on them is void, `terminate at` them fires at once).

use crate::util::{assert_order, run_checked, story};
use tdl::{RunOutcome, Runtime};

async fn sleep_s(s: u64) {
    tokio::time::sleep(std::time::Duration::from_secs(s)).await;
}

tdl::tdl! {
    command fetch_part(n: u32) { assert!(n > 0); sleep_s(2).await; }
    command optional() { sleep_s(5).await; }
    command after() { sleep_s(1).await; }
    command watcher() { std::future::pending::<()>().await; }

    goal fetch() {
        f2 serial f1;
        f2 terminate in 10s;
        f1: spawn fetch_part(1) with name "part-1";
        f2: spawn fetch_part(2) with name "part-2";
        f2 wait;
        spawn after();
    }

    goal chained() {
        a: spawn fetch_part(1) with name "part-a";
        b: spawn fetch_part(2) with name "part-b";
        // After both spawns: the children only start when the body ends, so this applies.
        b serial a;
        b disable execution for 1s after a completed;
    }

    goal maybe(go: bool) {
        if go {
            opt: spawn optional();
        }
        spawn after() with sequential execution opt;
        spawn watcher() with terminate at opt completed;
    }
}

#[tokio::test(start_paused = true)]
async fn constraint_statements_apply_to_later_spawns() {
    let (report, trace) = run_checked(Runtime::new(), fetch()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let st = story(&trace);
    // `f2 serial f1` was stated before either spawn; `f2 wait` blocks the body until part-2 is
    // done, so `after` starts at 4.
    assert_order(
        &st,
        &[
            "0 part-1 handling active",
            "2 part-1 execution completed",
            "2 part-2 handling active",
            "4 part-2 execution completed",
            "4 after handling active",
            "5 fetch execution completed",
        ],
    );
}

#[tokio::test(start_paused = true)]
async fn constraint_statements_after_the_spawn_apply() {
    let (report, trace) = run_checked(Runtime::new(), chained()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let st = story(&trace);
    // Without `b serial a` both parts would start at 0; with it, part-b waits for part-a (done at
    // 2) and then 1 s more.
    assert!(
        !st.contains(&"0 part-b handling active".to_owned()),
        "{st:#?}"
    );
    assert_order(
        &st,
        &[
            "0 part-a handling active",
            "2 part-a execution completed",
            "3 part-b execution active",
            "5 part-b execution completed",
            "5 chained execution completed",
        ],
    );
}

#[tokio::test(start_paused = true)]
async fn references_to_a_spawn_that_never_ran_are_dead() {
    let (report, trace) = run_checked(Runtime::new(), maybe(false)).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let st = story(&trace);
    assert_order(
        &st,
        &[
            "0 watcher terminated",
            "0 after handling active",
            "1 maybe execution completed",
        ],
    );
    // The reservation for `opt` dies with the body; nothing of it ever runs.
    assert!(st.iter().any(|l| l.ends_with(" dead")), "{st:?}");
    assert!(
        !st.iter()
            .any(|l| l.contains("optional") && !l.ends_with(" dead")),
        "{st:?}"
    );

    let (_, trace) = run_checked(Runtime::new(), maybe(true)).await;
    let st = story(&trace);
    assert_order(
        &st,
        &[
            "0 optional handling active",
            "5 optional execution completed",
            "5 watcher terminating",
            "5 after handling active",
            "6 maybe execution completed",
        ],
    );
}

tdl::tdl! {
    persistent command keepsake() { sleep_s(1).await; }
    command ephemeral() { sleep_s(1).await; }
    goal keep_one() {
        spawn keepsake();
        spawn ephemeral();
    }
}

#[tokio::test(start_paused = true)]
async fn a_persistent_task_is_kept_after_it_completes() {
    let (report, trace) = run_checked(Runtime::new(), keep_one()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let mut names = std::collections::BTreeMap::new();
    let mut reclaimed = Vec::new();
    for ev in &trace {
        match &ev.kind {
            tdl::TraceKind::Spawned { node, name, .. } => {
                names.insert(*node, name.clone());
            }
            tdl::TraceKind::Reclaimed { node } => {
                reclaimed.push(names.get(node).cloned().unwrap_or_default())
            }
            _ => {}
        }
    }
    assert!(
        reclaimed.contains(&"ephemeral".to_string()),
        "{reclaimed:?}"
    );
    assert!(
        !reclaimed.contains(&"keepsake".to_string()),
        "a persistent node is never reclaimed: {reclaimed:?}"
    );
    assert!(
        report.stats.live_nodes >= 3,
        "root, keep_one and keepsake stay: {:?}",
        report.stats
    );
}
