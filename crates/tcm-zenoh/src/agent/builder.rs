//! Building an agent: the tasks it offers (commands and goals, with their cleanups), its limits,
//! and its start on a zenoh session, which declares its tokens and its inbox.

use super::*;

/// An agent being built: the tasks it offers.
pub struct AgentBuilder {
    pub(super) system: String,
    pub(super) name: String,
    pub(super) offers: BTreeMap<String, Offer>,
    pub(super) duplicate: bool,
    pub(super) limits: Limits,
    pub(super) hold: std::time::Duration,
}

impl AgentBuilder {
    /// Keeps the bodies of an executive whose token went running for `hold`, so that the
    /// executive, resumed from its journal under the same id, re-attaches to them (and takes the
    /// ends of those that ended meanwhile) instead of starting them again (docs/distributed.md,
    /// "An executive that comes back"); a body not re-attached within `hold` is aborted and
    /// cleaned up. Default zero: aborted at once.
    pub fn hold(mut self, hold: std::time::Duration) -> AgentBuilder {
        self.hold = hold;
        self
    }

    /// Sets the agent's bounds (default: [`Limits::default`]).
    pub fn limits(mut self, limits: Limits) -> AgentBuilder {
        self.limits = limits;
        self
    }

    /// Offers the command `name`: `body` runs with the arguments the executive sent, read as an
    /// `A` (arguments that do not read fail the node with `RemoteError`); its value travels back
    /// as JSON, its failure typed ([`RemoteFailure::raise`]).
    pub fn command<A, R, F, Fut>(self, name: impl Into<String>, body: F) -> AgentBuilder
    where
        A: DeserializeOwned + Send + 'static,
        R: Serialize + 'static,
        F: Fn(RemoteCtx, A) -> Fut + Send + Sync + 'static,
        Fut: Future<Output = Result<R, RemoteFailure>> + Send + 'static,
    {
        self.offer(Kind::Command, name.into(), body)
    }

    /// Offers the goal `name`: as [`AgentBuilder::command`], and its body may spawn children
    /// through its [`RemoteCtx`].
    pub fn goal<A, R, F, Fut>(self, name: impl Into<String>, body: F) -> AgentBuilder
    where
        A: DeserializeOwned + Send + 'static,
        R: Serialize + 'static,
        F: Fn(RemoteCtx, A) -> Fut + Send + Sync + 'static,
        Fut: Future<Output = Result<R, RemoteFailure>> + Send + 'static,
    {
        self.offer(Kind::Goal, name.into(), body)
    }

    fn offer<A, R, F, Fut>(mut self, kind: Kind, name: String, body: F) -> AgentBuilder
    where
        A: DeserializeOwned + Send + 'static,
        R: Serialize + 'static,
        F: Fn(RemoteCtx, A) -> Fut + Send + Sync + 'static,
        Fut: Future<Output = Result<R, RemoteFailure>> + Send + 'static,
    {
        let task = name.clone();
        let body: BodyFn = Arc::new(move |ctx, args| match serde_json::from_value::<A>(args) {
            Ok(a) => {
                let fut = body(ctx, a);
                let task = task.clone();
                Box::pin(async move {
                    let v = fut.await?;
                    serde_json::to_value(v).map_err(|e| {
                        RemoteError::remote(format!("the value of {task} does not serialise: {e}"))
                    })
                })
            }
            Err(e) => {
                let message = format!("bad arguments for {task}: {e}");
                Box::pin(async move { Err(RemoteError::remote(message)) })
            }
        });
        self.offers.insert(
            name,
            Offer {
                kind,
                body,
                cleanup: None,
            },
        );
        self
    }

