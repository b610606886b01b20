//! Tasks placed on agents (`on`): the checker runs them as commands of its choice that may also
//! fail with `AgentLost`, the way a lost agent fails them at run time (docs/verification.md,
//! "Commands"). A program without a handler for it is caught with the shortest run; one with a
//! handler passes; the seeded simulation draws the loss too.

use tdl_verify::{NO_UNHANDLED, Program, SimOptions, Verdict};

const BARE: &str = r#"
goal fetch() {
    spawn grasp(1.0) with on "arm";
    spawn lift() with on "arm", sequential execution previous;
}
"#;

const HANDLED: &str = r#"
exception AgentLost;

handler shrug() handles AgentLost {
    let _ = ctx;
}

goal fetch() with exception handler shrug() {
    spawn grasp(1.0) with on "arm";
    with (on "arm") {
        spawn lift();
    }
}
"#;

fn unhandled(src: &str) -> Verdict {
    crate::builtin_verdict("fetch.tdl", src, "fetch", NO_UNHANDLED)
}

#[test]
fn a_lost_agent_is_an_unhandled_exception_unless_a_handler_takes_it() {
    let Verdict::Violated(c) = unhandled(BARE) else {
        panic!("AgentLost goes unhandled without a handler");
    };
    let steps = c.steps.join("\n");
    assert!(steps.contains("grasp fails with AgentLost"), "{steps}");
    assert_eq!(
        c.steps.len(),
        1,
        "the shortest run: the first placed task's agent lost\n{steps}"
    );
    assert!(matches!(unhandled(HANDLED), Verdict::Holds));
}

#[test]
fn the_simulation_draws_agent_loss() {
    let program = Program::load(&[("fetch.tdl".into(), BARE.into())]).expect("loads");
    let options = SimOptions {
        fail: 1.0,
        ..SimOptions::default()
    };
    let lost = (0..20).any(|seed| {
        let run =
            tdl_verify::simulate_seed(&program, "fetch", &options, &[], None, seed).expect("runs");
        run.violation.as_ref().is_some_and(|(p, c)| {
            p == NO_UNHANDLED && c.steps.join("\n").contains("fails with AgentLost")
        })
    });
    assert!(lost, "some seed loses the agent");
}
