//! Random programs (`random_program`) give the same trace with and without the pump, and the
//! programs the proptest once found giving another order.

use super::{ms, noop, sleeper, trace_of, without_run_ids};
use crate::{Failure, Handler, Monitor, NodeKind, Runtime, Task};
use proptest::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

/// One child of a random program (`random_program`).
#[derive(Clone, Debug)]
enum Kid {
    Ends,
    Sleeps(u64),
    Yields,
    Fails,
    Parent(u8),
    // Waits for the channel of the `Sends` with the same number, if there is one.
    Waits(u8),
    Sends(u8),
    // Terminates the child this many places before it.
    Terminates(u8),
    // Waits for the end of the child this many places before it (an engine watch).
    WaitsFor(u8),
    // Sleeps this long holding the one `base`: such children run one at a time.
    Uses(u64),
    // A monitor polling every millisecond, this many times (at least once).
    Polls(u8),
    // Fails on its first run; its handler retries it.
    Retries,
    // A goal whose child fails: the failure goes up to the program's handler.
    FailsBelow,
    // Its closure (code run when it starts, before its future) adds its place to a log.
    Marks,
    // Its future traces the log.
    Reads,
    // Synchronous actions (`Task::command_now`, `Task::goal_now`), named as their async twins
    // (`Kid::asynced`): one that ends, one that fails, a goal that spawns this many children, one
    // that sends on the channel of that number, one that terminates the child this many places
    // before it.
    EndsNow,
    FailsNow,
    ParentNow(u8),
    SendsNow(u8),
    TerminatesNow(u8),
}

impl Kid {
    /// The async twin of a synchronous kid: the same body, written async.
    fn asynced(self) -> Kid {
        match self {
            Kid::EndsNow => Kid::Ends,
            Kid::FailsNow => Kid::Fails,
            Kid::ParentNow(n) => Kid::Parent(n),
            Kid::SendsNow(c) => Kid::Sends(c),
            Kid::TerminatesNow(b) => Kid::Terminates(b),
            other => other,
        }
    }
}

fn kid() -> impl Strategy<Value = (Kid, Option<u8>)> {
    let kid = prop_oneof![
        3 => Just(Kid::Ends),
        2 => (1u64..4).prop_map(Kid::Sleeps),
        1 => Just(Kid::Yields),
        1 => Just(Kid::Fails),
        1 => (0u8..3).prop_map(Kid::Parent),
        1 => (0u8..3).prop_map(Kid::Waits),
        1 => (0u8..3).prop_map(Kid::Sends),
        1 => (1u8..6).prop_map(Kid::Terminates),
        1 => (1u8..6).prop_map(Kid::WaitsFor),
        1 => (1u64..4).prop_map(Kid::Uses),
        1 => (1u8..4).prop_map(Kid::Polls),
        1 => Just(Kid::Retries),
        1 => Just(Kid::FailsBelow),
        1 => Just(Kid::Marks),
        1 => Just(Kid::Reads),
        2 => Just(Kid::EndsNow),
        1 => Just(Kid::FailsNow),
        1 => (0u8..3).prop_map(Kid::ParentNow),
        1 => (0u8..3).prop_map(Kid::SendsNow),
        1 => (1u8..6).prop_map(Kid::TerminatesNow),
    ];
    (kid, proptest::option::weighted(0.5, 1u8..4))
}

