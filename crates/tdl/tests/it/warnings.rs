//! Generated code is warning-free (issue 12, point 8): the module below denies every warning, and
//! its TDL exercises handlers (with a binding, without one, bypass, retry), `name (expr)`,
//! monitors with persistent state, loops with iteration tags, groups, `previous`, `bind`,
//! on-terminate labels and waited values. A warning in the generated code fails the build of this
//! test binary.

#[deny(warnings)]
mod generated {
    use std::time::Duration;

    async fn pause(ms: u64) {
        tokio::time::sleep(Duration::from_millis(ms)).await;
    }

    tdl::tdl! {
        pub exception Fault { code: u32 }
        pub exception TerrainFault : Fault { leg: u32 }

        pub goal walk(steps: u32) with exception handler recover(), exception handler count_up() {
            let mut total = 0;
            for i in 0..steps {
                let reach = spawn plan(i) with wait;
                total += reach;
                step: spawn take_step(i) with name (format!("step {i}")), sequential execution previous;
                spawn log_step(i) with sequential execution step[.];
            }
            g: with (serial previous) {
                spawn pause_a();
                spawn pause_b();
            }
            spawn stability(3) with terminate at g completed, maximum activate 2;
            spawn grasp(total)
                with on terminate one: spawn release(), terminate in 1s, sequential execution g;
            spawn report() with sequential execution one;
            bind here = node!(parent);
            spawn note(node!(here));
        }
        pub command plan(i: u32) -> u32 {
            pause(10).await;
            i + 1
        }
        pub command take_step(i: u32) {
            pause(10).await;
            if i == 1 {
                fail TerrainFault { leg: i };
            }
        }
        pub command log_step(_i: u32) {}
        pub command pause_a() { pause(5).await; }
        pub command pause_b() { pause(5).await; }
        pub command grasp(_force: u32) { pause(5000).await; }
        pub command release() {}
        pub command report() {}
        pub command note(_node: tdl::NodeId) {}
        pub monitor stability(limit: u32) with period 100ms, persistent checks: u32 = 0 {
            checks += 1;
            if checks > limit { trigger; }
        }
        // A handler that reads its binding, one that binds nothing, one that retries.
        pub handler recover() handles Fault as fault with maximum activate 1 {
            if let Some(terrain) = fault.downcast::<TerrainFault>() {
                let _leg = terrain.leg;
                retry;
            }
        }
        pub handler count_up() handles Fault {
            let _ = failing;
            bypass;
        }
    }
}

#[tokio::test(start_paused = true)]
async fn denied_warnings_code_runs() {
    let (report, _) = crate::util::run_checked(tdl::Runtime::new(), generated::walk(3)).await;
    assert_eq!(report.outcome, tdl::RunOutcome::Completed);
}
