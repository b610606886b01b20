//! TDL programs run by the interpreter (`tdl_interp`, loaded from their text at run time) call
//! ROS 2 actions and services registered with `tcm_ros::interp`: the goal is made of the
//! extern's arguments, the result is the task's value whose fields the program reads, an aborted
//! goal is an `ActionAborted` a TDL handler takes by name, and a TDL `terminate in` cancels the
//! goal on the server.

use crate::util::{
    AddRequest, AddResponse, AddServer, FibFeedback, FibGoal, FibResult, FibServer, Log, Pair,
    Script, add_type, bounded, fib_type, fibonacci,
};
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tcm::testing::{handler_choices, run_checked, story};
use tcm::{Failure, RunOutcome, Runtime, Task};
use tcm_ros::{ActionClient, ServiceClient, interp};
use tdl_interp::{Program, Registry, Value};

type Fib = ActionClient<FibGoal, FibResult, FibFeedback>;
type Add = ServiceClient<AddRequest, AddResponse>;

fn load(src: &str, registry: &Registry) -> Program {
    match Program::from_sources(&[("test.tdl".into(), src.into())], registry) {
        Ok(p) => p,
        Err(e) => panic!("{e}"),
    }
}

/// A root goal that runs the program's task `name` with `args` and keeps its value.
fn root(program: &Program, name: &str, args: Vec<Value>) -> (Task, Arc<Mutex<Option<Value>>>) {
    let task = program.task(name, args).expect("the program's task");
    let value = Arc::new(Mutex::new(None));
    let v = value.clone();
    let main = Task::goal("main", move |ctx| async move {
        let got: Value = ctx.spawn(task).wait_value().await?;
        *v.lock().expect("value") = Some(got);
        Ok(())
    });
    (main, value)
}

const FIB_PROGRAM: &str = r#"
/// The first `order` Fibonacci numbers, from a ROS 2 action.
extern command fib(order: i64) -> Json;

/// The last number of the sequence; `big` or `small` runs after it, as it is.
pub goal mission(order: i64) -> i64 {
    let r = spawn fib(order) with wait;
    let n = r.sequence.len();
    let last = r.sequence[n - 1];
    if last > 3 {
        spawn big() with wait;
    } else {
        spawn small() with wait;
    }
    last
}

