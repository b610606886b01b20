//! Spawns held for an operator's approval (`with approval`): the checker lets the operator
//! approve or refuse each held node, so a refusal nobody handles is caught with the shortest run,
//! a handled one passes, and a node approved runs on.

use tdl_verify::{NO_STUCK, NO_UNHANDLED, Verdict};

const BARE: &str = r#"
command grasp() {}
goal pick() {
    spawn grasp() with approval;
}
"#;

const HANDLED: &str = r#"
command grasp() {}
command stow() {}
handler put_down() handles ApprovalRefused {
    spawn stow();
}
goal pick() {
    spawn grasp() with approval within 30s, exception handler put_down();
}
"#;

fn verdict(src: &str, property: &str) -> Verdict {
    crate::builtin_verdict("pick.tdl", src, "pick", property)
}

#[test]
fn a_refusal_nobody_handles_is_caught_and_a_handled_one_passes() {
    let Verdict::Violated(c) = verdict(BARE, NO_UNHANDLED) else {
        panic!("a refusal goes unhandled without a handler");
    };
    assert_eq!(c.steps, ["an operator refuses pick/grasp"]);
    assert!(matches!(verdict(HANDLED, NO_UNHANDLED), Verdict::Holds));
    // Held is not stuck: the operator may always act.
    assert!(matches!(verdict(BARE, NO_STUCK), Verdict::Holds));
    assert!(matches!(verdict(HANDLED, NO_STUCK), Verdict::Holds));
}
