//! Resources on the runtime (docs/semantics.md, "Resources"), on tokio's paused clock: capacity,
//! priority, all or nothing, reserve and lock from an action, the pending limit and denial as
//! typed exceptions a handler takes, release on every way a task ends (a cancelled action keeps
//! its grant through its grace period), task-level uses, errors, a wait cycle reported as stuck,
//! and the text log naming the holders of what a task waits for. Every trace goes through the
//! checker.

use crate::util::{only, run_checked, story};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tcm::{
    Ctx, Facet, Failure, Handler, Resource, ResourceDenied, ResourceDropped, RunOutcome, Runtime,
    Task,
};

fn secs(s: f64) -> Duration {
    Duration::from_secs_f64(s)
}

/// A command that sleeps `s` seconds.
fn sleeps(name: &'static str, s: f64) -> Task {
    Task::command(name, move |_| async move {
        tokio::time::sleep(secs(s)).await;
        Ok(())
    })
}

/// The story lines about resources, failures and terminations.
fn resource_lines(trace: &[tcm::TraceEvent]) -> Vec<String> {
    only(
        &story(trace),
        &[
            "requests",
            "granted",
            "released",
            "withdrawn",
            "denied",
            "dropped",
            "reserved",
            "locked",
            "failed",
            "terminat",
        ],
    )
}

#[tokio::test(start_paused = true)]
async fn a_third_user_of_two_arms_waits_until_one_is_free() {
    let mission = Task::goal("mission", |ctx| async move {
        ctx.spawn(sleeps("a", 3.0)).uses("arm", 1).start()?;
        ctx.spawn(sleeps("b", 5.0)).uses("arm", 1).start()?;
        ctx.spawn(sleeps("c", 1.0)).uses("arm", 1).start()?;
        Ok(())
    });
    let (report, trace) = run_checked(Runtime::new().resource("arm", 2), mission).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(report.elapsed, secs(5.0));
    assert_eq!(
        only(&story(&trace), &["granted", "released"]),
        [
            "0 a granted arm",
            "0 b granted arm",
            "3 a released arm",
            "3 c granted arm",
            "4 c released arm",
            "5 b released arm",
        ]
    );
}

#[tokio::test(start_paused = true)]
async fn lower_priority_first_then_request_order() {
    let mission = Task::goal("mission", |ctx| async move {
        ctx.spawn(sleeps("holder", 2.0)).uses("base", 1).start()?;
        ctx.spawn(sleeps("x", 1.0))
            .uses("base", 1)
            .priority(5)
            .start()?;
        ctx.spawn(sleeps("y", 1.0))
            .uses("base", 1)
            .priority(1)
            .start()?;
        ctx.spawn(sleeps("z", 1.0))
            .uses("base", 1)
            .priority(1)
            .start()?;
        Ok(())
    });
    let (_, trace) = run_checked(Runtime::new().resource("base", 1), mission).await;
    assert_eq!(
        only(&story(&trace), &["granted"]),
        [
            "0 holder granted base",
            "2 y granted base",
            "3 z granted base",
            "4 x granted base",
        ]
    );
}

#[tokio::test(start_paused = true)]
async fn a_task_needing_base_and_arm_holds_neither_while_the_arm_is_busy() {
    let mission = Task::goal("mission", |ctx| async move {
        ctx.spawn(sleeps("wave", 5.0)).uses("arm", 1).start()?;
        ctx.spawn(sleeps("fetch", 1.0))
            .uses("base", 1)
            .uses("arm", 1)
            .start()?;
        // Granted the base at once: `fetch` does not hold it while it waits for the arm.
        ctx.spawn(sleeps("patrol", 2.0))
            .uses("base", 1)
            .priority(-1)
            .start()?;
        Ok(())
    });
    let rt = Runtime::new().resource("base", 1).resource("arm", 1);
    let (_, trace) = run_checked(rt, mission).await;
    assert_eq!(
        only(&story(&trace), &["granted", "released"]),
        [
            "0 wave granted arm",
            "0 patrol granted base",
            "2 patrol released base",
            "5 wave released arm",
            "5 fetch granted base, arm",
            "6 fetch released base, arm",
        ]
    );
}