command big() {}
command small() {}
"#;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_program_calls_an_action_and_reads_a_field_of_its_result() {
    bounded(async {
        let pair = Pair::new().await;
        let server = FibServer::start(
            &pair.server,
            "/fib_interp",
            Script::Succeed {
                step: Duration::from_millis(5),
            },
        );
        let fib = Fib::new(&pair.client, "/fib_interp", &fib_type()).expect("action client");
        let mut registry = Registry::new();
        interp::action(&mut registry, "fib", &fib, &["order"]);
        let program = load(FIB_PROGRAM, &registry);
        for (order, branch) in [(6, "big"), (3, "small")] {
            let (main, value) = root(&program, "mission", vec![Value::Int(order)]);
            let (report, trace) = run_checked(Runtime::new(), main).await;
            assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
            assert!(report.is_clean(), "{report}");
            // The value the program computed from the result the server sent.
            let sent = fibonacci(i32::try_from(order).expect("small"));
            let last = i64::from(*sent.last().expect("a number"));
            assert_eq!(value.lock().expect("value").take(), Some(Value::Int(last)));
            let lines = story(&trace);
            assert!(
                lines.iter().any(|l| l.ends_with("fib handling completed")),
                "{lines:#?}"
            );
            assert!(
                lines
                    .iter()
                    .any(|l| l.ends_with(&format!("{branch} handling completed"))),
                "{lines:#?}"
            );
            assert!(
                server.log.entries().contains(&format!("goal {order}")),
                "{:?}",
                server.log.entries()
            );
        }
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_program_calls_a_service_and_reads_a_field_of_its_response() {
    bounded(async {
        let pair = Pair::new().await;
        let server = AddServer::start(&pair.server, "/add_interp");
        let add = Add::new(&pair.client, "/add_interp", &add_type()).expect("client");
        let mut registry = Registry::new();
        interp::service(&mut registry, "add", &add, &["a", "b"]);
        let src = r#"
            extern command add(a: i64, b: i64) -> Json;

            pub goal twice_sum(a: i64, b: i64) -> i64 {
                let s = spawn add(a, b) with wait;
                s.sum * 2
            }
        "#;
        let program = load(src, &registry);
        let (main, value) = root(&program, "twice_sum", vec![Value::Int(40), Value::Int(-2)]);
        let (report, trace) = run_checked(Runtime::new(), main).await;
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        assert!(report.is_clean(), "{report}");
        assert_eq!(
            value.lock().expect("value").take(),
            Some(Value::Int((40 - 2) * 2))
        );
        assert_eq!(server.requests.load(Ordering::SeqCst), 1);
        let lines = story(&trace);
        assert!(
            lines.iter().any(|l| l.ends_with("add handling completed")),
            "{lines:#?}"
        );
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_aborted_goal_is_taken_by_a_tdl_handler_of_action_aborted() {
    bounded(async {
        let pair = Pair::new().await;
        let _server = FibServer::start(&pair.server, "/fib_interp_abort", Script::Abort);
        let fib = Fib::new(&pair.client, "/fib_interp_abort", &fib_type()).expect("client");
        let mut registry = Registry::new();
        // The closure variant: the goal built from the values by hand.
        interp::action_with(&mut registry, "fib", &fib, |args: &[Value]| {
            let order = args.first().and_then(Value::as_int).unwrap_or(0);
            i32::try_from(order)
                .map(|order| FibGoal { order })
                .map_err(|_| Failure::new("TypeMismatch", "the order is no i32"))
        });
        let notes = Log::default();
        let n = notes.clone();
        registry.function("note", move |s: String| n.push(s));
        let src = r#"
            extern command fib(order: i64) -> Json;

            pub goal mission() {
                spawn fib(5) with wait, exception handler on_abort();
            }

            handler on_abort() handles ActionAborted as e {
                let a = e.downcast::<ActionAborted>().expect("its fields");
                note(format!("{} {} {:?}", e.name(), a.action, a.result.sequence));
            }
        "#;
        let program = load(src, &registry);
        let mission = program.task("mission", vec![]).expect("the program's task");
        let (report, trace) = run_checked(Runtime::new(), mission).await;
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        assert!(report.unhandled.is_empty(), "{report}");
        assert_eq!(handler_choices(&trace), ["on_abort<-ActionAborted"]);
        let lines = story(&trace);
        assert!(
            lines
                .iter()
                .any(|l| l.ends_with("fib failed ActionAborted")),
            "{lines:#?}"
        );
        // The result the server sent with the abort (the two numbers it had when it aborted,
        // after one feedback message) reached the handler.
        assert_eq!(
            notes.entries(),
            [format!(
                "ActionAborted /fib_interp_abort {:?}",
                fibonacci(5)[..2].to_vec()
            )]
        );
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn terminating_the_tdl_node_cancels_the_goal_on_the_server() {
    bounded(async {
        let pair = Pair::new().await;
        let server = FibServer::start(
            &pair.server,
            "/fib_interp_endless",
            Script::Endless {
                step: Duration::from_millis(10),
            },
        );
        let fib = Fib::new(&pair.client, "/fib_interp_endless", &fib_type()).expect("client");
        let mut registry = Registry::new();
        interp::action(&mut registry, "fib", &fib, &["order"]);
        let src = r#"
            extern command fib(order: i64) -> Json;

            pub goal mission() {
                spawn fib(3) with terminate in 400ms;
            }
        "#;
        let program = load(src, &registry);
        let mission = program.task("mission", vec![]).expect("the program's task");
        let started = Instant::now();
        let (report, trace) = run_checked(Runtime::new(), mission).await;
        let log = server.log.entries();
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        assert!(report.unhandled.is_empty(), "{report}");
        assert!(
            started.elapsed() < Duration::from_secs(10),
            "{:?}",
            started.elapsed()
        );
        // The server ran the goal, was asked to cancel it, and ended it canceled, all before
        // the run ended.
        assert!(log.contains(&"goal 3".to_string()), "{log:?}");
        assert!(log.iter().any(|e| e.starts_with("feedback")), "{log:?}");
        assert!(log.contains(&"cancel true".to_string()), "{log:?}");
        assert!(log.contains(&"result Canceled".to_string()), "{log:?}");
        let after = log.iter().skip_while(|e| *e != "cancel true").skip(1);
        assert!(after.clone().all(|e| !e.starts_with("feedback")), "{log:?}");
        let lines = story(&trace);
        assert!(
            lines.iter().any(|l| l.ends_with("fib terminated")),
            "{lines:#?}"
        );
    })
    .await;
}
