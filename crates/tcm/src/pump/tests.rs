//! The pump changes nothing observable: each program gives the same trace, record for record,
//! with released actions run inline and with every action a task; and it does run them inline.

use crate::testing::{lines, run_checked_allowing_panics};
use crate::{Failure, FailurePolicy, Handler, Monitor, NodeKind, NodeRef, Runtime, Task};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

mod random;

pub(super) fn ms(n: u64) -> Duration {
    Duration::from_millis(n)
}

pub(super) fn noop(name: &'static str) -> Task {
    Task::command(name, |_| async { Ok(()) })
}

pub(super) fn sleeper(name: &'static str, d: u64) -> Task {
    Task::command(name, move |_| async move {
        tokio::time::sleep(ms(d)).await;
        Ok(())
    })
}

/// Two actions wake at the same instant; the end of the first releases one that ends at once.
fn tie() -> Task {
    Task::goal("tie", |ctx| async move {
        ctx.spawn(sleeper("a", 10)).start()?;
        ctx.spawn(noop("c")).serial(NodeRef::Previous).start()?;
        ctx.spawn(sleeper("b", 10)).start()?;
        ctx.spawn(noop("d")).serial(NodeRef::Previous).start()?;
        Ok(())
    })
}

/// Waits, values, children started at once, a fan-out of actions that end at once.
fn waits() -> Task {
    Task::goal("waits", |ctx| async move {
        let v: u32 = ctx
            .spawn(Task::command("value", |_| async { Ok(7u32) }))
            .wait_value()
            .await?;
        ctx.hold_children(false)?;
        for _ in 0..v {
            ctx.spawn(noop("fan")).start()?;
        }
        ctx.spawn(sleeper("slow", 5)).wait().await?;
        ctx.spawn(Task::goal("inner", |ctx| async move {
            for _ in 0..3 {
                ctx.spawn(noop("step")).serial(NodeRef::Previous).start()?;
            }
            Ok(())
        }))
        .wait()
        .await?;
        Ok(())
    })
}

/// Failures handled three levels up, a retry, a panic, an unhandled failure.
fn failures() -> Task {
    let tries = Arc::new(Mutex::new(0u32));
    Task::goal("top", |ctx| async move {
        ctx.spawn(Task::goal("mid", |ctx| async move {
            for _ in 0..3 {
                ctx.spawn(Task::command("boom", |_| async {
                    Err::<(), _>(Failure::new("Boom", "at once"))
                }))
                .start()?;
            }
            ctx.spawn(Task::command("oops", |_| async {
                if true {
                    panic!("an action that panics");
                }
                Ok(())
            }))
            .start()?;
            ctx.spawn(Task::command("lone", |_| async {
                Err::<(), _>(Failure::new("Lone", "nobody handles it"))
            }))
            .start()?;
            Ok(())
        }))
        .start()?;
        ctx.spawn(
            Task::retryable(NodeKind::Command, "flaky", move |_| {
                let tries = tries.clone();
                async move {
                    let n = {
                        let mut t = tries.lock().map_err(|_| Failure::new("Lock", ""))?;
                        *t += 1;
                        *t
                    };
                    if n < 3 {
                        Err(Failure::new("Flaky", "again"))
                    } else {
                        Ok(())
                    }
                }
            })
            .handler(Handler::new("again", "Flaky", |ctx| async move {
                let retry = ctx.retry()?;
                ctx.wait(retry).await?;
                Ok(())
            })),
        )
        .start()?;
        Ok(())
    })
    .handler(Handler::new("recover", "Boom", |_| async { Ok(()) }))
}

/// Terminations: of a sleeping action, of one that looks at its signal and cleans up in its
/// grace period, of one released at the same time as the action that terminates it, and of
/// one not started yet.
fn terminations() -> Task {
    Task::goal("cancel", |ctx| async move {
        ctx.spawn(sleeper("long", 1000))
            .terminate_in(ms(5))
            .start()?;
        ctx.spawn(Task::command("careful", |ctx| async move {
            tokio::select! {
                () = tokio::time::sleep(ms(1000)) => {}
                () = ctx.cancelled() => tokio::time::sleep(ms(3)).await,
            }
            Ok(())
        }))
        .terminate_in(ms(7))
        .start()?;
        let victim = ctx.spawn(sleeper("victim", 50)).start()?;
        let later = ctx.reserve("later")?;
        ctx.spawn(Task::command("killer", move |ctx| async move {
            ctx.terminate(victim)?;
            ctx.terminate(later)?;
            Ok(())
        }))
        .start()?;
        ctx.spawn(noop("late")).fulfils(later).start()?;
        Ok(())
    })
}

