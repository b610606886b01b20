//! Exceptions declared in TDL and raised with `fail`, and handlers written in TDL: the failing
//! node fails with the exception's name; handlers are found up the tree, read the exception's data,
//! bypass, re-raise and retry; the generated types carry their data and ancestry.

use crate::util::{assert_order, run_checked, story};
use tdl::{RunOutcome, Runtime};

async fn sleep_s(s: u64) {
    tokio::time::sleep(std::time::Duration::from_secs(s)).await;
}

tdl::tdl! {
    exception HardwareFailure;
    exception Overheating : HardwareFailure { temperature: f64 }
    exception NoPath { from: u32, to: u32 }

    command plan(to: u32) -> u32 {
        sleep_s(1).await;
        if to > 10 {
            fail NoPath { from: 0, to };
        }
        to * 2
    }

    command drive(steps: u32) { assert!(steps > 0); sleep_s(2).await; }

    goal go_to(to: u32) {
        spawn plan(to) with wait;
        spawn drive(1);
    }

    goal go_and_use(to: u32) {
        let steps = spawn plan(to) with wait;
        spawn drive(steps);
    }

    command overheat(t: f64) {
        fail Overheating { temperature: t };
    }
}

#[tokio::test(start_paused = true)]
async fn fail_fails_the_node_with_the_exception() {
    let (report, trace) = run_checked(Runtime::new(), go_to(99)).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    let st = story(&trace);
    // No handler: the child is marked failed and the parent goes on (TCM's default).
    assert_order(
        &st,
        &[
            "1 plan failed NoPath",
            "1 drive handling active",
            "3 go_to execution completed",
        ],
    );
}

#[tokio::test(start_paused = true)]
async fn a_waited_value_flows_and_a_failed_one_fails_the_waiter() {
    let (report, trace) = run_checked(Runtime::new(), go_and_use(3)).await;
    assert_eq!(report.outcome, RunOutcome::Completed);
    assert_order(
        &story(&trace),
        &[
            "1 drive handling active",
            "3 go_and_use execution completed",
        ],
    );

    let (report, trace) = run_checked(Runtime::new(), go_and_use(42)).await;
    let RunOutcome::TaskFailed(failure) = report.outcome else {
        panic!(
            "expected the waiting goal to fail, got {:?}",
            report.outcome
        );
    };
    assert!(failure.message.contains("NoPath"), "{failure}");
    assert!(!story(&trace).iter().any(|l| l.contains("drive")));
}

#[tokio::test(start_paused = true)]
async fn a_failing_top_level_task_reports_its_exception_and_data() {
    let (report, _) = run_checked(Runtime::new(), overheat(95.5)).await;
    let RunOutcome::TaskFailed(failure) = report.outcome else {
        panic!("expected a failure, got {:?}", report.outcome);
    };
    assert_eq!(failure.exception, "Overheating");
    assert_eq!(failure.message, "Overheating { temperature: 95.5 }");
}

#[test]
fn exceptions_are_error_types_that_know_their_parent() {
    use tdl::Exception;
    assert_eq!(Overheating::ancestry(), ["HardwareFailure"]);
    assert_eq!(
        handlers::EngineOnFire::ancestry(),
        ["Overheating", "HardwareFailure"]
    );
    assert!(HardwareFailure::ancestry().is_empty());
    let e = NoPath { from: 1, to: 2 };
    let err: &dyn std::error::Error = &e;
    assert_eq!(err.to_string(), "NoPath { from: 1, to: 2 }");
    assert_eq!(format!("{:?}", HardwareFailure {}), "HardwareFailure");
}

/// The handler stories. Each test reads what handlers did from a per-thread log.
mod handlers {
    use crate::util::{assert_order, run_checked, story};
    use std::cell::{Cell, RefCell};
    use tdl::{RunOutcome, Runtime, TraceKind};

    thread_local! {
        // Per test thread: tokio's test runtime runs every action on the test's thread.
        static LOG: RefCell<Vec<String>> = const { RefCell::new(Vec::new()) };
        static ATTEMPTS: Cell<u32> = const { Cell::new(0) };
    }

    fn log(line: String) {
        LOG.with(|l| l.borrow_mut().push(line));
    }

    fn take_log() -> Vec<String> {
        LOG.with(|l| std::mem::take(&mut *l.borrow_mut()))
    }

    async fn sleep_s(s: u64) {
        tokio::time::sleep(std::time::Duration::from_secs(s)).await;
    }

    /// A handler read its binding as a type the caught value is not.
    #[derive(Debug)]
    struct BadData;

