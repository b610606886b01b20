//! Integration tests of ROS 2 from task trees, over ros2-client's zenoh backend on 127.0.0.1 (two
//! zenoh peers per test, multicast scouting off, no router, never DDS): the tree calls actions
//! and services served by ros2-client itself, and offers a task as an action that ros2-client's
//! own action client calls, and feeds a state variable from a topic that ros2-client publishes;
//! TDL programs run by the interpreter call actions and services registered for them.
//! Every test is bounded in time, and every run's trace is checked.

mod call_action;
mod call_service;
mod feed_state;
mod interpreted;
mod offer_action;
mod run_task;
mod util;
