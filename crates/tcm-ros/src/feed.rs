//! Reading a ROS 2 topic into a state variable ([`StateFeed`]): each message is mapped to a
//! value by the user's closure and set on the run through an [`EventHandle`], an input to the
//! engine recorded in the trace (docs/semantics.md, "State and conditions").
//!
//! The feed is a tokio task that awaits the subscription's messages (ros2-client's zenoh
//! subscription is asynchronous, so no thread polls it). It ends when its [`FeedHandle`] is
//! dropped, when the run refuses sets because it ended or was poisoned, or with the tokio runtime
//! it runs on; the subscription, and its liveliness token, go with it.

use crate::{Error, parse_name};
use ros2_client::{MessageTypeName, Node, QosProfile, ReadError};
use serde::de::DeserializeOwned;
use std::fmt::Display;
use std::panic::AssertUnwindSafe;
use tcm::{EventHandle, FromState, StateType, StateValue, StateVar};

/// What a feed's map returns for a message ([`StateFeed::new`]): a value for the variable, or no
/// value, which skips the message with a warning. Implemented for the Rust types of ROS 2's
/// scalar fields (`bool`, the integers (a `u64` above `i64::MAX` is no value), `f32`, `f64`),
/// `String`, `&'static str`, [`StateValue`], and `Option` (`None` is no value) and `Result` (an
/// error is no value, its text in the warning) of these.
pub trait FeedValue {
    /// The value, or why there is none.
    fn into_feed(self) -> Result<StateValue, String>;
}

macro_rules! feed_value_via {
    ($($t:ty => $via:ty),* $(,)?) => {$(
        impl FeedValue for $t {
            fn into_feed(self) -> Result<StateValue, String> {
                Ok(StateValue::from(<$via>::from(self)))
            }
        }
    )*};
}

feed_value_via!(
    bool => bool,
    i8 => i64,
    i16 => i64,
    i32 => i64,
    i64 => i64,
    u8 => i64,
    u16 => i64,
    u32 => i64,
    f32 => f64,
    f64 => f64,
    String => String,
    &'static str => &'static str,
);

impl FeedValue for u64 {
    fn into_feed(self) -> Result<StateValue, String> {
        i64::try_from(self)
            .map(StateValue::Int)
            .map_err(|_| format!("{self} does not fit an int"))
    }
}

impl FeedValue for StateValue {
    fn into_feed(self) -> Result<StateValue, String> {
        Ok(self)
    }
}

impl<T: FeedValue> FeedValue for Option<T> {
    fn into_feed(self) -> Result<StateValue, String> {
        match self {
            Some(v) => v.into_feed(),
            None => Err("the map gave no value".to_string()),
        }
    }
}

impl<T: FeedValue, E: Display> FeedValue for Result<T, E> {
    fn into_feed(self) -> Result<StateValue, String> {
        match self {
            Ok(v) => v.into_feed(),
            Err(e) => Err(e.to_string()),
        }
    }
}

type Map<M> = Box<dyn FnMut(M) -> Result<StateValue, String> + Send>;

/// A ROS 2 topic read into a state variable: a subscription on a node whose messages (of type
/// `M`) are mapped to values and set on a run ([`StateFeed::start`]).
///
/// ```no_run
/// # fn demo(node: &tcm_ros::ros2_client::Node) -> Result<(), Box<dyn std::error::Error>> {
/// # #[derive(serde::Deserialize)] struct BatteryState { percentage: f32 }
/// use tcm::{StateType, StateValue, StateVar};
/// use tcm_ros::ros2_client::MessageTypeName;
///
/// let battery = StateVar::new("battery", StateType::Float, StateValue::Unknown);
/// let rt = tcm::Runtime::new().state(battery.clone());
/// let feed = tcm_ros::StateFeed::new(
///     node,
///     "/battery_state",
///     &MessageTypeName::new("sensor_msgs", "BatteryState"),
///     &battery,
///     |m: BatteryState| m.percentage,
/// )?
/// .min_change(0.01)
/// .start(rt.events())?;
/// // … rt.run(mission).await; the feed stops when `feed` is dropped.
/// # Ok(())
/// # }
/// ```
pub struct StateFeed<M> {
    topic: String,
    subscription: ros2_client::Subscription<M>,
    var: StateVar,
    map: Map<M>,
    min_change: Option<f64>,
}

