//! A state variable fed from a ROS 2 topic that ros2-client's own publisher writes: a step that
//! waits on a condition over it starts after the message that makes the condition true; each
//! message is a `state_set` record with the mapped value; a minimum change skips the numbers
//! within it, a message the map gives no value for (or panics on) is skipped, and a dropped
//! feed undeclares its subscription.

use crate::util::{Float32, Pair, bounded, float32_type};
use std::time::{Duration, Instant};
use tcm::testing::{assert_checked, only, story};
use tcm::{
    BinOp, Constraint, Expr, Facet, Recorder, RunOutcome, Runtime, Session, StateType, StateValue,
    StateVar, Task, TraceEvent, TraceKind, When,
};
use tcm_ros::StateFeed;
use tcm_ros::ros2_client::{Name, Node, Publisher, QosProfile};

fn battery() -> StateVar {
    StateVar::new("battery", StateType::Float, StateValue::Unknown)
}

/// A publisher of `topic` on `node`, once it sees the feed's subscription.
async fn talker(node: &Node, topic: &str) -> Publisher<Float32> {
    let name = Name::parse(topic).expect("a ROS 2 name");
    let t = node.create_topic(&name, float32_type(), &QosProfile::publisher_default());
    let publisher = node
        .create_publisher::<Float32>(&t, None)
        .expect("publisher");
    publisher.wait_for_subscription(node).await;
    publisher
}

async fn publish(publisher: &Publisher<Float32>, data: f32) {
    publisher
        .async_publish(Float32 { data })
        .await
        .expect("published");
}

/// Waits until the run's `battery` is `value`.
async fn seen(session: &Session, value: f64) {
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        if session.state("battery").expect("state") == Some(StateValue::Float(value)) {
            return;
        }
        assert!(
            Instant::now() < deadline,
            "battery = {value} not seen in 10 s"
        );
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
}

/// A mission whose `drive` waits until `battery > 80`.
fn mission() -> Task {
    Task::goal("mission", |ctx| async move {
        let charged = ctx.condition(
            &[battery()],
            Expr::bin(BinOp::Gt, Expr::var("battery"), Expr::lit(80)),
        )?;
        ctx.spawn(Task::command("drive", |_| async { Ok(()) }))
            .with(Constraint::disable(
                Facet::Handling,
                When::Condition(charged),
            ))
            .start()?;
        Ok(())
    })
}

/// The values of the `state_set` records of `battery`, in order.
fn sets(trace: &[TraceEvent]) -> Vec<StateValue> {
    trace
        .iter()
        .filter_map(|e| match &e.kind {
            TraceKind::StateSet { var, value } if var == "battery" => Some(value.clone()),
            _ => None,
        })
        .collect()
}

/// The story's sets of `battery` and `drive`'s start, without their times.
fn sets_and_start(trace: &[TraceEvent]) -> Vec<String> {
    only(&story(trace), &["set battery", "drive handling active"])
        .iter()
        .map(|l| {
            l.split_once(' ')
                .map_or(l.as_str(), |(_, rest)| rest)
                .to_string()
        })
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_step_waiting_on_a_fed_variable_starts_after_the_message_that_makes_it_true() {
    bounded(async {
        let pair = Pair::new().await;
        let rec = Recorder::new();
        let session = Runtime::new()
            .state(battery())
            .with_sink(rec.clone())
            .start()
            .expect("session");
        let feed = StateFeed::new(
            &pair.client,
            "/battery",
            &float32_type(),
            &battery(),
            |m: Float32| m.data,
        )
        .expect("feed")
        .start(session.events())
        .expect("started");
        assert_eq!(feed.topic(), "/battery");
        session.spawn(mission()).expect("mission");
        let publisher = talker(&pair.server, "/battery").await;
        // Each value seen by the run before the next is sent: the sets are the run's inputs in
        // the order the topic gave them.
        for v in [20.0, 50.0, 90.0] {
            publish(&publisher, v).await;
            seen(&session, f64::from(v)).await;
        }
        let report = session.finish().await.expect("finished");
        let trace = rec.events();
        assert_checked(&trace);
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        assert!(report.is_clean(), "{report}");
        assert_eq!(
            sets(&trace),
            [20.0, 50.0, 90.0].map(StateValue::Float),
            "{:#?}",
            story(&trace)
        );
        assert_eq!(
            sets_and_start(&trace),
            [
                "set battery = 20.0",
                "set battery = 50.0",
                "set battery = 90.0",
                "drive handling active"
            ]
        );
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_minimum_change_and_unmapped_messages_skip_sets_and_a_dropped_feed_unsubscribes() {
    bounded(async {
        let pair = Pair::new().await;
        let rec = Recorder::new();
        let session = Runtime::new()
            .state(battery())
            .with_sink(rec.clone())
            .start()
            .expect("session");
        // A negative reading is none; a reading above 1000 makes the map panic.
        let feed = StateFeed::new(
            &pair.client,
            "/battery_level",
            &float32_type(),
            &battery(),
            |m: Float32| {
                assert!(m.data <= 1000.0, "a reading of {}", m.data);
                if m.data < 0.0 {
                    Err("no reading")
                } else {
                    Ok(m.data)
                }
            },
        )
        .expect("feed")
        .min_change(1.0)
        .start(session.events())
        .expect("started");
        session.spawn(mission()).expect("mission");
        let publisher = talker(&pair.server, "/battery_level").await;
        publish(&publisher, 20.0).await;
        seen(&session, 20.0).await;
        // 20.5 is within 1 of 20 (skipped); 21.25 is not (set), nor is 90.
        for v in [20.5, -1.0, 5000.0, 21.25, 90.0] {
            publish(&publisher, v).await;
        }
        seen(&session, 90.0).await;
        // The feed read on through the refused messages.
        assert!(feed.is_running());
        let report = session.finish().await.expect("finished");
        let trace = rec.events();
        assert_checked(&trace);
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        assert_eq!(
            sets(&trace),
            [20.0, 21.25, 90.0].map(StateValue::Float),
            "{:#?}",
            story(&trace)
        );
        assert_eq!(
            sets_and_start(&trace),
            [
                "set battery = 20.0",
                "set battery = 21.25",
                "set battery = 90.0",
                "drive handling active"
            ]
        );
        // Dropped, the feed undeclares its subscription, which the publisher's side sees go.
        assert_eq!(publisher.get_subscription_count(&pair.server), 1);
        drop(feed);
        let deadline = Instant::now() + Duration::from_secs(10);
        while publisher.get_subscription_count(&pair.server) > 0 {
            assert!(Instant::now() < deadline, "the subscription is still there");
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
    })
    .await;
}