    impl std::fmt::Display for BadData {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            f.write_str("the caught exception is not of the type read")
        }
    }

    impl std::error::Error for BadData {}

    /// A plain Rust struct with a field named `exception`, as in the report.
    struct Report {
        exception: String,
    }

    use tdl::testing::handler_choices as chosen;

    tdl::tdl! {
        pub exception HardwareFailure;
        pub exception Overheating : HardwareFailure { temperature: f64 }
        pub exception EngineOnFire : Overheating;
        pub exception NoPath { room: u32 }
        pub exception Blocked { by: &'static str }

        // The paper's navigateToLocn: handlers for Overheating and NoPath, each reading its data.
        goal navigate_to_locn(room: u32)
            with exception handler handle_overheating(), exception handler handle_no_path()
        {
            spawn move_leg(1);
            spawn plan_path(room);
        }
        command move_leg(n: u32) {
            sleep_s(n.into()).await;
            fail Overheating { temperature: 92.5 };
        }
        command plan_path(room: u32) {
            fail NoPath { room };
        }
        handler handle_overheating() handles Overheating as exception {
            let exception = exception.data().ok_or(BadData)?;
            log(format!("cool from {}", exception.temperature));
            spawn cool_down();
        }
        handler handle_no_path() handles NoPath as caught {
            // The failing node is the child; the handler is attached to the goal above it.
            let whose = if failing == attached { "own" } else { "child's" };
            let room = caught.data().map_or(0, |it| it.room);
            log(format!("give up on room {room}, the {whose} failure"));
        }
        command cool_down() { sleep_s(3).await; }

        // Subclass matching: a handler for the grandparent catches the grandchild.
        goal drive() with exception handler any_hardware() {
            spawn engine();
        }
        command engine() { fail EngineOnFire; }
        handler any_hardware() handles HardwareFailure {
            log("any hardware".to_owned());
        }

        // A bypass chain over three levels; `absorb("mid")` may be used once.
        goal top() with exception handler absorb("top") {
            spawn mid();
        }
        goal mid() with exception handler absorb("mid") maximum activate 1 {
            spawn bump(1) with exception handler pass_on();
            spawn bump(2) with exception handler pass_on(), sequential execution previous;
        }
        command bump(n: u32) {
            sleep_s(1).await;
            fail Blocked { by: if n == 1 { "cart" } else { "door" } };
        }
        handler pass_on() handles Blocked as blocked {
            log(format!("pass on {}", blocked.data().ok_or(BadData)?.by));
            bypass;
        }
        handler absorb(level: &'static str) handles Blocked as blocked {
            log(format!("{level} absorbs {}", blocked.data().ok_or(BadData)?.by));
        }

        // A handler that re-raises: its failure is searched for above the node it is attached to.
        goal escalating() with exception handler handle_no_path() {
            spawn move_leg(1) with exception handler escalate();
        }
        handler escalate() handles Overheating as hot {
            log(format!("escalate {}", hot.data().ok_or(BadData)?.temperature));
            fail NoPath { room: 0 };
        }

        // Retry: the handler runs the failed task again (same arguments); the second run works.
        goal deliver() with exception handler retry_move() maximum activate 2 {
            spawn flaky_move(2.5);
            spawn say_done() with sequential execution previous;
        }
        command flaky_move(dist: f64) {
            sleep_s(1).await;
            let attempt = ATTEMPTS.get() + 1;
            ATTEMPTS.set(attempt);
            log(format!("move {dist} attempt {attempt}"));
            if attempt == 1 {
                fail Blocked { by: "cart" };
            }
        }
        handler retry_move() handles Blocked {
            retry;
            log("retried".to_owned());
        }
        command say_done() { log("done".to_owned()); }

        // Issue 12, point 1: a handler for `Fault` catches a `TerrainFault` and reads its data,
        // as the handled type when it is one, by downcasting when it is a descendant; a field
        // named `exception` in the body is plain Rust.
        pub exception Fault { code: u32 }
        pub exception TerrainFault : Fault { leg: u32 }
        goal walk(terrain: bool) with exception handler recover() {
            spawn step(terrain);
        }
        command step(terrain: bool) {
            if terrain {
                fail TerrainFault { leg: 3 };
            }
            fail Fault { code: 7 };
        }
        handler recover() handles Fault as fault {
            let failure = Report { exception: fault.name().to_owned() };
            match (fault.data(), fault.downcast::<TerrainFault>()) {
                (Some(it), _) => log(format!("{}: code {}", failure.exception, it.code)),
                (None, Some(it)) => log(format!("{}: leg {}", failure.exception, it.leg)),
                (None, None) => return Err(BadData.into()),
            }
        }

        // A task whose argument is not `Clone` runs once; retrying it fails with `NotRetryable`.
        struct Token(u32);
        goal use_once() with exception handler retry_move() maximum activate 1 {
            spawn use_token(Token(7));
        }
        command use_token(token: Token) {
            log(format!("token {}", token.0));
            fail Blocked { by: "token" };
        }
    }

    #[tokio::test(start_paused = true)]
    async fn navigate_to_locn_handlers_read_the_exception_data() {
        take_log();
        let (report, trace) = run_checked(Runtime::new(), navigate_to_locn(7)).await;
        assert_eq!(report.outcome, RunOutcome::Completed);
        assert_eq!(
            chosen(&trace),
            ["handle_no_path<-NoPath", "handle_overheating<-Overheating"]
        );
        let log = take_log();
        assert_eq!(log.len(), 2, "{log:?}");
        assert_eq!(log[0], "give up on room 7, the child's failure");
        assert_eq!(log[1], "cool from 92.5");
        assert_order(
            &story(&trace),
            &[
                "0 plan_path failed NoPath",
                "1 move_leg failed Overheating",
                "1 cool_down handling active",
                "4 cool_down execution completed",
                "4 move_leg execution completed",
                "4 navigate_to_locn execution completed",
            ],
        );
    }

    #[tokio::test(start_paused = true)]
    async fn a_handler_reads_a_descendant_through_its_binding() {
        take_log();
        for terrain in [true, false] {
            let (report, trace) = run_checked(Runtime::new(), walk(terrain)).await;
            assert_eq!(report.outcome, RunOutcome::Completed);
            let chosen = chosen(&trace);
            let caught = if terrain { "TerrainFault" } else { "Fault" };
            assert_eq!(chosen, [format!("recover<-{caught}")]);
            // The handler did not fail: no failure of its own in the trace.
            let failed = trace
                .iter()
                .filter(|it| matches!(it.kind, TraceKind::Failed { .. }))
                .count();
            assert_eq!(failed, 1, "{trace:#?}");
        }
        assert_eq!(take_log(), ["TerrainFault: leg 3", "Fault: code 7"]);
    }

    #[tokio::test(start_paused = true)]
    async fn a_handler_for_an_ancestor_catches_the_descendant() {
        take_log();
        let (report, trace) = run_checked(Runtime::new(), drive()).await;
        assert_eq!(report.outcome, RunOutcome::Completed);
        assert_eq!(chosen(&trace), ["any_hardware<-EngineOnFire"]);
        assert_eq!(take_log(), ["any hardware"]);
    }

    #[tokio::test(start_paused = true)]
    async fn bypass_chain_over_three_levels_with_maximum_activations() {
        take_log();
        let (report, trace) = run_checked(Runtime::new(), top()).await;
        assert_eq!(report.outcome, RunOutcome::Completed);
        assert_eq!(
            chosen(&trace),
            [
                "pass_on<-Blocked",
                "bypass",
                "absorb<-Blocked",
                "pass_on<-Blocked",
                "bypass",
                "absorb<-Blocked",
            ]
        );
        // The second failure skips `mid`'s handler, used up, and reaches `top`'s.
        assert_eq!(
            take_log(),
            [
                "pass on cart",
                "mid absorbs cart",
                "pass on door",
                "top absorbs door"
            ]
        );
        assert_order(
            &story(&trace),
            &[
                "1 bump failed Blocked",
                "2 bump failed Blocked",
                "2 top execution completed",
            ],
        );
    }

    #[tokio::test(start_paused = true)]
    async fn a_handler_that_re_raises() {
        take_log();
        let (report, trace) = run_checked(Runtime::new(), escalating()).await;
        assert_eq!(report.outcome, RunOutcome::Completed);
        assert_eq!(
            chosen(&trace),
            ["escalate<-Overheating", "handle_no_path<-NoPath"]
        );
        let log = take_log();
        assert_eq!(log[0], "escalate 92.5");
        assert!(log[1].starts_with("give up on room 0"), "{log:?}");
        assert_order(
            &story(&trace),
            &["1 move_leg failed Overheating", "1 escalate failed NoPath"],
        );
    }

    #[tokio::test(start_paused = true)]
    async fn retry_succeeds_on_the_second_attempt() {
        take_log();
        ATTEMPTS.set(0);
        let (report, trace) = run_checked(Runtime::new(), deliver()).await;
        assert_eq!(report.outcome, RunOutcome::Completed);
        assert_eq!(chosen(&trace), ["retry_move<-Blocked"]);
        assert!(
            trace
                .iter()
                .any(|e| matches!(e.kind, TraceKind::Retried { .. }))
        );
        assert_eq!(
            take_log(),
            [
                "move 2.5 attempt 1",
                "move 2.5 attempt 2",
                "retried",
                "done"
            ]
        );
        assert_order(
            &story(&trace),
            &[
                "1 flaky_move failed Blocked",
                "1 retry_move handling active",
                "2 flaky_move execution completed",
                "2 say_done handling active",
                "2 deliver execution completed",
            ],
        );
    }

    #[tokio::test(start_paused = true)]
    async fn a_task_with_arguments_that_are_not_clone_runs_once() {
        take_log();
        let (report, trace) = run_checked(Runtime::new(), use_once()).await;
        assert_eq!(report.outcome, RunOutcome::Completed);
        assert_eq!(chosen(&trace), ["retry_move<-Blocked"]);
        assert_eq!(take_log(), ["token 7", "retried"]);
        assert_order(
            &story(&trace),
            &[
                "0 use_token failed Blocked",
                "0 use_token failed NotRetryable",
            ],
        );
    }
}

