//! ROS 2 from TDL task trees, over `ros2-client`'s zenoh backend (rmw_zenoh's key expressions,
//! attachments and liveliness tokens; docs/distributed.md, "ROS 2").
//!
//! - Calling: an action's goal ([`ActionClient::goal`]) and a service's request
//!   ([`ServiceClient::call`]) are `tcm` tasks. A goal's task sends the goal, passes its feedback
//!   on, cancels it when its node is terminated, and returns the result as its value; an aborted,
//!   server-canceled or rejected goal fails it with [`ActionAborted`], [`ActionCanceled`] or
//!   [`GoalRejected`], and a missing server with [`RosTimeout`]: `tcm` exceptions, whose common
//!   ancestor is [`RosError`], handled by the tree's handler search like any other.
//! - Offering: [`ActionServer::serve`] is a goal of the tree that serves a ROS 2 action; each
//!   accepted goal runs a task built from it as a child, a cancel request terminates that child,
//!   and the child's value (or failure) is the goal's result (or abort).
//! - Reading: [`StateFeed`] subscribes to a topic and sets a state variable of the run (through
//!   a [`tcm::EventHandle`]) to the value a closure maps each message to, optionally skipping
//!   numbers within a minimum change of the last value set; the tree's conditions over the
//!   variable then act on what the topic says. Its [`FeedHandle`] stops it when dropped.
//! - Interpreting: [`interp`] registers an action or a service in a `tdl_interp::Registry`, so a
//!   TDL program run without compiling it declares it `extern command fib(order: i64) -> Json;`
//!   and spawns it: the arguments make the goal, the result is the task's value (a map of its
//!   fields), the failures are the exceptions above, which the program handles by name, and
//!   terminating the node cancels the goal (docs/language.md, "Running programs without
//!   compiling them").
//!
//! ```no_run
//! # async fn demo(node: &tcm_ros::ros2_client::Node) -> Result<(), Box<dyn std::error::Error>> {
//! # #[derive(Clone, serde::Serialize, serde::Deserialize)] struct Goal { order: i32 }
//! # #[derive(serde::Serialize, serde::Deserialize)] struct Done { sequence: Vec<i32> }
//! # #[derive(serde::Serialize, serde::Deserialize)] struct Partial { sequence: Vec<i32> }
//! use tcm_ros::ros2_client::ActionTypeName;
//! let fib = tcm_ros::ActionClient::<Goal, Done, Partial>::new(
//!     node,
//!     "/fibonacci",
//!     &ActionTypeName::new("action_tutorials_interfaces", "Fibonacci"),
//! )?;
//! let task: tcm::Task = fib
//!     .goal(Goal { order: 5 })
//!     .on_feedback(|p: Partial| println!("so far {:?}", p.sequence))
//!     .task();
//! let report = tcm::Runtime::new().run(task).await?;
//! # Ok(())
//! # }
//! ```
//!
//! A node comes from a `ros2_client::Context` opened on a zenoh configuration
//! (`ContextOptions::new().zenoh_config(…)`), which needs a multi-thread tokio runtime around it.
#![warn(missing_docs)]

mod client;
mod failure;
mod feed;
pub mod interp;
mod off_thread;
pub mod run_task;
mod server;

pub use client::{ActionClient, Call, DEFAULT_SERVER_TIMEOUT, Goal, ServiceClient};
pub use failure::{ActionAborted, ActionCanceled, GoalRejected, RosError, RosTimeout, Waited};
pub use feed::{FeedHandle, FeedValue, StateFeed};
pub use server::{ActionServer, Feedback};

/// The ROS 2 client library this crate is built on, at the version it uses (for its `Context`,
/// `Node`, names and message traits).
pub use ros2_client;

/// Errors of this crate's API (a call's own failures are `tcm` failures).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A name that is no ROS 2 name.
    #[error("bad ROS 2 name {name:?}: {reason}")]
    BadName {
        /// The name given.
        name: String,
        /// Why it is refused.
        reason: String,
    },
    /// ros2-client refused: an entity that cannot be created, a message that cannot be sent.
    #[error("ros2-client: {0}")]
    Ros(String),
    /// [`StateFeed::start`] was called outside a tokio runtime, where its task cannot run.
    #[error("a feed starts inside a tokio runtime")]
    NoRuntime,
}

/// A ROS 2 name (`/navigate`, `ns/name`) as ros2-client reads it.
pub(crate) fn parse_name(name: &str) -> Result<ros2_client::Name, Error> {
    ros2_client::Name::parse(name).map_err(|e| Error::BadName {
        name: name.to_string(),
        reason: format!("{e:?}"),
    })
}