/// Actions that yield once (woken during their first poll) beside a chain that ends at once.
fn yields() -> Task {
    Task::goal("yield", |ctx| async move {
        for name in ["y1", "y2"] {
            ctx.spawn(Task::command(name, move |ctx| async move {
                tokio::task::yield_now().await;
                ctx.warn(format!("{name} resumed"))?;
                Ok(())
            }))
            .start()?;
        }
        for _ in 0..3 {
            ctx.spawn(Task::command("c", |ctx| async move {
                ctx.warn("chain")?;
                Ok(())
            }))
            .serial(NodeRef::Previous)
            .start()?;
        }
        Ok(())
    })
}

/// A polling monitor whose activations end at once, beside a sleeper.
fn monitor() -> Task {
    Task::goal("watch", |ctx| async move {
        let params = Monitor {
            max_activations: Some(4),
            period: Some(ms(2)),
            ..Monitor::default()
        };
        ctx.spawn(Task::monitor("poll", params, |_| async { Ok(()) }))
            .start()?;
        ctx.spawn(sleeper("beside", 4)).start()?;
        Ok(())
    })
}

/// The trace of `task` run on virtual time. The tokio runtime delivers deferred wake-ups
/// (`tokio::task::yield_now`) only when its queue is empty, not every 61 tasks as by default:
/// the pump's inline actions are no tasks to count (the module's documentation).
pub(super) fn trace_of(rt: Runtime, task: Task) -> Vec<String> {
    let run = async { Ok::<_, crate::Error>(run_checked_allowing_panics(rt, task).await) };
    let tokio = tokio::runtime::Builder::new_current_thread()
        .enable_time()
        .start_paused(true)
        .event_interval(u32::MAX)
        .build()
        .expect("a tokio runtime");
    let (_, trace) = tokio.block_on(run).expect("a run");
    lines(&trace)
}

/// The lines, without the run's number in a node's name (`node#2.0@run105`): each run has
/// its own.
pub(super) fn without_run_ids(lines: Vec<String>) -> Vec<String> {
    lines
        .into_iter()
        .map(|l| {
            let mut out = String::with_capacity(l.len());
            let mut rest = l.as_str();
            while let Some(i) = rest.find("@run") {
                out.push_str(&rest[..i + 4]);
                rest = rest[i + 4..].trim_start_matches(|c: char| c.is_ascii_digit());
            }
            out.push_str(rest);
            out
        })
        .collect()
}

/// Timer callbacks, which run when the lock under which they came due is let go: on ends in a
/// chain of actions that end at once, on an event already past (run inside the action), and one
/// that spawns.
fn callbacks() -> Task {
    Task::goal("callbacks", |ctx| async move {
        let x = ctx.spawn(noop("x")).start()?;
        let y = ctx
            .spawn(Task::command("y", move |ctx| async move {
                ctx.invoke_when(
                    "past",
                    crate::Event::new(x, crate::Point::Completed),
                    |_, _| {},
                )?;
                Ok(())
            }))
            .serial(NodeRef::Previous)
            .start()?;
        ctx.spawn(noop("z")).serial(NodeRef::Previous).start()?;
        ctx.spawn(sleeper("s", 3)).start()?;
        ctx.invoke_when(
            "x done",
            crate::Event::new(x, crate::Point::Completed),
            |ctx, _| {
                let _ = ctx.spawn(noop("from callback")).start();
            },
        )?;
        ctx.invoke_when(
            "y done",
            crate::Event::new(y, crate::Point::Completed),
            |_, _| {},
        )?;
        Ok(())
    })
}