/// Issue 12, points 6 and 7: a handler attached from outside to every node of a task (`for T`),
/// reading the arguments of the node it recovers; `retry with (..)` runs the task again with
/// changed arguments.
mod attached {
    use crate::util::{assert_order, run_checked, story};
    use std::cell::RefCell;
    use tdl::{RunOutcome, Runtime};

    thread_local! {
        static LOG: RefCell<Vec<String>> = const { RefCell::new(Vec::new()) };
    }

    fn log(line: String) {
        LOG.with(|l| l.borrow_mut().push(line));
    }

    fn take_log() -> Vec<String> {
        LOG.with(|l| std::mem::take(&mut *l.borrow_mut()))
    }

    tdl::tdl! {
        exception Contact { leg: u32 }

        /// A leg move that touches the terrain unless lifted at least 300 mm.
        command move_leg(leg: u32, lift: u32) {
            tokio::time::sleep(std::time::Duration::from_secs(1)).await;
            log(format!("leg {leg} lift {lift}"));
            if lift < 300 {
                fail Contact { leg };
            }
        }

        /// The walking code: it knows nothing of any recovery.
        goal walk() {
            spawn move_leg(1, 150) with name "first";
            spawn move_leg(2, 500) with name "second", sequential execution previous;
            spawn move_leg(3, 100) with sequential execution previous;
        }

        /// Attached from outside to every `move_leg`: it receives the failed move's arguments,
        /// raises the leg and runs the move again with the new lift.
        handler raise_leg(leg: u32, lift: u32) handles Contact as contact for move_leg
            with maximum activate 1
        {
            let touched = contact.data().map_or(0, |c| c.leg);
            log(format!("raise leg {leg} (touched {touched}) from {lift}"));
            retry with (leg, lift + 300);
        }

        /// A goal whose step fails: the handler attached to the goal reads the goal's arguments,
        /// not the failing child's.
        goal arc(number: u32) {
            spawn move_leg(number, 0);
        }
        handler replan_arc(number: u32) handles Contact for arc {
            log(format!("replan arc {number}"));
        }
    }

