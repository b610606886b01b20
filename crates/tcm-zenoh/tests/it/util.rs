//! Helpers: a fresh system per test (its own name, its own port), agents that join it, a bound
//! on every test, and stories without their (real) times.

use std::future::Future;
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tcm_zenoh::{Agent, AgentBuilder, Executive, RemoteOptions};

/// How long any test may take.
pub(crate) const BOUND: Duration = Duration::from_secs(60);

/// How long an agent may take to be seen by the executive.
pub(crate) const JOIN: Duration = Duration::from_secs(10);

/// Runs `test`, failing if it takes longer than [`BOUND`].
pub(crate) async fn bounded<T>(test: impl Future<Output = T>) -> T {
    tokio::time::timeout(BOUND, test)
        .await
        .expect("the test did not end within its bound")
}

/// A system name no other test (or test process) uses.
pub(crate) fn system(prefix: &str) -> String {
    static N: AtomicU32 = AtomicU32::new(0);
    format!(
        "{prefix}-{}-{}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    )
}

/// A system's executive, listening on a free port of 127.0.0.1.
pub(crate) struct Net {
    pub(crate) exec: Executive,
    pub(crate) port: u16,
    pub(crate) system: String,
}

impl Net {
    pub(crate) async fn new(prefix: &str) -> Net {
        Net::with(prefix, RemoteOptions::default(), false).await
    }

    pub(crate) async fn with(prefix: &str, defaults: RemoteOptions, duplicate: bool) -> Net {
        let system = system(prefix);
        let (exec, port) = Executive::open_loopback_with(&system, defaults, duplicate)
            .await
            .expect("executive opens");
        Net { exec, port, system }
    }

    /// An agent builder for this system.
    pub(crate) fn agent(&self, name: &str) -> AgentBuilder {
        Agent::builder(self.system.clone(), name)
    }

    /// Starts `agent` (connected to the executive) and waits until the executive sees it.
    pub(crate) async fn join(&self, agent: AgentBuilder, name: &str) -> Agent {
        let config = tcm_zenoh::config::loopback_connect(self.port).expect("config");
        self.join_with(agent, name, config).await
    }

    /// As [`Net::join`], the agent linked with `stranger` too.
    pub(crate) async fn join_beside(
        &self,
        agent: AgentBuilder,
        name: &str,
        stranger: &Stranger,
    ) -> Agent {
        let endpoints = [self.port, stranger.port].map(tcm_zenoh::config::endpoint);
        let config = tcm_zenoh::config::peer(&[], &endpoints).expect("config");
        self.join_with(agent, name, config).await
    }

    async fn join_with(&self, agent: AgentBuilder, name: &str, config: zenoh::Config) -> Agent {
        let agent = agent.start(config).await.expect("agent starts");
        self.exec
            .wait_for(name, None, JOIN)
            .await
            .expect("the executive sees the agent");
        agent
    }
}

/// A stranger on the system's network: a bare zenoh session listening on a free port of 127.0.0.1
/// (multicast scouting off) that agents are linked with (as every client of a shared router is
/// with every other), and that speaks the wire by hand: it forges messages.
pub(crate) struct Stranger {
    pub(crate) session: zenoh::Session,
    pub(crate) port: u16,
}

impl Stranger {
    pub(crate) async fn new() -> Stranger {
        for _ in 0..5 {
            let port = tcm_zenoh::config::free_port().expect("a free port");
            let config = tcm_zenoh::config::loopback_listen(port).expect("config");
            if let Ok(session) = zenoh::open(config).await {
                return Stranger { session, port };
            }
        }
        panic!("the stranger's session does not open")
    }

    /// Puts `msg` on `key` once a subscriber of it is known (at most [`JOIN`]).
    pub(crate) async fn forge(&self, key: String, msg: serde_json::Value) {
        put(&self.session, key, msg).await;
    }
}

/// Puts `msg` on `key` once `session` knows a subscriber of it (at most [`JOIN`]).
pub(crate) async fn put(session: &zenoh::Session, key: String, msg: serde_json::Value) {
    let publisher = session.declare_publisher(key).await.expect("a publisher");
    let deadline = tokio::time::Instant::now() + JOIN;
    while !publisher
        .matching_status()
        .await
        .expect("a status")
        .matching()
    {
        assert!(
            tokio::time::Instant::now() < deadline,
            "no subscriber of {} within {JOIN:?}",
            publisher.key_expr()
        );
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    publisher
        .put(serde_json::to_vec(&msg).expect("JSON"))
        .await
        .expect("a put");
}

/// The story of a run without the times (real time differs from run to run).
pub(crate) fn untimed(trace: &[tcm::TraceEvent]) -> Vec<String> {
    tcm::testing::story(trace)
        .into_iter()
        .map(|l| l.split_once(' ').map(|(_, r)| r.to_string()).unwrap_or(l))
        .collect()
}

/// What the bodies of a test did, in order.
#[derive(Clone, Default)]
pub(crate) struct Log(Arc<Mutex<Vec<String>>>);

impl Log {
    pub(crate) fn push(&self, what: impl Into<String>) {
        self.0.lock().expect("log").push(what.into());
    }

    pub(crate) fn entries(&self) -> Vec<String> {
        self.0.lock().expect("log").clone()
    }

    /// Waits until `what` was logged, at most `timeout`.
    pub(crate) async fn wait_for(&self, what: &str, timeout: Duration) {
        let start = tokio::time::Instant::now();
        while !self.entries().iter().any(|e| e == what) {
            assert!(
                start.elapsed() < timeout,
                "{what:?} not logged within {timeout:?}: {:?}",
                self.entries()
            );
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
    }
}

/// Nodes a goal's body noted, by label, for the test to look at after the run.
#[derive(Clone, Default)]
pub(crate) struct Nodes(Arc<Mutex<Vec<(&'static str, tcm::NodeId)>>>);

impl Nodes {
    pub(crate) fn note(&self, label: &'static str, node: tcm::NodeId) {
        self.0.lock().expect("nodes").push((label, node));
    }

    pub(crate) fn get(&self, label: &str) -> tcm::NodeId {
        self.0
            .lock()
            .expect("nodes")
            .iter()
            .find(|(l, _)| *l == label)
            .map(|(_, n)| *n)
            .unwrap_or_else(|| panic!("no node noted as {label}"))
    }
}
