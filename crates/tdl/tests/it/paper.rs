//! The paper's Figure 4 in TDL, and its `with (sequential execution) { ... with (parallel) { ... } }`
//! rewrite, which must yield the same trace.

use crate::util::{assert_order, only, run_checked, story};
use tdl::{RunOutcome, Runtime};

/// The stand-in world shared by both versions: commands that take virtual time, and a door
/// sensor that reads left, right, then centred. `monitor_pickup` is a plain command standing in
/// for the Figure 6 monitor, so the trace stays that of Figure 4 alone (the monitor itself runs
/// under `deliver_mail` in `monitors.rs`): the mail is taken after 5 s.
macro_rules! world {
    () => {
        thread_local! {
            // Per test thread: tokio's test runtime runs every action on the test's thread.
            static LOOKS: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
        }

        pub(crate) fn reset_world() {
            LOOKS.set(0);
        }

        fn get_room_coordinates(room: u32) -> (f64, f64) {
            (f64::from(room) * 10.0, 5.0)
        }

        async fn sleep_s(s: u64) {
            tokio::time::sleep(std::time::Duration::from_secs(s)).await;
        }

        tdl::tdl! {
            goal center_on_door(x: f64, y: f64) with delay expansion {
                let which_side = spawn look_for_door(x, y) with wait;
                if which_side != 0 {
                    if which_side < 0 {
                        spawn move_by(-10.0); // move left
                    } else {
                        spawn move_by(10.0); // move right
                    }
                    spawn center_on_door(x, y)
                        with disable execution until previous execution completed;
                }
            }

            command navigate_to_locn(x: f64, y: f64) {
                assert!(x > 0.0 && y > 0.0);
                sleep_s(6).await;
            }

            command look_for_door(x: f64, y: f64) -> i32 {
                assert!(x.is_finite() && y.is_finite());
                sleep_s(1).await;
                let n = LOOKS.get();
                LOOKS.set(n + 1);
                [-1, 1].get(n).copied().unwrap_or(0)
            }

            command move_by(dist: f64) {
                assert!(dist != 0.0);
                sleep_s(1).await;
            }

            command speak(text: &'static str) {
                assert!(!text.is_empty());
                // Repeats its announcement until terminated.
                std::future::pending::<()>().await;
            }

            command monitor_pickup() {
                sleep_s(5).await;
            }
        }
    };
}

mod spawn_by_spawn {
    world!();
    tdl::tdl! {
        pub goal deliver_mail(room: u32) {
            let (x, y) = get_room_coordinates(room);
            spawn navigate_to_locn(x, y);
            spawn center_on_door(x, y) with sequential execution previous, terminate in 30s;
            spawn speak("Xavier here with your mail")
                with sequential execution center_on_door, terminate at monitor_pickup completed;
            spawn monitor_pickup() with sequential execution center_on_door;
        }
    }
}

mod with_groups {
    world!();
    tdl::tdl! {
        pub goal deliver_mail(room: u32) {
            let (x, y) = get_room_coordinates(room);
            with (sequential execution) {
                spawn navigate_to_locn(x, y);
                spawn center_on_door(x, y) with terminate in 0:0:30.0;
                with (parallel) {
                    spawn speak("Xavier here with your mail")
                        with terminate at monitor_pickup completed;
                    spawn monitor_pickup();
                }
            }
        }
    }
}

#[tokio::test(start_paused = true)]
async fn figure_4_runs_in_the_papers_order() {
    spawn_by_spawn::reset_world();
    let (report, trace) = run_checked(Runtime::new(), spawn_by_spawn::deliver_mail(7)).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let st = story(&trace);
    // Navigation (0-6 s); centring: look, move left, look, move right, look (centred), each
    // expansion of center_on_door after the previous move; then speak and monitor_pickup
    // together; speak is terminated when monitor_pickup completes.
    assert_order(
        &st,
        &[
            "0 navigate_to_locn handling active",
            "6 navigate_to_locn execution completed",
            "6 center_on_door handling active",
            "6 look_for_door handling active",
            "7 look_for_door handling completed",
            "7 move_by handling active",
            "8 move_by execution completed",
            "8 center_on_door handling active",
            "9 move_by handling active",
            "10 center_on_door handling active",
            "11 look_for_door handling completed",
            "11 center_on_door execution completed",
            "11 speak handling active",
            "11 monitor_pickup handling active",
            "16 monitor_pickup execution completed",
            "16 speak terminating",
            "16 speak terminated",
            "16 deliver_mail execution completed",
        ],
    );
    assert_eq!(
        only(&st, &["center_on_door handling active"]),
        [
            "6 center_on_door handling active",
            "8 center_on_door handling active",
            "10 center_on_door handling active"
        ]
    );
    assert!(!st.iter().any(|l| l.contains("center_on_door terminating")));
}

#[tokio::test(start_paused = true)]
async fn the_with_group_rewrite_yields_the_same_trace() {
    spawn_by_spawn::reset_world();
    let (_, flat) = run_checked(Runtime::new(), spawn_by_spawn::deliver_mail(7)).await;
    with_groups::reset_world();
    let (report, grouped) = run_checked(Runtime::new(), with_groups::deliver_mail(7)).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let (flat, grouped) = (story(&flat), story(&grouped));
    assert!(
        flat.len() > 40,
        "the story is too short to compare:\n{}",
        flat.join("\n")
    );
    assert_eq!(
        flat,
        grouped,
        "\nflat:\n{}\n\ngrouped:\n{}",
        flat.join("\n"),
        grouped.join("\n")
    );
}
