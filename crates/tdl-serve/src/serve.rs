//! The server answering over zenoh (`proto.rs`): one queryable on
//! `tdl/<system>/serve/<executive>/*`, each query carried out by [`Server::handle`] for the client
//! its key's last segment names, answered with one reply.

use std::time::Duration;

use zenoh::Wait;

use crate::Error;
use crate::proto::{Request, Response, key};
use crate::server::Server;

/// A server answering requests: dropping it (or [`Serving::close`]) stops answering.
pub struct Serving {
    task: tokio::task::JoinHandle<()>,
    key: String,
}

impl Serving {
    /// The key expression it answers on.
    pub fn key(&self) -> &str {
        &self.key
    }

    /// Stops answering.
    pub fn close(self) {
        self.task.abort();
    }
}

impl Drop for Serving {
    fn drop(&mut self) {
        self.task.abort();
    }
}

/// Answers the requests to the executive named `name` of `session`'s system `system` with
/// `server`, until the returned [`Serving`] is dropped.
pub async fn serve(
    server: Server,
    session: &zenoh::Session,
    system: &str,
    name: &str,
) -> Result<Serving, Error> {
    let key = key(system, name, "*");
    let queryable = session
        .declare_queryable(&key)
        .await
        .map_err(|e| Error::Zenoh(e.to_string()))?;
    let task = tokio::spawn(async move {
        while let Ok(query) = queryable.recv_async().await {
            let client = query
                .key_expr()
                .as_str()
                .rsplit('/')
                .next()
                .unwrap_or("")
                .to_string();
            let bytes = query
                .payload()
                .map(|p| p.to_bytes().into_owned())
                .unwrap_or_default();
            let response = match serde_json::from_slice::<Request>(&bytes) {
                Ok(request) => {
                    tracing::info!(target: "tdl_serve", %client, ?request, "request");
                    server.handle(request, &client)
                }
                Err(e) => Response::Refused(format!("not a request: {e}")),
            };
            let payload = serde_json::to_vec(&response).unwrap_or_else(|e| {
                let why = Response::Refused(format!("the answer did not encode: {e}"));
                serde_json::to_vec(&why).unwrap_or_default()
            });
            if let Err(e) = query.reply(query.key_expr().clone(), payload).wait() {
                tracing::warn!(target: "tdl_serve", %client, "cannot reply: {e}");
            }
        }
    });
    Ok(Serving { task, key })
}

/// How long a client waits for an answer by default.
pub const DEFAULT_TIMEOUT: Duration = Duration::from_secs(10);

/// A client of serving executives, on a zenoh session of its own.
pub struct Client {
    session: zenoh::Session,
    system: String,
    name: String,
    timeout: Duration,
}

impl Client {
    /// A client named `name` (the name executives record as who asked) of `system`, on a session
    /// opened from `config` (`tcm_zenoh::config::loopback_connect(port)` on one machine).
    pub async fn open(system: &str, name: &str, config: zenoh::Config) -> Result<Client, Error> {
        if name.is_empty() || name.contains(['/', '*', '$', '#', '?']) {
            return Err(Error::Name(name.to_string()));
        }
        let session = zenoh::open(config)
            .await
            .map_err(|e| Error::Zenoh(e.to_string()))?;
        Ok(Client {
            session,
            system: system.to_string(),
            name: name.to_string(),
            timeout: DEFAULT_TIMEOUT,
        })
    }

    /// The same client, waiting at most `timeout` for each answer.
    pub fn with_timeout(mut self, timeout: Duration) -> Client {
        self.timeout = timeout;
        self
    }

    /// Sends `request` to the executive `executive`: its answer.
    pub async fn request(&self, executive: &str, request: &Request) -> Result<Response, Error> {
        let key = key(&self.system, executive, &self.name);
        let payload = serde_json::to_vec(request).map_err(|e| Error::Protocol(e.to_string()))?;
        let replies = self
            .session
            .get(&key)
            .payload(payload)
            .timeout(self.timeout)
            .await
            .map_err(|e| Error::Zenoh(e.to_string()))?;
        match replies.recv_async().await {
            Ok(reply) => match reply.result() {
                Ok(sample) => {
                    let bytes = sample.payload().to_bytes();
                    serde_json::from_slice(&bytes).map_err(|e| Error::Protocol(e.to_string()))
                }
                Err(e) => Err(Error::Protocol(format!(
                    "the executive answered with an error: {:?}",
                    e.payload().to_bytes()
                ))),
            },
            Err(_) => Err(Error::NoAnswer {
                executive: executive.to_string(),
                system: self.system.clone(),
                waited: self.timeout,
            }),
        }
    }

    /// Closes the client's session.
    pub async fn close(self) {
        let _ = self.session.close().await;
    }
}
