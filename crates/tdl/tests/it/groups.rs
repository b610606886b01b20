//! `with` groups: nested serial and parallel groups, a group label as a tag, and conditional
//! spawns in a serial chain (which spawn is `previous` is decided at run time).

use crate::util::{assert_order, run_checked, story};
use tdl::{RunOutcome, Runtime};

async fn sleep_s(s: u64) {
    tokio::time::sleep(std::time::Duration::from_secs(s)).await;
}

tdl::tdl! {
    command go_a() { sleep_s(1).await; }
    command go_b() { sleep_s(1).await; }
    command look_left() { sleep_s(2).await; }
    command look_right() { sleep_s(3).await; }
    command report() { sleep_s(1).await; }

    goal patrol() {
        outer: with (serial) {
            spawn go_a();
            with (parallel) {
                spawn look_left();
                spawn look_right();
            }
            spawn go_b();
        }
        spawn report() with sequential execution outer;
    }

    command lift_arm() { sleep_s(1).await; }
    command drive(d: f64) { assert!(d > 0.0); sleep_s(2).await; }
    command creep(d: f64) { assert!(d > 0.0); sleep_s(3).await; }
    command grasp() { sleep_s(1).await; }

    goal approach(distance: f64) {
        with (serial) {
            spawn lift_arm();
            if distance > 10.0 {
                spawn drive(distance - 10.0);
            } else {
                spawn creep(distance);
            }
            spawn grasp();
        }
    }
}

#[tokio::test(start_paused = true)]
async fn an_inner_parallel_group_is_one_entity_of_the_outer_serial_group() {
    let (report, trace) = run_checked(Runtime::new(), patrol()).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let st = story(&trace);
    // Both looks start together after go_a; go_b waits for *both* (the group is one entity);
    // report waits for every member of `outer`.
    assert_order(
        &st,
        &[
            "0 go_a handling active",
            "1 go_a execution completed",
            "1 look_left handling active",
            "1 look_right handling active",
            "3 look_left execution completed",
            "4 look_right execution completed",
            "4 go_b handling active",
            "5 go_b execution completed",
            "5 report handling active",
            "6 patrol execution completed",
        ],
    );
    assert!(
        !st.iter()
            .any(|l| l.starts_with("3 look_right handling active")),
        "the inner group must not be chained by the outer `serial`"
    );
}

#[tokio::test(start_paused = true)]
async fn a_conditional_spawn_in_a_serial_chain_is_the_next_ones_previous() {
    let (_, trace) = run_checked(Runtime::new(), approach(20.0)).await;
    let far = story(&trace);
    assert_order(
        &far,
        &[
            "1 lift_arm execution completed",
            "1 drive handling active",
            "3 drive execution completed",
            "3 grasp handling active",
            "4 approach execution completed",
        ],
    );
    assert!(!far.iter().any(|l| l.contains("creep")));

    let (_, trace) = run_checked(Runtime::new(), approach(5.0)).await;
    let near = story(&trace);
    assert_order(
        &near,
        &[
            "1 creep handling active",
            "4 creep execution completed",
            "4 grasp handling active",
            "5 approach execution completed",
        ],
    );
    assert!(!near.iter().any(|l| l.contains("drive")));
}
