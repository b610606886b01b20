//! State variables set by a body on an agent (docs/semantics.md, "State and conditions"): each
//! set an input to the executive's engine, recorded in its trace, which its conditions answer; a
//! value of the wrong type refused there with a warning.

use crate::util::{Net, bounded, untimed};
use std::time::Duration;
use tcm::testing::{assert_order, only, run_checked};
use tcm::{
    BinOp, Constraint, Expr, Facet, RunOutcome, Runtime, StateType, StateVar, Task, TraceKind, When,
};
use tcm_zenoh::{RemoteCtx, RemoteFailure};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_step_waits_on_a_condition_over_a_variable_an_agent_sets() {
    bounded(async {
        let net = Net::new("agent-state").await;
        let _probe = net
            .join(
                net.agent("probe")
                    .command("measure", |ctx: RemoteCtx, (): ()| async move {
                        ctx.set_state("battery", 20.0).await;
                        ctx.set_state("battery", "full").await; // the wrong type: refused
                        tokio::time::sleep(Duration::from_millis(30)).await;
                        ctx.set_state("battery", 90.0).await;
                        Ok::<_, RemoteFailure>(())
                    }),
                "probe",
            )
            .await;
        let exec = net.exec.clone();
        let battery = StateVar::new("battery", StateType::Float, 50.0);
        let rt = Runtime::new().state(battery.clone());
        let main = Task::goal("main", move |ctx| async move {
            let charged = ctx.condition(
                &[battery],
                Expr::bin(BinOp::Gt, Expr::var("battery"), Expr::lit(80.0)),
            )?;
            ctx.spawn(exec.remote("probe", "measure", ()).task())
                .start()?;
            ctx.spawn(Task::command("drive", |_| async { Ok(()) }))
                .with(Constraint::disable(
                    Facet::Handling,
                    When::Condition(charged),
                ))
                .start()?;
            Ok(())
        });
        let (report, trace) = run_checked(rt, main).await;
        assert_eq!(report.outcome, RunOutcome::Completed);
        let story = untimed(&trace);
        assert_eq!(
            only(&story, &["set battery"]),
            ["set battery = 20.0", "set battery = 90.0"]
        );
        assert_order(&story, &["set battery = 90.0", "drive handling active"]);
        let warned = trace.iter().any(|r| {
            matches!(&r.kind, TraceKind::Warning { message, .. }
                if message.contains("agent probe set state variable `battery`")
                    && message.contains("expected a value of type `float`"))
        });
        assert!(warned, "the refused set is a warning in the trace");
    })
    .await;
}
