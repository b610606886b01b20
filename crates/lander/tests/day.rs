//! The lander's day, behaviour by behaviour, on virtual time: the exact instants of each step,
//! from the trace (every trace passes the trace checker in `run_day`).

use lander::{Telemetry, World};
use tdl::RunOutcome;
use tdl::testing::{only, story};

fn day(world: &World, telemetry: Telemetry) -> Vec<String> {
    let (report, trace) =
        tdl::block_on_virtual(lander::run_day(world.clone(), telemetry)).expect("the day runs");
    assert_eq!(report.outcome, RunOutcome::Completed, "{report:?}");
    story(&trace)
}

const STARTS: &[&str] = &[
    "warm_up handling active",
    "panorama handling active",
    "range_target handling active",
    "dig handling active",
    "reset_arm handling active",
    "sample handling active",
    "downlink handling active",
    "mark_done handling active",
    "skipped",
];

#[test]
fn a_nominal_day_runs_each_step_after_the_one_before() {
    let world = World::new(Some(12.5), vec![]);
    let s = day(&world, Telemetry::none());
    assert_eq!(
        only(&s, STARTS),
        [
            "0 warm_up handling active",
            "10 panorama handling active",
            "70 range_target handling active",
            "75 dig handling active",
            "105 clear_arm skipped",
            "105 sample handling active",
            "125 downlink handling active",
            "135 mark_done handling active",
        ]
    );
    // The monitors stop when the plan is done.
    assert_eq!(
        only(&s, &["heater terminated", "power_log terminated", "set "]),
        [
            "75 set target_range = 12.5",
            "135 set mission_over = true",
            "135 heater terminated",
            "135 power_log terminated",
        ]
    );
    assert_eq!(world.notes(), ["dug", "sampled"]);
}

#[test]
fn steps_are_held_while_the_lander_is_unhealthy_and_go_on_when_it_is_healthy_again() {
    let world = World::new(Some(12.5), vec![]);
    let telemetry = Telemetry::none()
        .at(30, "battery", 15.0)
        .at(200, "battery", 80.0);
    let s = day(&world, telemetry);
    // Low at 30: the panorama, running, goes on to 70; the ranging due at 70 waits until the
    // battery is back at 200, and starts then.
    assert_eq!(
        only(
            &s,
            &[
                "steps suspended",
                "steps unsuspended",
                "panorama handling completed",
                "range_target handling active"
            ]
        ),
        [
            "30 steps suspended",
            "70 panorama handling completed",
            "200 steps unsuspended",
            "200 range_target handling active",
        ]
    );
    assert_eq!(
        only(&s, &["mark_done handling active"]),
        ["265 mark_done handling active"]
    );
    assert_eq!(
        world.notes(),
        ["battery Some(15.0)", "battery Some(80.0)", "dug", "sampled"]
    );
}

#[test]
fn the_arm_is_reset_again_while_its_fault_persists_each_try_at_most_20_s() {
    // The first try hangs (30 s, cut at 20), the second does not clear it, the third does.
    let world = World::new(Some(12.5), vec![(30, false), (5, false), (8, true)]);
    let s = day(&world, Telemetry::none().at(1, "arm_fault", true));
    assert_eq!(
        only(
            &s,
            &[
                "reset_arm handling active",
                "reset_arm terminated",
                "clear_arm skipped",
                "set arm_fault",
                "sample handling active"
            ]
        ),
        [
            "1 set arm_fault = true",
            "105 reset_arm handling active",
            "125 reset_arm terminated",
            "125 reset_arm handling active",
            "130 reset_arm handling active",
            "138 set arm_fault = false",
            "138 clear_arm skipped",
            "138 sample handling active",
        ]
    );
}

#[test]
fn sampling_is_skipped_while_the_target_range_is_unknown() {
    let world = World::new(None, vec![]);
    let s = day(&world, Telemetry::none());
    assert_eq!(
        only(
            &s,
            &[
                "sample skipped",
                "sample handling active",
                "downlink handling active"
            ]
        ),
        ["105 sample skipped", "105 downlink handling active"]
    );
    assert_eq!(world.notes(), ["dug"]);
}

#[test]
fn digging_fails_when_the_charge_falls_below_its_invariant() {
    let world = World::new(Some(12.5), vec![]);
    let telemetry = Telemetry::none()
        .at(90, "battery", 8.0)
        .at(150, "battery", 50.0);
    let s = day(&world, telemetry);
    // At 90 the steps pause (the charge is low; the pause was armed first, so it acts first)
    // and the dig fails (its invariant); its handler, under the paused steps, runs when they go
    // on at 150.
    assert_eq!(
        only(
            &s,
            &[
                "dig failed",
                "steps suspended",
                "steps unsuspended",
                "dig_aborted handling active",
                "sample handling active"
            ]
        ),
        [
            "90 steps suspended",
            "90 dig failed InvariantFailed",
            "150 steps unsuspended",
            "150 dig_aborted handling active",
            "150 sample handling active",
        ]
    );
    assert_eq!(
        world.notes(),
        [
            "battery Some(8.0)",
            // Both at 150: the handler, released from the pause, starts before the log's
            // activation (docs/semantics.md, "Agenda and release order").
            "dig aborted: invariant `battery >= 10.0` no longer holds (battery = 8.0)",
            "battery Some(50.0)",
            "sampled",
        ]
    );
}

#[test]
fn the_heater_goes_on_each_time_it_gets_colder_than_minus_30() {
    let world = World::new(Some(12.5), vec![]);
    let telemetry = Telemetry::none()
        .at(20, "temperature", -35.0)
        .at(30, "temperature", -38.0)
        .at(40, "temperature", -25.0)
        .at(50, "temperature", -40.0);
    let s = day(&world, telemetry);
    assert_eq!(
        only(&s, &["ACT-heater handling active"]),
        [
            "20 ACT-heater handling active",
            "50 ACT-heater handling active"
        ]
    );
    assert_eq!(world.notes(), ["heater on", "heater on", "dug", "sampled"]);
}
