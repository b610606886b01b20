//! `approvals.tdl`: a lift held for an operator's approval that never comes, refused after two
//! seconds and taken by a handler, both ways alike. (`wait_for_operator` waits for an approval
//! as long as it takes: a run of it alone would wait for its operator, and is not run here.)

// The program as written (a handler's exception it does not read) and as generated.
#![allow(unused_variables)]

use tdl_interp::Registry;

use crate::util::Case;

include!(concat!(env!("OUT_DIR"), "/approvals.rs"));

#[tokio::test(start_paused = true)]
async fn a_refused_approval_and_its_handler_run_alike() {
    let case = Case::new(&["approvals"], &Registry::new());
    case.alike(pick(), "pick", vec![]).await;
    case.alike(lift(), "lift", vec![]).await;
    let _ = wait_for_operator;
    // What the traces hold: the lift held, refused at 2 s, the handler chosen.
    let (_, trace) = tdl::testing::run_checked(tdl::Runtime::new(), pick()).await;
    let refused = trace.iter().find(|e| {
        matches!(&e.kind,
        tdl::TraceKind::Failed { exception, message, .. }
            if exception == "ApprovalRefused" && message == "not approved: no approval within 2s")
    });
    assert_eq!(refused.map(|e| e.t), Some(2_000_000_000));
    assert!(
        trace
            .iter()
            .any(|e| matches!(e.kind, tdl::TraceKind::Held { .. }))
    );
    assert!(trace.iter().any(|e| matches!(&e.kind,
        tdl::TraceKind::HandlerChosen { handler, .. } if handler == "put_down")));
}