/// A goal whose children are `kids`, each serial after the one that many places before it,
/// if it says so (several after one are released together).
fn random_program(kids: Vec<(Kid, Option<u8>)>) -> Task {
    type Chan = Arc<Mutex<Vec<Option<tokio::sync::oneshot::Sender<()>>>>>;
    Task::goal("random", move |ctx| {
        let kids = kids.clone();
        async move {
            ctx.hold_children(false)?;
            let mut senders = Vec::new();
            let mut receivers = Vec::new();
            for _ in 0..3 {
                let (tx, rx) = tokio::sync::oneshot::channel::<()>();
                senders.push(Some(tx));
                receivers.push(Some(rx));
            }
            let senders: Chan = Arc::new(Mutex::new(senders));
            let log: Arc<Mutex<Vec<usize>>> = Arc::default();
            let mut ids = Vec::new();
            for (i, (kid, after)) in kids.into_iter().enumerate() {
                let task = match kid {
                    Kid::Ends => noop("ends"),
                    Kid::Sleeps(d) => sleeper("sleeps", d),
                    Kid::Yields => Task::command("yields", |ctx| async move {
                        tokio::task::yield_now().await;
                        ctx.warn("resumed")?;
                        Ok(())
                    }),
                    Kid::Fails => Task::command("fails", |_| async {
                        Err::<(), _>(Failure::new("Boom", "random"))
                    }),
                    Kid::EndsNow => Task::command_now("ends", |_| Ok(())),
                    Kid::FailsNow => {
                        Task::command_now("fails", |_| Err::<(), _>(Failure::new("Boom", "random")))
                    }
                    Kid::ParentNow(n) => Task::goal_now("parent", move |ctx| {
                        for _ in 0..n {
                            ctx.spawn(Task::command_now("grandchild", |_| Ok(())))
                                .start()?;
                        }
                        Ok(())
                    }),
                    Kid::SendsNow(c) => {
                        let senders = senders.clone();
                        Task::command_now("sends", move |_| {
                            let tx = senders.lock().ok().and_then(|mut s| s[c as usize].take());
                            if let Some(tx) = tx {
                                let _ = tx.send(());
                            }
                            Ok(())
                        })
                    }
                    Kid::TerminatesNow(back) => {
                        let victim = i.checked_sub(back as usize).map(|j| ids[j]);
                        Task::command_now("terminates", move |ctx| {
                            if let Some(v) = victim {
                                ctx.terminate(v)?;
                            }
                            Ok(())
                        })
                    }
                    Kid::Parent(n) => Task::goal("parent", move |ctx| async move {
                        for _ in 0..n {
                            ctx.spawn(noop("grandchild")).start()?;
                        }
                        Ok(())
                    }),
                    Kid::Waits(c) => {
                        let rx = receivers[c as usize].take();
                        let rx = Arc::new(Mutex::new(rx));
                        Task::command("waits", move |ctx| {
                            let rx = rx.clone();
                            async move {
                                let rx = rx.lock().ok().and_then(|mut r| r.take());
                                if let Some(rx) = rx {
                                    // Bounded: its sender may come after it, or never.
                                    let _ = tokio::time::timeout(ms(20), rx).await;
                                }
                                ctx.warn("woke")?;
                                Ok(())
                            }
                        })
                    }
                    Kid::Sends(c) => {
                        let senders = senders.clone();
                        Task::command("sends", move |_| {
                            let senders = senders.clone();
                            async move {
                                let tx = senders.lock().ok().and_then(|mut s| s[c as usize].take());
                                if let Some(tx) = tx {
                                    let _ = tx.send(());
                                }
                                Ok(())
                            }
                        })
                    }
                    Kid::Terminates(back) => {
                        let victim = i.checked_sub(back as usize).map(|j| ids[j]);
                        Task::command("terminates", move |ctx| async move {
                            if let Some(v) = victim {
                                ctx.terminate(v)?;
                            }
                            Ok(())
                        })
                    }
                    Kid::WaitsFor(back) => {
                        let target = i.checked_sub(back as usize).map(|j| ids[j]);
                        Task::command("waits_for", move |ctx| async move {
                            if let Some(t) = target {
                                ctx.wait(t).await?;
                            }
                            Ok(())
                        })
                    }
                    Kid::Uses(d) => sleeper("uses", d).uses("base", 1),
                    Kid::Polls(n) => {
                        let params = Monitor {
                            max_activations: Some(u32::from(n)),
                            period: Some(ms(1)),
                            ..Monitor::default()
                        };
                        Task::monitor("polls", params, |ctx| async move {
                            ctx.warn("polled")?;
                            Ok(())
                        })
                    }
                    Kid::Retries => {
                        let runs = Arc::new(AtomicUsize::new(0));
                        Task::retryable(NodeKind::Command, "retries", move |_| {
                            let first = runs.fetch_add(1, Ordering::SeqCst) == 0;
                            async move {
                                if first {
                                    return Err(Failure::new("Flaky", "first run"));
                                }
                                Ok(())
                            }
                        })
                        .handler(Handler::new(
                            "again",
                            "Flaky",
                            |ctx| async move {
                                ctx.retry()?;
                                Ok(())
                            },
                        ))
                    }
                    Kid::Marks => {
                        let log = log.clone();
                        Task::command("marks", move |_| {
                            if let Ok(mut l) = log.lock() {
                                l.push(i);
                            }
                            async { Ok(()) }
                        })
                    }
                    Kid::Reads => {
                        let log = log.clone();
                        Task::command("reads", move |ctx| {
                            let log = log.clone();
                            async move {
                                let seen = log.lock().map(|l| format!("{l:?}")).ok();
                                ctx.warn(format!("log {seen:?}"))?;
                                Ok(())
                            }
                        })
                    }
                    Kid::FailsBelow => Task::goal("fails_below", |ctx| async move {
                        ctx.spawn(Task::command("fails", |_| async {
                            Err::<(), _>(Failure::new("Boom", "below"))
                        }))
                        .start()?;
                        Ok(())
                    }),
                };
                let spawner = ctx.spawn(task);
                let before = after.and_then(|k| i.checked_sub(k as usize));
                let spawner = match before {
                    Some(j) => spawner.serial(ids[j]),
                    None => spawner,
                };
                ids.push(spawner.start()?);
            }
            Ok(())
        }
    })
    .handler(Handler::new("recover", "Boom", |_| async { Ok(()) }))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    /// Random programs (ending, synchronously or not, sleeping, yielding, failing into a handler or below,
    /// retrying, spawning, waking one another through channels and engine watches,
    /// terminating one another, polling, sharing a resource, running code in their closures
    /// that others' futures look at; some after others, several released together) give the
    /// same trace with and without the pump, record for record, and the same pumped trace on
    /// every run.
    #[test]
    fn random_programs_give_the_same_trace_with_and_without_the_pump(
        kids in proptest::collection::vec(kid(), 1..40),
    ) {
        let rt = || Runtime::new().resource("base", 1);
        let pumped = trace_of(rt(), random_program(kids.clone()));
        let again = trace_of(rt(), random_program(kids.clone()));
        let asynced: Vec<_> = kids.iter().cloned().map(|(k, a)| (k.asynced(), a)).collect();
        let tasks = trace_of(rt().without_pump(), random_program(kids));
        let written_async = trace_of(rt(), random_program(asynced));
        prop_assert_eq!(without_run_ids(pumped.clone()), without_run_ids(again));
        prop_assert_eq!(without_run_ids(pumped.clone()), without_run_ids(tasks));
        // A synchronous action gives the trace its body written async gives.
        prop_assert_eq!(without_run_ids(pumped), without_run_ids(written_async));
    }
}

