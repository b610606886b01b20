//! The wire: the key expressions a system uses on zenoh, and the messages exchanged between an
//! executive and its agents, as JSON (docs/distributed.md, "Messages").
//!
//! Every message names its remote task (`task`, unique per executive) and carries a sequence
//! number (`seq`, from 1, per task and direction): the receiver applies a message only when it is
//! numbered one more than the last it applied of that task (zenoh delivers one publisher's
//! messages in order), and counts the rest as duplicates, refused (out of order) or late. The
//! key of every message names its sender: the executive that sent it to an agent, the agent
//! that sent it to an executive.

use crate::failure::RemoteFailure;
use serde::{Deserialize, Serialize};
use tcm::Facet;

/// Arguments and values as they travel: any JSON value.
pub type Json = serde_json::Value;

/// The liveliness token of an agent.
pub(crate) fn agent_token(system: &str, agent: &str) -> String {
    format!("tdl/{system}/agents/{agent}")
}

/// The liveliness token an agent holds for each task it offers.
pub(crate) fn offer_token(system: &str, task: &str, agent: &str) -> String {
    format!("tdl/{system}/offers/{task}/{agent}")
}

/// The liveliness token of an executive.
pub(crate) fn executive_token(system: &str, exec: &str) -> String {
    format!("tdl/{system}/executives/{exec}")
}

/// Where an agent receives the messages of executive `exec`: the key names the sender, so the
/// agent finds a task by executive and id without a field for it in every message.
pub(crate) fn agent_inbox(system: &str, agent: &str, exec: &str) -> String {
    format!("tdl/{system}/to-agent/{agent}/{exec}")
}

/// Every inbox of an agent (`agent_inbox` for any executive).
pub(crate) fn agent_inboxes(system: &str, agent: &str) -> String {
    format!("tdl/{system}/to-agent/{agent}/*")
}

/// Where executive `exec` receives the messages of agent `agent`: the key names the sender, so the
/// executive accepts a task's messages only from the agent it placed the task on (a key that
/// zenoh's access control can reserve to that agent, see docs/distributed.md, "Who may speak").
pub(crate) fn executive_inbox(system: &str, exec: &str, agent: &str) -> String {
    format!("tdl/{system}/to-exec/{exec}/{agent}")
}

/// Every inbox of an executive (`executive_inbox` for any agent).
pub(crate) fn executive_inboxes(system: &str, exec: &str) -> String {
    format!("tdl/{system}/to-exec/{exec}/*")
}

/// Whether `name` can be one chunk of a key expression: ASCII letters, digits, `_`, `-` and `.`,
/// not empty. System, agent and task names must be.
pub(crate) fn valid_name(name: &str) -> bool {
    !name.is_empty()
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'_' | b'-' | b'.'))
}

/// One message: the remote task it is about, its sequence number, and what it says.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub(crate) struct Msg<B> {
    pub(crate) task: u64,
    pub(crate) seq: u64,
    pub(crate) body: B,
}

impl<B: Serialize> Msg<B> {
    pub(crate) fn encode(&self) -> Vec<u8> {
        // Serialising these types cannot fail: every map key is a string.
        serde_json::to_vec(self).unwrap_or_default()
    }
}

/// A message to an executive, read from its bytes (JSON nested deeper than 128 levels does not
/// read: serde_json's limit).
pub(crate) fn decode_to_exec(bytes: &[u8]) -> Result<Msg<ToExec>, serde_json::Error> {
    serde_json::from_slice(bytes)
}

/// A message to an agent, read from its bytes.
pub(crate) fn decode_to_agent(bytes: &[u8]) -> Result<Msg<ToAgent>, serde_json::Error> {
    serde_json::from_slice(bytes)
}

/// The kind of node a remote task is on the executive.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Kind {
    /// A command: its body does the work.
    Command,
    /// A goal: its body may spawn children through the executive.
    Goal,
}

/// What an executive tells an agent.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub(crate) enum ToAgent {
    /// Run the offered task `name` with `args`, for the node numbered `node` (its display
    /// number, for logs); replies go to the inbox of the executive the key names.
    Start {
        node: u64,
        name: String,
        task_kind: Kind,
        args: Json,
    },
    /// The node was terminated: abort the body, run its cleanup, confirm with `Cancelled`.
    Cancel,
    /// The answer to a call of the body.
    Reply {
        call: u64,
        result: Result<Answer, RemoteFailure>,
    },
    /// From an executive resumed from its journal, under the id of the one that placed the task
    /// (docs/distributed.md, "An executive that comes back"): the task is wanted still; answer
    /// with `Attached` (or `Unattached`). Numbered 0, outside the task's sequence.
    Reattach,
}

/// What an agent tells an executive.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub(crate) enum ToExec {
    /// The body started (schedule-to-start ends; start-to-close and heartbeat timeouts begin).
    Started,
    /// The body is alive (resets the heartbeat timeout).
    Heartbeat,
    /// The body ended: its value, or its typed failure.
    Done { result: Result<Json, RemoteFailure> },
    /// The body was aborted after a `Cancel`, and its cleanup ran.
    Cancelled,
    /// A request of a goal's body to the executive's tree.
    Call { call: u64, op: Op },
    /// The body sets a state variable of the executive's run (docs/semantics.md, "State and
    /// conditions"); `value` is the value itself in JSON (`null` for unknown).
    SetState { var: String, value: tcm::StateValue },
    /// The answer to `Reattach`, numbered 0: the agent has the task. It applied the executive's
    /// messages up to `received` and sent its own up to `sent` (the next are numbered after);
    /// `done` is the body's end if it ended meanwhile (its `Done` may have been lost).
    Attached {
        received: u64,
        sent: u64,
        done: Option<Result<Json, RemoteFailure>>,
    },
    /// The answer to `Reattach`, numbered 0: the agent does not have the task. `started`: it had
    /// it (it ended, was cancelled, or was aborted when its hold ended); if not, its start never
    /// reached the agent, and the executive sends it now.
    Unattached {
        reason: String,
        #[serde(default)]
        started: bool,
    },
}

