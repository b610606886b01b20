//! Typed exceptions through the async runtime: handlers reading the exception's data, retry,
//! bypass, and a wiretap vetoing a move.

use crate::util::{assert_order, run_checked, story};
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tcm::{
    Exception, Facet, Failure, Handler, NodeKind, NodeRef, RunOutcome, Runtime, TapWhen, Task,
};

#[derive(Debug, thiserror::Error)]
#[error("motor at {temperature} C")]
struct Overheating {
    temperature: f64,
}

impl Exception for Overheating {
    fn ancestry() -> &'static [&'static str] {
        &["HardwareFailure"]
    }
}

#[derive(Debug, thiserror::Error)]
#[error("every route to room {room} is blocked")]
struct NoPath {
    room: u32,
}

impl Exception for NoPath {}

fn secs(s: f64) -> Duration {
    Duration::from_secs_f64(s)
}

use tcm::testing::handler_choices as chosen;

#[tokio::test(start_paused = true)]
async fn navigate_to_locn_handlers_read_the_exception_data() {
    let log = Arc::new(Mutex::new(Vec::<String>::new()));
    let (l1, l2) = (log.clone(), log.clone());
    let task = Task::goal("navigateToLocn", |ctx| async move {
        ctx.spawn(Task::command("move", |_| async {
            tokio::time::sleep(secs(1.0)).await;
            Err::<(), _>(Overheating { temperature: 92.5 }.raise())
        }))
        .start()?;
        ctx.spawn(Task::command("plan", |_| async {
            Err::<(), _>(NoPath { room: 7 }.raise())
        }))
        .start()?;
        Ok(())
    })
    .handler(Handler::on::<Overheating, _, _, _>(
        "handleOverheating",
        move |ctx| {
            let log = l1.clone();
            async move {
                let t = ctx.caught::<Overheating>().map(|o| o.temperature);
                log.lock().expect("log").push(format!("cool from {t:?}"));
                ctx.spawn(Task::command("coolDown", |_| async {
                    tokio::time::sleep(secs(3.0)).await;
                    Ok(())
                }))
                .start()?;
                Ok(())
            }
        },
    ))
    .handler(Handler::on::<NoPath, _, _, _>(
        "handlePlannerFailure",
        move |ctx| {
            let log = l2.clone();
            async move {
                let room = ctx.caught::<NoPath>().map(|n| n.room);
                log.lock()
                    .expect("log")
                    .push(format!("give up on {room:?}"));
                Ok(())
            }
        },
    ));
    let (report, trace) = run_checked(Runtime::new(), task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(
        chosen(&trace),
        [
            "handlePlannerFailure<-NoPath",
            "handleOverheating<-Overheating"
        ]
    );
    assert_eq!(
        *log.lock().expect("log"),
        ["give up on Some(7)", "cool from Some(92.5)"]
    );
    assert_order(
        &story(&trace),
        &[
            "1 move failed Overheating",
            "1 coolDown handling active",
            "4 coolDown handling completed",
            "4 move execution completed",
        ],
    );
}

#[tokio::test(start_paused = true)]
async fn a_handler_for_the_parent_type_catches_the_child() {
    let task = Task::goal("drive", |ctx| async move {
        ctx.spawn(Task::command("motor", |_| async {
            Err::<(), _>(Overheating { temperature: 80.0 }.raise())
        }))
        .start()?;
        Ok(())
    })
    .handler(Handler::new("anyHardware", "HardwareFailure", |_| async {
        Ok(())
    }));
    let (_, trace) = run_checked(Runtime::new(), task).await;
    assert_eq!(chosen(&trace), ["anyHardware<-Overheating"]);
}

#[tokio::test(start_paused = true)]
async fn a_nodes_handlers_are_tried_first_listed_first() {
    // `left` lists task-level handlers `first`, `second`; `right` gets spawn-level `third`,
    // `fourth`. Each node's failure goes to the handler listed first.
    let fails = |name: &'static str| {
        Task::command(name, |_| async {
            Err::<(), _>(Overheating { temperature: 80.0 }.raise())
        })
    };
    let handler = |name: &'static str| Handler::new(name, "HardwareFailure", |_| async { Ok(()) });
    let task = Task::goal("drive", move |ctx| async move {
        ctx.spawn(
            fails("left")
                .handler(handler("first"))
                .handler(handler("second")),
        )
        .start()?;
        ctx.spawn(fails("right"))
            .handler(handler("third"))
            .handler(handler("fourth"))
            .start()?;
        Ok(())
    });
    let (_, trace) = run_checked(Runtime::new(), task).await;
    assert_eq!(chosen(&trace), ["first<-Overheating", "third<-Overheating"]);
}

