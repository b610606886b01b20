//! Helpers: two ROS 2 contexts joined on 127.0.0.1 (zenoh peers, multicast scouting off, every
//! endpoint pinned), a Fibonacci-like action, an adding service and a float topic defined here with
//! ros2-client's message trait, a scripted action server and a service server written with
//! ros2-client alone, a bound on every test, and runs whose traces go through the trace checker.

use ros2_client::action_msgs::{CancelGoalResponseEnum, GoalInfo, GoalStatusEnum};
use ros2_client::builtin_interfaces::Time;
use ros2_client::{
    ActionTypeName, Context, ContextOptions, GoalId, Message, MessageTypeName, Node, NodeName,
    NodeOptions, RmwRequestId, ServiceTypeName,
};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::future::Future;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tcm_ros::ros2_client;

/// How long any test may take.
pub(crate) const BOUND: Duration = Duration::from_secs(60);

/// Runs `test`, failing if it takes longer than [`BOUND`].
pub(crate) async fn bounded<T>(test: impl Future<Output = T>) -> T {
    tokio::time::timeout(BOUND, test)
        .await
        .expect("the test did not end within its bound")
}

// ---- Messages: the shapes of action_tutorials_interfaces/Fibonacci,
// example_interfaces/AddTwoInts and std_msgs/Float32, three of the types whose ROS 2 type hash
// ros2-client knows, so the key expressions are those a ROS 2 Jazzy node would use (CDR is
// positional: the fields need only the right types and order).

#[derive(Clone, Debug, Serialize, Deserialize)]
pub(crate) struct FibGoal {
    pub(crate) order: i32,
}
impl Message for FibGoal {}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub(crate) struct FibResult {
    pub(crate) sequence: Vec<i32>,
}
impl Message for FibResult {}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub(crate) struct FibFeedback {
    pub(crate) sequence: Vec<i32>,
}
impl Message for FibFeedback {}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub(crate) struct AddRequest {
    pub(crate) a: i64,
    pub(crate) b: i64,
}
impl Message for AddRequest {}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub(crate) struct AddResponse {
    pub(crate) sum: i64,
}
impl Message for AddResponse {}

/// std_msgs/Float32 (a battery's percentage, in the tests).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub(crate) struct Float32 {
    pub(crate) data: f32,
}
impl Message for Float32 {}

pub(crate) fn float32_type() -> MessageTypeName {
    MessageTypeName::new("std_msgs", "Float32")
}

pub(crate) fn fib_type() -> ActionTypeName {
    ActionTypeName::new("action_tutorials_interfaces", "Fibonacci")
}

pub(crate) fn add_type() -> ServiceTypeName {
    ServiceTypeName::new("example_interfaces", "AddTwoInts")
}

/// The first `order` Fibonacci numbers (at least two).
pub(crate) fn fibonacci(order: i32) -> Vec<i32> {
    let mut seq = vec![0, 1];
    while seq.len() < usize::try_from(order).unwrap_or(0) {
        let n = seq.len();
        seq.push(seq[n - 1] + seq[n - 2]);
    }
    seq
}

// ---- Two contexts on loopback.

