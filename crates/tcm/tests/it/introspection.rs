//! Introspection from a body (issue 11, point 13): a node's facet states and termination, its
//! parent and children, the task it is an instance of, and a monitor's counts and parameters
//! (TCM's node queries).

use crate::util::{assert_order, run_checked, story};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tcm::{Facet, Handler, Monitor, NodeKind, Point, RunOutcome, Runtime, State, Task};

fn secs(s: u64) -> Duration {
    Duration::from_secs(s)
}

#[tokio::test(start_paused = true)]
async fn a_body_reads_states_termination_parent_and_children() {
    let task = Task::goal("g", |ctx| async move {
        let me = ctx.node();
        let step = ctx
            .spawn(Task::command("step", |_| async {
                tokio::time::sleep(secs(2)).await;
                Ok(())
            }))
            .start()?;
        let later = ctx
            .spawn(Task::command("later", move |ctx| async move {
                assert_eq!(ctx.parent()?, Some(me));
                Ok(())
            }))
            .disable_for(Facet::Handling, secs(1))
            .start()?;
        let grip = ctx
            .spawn(Task::command("grip", |_| async {
                std::future::pending::<()>().await;
                Ok(())
            }))
            .on_terminate(Task::command("release", |_| async {
                tokio::time::sleep(secs(3)).await;
                Ok(())
            }))
            .start()?;
        // Held until this body waits: nothing has started.
        let info = ctx.info(step)?.expect("step is alive");
        assert_eq!(info.kind, NodeKind::Command);
        assert_eq!(info.state(Facet::Handling), State::Disabled);
        assert_eq!(ctx.children(me)?, [step, later, grip]);
        assert_eq!(ctx.parent_of(step)?, Some(me));
        // The root is the top-level task's parent.
        assert!(ctx.parent()?.is_some());
        tokio::time::sleep(secs(1)).await;
        let info = ctx.info(step)?.expect("step is alive");
        assert_eq!(info.state(Facet::Handling), State::Disabled, "still held");
        ctx.wait(later).await?;
        // `later` waited 1 s from its spawn, and its wait released the others at 1 s.
        assert_eq!(ctx.now(), secs(1));
        let info = ctx.info(step)?.expect("step is alive");
        assert!(info.reached(Facet::Handling, Point::Active));
        assert!(!info.reached(Facet::Execution, Point::Completed));
        assert!(ctx.info(later)?.is_none(), "completed, and reclaimed");
        ctx.terminate(grip)?;
        let info = ctx.info(grip)?.expect("grip is alive while it cleans up");
        assert!(info.is_terminating() && !info.is_terminated());
        assert!(info.reached(Facet::Handling, Point::Completed));
        assert!(!info.failed && !info.suspended);
        Ok(())
    });
    let (report, trace) = run_checked(Runtime::new(), task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_order(
        &story(&trace),
        &[
            "1 grip terminating",
            "3 step handling completed",
            "4 grip terminated",
        ],
    );
}

#[tokio::test(start_paused = true)]
async fn a_renamed_instance_is_still_an_instance_of_its_task() {
    let task = Task::goal("g", |ctx| async move {
        let nav = ctx
            .spawn(Task::command("navigate", |_| async { Ok(()) }).named("toDoor"))
            .start()?;
        let plain = ctx
            .spawn(Task::command("speak", |_| async { Ok(()) }))
            .start()?;
        assert_eq!(ctx.info(nav)?.map(|i| i.name), Some("toDoor".to_string()));
        assert_eq!(ctx.task_name(nav)?.as_deref(), Some("navigate"));
        assert!(ctx.is_instance_of(nav, "navigate")?);
        assert!(!ctx.is_instance_of(nav, "toDoor")?);
        assert_eq!(ctx.task_name(plain)?.as_deref(), Some("speak"));
        assert!(ctx.is_instance_of(plain, "speak")?);
        ctx.wait(nav).await?;
        // Gone nodes are instances of nothing.
        assert_eq!(ctx.task_name(nav)?, None);
        assert!(!ctx.is_instance_of(nav, "navigate")?);
        Ok(())
    });
    let (report, _) = run_checked(Runtime::new(), task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
}

#[tokio::test(start_paused = true)]
async fn a_retried_node_is_an_instance_of_the_failed_task() {
    let names = Arc::new(Mutex::new(Vec::new()));
    let (n1, n2) = (names.clone(), names.clone());
    let task = Task::goal("g", move |ctx| async move {
        let flaky = Task::retryable(NodeKind::Command, "move", move |ctx| {
            let n = n1.clone();
            async move {
                let name = ctx.task_name(ctx.node())?;
                let instance = ctx.info(ctx.node())?.map(|i| i.name);
                let mut n = n.lock().expect("names");
                n.push((name, instance));
                if n.len() < 2 {
                    return Err(tcm::Failure::new("Bump", "bumped"));
                }
                Ok(())
            }
        })
        .named("move-1");
        ctx.spawn(flaky)
            .handler(Handler::new("again", "Bump", move |ctx| {
                let n = n2.clone();
                async move {
                    let again = ctx.retry()?;
                    let name = ctx.task_name(again)?;
                    n.lock().expect("names").push((name, Some("retry".into())));
                    Ok(())
                }
            }))
            .start()?;
        Ok(())
    });
    let (report, _) = run_checked(Runtime::new(), task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let move_ = Some("move".to_string());
    assert_eq!(
        *names.lock().expect("names"),
        [
            (move_.clone(), Some("move-1".to_string())),
            (move_.clone(), Some("retry".to_string())),
            (move_, Some("move-1".to_string())),
        ]
    );
}

#[tokio::test(start_paused = true)]
async fn a_monitor_activation_is_an_instance_of_its_monitor_s_task() {
    // As in TDL, a monitor and each of its `ACT-` children are instances of the monitor's task
    // (`watch`, whatever the instance is named); an activation's own task name stays its
    // activation name, and an instance name is no task.
    let seen = Arc::new(Mutex::new(Vec::new()));
    let s = seen.clone();
    let params = Monitor {
        max_activations: Some(1),
        ..Monitor::default()
    };
    let task = Task::goal("g", move |ctx| async move {
        let watch = Task::monitor("watch", params, move |ctx| {
            let s = s.clone();
            async move {
                let me = ctx.node();
                let is = |task: &str| ctx.is_instance_of(me, task);
                let answers = (is("watch")?, is("ACT-door")?, is("door")?, is("g")?);
                s.lock().expect("seen").push((ctx.task_name(me)?, answers));
                Ok(())
            }
        });
        let m = ctx
            .spawn(watch.named("door"))
            .activate(tcm::When::Now)
            .start()?;
        let step = ctx
            .spawn(Task::command("step", |_| async { Ok(()) }))
            .start()?;
        assert!(ctx.is_instance_of(m, "watch")?);
        assert!(!ctx.is_instance_of(m, "door")?);
        assert!(!ctx.is_instance_of(step, "watch")?);
        assert!(!ctx.is_instance_of(ctx.node(), "watch")?);
        ctx.wait(m).await?;
        Ok(())
    });
    let (report, trace) = run_checked(Runtime::new(), task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(
        *seen.lock().expect("seen"),
        [(Some("ACT-door".to_string()), (true, true, false, false))]
    );
    assert_order(
        &story(&trace),
        &[
            "0 door handling completed",
            "0 ACT-door handling active",
            "0 door execution completed",
        ],
    );
}

#[tokio::test(start_paused = true)]
async fn a_monitor_body_reads_its_counts_and_parameters() {
    let seen = Arc::new(Mutex::new(Vec::new()));
    let s = seen.clone();
    let params = Monitor {
        max_activations: Some(5),
        max_triggers: Some(2),
        period: Some(secs(2)),
        ..Monitor::default()
    };
    let task = Task::goal("g", move |ctx| async move {
        let m = ctx
            .spawn(Task::monitor("watch", params, move |ctx| {
                let s = s.clone();
                async move {
                    let info = ctx
                        .monitor_info(ctx.node())?
                        .expect("a monitor's activation");
                    if info.activations >= 2 {
                        ctx.trigger()?;
                    }
                    let info = ctx
                        .monitor_info(ctx.node())?
                        .expect("a monitor's activation");
                    assert_eq!(ctx.parent()?, Some(info.monitor));
                    s.lock().expect("seen").push((
                        info.activations,
                        info.triggers,
                        info.max_activations,
                        info.max_triggers,
                        info.period,
                        info.initial_wait,
                    ));
                    Ok(())
                }
            }))
            .start()?;
        ctx.wait(m).await?;
        // Reclaimed once done: nothing to read any more.
        assert_eq!(ctx.monitor_info(m)?, None);
        // Not a monitor.
        assert_eq!(ctx.monitor_info(ctx.node())?, None);
        Ok(())
    });
    let (report, trace) = run_checked(Runtime::new(), task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let p = Some(secs(2));
    assert_eq!(
        *seen.lock().expect("seen"),
        [
            (1, 0, Some(5), Some(2), p, false),
            (2, 1, Some(5), Some(2), p, false),
            (3, 2, Some(5), Some(2), p, false),
        ]
    );
    assert_order(&story(&trace), &["4 watch handling completed"]);
}

#[tokio::test(start_paused = true)]
async fn an_action_says_where_it_runs_and_warns_in_the_trace() {
    // What a distribution layer does: `placed` when the action is sent to an agent, a warning
    // for a message that came twice. Both are records of the node, in order, through the checker.
    let task = Task::goal("g", |ctx| async move {
        ctx.spawn(Task::command("far", |ctx| async move {
            ctx.placed("arm")?;
            tokio::time::sleep(secs(1)).await;
            ctx.warn("a completion from agent arm came twice; ignored")?;
            Ok(())
        }))
        .wait()
        .await?;
        Ok(())
    });
    let (report, trace) = run_checked(Runtime::new(), task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let far = trace
        .iter()
        .find_map(|ev| match &ev.kind {
            tcm::TraceKind::Spawned { node, name, .. } if name == "far" => Some(*node),
            _ => None,
        })
        .expect("far spawned");
    let placed: Vec<_> = trace
        .iter()
        .filter_map(|ev| match &ev.kind {
            tcm::TraceKind::Placed { node, agent } => Some((*node, agent.clone(), ev.t)),
            _ => None,
        })
        .collect();
    assert_eq!(placed, [(far, "arm".to_string(), 0)]);
    let warned = trace.iter().find_map(|ev| match &ev.kind {
        tcm::TraceKind::Warning { node, message } if message.contains("came twice") => {
            Some((*node, ev.t))
        }
        _ => None,
    });
    assert_eq!(warned, Some((Some(far), 1_000_000_000)));
    assert_eq!(report.warnings, 1);
}
