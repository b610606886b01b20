//! The tree calls a ROS 2 service served by ros2-client's own service server: the response is the
//! task's value; with no server, the task fails with a timeout a handler takes.

use crate::util::{AddRequest, AddResponse, AddServer, Log, Pair, add_type, bounded};
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tcm::testing::{handler_choices, run_checked};
use tcm::{Handler, RunOutcome, Runtime, Task};
use tcm_ros::{RosTimeout, ServiceClient, Waited};

type Add = ServiceClient<AddRequest, AddResponse>;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_service_call_is_a_task_whose_value_is_the_response() {
    bounded(async {
        let pair = Pair::new().await;
        let server = AddServer::start(&pair.server, "/add_two_ints");
        let add = Add::new(&pair.client, "/add_two_ints", &add_type()).expect("client");
        let sums = Arc::new(Mutex::new(Vec::new()));
        let s = sums.clone();
        let main = Task::goal("main", move |ctx| async move {
            for (a, b) in [(2, 40), (-5, 3)] {
                let r: AddResponse = ctx
                    .spawn(add.call(AddRequest { a, b }).task())
                    .wait_value()
                    .await?;
                s.lock().expect("sums").push(r.sum);
            }
            Ok(())
        });
        let (report, _trace) = run_checked(Runtime::new(), main).await;
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        assert!(report.is_clean(), "{report}");
        assert_eq!(*sums.lock().expect("sums"), [42, -2]);
        assert_eq!(server.requests.load(Ordering::SeqCst), 2);
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_service_with_no_server_fails_with_a_timeout_never_a_silent_hang() {
    bounded(async {
        let pair = Pair::new().await;
        let add = Add::new(&pair.client, "/nobody_adds", &add_type()).expect("client");
        let log = Log::default();
        let l = log.clone();
        let on_timeout = Handler::on::<RosTimeout, _, _, _>("on_timeout", move |ctx| {
            let l = l.clone();
            async move {
                let e = ctx.caught::<RosTimeout>().expect("a RosTimeout");
                assert_eq!(e.waited, Waited::Response);
                l.push(e.to_string());
                Ok(())
            }
        });
        let call = add
            .call(AddRequest { a: 1, b: 1 })
            .timeout(Duration::from_millis(300))
            .task();
        let main = Task::goal("main", move |ctx| async move {
            ctx.spawn(call).handler(on_timeout).wait().await?;
            Ok(())
        });
        let started = Instant::now();
        let (report, trace) = run_checked(Runtime::new(), main).await;
        let took = started.elapsed();
        assert!(
            took >= Duration::from_millis(300) && took < Duration::from_secs(5),
            "{took:?}"
        );
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        assert_eq!(handler_choices(&trace), ["on_timeout<-RosTimeout"]);
        assert_eq!(
            log.entries(),
            ["/nobody_adds: waited 300 ms for a response"]
        );
    })
    .await;
}
