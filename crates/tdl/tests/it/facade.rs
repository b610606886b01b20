//! A program that names only `tdl`: the runtime, tokio (`tdl::tokio`, also for its attribute
//! macros) and one `Result` from `block_on_virtual`.

use std::time::Duration;

tdl::tdl! {
    command wait_a_minute() {
        tdl::tokio::time::sleep(std::time::Duration::from_secs(60)).await;
    }
    goal twice() {
        spawn wait_a_minute();
        spawn wait_a_minute() with sequential execution previous;
    }
}

fn simulate() -> Result<tdl::Report, tdl::Error> {
    // The runtime is made inside, so that its time zero is on the paused clock.
    tdl::block_on_virtual(async { tdl::Runtime::new().run(twice()).await })
}

#[test]
fn block_on_virtual_returns_one_result() {
    match simulate() {
        Ok(report) => {
            assert_eq!(report.outcome, tdl::RunOutcome::Completed);
            assert_eq!(report.elapsed, Duration::from_secs(120));
        }
        Err(e) => panic!("the run failed: {e}"),
    }
}

#[tdl::tokio::test(crate = "tdl::tokio", start_paused = true)]
async fn tokio_through_tdl_runs_a_test_on_virtual_time() {
    let start = tdl::tokio::time::Instant::now();
    let report = match tdl::Runtime::new().run(twice()).await {
        Ok(report) => report,
        Err(e) => panic!("the run failed: {e}"),
    };
    assert!(report.is_clean(), "{report}");
    assert_eq!(start.elapsed(), Duration::from_secs(120));
}