    #[tokio::test(start_paused = true)]
    async fn a_handler_attached_for_a_task_recovers_each_node_with_its_arguments() {
        take_log();
        let rt = Runtime::new().attach(raise_leg());
        let (report, trace) = run_checked(rt, walk()).await;
        assert_eq!(report.outcome, RunOutcome::Completed);
        assert!(report.unhandled.is_empty(), "{:?}", report.unhandled);
        assert_eq!(
            take_log(),
            [
                "leg 1 lift 150",
                "raise leg 1 (touched 1) from 150",
                "leg 1 lift 450",
                "leg 2 lift 500",
                "leg 3 lift 100",
                "raise leg 3 (touched 3) from 100",
                "leg 3 lift 400",
            ]
        );
        assert_order(
            &story(&trace),
            &[
                "1 first failed Contact",
                "1 raise_leg handling active",
                "2 first execution completed",
                "2 second handling active",
                "4 move_leg failed Contact",
                "5 move_leg execution completed",
                "5 walk execution completed",
            ],
        );
    }

    #[tokio::test(start_paused = true)]
    async fn without_attaching_it_the_failures_are_unhandled() {
        take_log();
        let (report, _) = run_checked(Runtime::new(), walk()).await;
        assert_eq!(report.unhandled.len(), 2, "{:?}", report.unhandled);
        assert_eq!(
            take_log(),
            ["leg 1 lift 150", "leg 2 lift 500", "leg 3 lift 100"]
        );
    }

    #[tokio::test(start_paused = true)]
    async fn a_handler_attached_to_a_goal_reads_the_goals_arguments() {
        take_log();
        let rt = Runtime::new().attach(replan_arc());
        let (report, _) = run_checked(rt, arc(4)).await;
        assert!(report.unhandled.is_empty(), "{:?}", report.unhandled);
        assert_eq!(take_log(), ["leg 4 lift 0", "replan arc 4"]);
    }
}