    /// Sets the cleanup of the offered task `name` (TDL's `on terminate`, on the agent): when a
    /// body of it is cancelled, it is aborted, then `cleanup` runs with its arguments, and the
    /// cancel is confirmed when it returns.
    pub fn on_terminate<A, F, Fut>(mut self, name: &str, cleanup: F) -> AgentBuilder
    where
        A: DeserializeOwned + Send + 'static,
        F: Fn(A) -> Fut + Send + Sync + 'static,
        Fut: Future<Output = ()> + Send + 'static,
    {
        let cleanup: CleanupFn = Arc::new(move |args| match serde_json::from_value::<A>(args) {
            Ok(a) => Box::pin(cleanup(a)),
            Err(_) => Box::pin(async {}),
        });
        if let Some(o) = self.offers.get_mut(name) {
            o.cleanup = Some(cleanup);
        }
        self
    }

    /// Fault injection for tests: every message this agent sends is sent twice, so the executive's
    /// exactly-once handling is exercised.
    pub fn duplicate_messages(mut self, on: bool) -> AgentBuilder {
        self.duplicate = on;
        self
    }

    /// Joins the system with a zenoh session opened from `config` (see [`crate::config`]) and
    /// starts serving. Must be called inside a tokio runtime, where the bodies run.
    pub async fn start(self, config: zenoh::Config) -> Result<Agent, Error> {
        for name in [&self.system, &self.name]
            .into_iter()
            .chain(self.offers.keys())
        {
            if !wire::valid_name(name) {
                return Err(Error::BadName(name.clone()));
            }
        }
        let rt = tokio::runtime::Handle::try_current()
            .map_err(|_| Error::Zenoh("an agent must start inside a tokio runtime".into()))?;
        let session = zenoh::open(config).await.map_err(Error::zenoh)?;
        let inner = Arc::new(AgentInner {
            session: session.clone(),
            system: self.system.clone(),
            name: self.name.clone(),
            offers: self.offers,
            rt,
            duplicate: self.duplicate,
            limits: self.limits,
            hold: self.hold,
            state: Mutex::new(AgentState::default()),
        });
        let weak = Arc::downgrade(&inner);
        let inbox = session
            .declare_subscriber(wire::agent_inboxes(&self.system, &self.name))
            .callback(move |sample| {
                if let Some(inner) = weak.upgrade() {
                    let key = sample.key_expr().as_str();
                    let exec = key.rsplit('/').next().unwrap_or_default();
                    inner.receive(exec, &sample.payload().to_bytes());
                }
            })
            .await
            .map_err(Error::zenoh)?;
        let weak = Arc::downgrade(&inner);
        let execs = session
            .liveliness()
            .declare_subscriber(format!("tdl/{}/executives/*", self.system))
            .history(true)
            .callback(move |sample| {
                let Some(inner) = weak.upgrade() else { return };
                let key = sample.key_expr().as_str();
                let Some(exec) = key.rsplit('/').next() else {
                    return;
                };
                if sample.kind() == SampleKind::Delete {
                    inner.executive_gone(exec);
                } else {
                    inner.lock().live.insert(exec.to_string());
                    inner.unpark(exec);
                    // Declared now, so the first `Done` to it can leave from the receiving thread.
                    let exec = exec.to_string();
                    let me = inner.clone();
                    inner.rt.spawn(async move {
                        if let Err(e) = me.outlet(&exec).await {
                            tracing::warn!(target: "tcm_zenoh", agent = me.name, "no publisher to {exec}: {e}");
                        }
                    });
                }
            })
            .await
            .map_err(Error::zenoh)?;
        // Offers first, so an executive that sees the agent sees what it offers.
        let mut tokens = Vec::new();
        for task in inner.offers.keys() {
            let key = wire::offer_token(&self.system, task, &self.name);
            tokens.push(
                session
                    .liveliness()
                    .declare_token(key)
                    .await
                    .map_err(Error::zenoh)?,
            );
        }
        let key = wire::agent_token(&self.system, &self.name);
        tokens.push(
            session
                .liveliness()
                .declare_token(key)
                .await
                .map_err(Error::zenoh)?,
        );
        Ok(Agent {
            inner,
            _inbox: inbox,
            _execs: execs,
            _tokens: tokens,
        })
    }
}