/// A zenoh configuration: peer mode, multicast scouting off, listening on `listen` and connecting
/// to `connect` (127.0.0.1 only).
fn config(listen: Option<u16>, connect: Option<u16>) -> zenoh::Config {
    let mut c = zenoh::Config::default();
    let list = |p: Option<u16>| match p {
        Some(p) => format!(r#"["tcp/127.0.0.1:{p}"]"#),
        None => "[]".to_string(),
    };
    for (key, value) in [
        ("mode", r#""peer""#.to_string()),
        ("scouting/multicast/enabled", "false".to_string()),
        ("listen/endpoints", list(listen)),
        ("connect/endpoints", list(connect)),
    ] {
        c.insert_json5(key, &value)
            .expect("a valid zenoh configuration");
    }
    c
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("a free port on 127.0.0.1")
}

/// Two ROS 2 contexts, each its own zenoh session: the server's listens on a free port of
/// 127.0.0.1, the client's connects to it and listens nowhere. A domain id per pair keeps the
/// tests of one process apart.
pub(crate) struct Pair {
    pub(crate) server: Node,
    pub(crate) client: Node,
    _contexts: (Context, Context),
}

impl Pair {
    pub(crate) async fn new() -> Pair {
        static DOMAIN: AtomicU32 = AtomicU32::new(1);
        let domain = u16::try_from(DOMAIN.fetch_add(1, Ordering::Relaxed)).expect("few tests");
        tokio::task::spawn_blocking(move || {
            let mut tries = 0;
            let (server_ctx, port) = loop {
                let port = free_port();
                let opened = Context::with_options(
                    ContextOptions::new()
                        .domain_id(domain)
                        .zenoh_config(config(Some(port), None)),
                );
                match opened {
                    Ok(c) => break (c, port),
                    Err(e) if tries < 5 => {
                        tries += 1;
                        eprintln!("port {port} taken meanwhile ({e}); another");
                    }
                    Err(e) => panic!("cannot open the server's context: {e}"),
                }
            };
            let client_ctx = Context::with_options(
                ContextOptions::new()
                    .domain_id(domain)
                    .zenoh_config(config(None, Some(port))),
            )
            .expect("the client's context opens");
            let options = || {
                NodeOptions::new()
                    .enable_rosout(false)
                    .start_parameter_services(false)
            };
            let server = server_ctx
                .new_node(NodeName::new("/", "server").expect("name"), options())
                .expect("server node");
            let client = client_ctx
                .new_node(NodeName::new("/", "client").expect("name"), options())
                .expect("client node");
            Pair {
                server,
                client,
                _contexts: (server_ctx, client_ctx),
            }
        })
        .await
        .expect("contexts open")
    }
}

// ---- What a server did, in order.

#[derive(Clone, Default)]
pub(crate) struct Log(Arc<Mutex<Vec<String>>>);

impl Log {
    pub(crate) fn push(&self, what: impl Into<String>) {
        self.0.lock().expect("log").push(what.into());
    }

    pub(crate) fn entries(&self) -> Vec<String> {
        self.0.lock().expect("log").clone()
    }
}

// ---- A Fibonacci action server written with ros2-client alone.

/// How the scripted server treats each goal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Script {
    /// One feedback message per number, every `step`, then the result: succeeded.
    Succeed { step: Duration },
    /// One feedback message, then aborted with the sequence so far.
    Abort,
    /// Rejects every goal.
    Reject,
    /// Feedback every `step` for ever; a cancel request ends the goal canceled.
    Endless { step: Duration },
    /// Ends each goal canceled on its own after one feedback message.
    CancelItself,
}

struct Running {
    order: i32,
    next: usize,
    due: Instant,
    ended: Option<(GoalStatusEnum, FibResult)>,
}

/// ros2-client's own action server for the Fibonacci action, on a thread of its own, polled
/// every millisecond, logging what it does: `goal <order>`, `rejected`, `feedback <n>`,
/// `cancel <ok>`, `result <status>`.
pub(crate) struct FibServer {
    pub(crate) log: Log,
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl FibServer {
    pub(crate) fn start(node: &Node, action: &str, script: Script) -> FibServer {
        let name = ros2_client::Name::parse(action).expect("a ROS 2 name");
        let server: ros2_client::ActionServer<FibGoal, FibResult, FibFeedback> = node
            .create_action_server(&name, &fib_type())
            .expect("action server");
        let log = Log::default();
        let stop = Arc::new(AtomicBool::new(false));
        let (l, s) = (log.clone(), stop.clone());
        let thread = std::thread::spawn(move || serve_fib(&server, script, &l, &s));
        FibServer {
            log,
            stop,
            thread: Some(thread),
        }
    }
}

impl Drop for FibServer {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn serve_fib(
    server: &ros2_client::ActionServer<FibGoal, FibResult, FibFeedback>,
    script: Script,
    log: &Log,
    stop: &AtomicBool,
) {
    let mut goals: BTreeMap<GoalId, Running> = BTreeMap::new();
    let mut waiting: Vec<(RmwRequestId, GoalId)> = Vec::new();
    let deadline = Instant::now() + BOUND;
    while !stop.load(Ordering::Relaxed) && Instant::now() < deadline {
        while let Some((request, goal, message)) = server.try_receive_goal() {
            let accept = script != Script::Reject;
            server.respond_goal(request, accept).expect("respond_goal");
            if !accept {
                log.push("rejected");
                continue;
            }
            log.push(format!("goal {}", message.order));
            goals.insert(
                goal,
                Running {
                    order: message.order,
                    next: 1,
                    due: Instant::now(),
                    ended: None,
                },
            );
        }
        while let Some((request, goal)) = server.try_receive_cancel() {
            let canceling = match goals.get_mut(&goal) {
                Some(g) if g.ended.is_none() => {
                    let seq = fibonacci(g.order);
                    let so_far = seq[..g.next.min(seq.len())].to_vec();
                    g.ended = Some((GoalStatusEnum::Canceled, FibResult { sequence: so_far }));
                    vec![GoalInfo {
                        goal_id: goal,
                        stamp: Time::ZERO,
                    }]
                }
                _ => vec![],
            };
            let code = if canceling.is_empty() {
                CancelGoalResponseEnum::UnknownGoal
            } else {
                CancelGoalResponseEnum::None
            };
            log.push(format!("cancel {}", !canceling.is_empty()));
            server
                .respond_cancel(request, code, canceling)
                .expect("respond_cancel");
        }
        while let Some(r) = server.try_receive_result_request() {
            waiting.push(r);
        }
        let now = Instant::now();
        for (id, g) in goals.iter_mut() {
            let feedback = |sequence: Vec<i32>| {
                // A feedback message nobody hears is no error of the server's.
                let _ = server.publish_feedback(*id, FibFeedback { sequence });
            };
            if g.ended.is_some() || now < g.due {
                continue;
            }
            let seq = fibonacci(g.order);
            let so_far = seq[..g.next.min(seq.len())].to_vec();
            match script {
                Script::Succeed { step } => {
                    if g.next <= seq.len() {
                        log.push(format!("feedback {}", g.next));
                        feedback(so_far.clone());
                        g.next += 1;
                        g.due = now + step;
                    } else {
                        g.ended = Some((GoalStatusEnum::Succeeded, FibResult { sequence: seq }));
                    }
                }
                Script::Abort | Script::CancelItself => {
                    if g.next == 1 {
                        log.push("feedback 1");
                        feedback(so_far.clone());
                        g.next = 2;
                    } else {
                        let status = if script == Script::Abort {
                            GoalStatusEnum::Aborted
                        } else {
                            GoalStatusEnum::Canceled
                        };
                        g.ended = Some((status, FibResult { sequence: so_far }));
                    }
                }
                Script::Endless { step } => {
                    log.push(format!("feedback {}", g.next));
                    feedback(vec![0; g.next.min(1000)]);
                    g.next += 1;
                    g.due = now + step;
                }
                Script::Reject => {}
            }
        }
        waiting.retain(|(request, goal)| match goals.get(goal) {
            Some(Running {
                ended: Some((status, result)),
                ..
            }) => {
                log.push(format!("result {status:?}"));
                server
                    .respond_result(*request, *status as i8, result.clone())
                    .expect("respond_result");
                false
            }
            Some(_) => true,
            None => {
                server
                    .respond_result(
                        *request,
                        GoalStatusEnum::Unknown as i8,
                        FibResult::default(),
                    )
                    .expect("respond_result");
                false
            }
        });
        std::thread::sleep(Duration::from_millis(1));
    }
}

// ---- An adding service written with ros2-client alone.

/// ros2-client's own service server for AddTwoInts, on a thread of its own, counting requests.
pub(crate) struct AddServer {
    pub(crate) requests: Arc<AtomicU32>,
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl AddServer {
    pub(crate) fn start(node: &Node, service: &str) -> AddServer {
        let name = ros2_client::Name::parse(service).expect("a ROS 2 name");
        let server: ros2_client::Server<AddRequest, AddResponse> =
            node.create_server(&name, &add_type()).expect("server");
        let requests = Arc::new(AtomicU32::new(0));
        let stop = Arc::new(AtomicBool::new(false));
        let (n, s) = (requests.clone(), stop.clone());
        let thread = std::thread::spawn(move || {
            let deadline = Instant::now() + BOUND;
            while !s.load(Ordering::Relaxed) && Instant::now() < deadline {
                while let Ok(Some((id, req))) = server.try_receive_request() {
                    n.fetch_add(1, Ordering::SeqCst);
                    server
                        .send_response(id, AddResponse { sum: req.a + req.b })
                        .expect("send_response");
                }
                std::thread::sleep(Duration::from_millis(1));
            }
        });
        AddServer {
            requests,
            stop,
            thread: Some(thread),
        }
    }
}

impl Drop for AddServer {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