impl ToAgent {
    /// What the message is, for people (a warning about it).
    pub(crate) fn name(&self) -> &'static str {
        match self {
            ToAgent::Start { .. } => "start",
            ToAgent::Cancel => "cancel",
            ToAgent::Reply { .. } => "reply",
            ToAgent::Reattach => "reattach",
        }
    }
}

impl ToExec {
    /// What the message is, for people (a warning about it).
    pub(crate) fn name(&self) -> &'static str {
        match self {
            ToExec::Started => "started",
            ToExec::Heartbeat => "heartbeat",
            ToExec::Done { .. } => "done",
            ToExec::Cancelled => "cancelled",
            ToExec::Call { .. } => "call",
            ToExec::SetState { .. } => "set_state",
            ToExec::Attached { .. } => "attached",
            ToExec::Unattached { .. } => "unattached",
        }
    }
}

/// A child a remote body names: an offered or registered task, its arguments, and where it runs.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub(crate) struct ChildSpec {
    pub(crate) name: String,
    pub(crate) args: Json,
    pub(crate) at: ChildAt,
    pub(crate) task_kind: Kind,
}

/// Where a child of a remote body runs.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub(crate) enum ChildAt {
    /// A task registered on the executive (`Executive::register`).
    Local,
    /// On this agent.
    Agent(String),
    /// On the first live agent by name that offers it.
    Any,
    /// On the agent that runs the body.
    Same,
}

/// A node a constraint of a remote body names.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ChildRef {
    /// The child the body's node spawned just before (TDL's `previous`).
    Previous,
    /// A child the body spawned, by the id `spawn` returned.
    Child(u32),
}

/// The constraints a remote body may put on a child it spawns.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub(crate) enum Constraint {
    Serial(ChildRef),
    Sequential(Facet, ChildRef),
    TerminateInMs(u64),
    DisableForMs(Facet, u64),
}

/// A call of a remote body.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(tag = "op", rename_all = "snake_case")]
pub(crate) enum Op {
    /// Spawn a child; answered with its id.
    Spawn {
        child: ChildSpec,
        constraints: Vec<Constraint>,
    },
    /// Spawn a child and wait for its value or failure (TDL's `let v = spawn … with wait`).
    Call {
        child: ChildSpec,
        constraints: Vec<Constraint>,
    },
    /// Wait until a child's execution completes.
    Wait { child: u32 },
    /// Terminate a child and its subtree.
    Terminate { child: u32 },
    /// Raise a named external event of the executive's run.
    Raise { event: String },
}

/// The answer to a call.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(tag = "answer", rename_all = "snake_case")]
pub(crate) enum Answer {
    Spawned { child: u32 },
    Ended { ended: ChildEnded },
    Done,
}

/// How a child a remote body waited for ended.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "outcome", rename_all = "snake_case")]
pub enum ChildEnded {
    /// It succeeded: its value (`null` when it has none, or when it was only waited for).
    Succeeded {
        /// The value.
        value: Json,
    },
    /// It failed; `handled` when a handler in the executive's tree took the failure.
    Failed {
        /// The failure, typed.
        failure: RemoteFailure,
        /// Whether a handler took it.
        handled: bool,
    },
    /// It was terminated (or never ran).
    Terminated,
}

impl ChildEnded {
    /// Whether it succeeded.
    pub fn succeeded(&self) -> bool {
        matches!(self, ChildEnded::Succeeded { .. })
    }

    /// Its failure, if it failed.
    pub fn failure(&self) -> Option<&RemoteFailure> {
        match self {
            ChildEnded::Failed { failure, .. } => Some(failure),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_must_be_one_key_chunk() {
        assert!(valid_name("arm-1.left_2"));
        for bad in ["", "a/b", "a*", "$x", "a b", "a?", "a#"] {
            assert!(!valid_name(bad), "{bad:?}");
        }
    }

    #[test]
    fn messages_round_trip_as_json() {
        let msg = Msg {
            task: 7,
            seq: 2,
            body: ToExec::Call {
                call: 1,
                op: Op::Spawn {
                    child: ChildSpec {
                        name: "grasp".into(),
                        args: serde_json::json!({"x": 1}),
                        at: ChildAt::Agent("arm".into()),
                        task_kind: Kind::Command,
                    },
                    constraints: vec![Constraint::Serial(ChildRef::Previous)],
                },
            },
        };
        let bytes = msg.encode();
        let back: Msg<ToExec> = serde_json::from_slice(&bytes).expect("decodes");
        assert_eq!((back.task, back.seq), (7, 2));
        let ToExec::Call {
            op: Op::Spawn { child, constraints },
            ..
        } = back.body
        else {
            panic!("wrong body: {back:?}");
        };
        assert_eq!(child.name, "grasp");
        assert_eq!(constraints, [Constraint::Serial(ChildRef::Previous)]);
    }
}