impl<M: DeserializeOwned + Send + 'static> StateFeed<M> {
    /// A feed of the variable `var` from the topic `topic` (a ROS 2 name such as `/battery_state`)
    /// of type `message_type` (`MessageTypeName::new("sensor_msgs", "BatteryState")`) on `node`:
    /// each message becomes the value `map` returns for it ([`FeedValue`]). The subscription is
    /// made now (with ROS 2's default subscription QoS); messages are read once the feed is
    /// [started](StateFeed::start).
    pub fn new<V: FeedValue>(
        node: &Node,
        topic: &str,
        message_type: &MessageTypeName,
        var: &StateVar,
        mut map: impl FnMut(M) -> V + Send + 'static,
    ) -> Result<StateFeed<M>, Error> {
        let name = parse_name(topic)?;
        let qos = QosProfile::subscription_default();
        let t = node.create_topic(&name, message_type.clone(), &qos);
        let subscription = node
            .create_subscription::<M>(&t, None)
            .map_err(|e| Error::Ros(format!("subscription {topic}: {e}")))?;
        Ok(StateFeed {
            topic: topic.to_string(),
            subscription,
            var: var.clone(),
            map: Box::new(move |m| map(m).into_feed()),
            min_change: None,
        })
    }

    /// Skips a number that differs by less than `delta` from the last value this feed set (a
    /// tolerance for a float that jitters): the variable then moves in steps of at least `delta`,
    /// never drifting away unseen, since the comparison is with the last value set, not the last
    /// message. Other values (a `bool`, a `string`, unknown), and a number after one of those,
    /// are always set. A `delta` that is zero, negative or not a number skips nothing. Without
    /// it, every message is a set, recorded in the trace; only a different value is a change.
    pub fn min_change(mut self, delta: f64) -> Self {
        self.min_change = (delta > 0.0).then_some(delta);
        self
    }

    /// The topic's name.
    pub fn topic(&self) -> &str {
        &self.topic
    }

    /// Starts reading messages, on a task of the current tokio runtime, setting the variable
    /// through `events` (from [`tcm::Runtime::events`] or [`tcm::Session::events`]; while it is
    /// open, an idle run waits for it instead of ending stuck). The feed runs until the
    /// [`FeedHandle`] is dropped, or the run refuses a set because it ended, or the tokio runtime
    /// shuts down. A message that cannot be read, that the map gives no value for (or panics
    /// on), or whose value is not of the variable's type is skipped with a warning (the
    /// `tracing` target `tcm_ros`). The variable must be declared on the run ([`tcm::Runtime::state`]
    /// or the program's declaration); else the first set declares it with the value's type.
    pub fn start(self, events: EventHandle) -> Result<FeedHandle, Error> {
        let rt = tokio::runtime::Handle::try_current().map_err(|_| Error::NoRuntime)?;
        let topic = self.topic.clone();
        let task = rt.spawn(self.run(events));
        Ok(FeedHandle { topic, task })
    }

    async fn run(mut self, events: EventHandle) {
        let var = self.var.name().to_string();
        let ty = self.var.ty();
        let mut last: Option<StateValue> = None;
        loop {
            let message = match self.subscription.async_take().await {
                Ok((m, _)) => m,
                Err(ReadError::Closed) => {
                    tracing::debug!(target: "tcm_ros", topic = %self.topic, "the subscription closed: the feed ends");
                    return;
                }
                Err(e) => {
                    tracing::warn!(target: "tcm_ros", topic = %self.topic, var, "a message could not be read: {e}");
                    continue;
                }
            };
            let value = match self.value_of(message, ty) {
                Ok(v) => v,
                Err(why) => {
                    tracing::warn!(target: "tcm_ros", topic = %self.topic, var, "a message was not set: {why}");
                    continue;
                }
            };
            if within(self.min_change, last.as_ref(), &value) {
                continue;
            }
            match events.set_state(&var, value.clone()) {
                Ok(()) => last = Some(value),
                Err(tcm::Error::RunEnded | tcm::Error::Poisoned) => {
                    tracing::debug!(target: "tcm_ros", topic = %self.topic, var, "the run takes no more sets: the feed ends");
                    return;
                }
                Err(e) => {
                    tracing::warn!(target: "tcm_ros", topic = %self.topic, var, "the run refused {value}: {e}");
                }
            }
        }
    }

    /// A message's value, of the variable's type: the map's, caught if it panics.
    fn value_of(&mut self, message: M, ty: StateType) -> Result<StateValue, String> {
        let map = &mut self.map;
        let value = std::panic::catch_unwind(AssertUnwindSafe(|| map(message)))
            .map_err(|p| format!("the map panicked: {}", panic_text(p.as_ref())))??;
        value.coerce(ty).map_err(|e| e.to_string())
    }
}