#[tokio::test(start_paused = true)]
async fn a_resource_reserved_by_an_action_goes_to_its_subtree_only() {
    let plan = Task::goal("plan", |ctx| async move {
        ctx.reserve_resource("base", ctx.node())?;
        ctx.spawn(sleeps("own_move", 1.0)).uses("base", 1).start()?;
        ctx.spawn(sleeps("own_turn", 1.0))
            .uses("base", 1)
            .disable_for(Facet::Handling, secs(2.0))
            .start()?;
        Ok(())
    });
    let mission = Task::goal("mission", |ctx| async move {
        ctx.spawn(plan).start()?;
        // Asks while `plan` holds the reservation, and before its second move.
        ctx.spawn(sleeps("stranger", 1.0))
            .uses("base", 1)
            .disable_for(Facet::Handling, secs(0.5))
            .start()?;
        Ok(())
    });
    let (_, trace) = run_checked(Runtime::new().resource("base", 1), mission).await;
    assert_eq!(
        resource_lines(&trace),
        [
            "0 base reserved for plan",
            "0 own_move requests base",
            "0 own_move granted base",
            "0.5 stranger requests base",
            "1 own_move released base",
            "2 own_turn requests base",
            "2 own_turn granted base",
            "3 own_turn released base",
            "3 base unreserved",
            "3 stranger granted base",
            "4 stranger released base",
        ]
    );
}

#[tokio::test(start_paused = true)]
async fn a_locked_resource_waits_for_its_unlock() {
    let mission = Task::goal("mission", |ctx| async move {
        ctx.lock_resource("camera")?;
        ctx.spawn(sleeps("snap", 1.0)).uses("camera", 1).start()?;
        ctx.spawn(Task::command("calibrated", |ctx| async move {
            ctx.unlock_resource("camera")?;
            Ok(())
        }))
        .disable_for(Facet::Handling, secs(3.0))
        .start()?;
        Ok(())
    });
    let (_, trace) = run_checked(Runtime::new().resource("camera", 1), mission).await;
    assert_eq!(
        resource_lines(&trace),
        [
            "0 camera locked",
            "0 snap requests camera",
            "3 camera unlocked",
            "3 snap granted camera",
            "4 snap released camera",
        ]
    );
}

#[tokio::test(start_paused = true)]
async fn past_the_pending_limit_the_oldest_is_dropped_with_a_typed_exception() {
    let seen: Arc<Mutex<Vec<String>>> = Arc::default();
    let seen2 = seen.clone();
    let on_dropped = Handler::on::<ResourceDropped, _, _, _>("requeue", move |ctx: Ctx| {
        let seen = seen2.clone();
        async move {
            if let Some(d) = ctx.caught::<ResourceDropped>() {
                seen.lock().expect("lock").push(d.resource.clone());
            }
            Ok::<_, Failure>(())
        }
    });
    let mission = Task::goal("mission", move |ctx| async move {
        ctx.spawn(sleeps("holder", 5.0)).uses("arm", 1).start()?;
        ctx.spawn(sleeps("first", 1.0))
            .uses("arm", 1)
            .handler(on_dropped)
            .start()?;
        ctx.spawn(sleeps("second", 1.0)).uses("arm", 1).start()?;
        Ok(())
    });
    let rt = Runtime::new().declare(Resource::new("arm", 1).pending_limit(1));
    let (report, trace) = run_checked(rt, mission).await;
    assert!(report.unhandled.is_empty(), "{report}");
    assert_eq!(*seen.lock().expect("lock"), ["arm"]);
    assert_eq!(
        resource_lines(&trace),
        [
            "0 holder requests arm",
            "0 holder granted arm",
            "0 first requests arm",
            "0 second requests arm",
            "0 first dropped arm",
            "0 first failed ResourceDropped",
            "5 holder released arm",
            "5 second granted arm",
            "6 second released arm",
        ]
    );
}