#[tokio::test(start_paused = true)]
async fn retry_succeeds_on_the_second_attempt_and_bypass_passes_it_up() {
    let attempts = Arc::new(AtomicU32::new(0));
    let a = attempts.clone();
    let task = Task::goal("deliver", move |ctx| async move {
        let a = a.clone();
        ctx.spawn(
            Task::retryable(NodeKind::Command, "move", move |_| {
                let a = a.clone();
                async move {
                    tokio::time::sleep(secs(1.0)).await;
                    if a.fetch_add(1, Ordering::SeqCst) == 0 {
                        return Err(Failure::new("Blocked", "cart in the way"));
                    }
                    Ok(())
                }
            })
            .handler(Handler::new("notMine", "Blocked", |ctx| async move {
                ctx.bypass()
            })),
        )
        .start()?;
        ctx.spawn(Task::command("speak", |_| async { Ok(()) }))
            .sequential(Facet::Execution, NodeRef::Previous)
            .start()?;
        Ok(())
    })
    .handler(
        Handler::new("retryMove", "Blocked", |ctx| async move {
            let again = ctx.retry()?;
            ctx.wait(again).await?;
            Ok(())
        })
        .max_activations(2),
    );
    let (report, trace) = run_checked(Runtime::new(), task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(attempts.load(Ordering::SeqCst), 2);
    assert_eq!(
        chosen(&trace),
        ["notMine<-Blocked", "bypass", "retryMove<-Blocked"]
    );
    assert_order(
        &story(&trace),
        &[
            "1 move failed Blocked",
            "1 retryMove handling active",
            "2 move handling completed",
            "2 speak handling active",
        ],
    );
}

/// A wiretap is on a class of tasks: naming the instances of `step` does not unhook it; tapping
/// one instance name is the explicit `wiretap_instance`.
#[tokio::test(start_paused = true)]
async fn a_wiretap_taps_every_instance_of_its_task_whatever_its_name() {
    let (by_task, by_instance) = (Arc::new(AtomicU32::new(0)), Arc::new(AtomicU32::new(0)));
    let (t, i) = (by_task.clone(), by_instance.clone());
    let rt = Runtime::new()
        .wiretap("step", TapWhen::Before, move |_| {
            t.fetch_add(1, Ordering::SeqCst);
            async { Ok(()) }
        })
        .wiretap_instance("left_front", TapWhen::After, move |_| {
            i.fetch_add(1, Ordering::SeqCst);
            async { Ok(()) }
        });
    let task = Task::goal("walk", |ctx| async move {
        for leg in ["left_front", "right_front", "left_rear"] {
            ctx.spawn(Task::command("step", |_| async { Ok(()) }).named(leg))
                .sequential(Facet::Execution, NodeRef::Previous)
                .start()?;
        }
        // Not a `step`, though it has the tapped instance name of one.
        ctx.spawn(Task::command("stand", |_| async { Ok(()) }).named("left_front"))
            .sequential(Facet::Execution, NodeRef::Previous)
            .start()?;
        Ok(())
    });
    let (report, trace) = run_checked(rt, task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(
        by_task.load(Ordering::SeqCst),
        3,
        "{}",
        story(&trace).join("\n")
    );
    assert_eq!(by_instance.load(Ordering::SeqCst), 2);
}

#[tokio::test(start_paused = true)]
async fn a_wiretap_vetoes_one_of_five_moves() {
    let checks = Arc::new(AtomicU32::new(0));
    let c = checks.clone();
    let rt = Runtime::new().wiretap("move", TapWhen::Before, move |_| {
        let n = c.fetch_add(1, Ordering::SeqCst) + 1;
        async move {
            if n == 3 {
                return Err(Failure::new("Unstable", "the robot would tip over"));
            }
            Ok(())
        }
    });
    let task = Task::goal("walk", |ctx| async move {
        for _ in 0..5 {
            ctx.spawn(Task::command("move", |_| async {
                tokio::time::sleep(secs(1.0)).await;
                Ok(())
            }))
            .sequential(Facet::Execution, NodeRef::Previous)
            .start()?;
        }
        Ok(())
    });
    let (report, trace) = run_checked(rt, task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(checks.load(Ordering::SeqCst), 5);
    let st = story(&trace);
    assert_eq!(
        st.iter()
            .filter(|l| l.ends_with("move handling active"))
            .count(),
        4
    );
    assert!(
        st.iter().any(|l| l == "2 move failed Unstable"),
        "{}",
        st.join("\n")
    );
}

#[derive(Debug, thiserror::Error)]
#[error("leg {leg} touched the terrain early")]
struct TerrainContact {
    leg: u32,
}

impl Exception for TerrainContact {}

/// TCA's recovery added without touching the components: a handler attached on the runtime to
/// every `step` (whatever the instance is named) is found by the same search, after the node's
/// own handlers, with its own uses per node; a task with another name is not concerned.
#[tokio::test(start_paused = true)]
async fn a_handler_attached_to_a_task_from_outside_recovers_each_of_its_nodes() {
    let step = |leg: u32| {
        Task::command("step", move |_| async move {
            tokio::time::sleep(secs(1.0)).await;
            Err::<(), _>(TerrainContact { leg }.raise())
        })
        .named(format!("leg{leg}"))
    };
    let raised = Arc::new(Mutex::new(Vec::<(u32, f64)>::new()));
    let r = raised.clone();
    let rt = Runtime::new()
        .handler_for(
            "step",
            Handler::on::<TerrainContact, _, _, _>("raise_leg", move |ctx| {
                let r = r.clone();
                async move {
                    let leg = ctx.caught::<TerrainContact>().map_or(0, |c| c.leg);
                    let now = ctx.now().as_secs_f64();
                    r.lock().expect("log").push((leg, now));
                    Ok(())
                }
            })
            .max_activations(1),
        )
        .handler_for(
            "step",
            Handler::on::<TerrainContact, _, _, _>("never_reached", |_| async { Ok(()) }),
        );
    let task = Task::goal("walk", move |ctx| async move {
        ctx.spawn(step(1)).start()?;
        ctx.spawn(step(2))
            .sequential(Facet::Execution, NodeRef::Previous)
            .start()?;
        // Its own handler comes first; bypassing it goes on to the one attached from outside.
        ctx.spawn(step(3))
            .sequential(Facet::Execution, NodeRef::Previous)
            .handler(Handler::on::<TerrainContact, _, _, _>(
                "own",
                |ctx| async move {
                    ctx.bypass()?;
                    Ok(())
                },
            ))
            .start()?;
        // Another task with the same failure: no handler.
        ctx.spawn(Task::command("stand", |_| async {
            Err::<(), _>(TerrainContact { leg: 9 }.raise())
        }))
        .sequential(Facet::Execution, NodeRef::Previous)
        .start()?;
        Ok(())
    });
    let (report, trace) = run_checked(rt, task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(
        chosen(&trace),
        [
            "raise_leg<-TerrainContact",
            "raise_leg<-TerrainContact",
            "own<-TerrainContact",
            "bypass",
            "raise_leg<-TerrainContact",
        ],
        "{}",
        story(&trace).join("\n")
    );
    assert_eq!(*raised.lock().expect("log"), [(1, 1.0), (2, 2.0), (3, 3.0)]);
    assert_eq!(report.unhandled.len(), 1, "{report}");
    assert_eq!(report.unhandled[0].path, "walk/stand");
}

/// A leg move's arguments: which leg, and how high to lift it.
#[derive(Clone, Debug, PartialEq)]
struct LegMove {
    leg: u32,
    lift: f64,
}

/// TCA's monitors saw the message data: a wiretap check reads the tapped node's arguments
/// (`Task::with_args`), and vetoes the move of one leg only.
#[tokio::test(start_paused = true)]
async fn a_wiretap_check_reads_the_tapped_tasks_arguments() {
    let seen = Arc::new(Mutex::new(Vec::new()));
    let s = seen.clone();
    let rt = Runtime::new().wiretap("move", TapWhen::Before, move |ctx| {
        let s = s.clone();
        async move {
            let Some(args) = ctx.tapped_args::<LegMove>() else {
                return Err(Failure::new("NoArgs", "the move keeps no LegMove"));
            };
            // Another type reads nothing.
            assert!(ctx.tapped_args::<u32>().is_none());
            if let Ok(mut s) = s.lock() {
                s.push(args.leg);
            }
            if args.leg == 2 {
                return Err(Failure::new("Unstable", "leg 2 would tip the robot over"));
            }
            Ok(())
        }
    });
    let task = Task::goal("walk", |ctx| async move {
        for leg in 1..=3 {
            let args = LegMove { leg, lift: 0.1 };
            ctx.spawn(
                Task::command("move", move |ctx| async move {
                    // The action sees the same arguments.
                    assert_eq!(ctx.args::<LegMove>().map(|a| a.leg), Some(leg));
                    assert!(ctx.tapped_args::<LegMove>().is_none(), "not a check");
                    tokio::time::sleep(secs(1.0)).await;
                    Ok(())
                })
                .with_args(args),
            )
            .sequential(Facet::Execution, NodeRef::Previous)
            .start()?;
        }
        Ok(())
    });
    let (report, trace) = run_checked(rt, task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_eq!(*seen.lock().unwrap_or_else(|e| e.into_inner()), [1, 2, 3]);
    let st = story(&trace);
    assert!(
        st.iter().any(|l| l == "1 move failed Unstable"),
        "{}",
        st.join("\n")
    );
}

/// The Ambler's recovery: the handler reads the failed move's arguments, raises the lift and
/// retries with the changed arguments; the retried node's action and its wiretap check see them.
#[tokio::test(start_paused = true)]
async fn a_handler_retries_with_changed_arguments() {
    let tapped = Arc::new(Mutex::new(Vec::new()));
    let t = tapped.clone();
    let rt = Runtime::new().wiretap("move_leg", TapWhen::Before, move |ctx| {
        let t = t.clone();
        async move {
            if let (Ok(mut t), Some(a)) = (t.lock(), ctx.tapped_args::<LegMove>()) {
                t.push(a.lift);
            }
            Ok(())
        }
    });
    let ran = Arc::new(Mutex::new(Vec::new()));
    let r = ran.clone();
    let task = Task::goal("step", move |ctx| async move {
        let r = r.clone();
        ctx.spawn(
            Task::retryable_with(
                NodeKind::Command,
                "move_leg",
                LegMove { leg: 1, lift: 0.1 },
                move |_, args: LegMove| {
                    let r = r.clone();
                    async move {
                        if let Ok(mut r) = r.lock() {
                            r.push(args.lift);
                        }
                        tokio::time::sleep(secs(1.0)).await;
                        if args.lift < 0.3 {
                            return Err(TerrainContact { leg: args.leg }.raise());
                        }
                        Ok(())
                    }
                },
            )
            .handler(
                Handler::on::<TerrainContact, _, _, _>("raise_leg", |ctx| async move {
                    let Some(old) = ctx.failing_args::<LegMove>() else {
                        return Err(Failure::new("NoArgs", "no leg move to raise"));
                    };
                    // The wrong type is refused, and nothing is retried.
                    assert!(ctx.retry_with(7u32).is_err());
                    let raised = LegMove {
                        lift: old.lift + 0.15,
                        ..(*old).clone()
                    };
                    let again = ctx.retry_with(raised)?;
                    ctx.wait(again).await?;
                    Ok(())
                })
                .max_activations(3),
            ),
        )
        .start()?;
        Ok(())
    });
    let (report, trace) = run_checked(rt, task).await;
    assert_eq!(
        report.outcome,
        RunOutcome::Completed,
        "{}",
        story(&trace).join("\n")
    );
    let lifts = |v: &Mutex<Vec<f64>>| -> Vec<String> {
        v.lock()
            .unwrap_or_else(|e| e.into_inner())
            .iter()
            .map(|l| format!("{l:.2}"))
            .collect()
    };
    // 0.10 fails, 0.25 fails (its failure searches from the handler node: the attempt's own
    // handler raises it again), 0.40 succeeds.
    assert_eq!(lifts(&ran), ["0.10", "0.25", "0.40"]);
    assert_eq!(lifts(&tapped), ["0.10", "0.25", "0.40"]);
}

/// A plain `retry` of a task keeping arguments re-runs it with the failed run's arguments.
#[tokio::test(start_paused = true)]
async fn retry_keeps_the_failed_runs_arguments() {
    let ran = Arc::new(Mutex::new(Vec::new()));
    let r = ran.clone();
    let task = Task::goal("step", move |ctx| async move {
        let r = r.clone();
        ctx.spawn(Task::retryable_with(
            NodeKind::Command,
            "move_leg",
            LegMove { leg: 4, lift: 0.1 },
            move |_, args: LegMove| {
                let r = r.clone();
                async move {
                    let n = r.lock().map(|mut r| {
                        r.push(args.clone());
                        r.len()
                    });
                    if n.unwrap_or(0) == 1 {
                        return Err(Failure::new("Blocked", "once"));
                    }
                    Ok(())
                }
            },
        ))
        .start()?;
        Ok(())
    })
    .handler(Handler::new("again", "Blocked", |ctx| async move {
        let again = ctx.retry()?;
        ctx.wait(again).await?;
        Ok(())
    }));
    let (report, _) = run_checked(Runtime::new(), task).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let ran = ran.lock().unwrap_or_else(|e| e.into_inner()).clone();
    assert_eq!(
        ran,
        [LegMove { leg: 4, lift: 0.1 }, LegMove { leg: 4, lift: 0.1 }]
    );
}
