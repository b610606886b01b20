//! Nodes between TDL and Rust: `node!(tag)` gives a tag's node to Rust code, `bind name = node;`
//! makes a node held in Rust a tag, and `parent <node>` spawns under another node
//! (docs/language.md, "Tags, `previous` and groups").

use crate::util::{assert_order, only, run_checked, story};
use tdl::{NodeId, RunOutcome, Runtime, TraceKind};

async fn sleep_s(s: u64) {
    tokio::time::sleep(std::time::Duration::from_secs(s)).await;
}

tdl::tdl! {
    command sleeper() { std::future::pending::<()>().await; }
    command stopper(target: NodeId) { sleep_s(2).await; ctx.terminate(target)?; }
    command work() { sleep_s(1).await; }
    command after() { sleep_s(1).await; }
    goal host() { sleep_s(5).await; }

    // A tag's node handed to a task as an argument.
    goal hand_over() {
        s: spawn sleeper();
        spawn stopper(node!(s));
    }

    // A node spawned by hand, bound to a tag for TDL constraints.
    goal by_hand() {
        let w = ctx.spawn(work()).start()?;
        bind w_tag = w;
        spawn after() with sequential execution w_tag;
    }

    // A bind that did not run is a dead reference: enablement void, `terminate at` at once.
    goal maybe_bound(go: bool) {
        if go {
            let w = ctx.spawn(work()).start()?;
            bind w_tag = w;
        }
        spawn after() with sequential execution w_tag;
        spawn sleeper() with terminate at w_tag completed;
    }

    // Spawned under `host`, not under this body; a tag names it after its spawn.
    goal delegate() {
        h: spawn host();
        u: spawn work() with parent node!(h);
        spawn after() with sequential execution u;
    }
}

#[tokio::test(start_paused = true)]
async fn node_gives_a_tags_node_to_rust_code() {
    let (report, trace) = run_checked(Runtime::new(), hand_over()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_order(
        &story(&trace),
        &[
            "0 sleeper handling active",
            "2 sleeper terminating",
            "2 hand_over execution completed",
        ],
    );
}

#[tokio::test(start_paused = true)]
async fn bind_makes_a_node_held_in_rust_a_tag() {
    let (report, trace) = run_checked(Runtime::new(), by_hand()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_order(
        &story(&trace),
        &["1 work execution completed", "1 after handling active"],
    );

    let (report, trace) = run_checked(Runtime::new(), maybe_bound(true)).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(
        only(
            &story(&trace),
            &["after handling active", "sleeper terminating"]
        ),
        ["1 sleeper terminating", "1 after handling active"]
    );
    let (report, trace) = run_checked(Runtime::new(), maybe_bound(false)).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(
        only(
            &story(&trace),
            &["after handling active", "sleeper terminating"]
        ),
        ["0 sleeper terminating", "0 after handling active"]
    );
}

#[tokio::test(start_paused = true)]
async fn parent_spawns_under_another_node() {
    let (report, trace) = run_checked(Runtime::new(), delegate()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let spawned = |name: &str| {
        trace.iter().find_map(|ev| match &ev.kind {
            TraceKind::Spawned {
                node,
                parent,
                name: n,
                ..
            } if n == name => Some((*node, *parent)),
            _ => None,
        })
    };
    let (host, _) = spawned("host").expect("host spawned");
    let (_, under) = spawned("work").expect("work spawned");
    assert_eq!(under, host, "`work` is a child of `host`");
    assert_order(
        &story(&trace),
        &["1 work execution completed", "1 after handling active"],
    );
}