#[tokio::test(start_paused = true)]
async fn a_request_that_may_not_wait_is_denied_with_a_typed_exception() {
    let mission = Task::goal("mission", |ctx| async move {
        ctx.spawn(sleeps("video", 5.0)).uses("camera", 1).start()?;
        let snap = ctx
            .spawn(sleeps("snap", 1.0))
            .uses("camera", 1)
            .deny_if_busy()
            .wait_outcome::<()>()
            .await?;
        let denied = snap.failure().and_then(|f| f.data::<ResourceDenied>());
        assert_eq!(
            denied.map(|d| d.reason.clone()).as_deref(),
            Some("1 of 1 of `camera` are held by video {2}")
        );
        assert!(snap.failed_with::<ResourceDenied>());
        Ok(())
    });
    let (report, trace) = run_checked(Runtime::new().resource("camera", 1), mission).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(
        resource_lines(&trace),
        [
            "0 video requests camera",
            "0 video granted camera",
            "0 snap requests camera",
            "0 snap denied camera",
            "0 snap failed ResourceDenied",
            "5 video released camera",
        ]
    );
}

#[tokio::test(start_paused = true)]
async fn released_when_a_task_fails_is_terminated_running_or_waiting() {
    let mission = Task::goal("mission", |ctx| async move {
        ctx.spawn(Task::command("stalls", |_| async {
            tokio::time::sleep(secs(1.0)).await;
            Err::<(), _>(Failure::new("Stalled", "wheels blocked"))
        }))
        .uses("base", 1)
        .start()?;
        ctx.spawn(sleeps("stopped", 60.0))
            .uses("base", 1)
            .terminate_in(secs(3.0))
            .start()?;
        ctx.spawn(sleeps("cancelled", 1.0))
            .uses("base", 1)
            .terminate_in(secs(2.0))
            .start()?;
        ctx.spawn(sleeps("last", 1.0)).uses("base", 1).start()?;
        Ok(())
    });
    let (_, trace) = run_checked(Runtime::new().resource("base", 1), mission).await;
    assert_eq!(
        resource_lines(&trace),
        [
            "0 stalls requests base",
            "0 stalls granted base",
            "0 stopped requests base",
            "0 cancelled requests base",
            "0 last requests base",
            "1 stalls failed Stalled",
            "1 stalls released base",
            "1 stopped granted base",
            "2 cancelled terminating",
            "2 cancelled withdrawn",
            "2 cancelled terminated",
            "3 stopped terminating",
            "3 stopped released base",
            "3 stopped terminated",
            "3 last granted base",
            "4 last released base",
        ]
    );
}

#[tokio::test(start_paused = true)]
async fn a_cancelled_action_keeps_its_grant_until_its_cleanup_ends() {
    // `drive` looks at its cancellation and takes half a second to stop the wheels: the base is
    // still its own meanwhile.
    let drive = Task::command("drive", |ctx| async move {
        let cancelled = ctx.cancelled();
        tokio::select! {
            () = tokio::time::sleep(secs(60.0)) => {}
            () = cancelled => tokio::time::sleep(secs(0.5)).await,
        }
        Ok(())
    });
    let mission = Task::goal("mission", |ctx| async move {
        ctx.spawn(drive)
            .uses("base", 1)
            .terminate_in(secs(2.0))
            .start()?;
        ctx.spawn(sleeps("dock", 1.0)).uses("base", 1).start()?;
        Ok(())
    });
    let (_, trace) = run_checked(Runtime::new().resource("base", 1), mission).await;
    assert_eq!(
        resource_lines(&trace),
        [
            "0 drive requests base",
            "0 drive granted base",
            "0 dock requests base",
            "2 drive terminating",
            "2.5 drive released base",
            "2.5 drive terminated",
            "2.5 dock granted base",
            "3.5 dock released base",
        ]
    );
}