/// Programs the proptest above found giving another order than tasks, each fixed since: the
/// same trace, record for record.
#[test]
fn programs_once_found_giving_another_order_give_the_same_trace() {
    use Kid::*;
    type Kids = Vec<(Kid, Option<u8>)>;
    // A monitor's activation dropped in its batch, a node released by its stop, and `then`
    // released with that node.
    let after_a_dropped_activation = |then: Kid| -> Kids {
        vec![
            (Ends, None),
            (Ends, None),
            (Ends, None),
            (Waits(0), None),
            (Fails, None),
            (Ends, None),
            (Polls(1), Some(2)),
            (Terminates(1), Some(3)),
            (Ends, Some(2)),
            (then, Some(2)),
            (WaitsFor(4), None),
            (Ends, Some(1)),
            (Ends, None),
            (Ends, None),
        ]
    };
    let programs: Vec<(&str, Kids)> = vec![
        // A handler about to start when a node of the same batch terminates its failed node:
        // what an end starts is started before the next end, or the future that took the
        // lock, is looked at (`flush`).
        (
            "handler started before the terminator's lock",
            vec![(Ends, None), (Fails, Some(1)), (Terminates(1), Some(2))],
        ),
        // A monitor's activation cancelled by a node of its batch polled before it: dropped
        // unpolled in its turn, its stop reported by whoever runs next.
        (
            "activation cancelled in its batch",
            vec![
                (Ends, None),
                (Ends, None),
                (Ends, None),
                (Uses(1), None),
                (Ends, None),
                (Polls(1), Some(2)),
                (Terminates(1), Some(3)),
            ],
        ),
        // The same, the stop then releasing a node a later future waits for.
        (
            "stop of a dropped activation, then a send",
            after_a_dropped_activation(Sends(0)),
        ),
        // A stop reported before a node it releases is terminated by the lock that reported
        // it (`host::stops_first` starts what the stop starts).
        (
            "stop, then a termination in the same lock",
            after_a_dropped_activation(Terminates(1)),
        ),
        // Two handlers started in one batch, the second cancelled: dropped in its turn, after
        // the first ran.
        (
            "second of two handlers cancelled",
            vec![
                (Ends, None),
                (Fails, Some(1)),
                (Retries, Some(2)),
                (Terminates(1), Some(3)),
                (Ends, Some(1)),
                (Ends, Some(1)),
            ],
        ),
        // An end reported with a held wake-up (its future woke a waiting task) starts a node
        // the next future of its batch terminates: the start went to the host first, so the
        // node is stopped as a running action, not struck from the engine's effects.
        (
            "a start by an end reported with a wake-up, terminated in the same batch",
            vec![
                (Sends(1), None),
                (Ends, None),
                (Ends, None),
                (Ends, Some(1)),
                (Sends(0), Some(1)),
                (Ends, Some(1)),
                (Terminates(1), Some(3)),
                (Waits(0), None),
                (Uses(1), None),
                (Ends, Some(1)),
                (Ends, None),
            ],
        ),
        // A handler dropped unpolled last in its batch; the next batch's one future yields
        // (no end reported): the stop is handed over then, not reported by the pump, so the
        // node it releases starts after the yielded future resumed, as with tasks.
        (
            "a stop kept past a batch that reported nothing",
            vec![
                (Ends, None),
                (Ends, None),
                (Waits(0), Some(1)),
                (Fails, Some(2)),
                (Terminates(1), Some(2)),
                (Yields, Some(1)),
                (Terminates(1), Some(3)),
            ],
        ),
    ];
    for (what, kids) in programs {
        let rt = || Runtime::new().resource("base", 1);
        let pumped = trace_of(rt(), random_program(kids.clone()));
        let again = trace_of(rt(), random_program(kids.clone()));
        let tasks = trace_of(rt().without_pump(), random_program(kids));
        assert!(pumped.len() > 20, "{what}: a real trace");
        assert_eq!(
            without_run_ids(pumped.clone()),
            without_run_ids(again),
            "{what}"
        );
        assert_eq!(without_run_ids(pumped), without_run_ids(tasks), "{what}");
    }
}
