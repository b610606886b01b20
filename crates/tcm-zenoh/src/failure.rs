//! Failures across processes: a remote body's typed failure as it travels ([`RemoteFailure`]), and
//! the exceptions of the distribution layer itself ([`RemoteError`], [`AgentLost`],
//! [`RemoteTimeout`], [`RemoteCancelled`], [`RemoteRefused`]), real `tcm` exception types that handlers name like any other.
//!
//! On the executive a remote failure becomes a [`tcm::Failure`] with the remote exception's name
//! and ancestry, so the tree's handler search by type works across processes; its data is the
//! [`RemoteFailure`] itself, read with [`caught`].

use crate::wire::Json;
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use std::borrow::Cow;
use std::fmt;
use std::sync::Arc;
use tcm::{Ctx, Exception, Failure};

/// A typed failure as it travels: the exception's type name, its message, its ancestors' names
/// (nearest first) and its value as JSON.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RemoteFailure {
    /// The exception's type name, e.g. `NoGrasp`.
    pub exception: String,
    /// A human-readable description.
    pub message: String,
    /// The exception type's ancestors, nearest first.
    #[serde(default)]
    pub ancestry: Vec<String>,
    /// The exception's value (`null` when it carries none).
    #[serde(default)]
    pub data: Json,
}

impl RemoteFailure {
    /// A failure of exception type `exception`, with no ancestors and no data.
    pub fn new(exception: impl Into<String>, message: impl Into<String>) -> RemoteFailure {
        RemoteFailure {
            exception: exception.into(),
            message: message.into(),
            ancestry: Vec::new(),
            data: Json::Null,
        }
    }

    /// Raises a typed exception from a remote body (TDL's `fail`): its name and ancestry are the
    /// type's ([`Exception::name`], [`Exception::ancestry`]), its value travels as JSON, so the
    /// executive's handlers of `E` or of any ancestor take it.
    pub fn raise<E: Exception + Serialize>(e: E) -> RemoteFailure {
        RemoteFailure {
            exception: E::name().to_string(),
            message: e.to_string(),
            ancestry: E::ancestry().iter().map(ToString::to_string).collect(),
            data: serde_json::to_value(&e).unwrap_or(Json::Null),
        }
    }

    /// Whether this failure is of exception type `name` or of a type derived from it.
    pub fn is_a(&self, name: &str) -> bool {
        self.exception == name || self.ancestry.iter().any(|a| a == name)
    }

    /// The exception's value read as an `E`, if it is one.
    pub fn data_as<E: DeserializeOwned>(&self) -> Option<E> {
        serde_json::from_value(self.data.clone()).ok()
    }

    /// This failure as the tree sees it: the same type name and ancestry, the [`RemoteFailure`]
    /// as its data.
    pub fn into_failure(self) -> Failure {
        let mut f = Failure::new(Cow::Owned(self.exception.clone()), self.message.clone());
        f.ancestry = self.ancestry.iter().cloned().map(Cow::Owned).collect();
        f.data = Some(Arc::new(self));
        f
    }

    /// A failure of the tree as it travels to a remote body: its type, message and ancestry, and
    /// its value when it is a remote failure or an exception of this crate (other values stay
    /// behind: `null`).
    pub fn from_failure(f: &Failure) -> RemoteFailure {
        if let Some(r) = f.data::<RemoteFailure>() {
            return RemoteFailure::clone(&r);
        }
        let data = if let Some(e) = f.data::<AgentLost>() {
            serde_json::to_value(&*e).unwrap_or(Json::Null)
        } else if let Some(e) = f.data::<RemoteTimeout>() {
            serde_json::to_value(&*e).unwrap_or(Json::Null)
        } else if let Some(e) = f.data::<RemoteCancelled>() {
            serde_json::to_value(&*e).unwrap_or(Json::Null)
        } else if let Some(e) = f.data::<RemoteRefused>() {
            serde_json::to_value(&*e).unwrap_or(Json::Null)
        } else if let Some(e) = f.data::<RemoteError>() {
            serde_json::to_value(&*e).unwrap_or(Json::Null)
        } else {
            Json::Null
        };
        RemoteFailure {
            exception: f.exception.to_string(),
            message: f.message.clone(),
            ancestry: f.ancestry.iter().map(ToString::to_string).collect(),
            data,
        }
    }
}

impl fmt::Display for RemoteFailure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.exception, self.message)
    }
}

impl From<RemoteFailure> for Failure {
    fn from(r: RemoteFailure) -> Failure {
        r.into_failure()
    }
}

/// In a handler: the caught exception as an `E`, whether it was raised in this process (its value
/// is an `E`) or in a remote body (its JSON value read as an `E`).
pub fn caught<E: Clone + Send + Sync + DeserializeOwned + 'static>(ctx: &Ctx) -> Option<E> {
    if let Some(e) = ctx.caught::<E>() {
        return Some(E::clone(&e));
    }
    ctx.caught::<RemoteFailure>()?.data_as::<E>()
}

/// The common ancestor of the distribution layer's exceptions, and the exception of its other
/// failures: a task nobody registered, arguments that do not serialise, a message that could not
/// be sent. A handler of `RemoteError` takes [`AgentLost`], [`RemoteTimeout`],
/// [`RemoteCancelled`] and [`RemoteRefused`] too.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize, thiserror::Error)]
#[error("{message}")]
pub struct RemoteError {
    /// What went wrong.
    pub message: String,
}