#[tokio::test(start_paused = true)]
async fn a_task_level_use_applies_to_every_spawn_and_adds_to_the_spawns() {
    let mission = Task::goal("mission", |ctx| async move {
        let plan = || {
            Task::command("plan_path", |_| async {
                tokio::time::sleep(secs(2.0)).await;
                Ok(())
            })
            .uses("cpu", 1)
        };
        ctx.spawn(plan()).start()?;
        ctx.spawn(plan()).uses("base", 1).start()?;
        Ok(())
    });
    let rt = Runtime::new().resource("cpu", 1).resource("base", 1);
    let (report, trace) = run_checked(rt, mission).await;
    assert_eq!(report.elapsed, secs(4.0));
    assert_eq!(
        only(&story(&trace), &["granted"]),
        ["0 plan_path granted cpu", "2 plan_path granted cpu, base"]
    );
}

#[tokio::test(start_paused = true)]
async fn a_declaration_given_at_the_spawn_is_declared_on_first_use() {
    let gripper = Resource::new("gripper", 1).pending_limit(3);
    let mission = Task::goal("mission", move |ctx| async move {
        ctx.spawn(sleeps("grip", 1.0)).uses(&gripper, 1).start()?;
        ctx.spawn(sleeps("regrip", 1.0)).uses(gripper, 1).start()?;
        let info = ctx.resource_info("gripper")?.expect("declared");
        assert_eq!((info.capacity, info.pending_limit), (1, Some(3)));
        Ok(())
    });
    let (report, trace) = run_checked(Runtime::new(), mission).await;
    assert_eq!(report.elapsed, secs(2.0));
    let declared = trace
        .iter()
        .filter(|e| matches!(e.kind, tcm::TraceKind::Resource { .. }))
        .count();
    assert_eq!(declared, 1);
}

#[tokio::test(start_paused = true)]
async fn misuses_are_errors_not_panics() {
    // A resource declared twice: the run does not start.
    let rt = Runtime::new().resource("arm", 2).resource("arm", 1);
    let err = rt.run(sleeps("a", 1.0)).await.err().map(|e| e.to_string());
    assert_eq!(err.as_deref(), Some("resource `arm` is already declared"));
    // An unknown resource, a zero amount: the spawn is refused; the body fails with the error.
    let mission = Task::goal("mission", |ctx| async move {
        let unknown = ctx.spawn(sleeps("a", 1.0)).uses("gripper", 1).start();
        assert_eq!(
            unknown.err().map(|e| e.to_string()).as_deref(),
            Some("no resource `gripper` is declared")
        );
        let zero = ctx.spawn(sleeps("b", 1.0)).uses("arm", 0).start();
        assert_eq!(
            zero.err().map(|e| e.to_string()).as_deref(),
            Some("a spawn uses 0 of resource `arm`: an amount is at least 1")
        );
        assert!(ctx.lock_resource("gripper").is_err());
        Ok(())
    });
    let (report, _) = run_checked(Runtime::new().resource("arm", 2), mission).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
}

#[tokio::test(start_paused = true)]
async fn a_goal_holding_the_base_whose_child_needs_it_is_stuck_with_the_cycle_named() {
    let plan = Task::goal("plan", |ctx| async move {
        ctx.spawn(sleeps("drive", 1.0))
            .uses("base", 1)
            .wait()
            .await?;
        Ok(())
    })
    .uses("base", 1);
    let never = Duration::from_secs(24 * 3600);
    let run = run_checked(Runtime::new().resource("base", 1), plan);
    let (report, trace) = tokio::time::timeout(never, run)
        .await
        .expect("the run ends by itself");
    let RunOutcome::Stuck(blocked) = report.outcome else {
        panic!("expected stuck, got {:?}", report.outcome);
    };
    let text: Vec<String> = blocked.iter().map(ToString::to_string).collect();
    assert_eq!(
        text,
        [
            "plan {1} handling is active and waits for its action, which awaits drive {2} \
             execution completed",
            "drive {2} handling is enabled and waits for resource `base`, held by plan {1} \
             (1 of 1), in the wait cycle: drive {2} needs `base`, held by plan {1}; plan {1}'s \
             action awaits drive {2}",
        ]
    );
    // The text log says who holds what `drive` waits for.
    let log = tcm_trace::TextLog::render(Default::default(), &trace);
    assert!(
        log.contains("Resource wait: drive {2} waits: base is held by plan {1}"),
        "{log}"
    );
}
