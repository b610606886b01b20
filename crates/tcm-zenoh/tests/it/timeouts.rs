//! Timeouts of remote tasks in the style of durable workflows: schedule-to-start (no agent took
//! the task), start-to-close and heartbeat, each a typed `RemoteTimeout`; an agent whose task
//! timed out is told to cancel it, and what it says afterwards is late.

use crate::util::{Log, Net, bounded, untimed};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tcm::testing::{assert_order, handler_choices, run_checked};
use tcm::{Handler, RunOutcome, Runtime, Task};
use tcm_zenoh::{At, RemoteCtx, RemoteFailure, RemoteTimeout, TimeoutKind};

fn ms(n: u64) -> Duration {
    Duration::from_millis(n)
}

/// A handler of `RemoteTimeout` that keeps what it caught.
fn keep(caught: &Arc<Mutex<Vec<RemoteTimeout>>>) -> Handler {
    let caught = caught.clone();
    Handler::on::<RemoteTimeout, _, _, _>("on_timeout", move |ctx| {
        let caught = caught.clone();
        async move {
            let t = tcm_zenoh::caught::<RemoteTimeout>(&ctx).expect("a RemoteTimeout");
            caught.lock().expect("caught").push(t);
            Ok(())
        }
    })
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_task_no_agent_offers_times_out_before_it_starts() {
    bounded(async {
        let net = Net::new("sts").await;
        // Live, but offering something else.
        let other = net
            .agent("other")
            .command("else", |_: RemoteCtx, (): ()| async {
                Ok::<_, RemoteFailure>(())
            });
        let _other = net.join(other, "other").await;
        let caught = Arc::new(Mutex::new(Vec::new()));
        let (h1, h2) = (keep(&caught), keep(&caught));
        let exec = net.exec.clone();
        let start = Instant::now();
        let main = Task::goal("main", move |ctx| async move {
            ctx.spawn(
                exec.remote(At::Any, "nobody", ())
                    .schedule_to_start(Some(ms(300)))
                    .task(),
            )
            .handler(h1)
            .start()?;
            ctx.spawn(
                exec.remote("other", "nobody", ())
                    .schedule_to_start(Some(ms(200)))
                    .task(),
            )
            .handler(h2)
            .start()?;
            Ok(())
        });
        let (report, trace) = run_checked(Runtime::new(), main).await;
        let elapsed = start.elapsed();
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        assert!(report.unhandled.is_empty(), "{report}");
        assert!(
            elapsed >= ms(300) && elapsed < Duration::from_secs(5),
            "{elapsed:?}"
        );
        assert_eq!(handler_choices(&trace).len(), 2);
        let caught = caught.lock().expect("caught").clone();
        assert_eq!(
            caught,
            [
                RemoteTimeout {
                    kind: TimeoutKind::ScheduleToStart,
                    task: "nobody".into(),
                    agent: Some("other".into()),
                    after_ms: 200,
                },
                RemoteTimeout {
                    kind: TimeoutKind::ScheduleToStart,
                    task: "nobody".into(),
                    agent: None,
                    after_ms: 300,
                },
            ]
        );
        assert_eq!(net.exec.placements(), []);
        assert_eq!(net.exec.stats().timeouts, 2);
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_body_that_stops_heartbeating_or_runs_too_long_times_out_and_is_cancelled() {
    bounded(async {
        let net = Net::new("hb").await;
        let log = Log::default();
        let (l1, l2, l3) = (log.clone(), log.clone(), log.clone());
        let agent = net
            .agent("slow")
            .command("watch", move |ctx: RemoteCtx, (): ()| {
                let log = l1.clone();
                async move {
                    for _ in 0..3 {
                        tokio::time::sleep(ms(20)).await;
                        ctx.heartbeat().await;
                    }
                    log.push("watch stops heartbeating");
                    tokio::time::sleep(Duration::from_secs(3600)).await;
                    Ok::<_, RemoteFailure>(())
                }
            })
            .on_terminate("watch", move |(): ()| {
                let log = l2.clone();
                async move { log.push("watch cleanup") }
            })
            .command("long", |_: RemoteCtx, (): ()| async {
                tokio::time::sleep(Duration::from_secs(3600)).await;
                Ok::<_, RemoteFailure>(())
            })
            .on_terminate("long", move |(): ()| {
                let log = l3.clone();
                async move { log.push("long cleanup") }
            });
        let slow = net.join(agent, "slow").await;
        let caught = Arc::new(Mutex::new(Vec::new()));
        let (h1, h2) = (keep(&caught), keep(&caught));
        let exec = net.exec.clone();
        let main = Task::goal("main", move |ctx| async move {
            ctx.spawn(exec.remote("slow", "watch", ()).heartbeat(ms(400)).task())
                .handler(h1)
                .start()?;
            ctx.spawn(
                exec.remote("slow", "long", ())
                    .start_to_close(ms(1000))
                    .task(),
            )
            .handler(h2)
            .start()?;
            Ok(())
        });
        let (report, trace) = run_checked(Runtime::new(), main).await;
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        assert!(report.unhandled.is_empty(), "{report}");
        assert_order(
            &untimed(&trace),
            &["watch failed RemoteTimeout", "long failed RemoteTimeout"],
        );
        let kinds: Vec<TimeoutKind> = caught
            .lock()
            .expect("caught")
            .iter()
            .map(|t| t.kind)
            .collect();
        assert_eq!(kinds, [TimeoutKind::Heartbeat, TimeoutKind::StartToClose]);
        // Both bodies were cancelled on the agent; their confirmations came after the executive
        // had given up on them: late, ignored.
        log.wait_for("watch cleanup", Duration::from_secs(5)).await;
        log.wait_for("long cleanup", Duration::from_secs(5)).await;
        let start = Instant::now();
        while net.exec.stats().late < 2 {
            assert!(
                start.elapsed() < Duration::from_secs(5),
                "{:?}",
                net.exec.stats()
            );
            tokio::time::sleep(ms(5)).await;
        }
        let stats = net.exec.stats();
        assert_eq!(
            (stats.timeouts, stats.late, stats.cancelled),
            (2, 2, 0),
            "{stats:?}"
        );
        assert_eq!(slow.stats().cancelled, 2);
        assert_eq!(log.entries()[0], "watch stops heartbeating");
    })
    .await;
}