impl RemoteError {
    pub(crate) fn failure(message: impl Into<String>) -> Failure {
        RemoteError {
            message: message.into(),
        }
        .raise()
    }

    pub(crate) fn remote(message: impl Into<String>) -> RemoteFailure {
        RemoteFailure::raise(RemoteError {
            message: message.into(),
        })
    }
}

impl Exception for RemoteError {}

/// The agent running a remote task was lost: its liveliness token was deleted (its process died,
/// or its link to the executive broke) while the task ran there.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize, thiserror::Error)]
#[error("agent {agent} was lost while it ran {task}")]
pub struct AgentLost {
    /// The agent.
    pub agent: String,
    /// The task it ran.
    pub task: String,
}

impl Exception for AgentLost {
    fn ancestry() -> &'static [&'static str] {
        &["RemoteError"]
    }
}

/// Which timeout of a remote task expired (the timeouts of durable-workflow systems).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TimeoutKind {
    /// No agent took the task in time: none offered it, or the one that did never started it.
    ScheduleToStart,
    /// The body started but did not end in time.
    StartToClose,
    /// The body started but sent no heartbeat in time.
    Heartbeat,
}

impl fmt::Display for TimeoutKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            TimeoutKind::ScheduleToStart => "schedule-to-start",
            TimeoutKind::StartToClose => "start-to-close",
            TimeoutKind::Heartbeat => "heartbeat",
        })
    }
}

/// A timeout of a remote task expired; the agent, if one had the task, was told to cancel it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize, thiserror::Error)]
#[error("{kind} timeout of {task} after {after_ms} ms{}", .agent.as_ref().map(|a| format!(" on agent {a}")).unwrap_or_default())]
pub struct RemoteTimeout {
    /// Which timeout.
    pub kind: TimeoutKind,
    /// The task.
    pub task: String,
    /// The agent that had it, if one did.
    pub agent: Option<String>,
    /// The timeout, in milliseconds.
    pub after_ms: u64,
}

impl Exception for RemoteTimeout {
    fn ancestry() -> &'static [&'static str] {
        &["RemoteError"]
    }
}

/// The agent running a remote task said the body was cancelled (`cancelled`) though the executive
/// never sent it a `cancel`: the body was aborted on the agent by someone else (a forged cancel,
/// or an agent that cancels on its own), so the node has no value. The node fails with this
/// rather than succeed with nothing (docs/distributed.md, "Exactly once").
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize, thiserror::Error)]
#[error("agent {agent} cancelled {task}, which the executive never asked it to cancel")]
pub struct RemoteCancelled {
    /// The agent.
    pub agent: String,
    /// The task it ran.
    pub task: String,
}

impl Exception for RemoteCancelled {
    fn ancestry() -> &'static [&'static str] {
        &["RemoteError"]
    }
}

/// An agent refused to start a remote task because one of its bounds was reached: too many
/// bodies running for the executive that asked, or in all, or too many threads busy (a Python
/// agent's plain-function bodies). The node fails with this at once instead of waiting for a body
/// that will never run (docs/distributed.md, "Bounds").
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize, thiserror::Error)]
#[error("agent {agent} refused to start {task}: {reason}")]
pub struct RemoteRefused {
    /// The agent.
    pub agent: String,
    /// The task it was asked to start.
    pub task: String,
    /// Which bound was reached.
    pub reason: String,
}

impl Exception for RemoteRefused {
    fn ancestry() -> &'static [&'static str] {
        &["RemoteError"]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, Clone, Serialize, Deserialize, thiserror::Error)]
    #[error("no grasp at {x}")]
    struct NoGrasp {
        x: i32,
    }

    impl Exception for NoGrasp {
        fn ancestry() -> &'static [&'static str] {
            &["ArmFailure", "HardwareFailure"]
        }
    }

    #[test]
    fn a_raised_exception_keeps_its_type_ancestry_and_value() {
        let r = RemoteFailure::raise(NoGrasp { x: 3 });
        assert_eq!(r.exception, "NoGrasp");
        assert_eq!(r.message, "no grasp at 3");
        assert!(r.is_a("HardwareFailure") && !r.is_a("Other"));
        assert_eq!(r.data_as::<NoGrasp>().map(|e| e.x), Some(3));
        let f = r.clone().into_failure();
        assert!(f.is_a("ArmFailure"));
        assert_eq!(f.exception, "NoGrasp");
        assert_eq!(RemoteFailure::from_failure(&f), r);
    }

    #[test]
    fn the_layers_exceptions_descend_from_remote_error() {
        let f = AgentLost {
            agent: "arm".into(),
            task: "grasp".into(),
        }
        .raise();
        assert_eq!(f.exception, "AgentLost");
        assert!(f.is_a("RemoteError"));
        let r = RemoteFailure::from_failure(&f);
        assert_eq!(
            r.data_as::<AgentLost>().map(|e| e.agent),
            Some("arm".into())
        );
        let f = RemoteCancelled {
            agent: "arm".into(),
            task: "grasp".into(),
        }
        .raise();
        assert_eq!(f.exception, "RemoteCancelled");
        assert!(f.is_a("RemoteError"));
        let r = RemoteFailure::from_failure(&f);
        assert_eq!(
            r.data_as::<RemoteCancelled>().map(|e| e.task),
            Some("grasp".into())
        );
    }
}