/// Whether `value` is a number within `min_change` of the number `last`.
fn within(min_change: Option<f64>, last: Option<&StateValue>, value: &StateValue) -> bool {
    let (Some(delta), Some(last)) = (min_change, last) else {
        return false;
    };
    match (f64::from_state(last), f64::from_state(value)) {
        (Some(a), Some(b)) => (b - a).abs() < delta,
        _ => false,
    }
}

fn panic_text(p: &(dyn std::any::Any + Send)) -> &str {
    p.downcast_ref::<&str>()
        .copied()
        .or_else(|| p.downcast_ref::<String>().map(String::as_str))
        .unwrap_or("(not a string)")
}

/// A running feed ([`StateFeed::start`]): dropped, or [stopped](FeedHandle::stop), it stops
/// reading, and its subscription is undeclared.
pub struct FeedHandle {
    topic: String,
    task: tokio::task::JoinHandle<()>,
}

impl FeedHandle {
    /// The topic's name.
    pub fn topic(&self) -> &str {
        &self.topic
    }

    /// Whether it still reads: false once the run refused a set because it ended, or the
    /// subscription closed.
    pub fn is_running(&self) -> bool {
        !self.task.is_finished()
    }

    /// Stops the feed, and waits until its task ended: its subscription is then dropped.
    pub async fn stop(mut self) {
        self.task.abort();
        let _ = (&mut self.task).await;
    }
}

impl Drop for FeedHandle {
    fn drop(&mut self) {
        self.task.abort();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_number_within_the_minimum_change_of_the_last_set_is_skipped() {
        let f = StateValue::Float;
        assert!(!within(None, Some(&f(1.0)), &f(1.0)));
        assert!(!within(Some(0.5), None, &f(1.0)));
        assert!(within(Some(0.5), Some(&f(1.0)), &f(1.4)));
        assert!(within(Some(0.5), Some(&f(1.0)), &f(0.6)));
        assert!(!within(Some(0.5), Some(&f(1.0)), &f(1.5)));
        assert!(within(
            Some(2.0),
            Some(&StateValue::Int(3)),
            &StateValue::Int(4)
        ));
        assert!(!within(Some(0.5), Some(&StateValue::Unknown), &f(1.0)));
        assert!(!within(Some(0.5), Some(&f(1.0)), &StateValue::Unknown));
        assert!(!within(
            Some(0.5),
            Some(&StateValue::Bool(true)),
            &StateValue::Bool(true)
        ));
    }

    #[test]
    fn map_results_become_values_or_reasons() {
        assert_eq!(0.5f32.into_feed(), Ok(StateValue::Float(0.5)));
        assert_eq!(7u8.into_feed(), Ok(StateValue::Int(7)));
        assert!(u64::MAX.into_feed().is_err());
        assert_eq!(Some(true).into_feed(), Ok(StateValue::Bool(true)));
        assert!(None::<f64>.into_feed().is_err());
        assert_eq!(
            Err::<f64, _>("no reading").into_feed(),
            Err("no reading".to_string())
        );
        assert_eq!(f64::NAN.into_feed(), Ok(StateValue::Unknown));
    }
}
