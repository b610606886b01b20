//! The exceptions of ROS 2 calls made from the tree: real `tcm` exception types, so handlers name
//! them like any other and the tree's handler search takes them by type or by their common
//! ancestor [`RosError`].
//!
//! Each is `Serialize`, so a ROS 2 failure raised on a `tcm-zenoh` agent travels typed as well.

use serde::{Deserialize, Serialize};
use std::fmt;
use tcm::{Exception, Failure};

/// The common ancestor of this crate's exceptions, and the exception of its other failures: a
/// name that is no ROS 2 name, a link that fails, a goal that ended in a status ROS 2 does not
/// define as terminal. A handler of `RosError` takes every other exception of this crate too.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize, thiserror::Error)]
#[error("{message}")]
pub struct RosError {
    /// What went wrong.
    pub message: String,
}

impl RosError {
    pub(crate) fn failure(message: impl Into<String>) -> Failure {
        RosError {
            message: message.into(),
        }
        .raise()
    }
}

impl Exception for RosError {}

/// The action server rejected the goal.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize, thiserror::Error)]
#[error("the server of {action} rejected the goal")]
pub struct GoalRejected {
    /// The action's name, e.g. `/navigate`.
    pub action: String,
}

impl Exception for GoalRejected {
    fn ancestry() -> &'static [&'static str] {
        &["RosError"]
    }
}

/// The action server aborted the goal (status `ABORTED`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, thiserror::Error)]
#[error("the server of {action} aborted goal {goal}")]
pub struct ActionAborted {
    /// The action's name.
    pub action: String,
    /// The goal's id (32 hexadecimal digits).
    pub goal: String,
    /// The result the server sent with the abort (an action's result often says why), as JSON.
    pub result: serde_json::Value,
}

impl Exception for ActionAborted {
    fn ancestry() -> &'static [&'static str] {
        &["RosError"]
    }
}

/// The action server canceled the goal (status `CANCELED`) although the tree did not ask for it.
/// (A goal the tree canceled, by terminating its node, ends with the node and raises nothing.)
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, thiserror::Error)]
#[error("the server of {action} canceled goal {goal}")]
pub struct ActionCanceled {
    /// The action's name.
    pub action: String,
    /// The goal's id (32 hexadecimal digits).
    pub goal: String,
    /// The result the server sent with the cancellation, as JSON.
    pub result: serde_json::Value,
}

impl Exception for ActionCanceled {
    fn ancestry() -> &'static [&'static str] {
        &["RosError"]
    }
}

/// What a [`RosTimeout`] waited for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Waited {
    /// A service's response (no server, or none that answered).
    Response,
    /// An action server's answer to a goal (accepted or rejected).
    GoalAnswer,
    /// An action server that went away while it ran the goal: every request for the result found
    /// no server for this long.
    Server,
}

impl fmt::Display for Waited {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Waited::Response => "a response",
            Waited::GoalAnswer => "an answer to the goal",
            Waited::Server => "the server",
        })
    }
}

/// Nothing answered in time: a service or action with no server (none started, or one that went
/// away), or a server that does not answer. Never a silent hang.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize, thiserror::Error)]
#[error("{name}: waited {after_ms} ms for {waited}")]
pub struct RosTimeout {
    /// The service's or action's name.
    pub name: String,
    /// What was awaited.
    pub waited: Waited,
    /// How long, in milliseconds.
    pub after_ms: u64,
}

impl Exception for RosTimeout {
    fn ancestry() -> &'static [&'static str] {
        &["RosError"]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_exception_descends_from_ros_error_and_keeps_its_data() {
        let f = ActionAborted {
            action: "/navigate".into(),
            goal: "00".into(),
            result: serde_json::json!({"code": 3}),
        }
        .raise();
        assert_eq!(f.exception, "ActionAborted");
        assert!(f.is_a("RosError"));
        let data = f.data::<ActionAborted>().expect("the value is kept");
        assert_eq!(data.result["code"], 3);
        let t = RosTimeout {
            name: "/add".into(),
            waited: Waited::Response,
            after_ms: 200,
        };
        assert_eq!(t.to_string(), "/add: waited 200 ms for a response");
        assert!(t.raise().is_a("RosError"));
        assert!(
            GoalRejected {
                action: "/a".into()
            }
            .raise()
            .is_a("RosError")
        );
        assert!(!RosError::failure("x").is_a("GoalRejected"));
    }
}
