//! TDL's `on AGENT` over zenoh: a TDL program whose spawns name agents, run with the executive as
//! the run's placer (`Runtime::placer`). The values come back typed, the tree's constraints hold,
//! a remote failure is handled by a TDL handler, and the trace names each node's agent.

use crate::util::{Log, Net, bounded, untimed};
use tcm::testing::{assert_order, run_checked};
use tcm::{RunOutcome, Runtime, TraceKind};
use tcm_zenoh::{RemoteCtx, RemoteFailure};

tdl::tdl! {
    exception Jammed;

    handler shrug() handles Jammed {
        let _ = ctx;
    }

    goal pick(n: i64) {
        let doubled: i64 = spawn double(n) with on "arm", wait;
        spawn double(doubled) with on "arm", sequential execution previous, name "again";
        spawn jam() with on "gripper", exception handler shrug();
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_tdl_program_places_its_spawns_on_the_agents_it_names() {
    bounded(async {
        let net = Net::new("tdl").await;
        let log = Log::default();
        let l = log.clone();
        let _arm = net
            .join(
                net.agent("arm")
                    .command("double", move |_: RemoteCtx, x: i64| {
                        let log = l.clone();
                        async move {
                            log.push(format!("double {x}"));
                            Ok::<_, RemoteFailure>(x * 2)
                        }
                    }),
                "arm",
            )
            .await;
        let _gripper = net
            .join(
                net.agent("gripper")
                    .command("jam", |_: RemoteCtx, (): ()| async move {
                        Err::<(), _>(RemoteFailure::new("Jammed", "a pebble in the jaw"))
                    }),
                "gripper",
            )
            .await;
        let rt = Runtime::new().placer(net.exec.clone());
        let (report, trace) = run_checked(rt, pick(21)).await;
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        // The second call got the first one's value, typed as an i64 and sent back as JSON.
        assert_eq!(log.entries(), ["double 21", "double 42"]);
        let story = untimed(&trace);
        assert_order(
            &story,
            &[
                "double execution completed",
                "again execution active",
                "shrug handling active",
            ],
        );
        let mut agents: Vec<String> = trace
            .iter()
            .filter_map(|ev| match &ev.kind {
                TraceKind::Placed { agent, .. } => Some(agent.clone()),
                _ => None,
            })
            .collect();
        agents.sort();
        assert_eq!(agents, ["arm", "arm", "gripper"]);
    })
    .await;
}