#[test]
fn each_program_gives_the_same_trace_with_and_without_the_pump() {
    type Program = (&'static str, fn() -> Task);
    let programs: [Program; 7] = [
        ("tie", tie),
        ("waits", waits),
        ("failures", failures),
        ("terminations", terminations),
        ("monitor", monitor),
        ("yields", yields),
        ("callbacks", callbacks),
    ];
    for (name, program) in programs {
        let pumped = trace_of(Runtime::new(), program());
        let tasks = trace_of(Runtime::new().without_pump(), program());
        assert!(pumped.len() > 10, "{name}: a real trace");
        assert_eq!(pumped, tasks, "{name}: the same trace");
    }
}

/// A batch in which one action wakes another that awaits: `b` (released with `a`) wakes `w`,
/// and `a`'s end releases `x`. Plain tasks run `x` before `w`. The pump reports `a`'s end
/// after polling `b`; it holds `w`'s wake-up back until then (`hold_wake`), so that `x` runs
/// first there too (without that, `w` ran first).
fn wake_in_batch() -> Task {
    Task::goal("wake", |ctx| async move {
        ctx.hold_children(false)?;
        let (tx, rx) = tokio::sync::oneshot::channel::<()>();
        let tx = Arc::new(Mutex::new(Some(tx)));
        ctx.spawn(Task::command("w", move |ctx| async move {
            let _ = rx.await;
            ctx.warn("w woke")?;
            Ok(())
        }))
        .start()?;
        let p = ctx.spawn(noop("p")).start()?;
        let a = ctx.spawn(noop("a")).serial(p).start()?;
        ctx.spawn(Task::command("x", |ctx| async move {
            ctx.warn("x ran")?;
            Ok(())
        }))
        .serial(a)
        .start()?;
        ctx.spawn(Task::command("b", move |_| async move {
            if let Some(tx) = tx.lock().ok().and_then(|mut t| t.take()) {
                let _ = tx.send(());
            }
            Ok(())
        }))
        .serial(p)
        .start()?;
        Ok(())
    })
}

#[test]
fn a_wake_within_a_batch_gives_the_same_trace_with_and_without_the_pump() {
    let warnings = |trace: &[String]| -> Vec<&'static str> {
        trace
            .iter()
            .filter_map(|l| {
                ["w woke", "x ran"]
                    .into_iter()
                    .find(|w| l.contains(w) && l.contains("warning"))
            })
            .collect()
    };
    let pumped = trace_of(Runtime::new(), wake_in_batch());
    let tasks = trace_of(Runtime::new().without_pump(), wake_in_batch());
    assert_eq!(warnings(&tasks), ["x ran", "w woke"]);
    assert_eq!(pumped, tasks, "the same trace, record for record");
}

/// A release wider than a batch of reported ends (`REPORT_EVERY`): 300 children, most
/// ending at once, some failing into a handler, some sleeping, some spawning a child of their
/// own; one released by an early end terminates two sleepers; a chain follows.
fn wide_with_terminations() -> Task {
    Task::goal("wide", |ctx| async move {
        let mut ids = Vec::new();
        for i in 0..300u64 {
            let task = match i % 10 {
                3 => Task::command("fails", |_| async {
                    Err::<(), _>(Failure::new("Boom", "wide"))
                }),
                5 => sleeper("sleeps", i % 4 + 1),
                7 => Task::goal("parent", |ctx| async move {
                    ctx.spawn(noop("grandchild")).start()?;
                    Ok(())
                }),
                _ => noop("ends"),
            };
            ids.push(ctx.spawn(task).start()?);
        }
        let (early, far, near) = (ids[10], ids[295], ids[15]);
        ctx.spawn(Task::command("terminator", move |ctx| async move {
            ctx.terminate(far)?;
            ctx.terminate(near)?;
            Ok(())
        }))
        .serial(early)
        .start()?;
        for _ in 0..5 {
            ctx.spawn(noop("chained"))
                .serial(NodeRef::Previous)
                .start()?;
        }
        Ok(())
    })
    .handler(Handler::new("recover", "Boom", |_| async { Ok(()) }))
}

/// Found with the program above: the stops of the terminated sleepers came after the ends
/// of a chain the pump ran meanwhile, where with every action a task they came before. An
/// aborted task now counts as queued until its stop is reported, and the stop is reported by
/// whoever takes the lock next (not only the driver), so both give the same trace.
#[test]
fn terminations_in_a_wide_release_give_the_same_trace_with_and_without_the_pump() {
    let pumped = trace_of(Runtime::new(), wide_with_terminations());
    let tasks = trace_of(Runtime::new().without_pump(), wide_with_terminations());
    assert!(pumped.len() > 3000, "a real trace: {}", pumped.len());
    let stop = |t: &[String]| t.iter().position(|l| l.contains("\"ev\":\"terminated\""));
    let chain_end = |t: &[String]| {
        t.iter()
            .rposition(|l| l.contains("\"ev\":\"reclaimed\"") && l.contains("\"node\":307}"))
    };
    assert!(stop(&tasks).is_some() && stop(&tasks) < chain_end(&tasks));
    assert_eq!(pumped, tasks, "the same trace, record for record");
}

/// Code an action runs when it starts (its closure, before its future), started by the end of
/// an action of a batch, runs before the next action of that batch, as with tasks (the end is
/// reported at once, `report_now`): `y` starts when `x` ends, and `z`, released with `x`, sees
/// what `y`'s closure set.
#[test]
fn code_an_end_starts_runs_before_the_rest_of_its_batch() {
    let run = |rt: Runtime| {
        let started = Arc::new(AtomicBool::new(false));
        let task = Task::goal("g", move |ctx| {
            let started = started.clone();
            async move {
                let x = ctx.spawn(noop("x")).start()?;
                let seen = started.clone();
                ctx.spawn(Task::command("z", move |ctx| {
                    let seen = seen.clone();
                    async move {
                        let y = if seen.load(Ordering::SeqCst) {
                            "started"
                        } else {
                            "not started"
                        };
                        ctx.warn(format!("y {y}"))?;
                        Ok(())
                    }
                }))
                .start()?;
                let set = started.clone();
                ctx.spawn(Task::command("y", move |_| {
                    set.store(true, Ordering::SeqCst);
                    async { Ok(()) }
                }))
                .serial(x)
                .start()?;
                Ok(())
            }
        });
        trace_of(rt, task)
    };
    let saw = |t: &[String], what: &str| t.iter().any(|l| l.contains(what));
    let pumped = run(Runtime::new());
    let tasks = run(Runtime::new().without_pump());
    assert!(
        saw(&tasks, "\"y started\""),
        "tasks: y started before z ran"
    );
    assert!(saw(&pumped, "\"y started\""), "pumped: likewise");
    assert_eq!(without_run_ids(pumped), without_run_ids(tasks));
}

/// Sets its flag when dropped.
struct DropFlag(Arc<AtomicBool>);

impl Drop for DropFlag {
    fn drop(&mut self) {
        self.0.store(true, Ordering::SeqCst);
    }
}

/// A run that ends (a fatal failure) while an action that waits for ever is parked: the
/// parked future is dropped when the run ends, as a task would be, and the same trace results.
#[test]
fn a_future_parked_when_the_run_ends_is_dropped() {
    let run = |rt: Runtime| {
        let dropped = Arc::new(AtomicBool::new(false));
        let flag = dropped.clone();
        let task = Task::goal("ends", move |ctx| async move {
            let flag = flag.clone();
            ctx.spawn(Task::command("forever", move |_| async move {
                let _guard = DropFlag(flag);
                std::future::pending::<()>().await;
                Ok(())
            }))
            .start()?;
            ctx.spawn(Task::command("fails", |_| async {
                Err::<(), _>(Failure::new("Boom", "fatal"))
            }))
            .start()?;
            Ok(())
        });
        let trace = trace_of(rt.failure_policy(FailurePolicy::Fatal), task);
        (trace, dropped.load(Ordering::SeqCst))
    };
    let (pumped, pumped_dropped) = run(Runtime::new());
    let (tasks, tasks_dropped) = run(Runtime::new().without_pump());
    assert!(pumped_dropped, "the parked future was dropped");
    assert!(tasks_dropped, "the task's future was dropped");
    assert_eq!(pumped, tasks, "the same trace");
}

type TaskId = Option<tokio::task::Id>;

/// The id of the tokio task the goal's body ran on, and those its children's bodies ran on.
fn task_ids(rt: Runtime) -> (TaskId, Vec<TaskId>) {
    let ids: Arc<Mutex<Vec<TaskId>>> = Arc::default();
    let goal_id: Arc<Mutex<TaskId>> = Arc::default();
    let (i, g) = (ids.clone(), goal_id.clone());
    let task = Task::goal("g", move |ctx| async move {
        if let Ok(mut g) = g.lock() {
            *g = tokio::task::try_id();
        }
        for _ in 0..5 {
            let i = i.clone();
            ctx.spawn(Task::command("c", move |_| async move {
                if let Ok(mut i) = i.lock() {
                    i.push(tokio::task::try_id());
                }
                Ok(())
            }))
            .serial(NodeRef::Previous)
            .start()?;
        }
        Ok(())
    });
    let _ = trace_of(rt, task);
    let goal = goal_id.lock().map(|g| *g).unwrap_or(None);
    let ids = ids.lock().map(|i| i.clone()).unwrap_or_default();
    (goal, ids)
}

#[test]
fn released_actions_run_on_the_task_that_released_them() {
    let (goal, ids) = task_ids(Runtime::new());
    assert!(goal.is_some());
    assert_eq!(ids, vec![goal; 5], "each ran inline, on the goal's task");
    let (goal, ids) = task_ids(Runtime::new().without_pump());
    assert_eq!(ids.len(), 5);
    assert!(
        ids.iter().all(|id| id.is_some() && *id != goal),
        "tasks of their own"
    );
}
