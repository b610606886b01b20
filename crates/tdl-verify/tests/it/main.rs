//! `tdl-verify` on the Xavier mission and on copies of it with one seeded bug each
//! (`test_data/`): each bug is found, with a counterexample as short as any (breadth-first), a
//! trace the trace checker accepts and `tdl trace story` can replay; the mission itself passes.
//!
//! The bounds are smaller than the defaults (one loop iteration where two are not needed, no
//! command left running forever, no command outlasting a deadline) so that the tests run in
//! seconds in a debug build; `docs/verification.md` has the run with the default bounds.

mod agents;
mod approvals;
mod mission;
mod sim;
mod state;
mod status;

/// The verdict of the built-in `property` on task `task` of a one-file program `src` (named
/// `file`), verified with the default bounds.
pub(crate) fn builtin_verdict(
    file: &str,
    src: &str,
    task: &str,
    property: &str,
) -> tdl_verify::Verdict {
    let program =
        tdl_verify::Program::load(&[(file.into(), src.into())]).expect("the program loads");
    let report = tdl_verify::verify(
        &program,
        task,
        &tdl_verify::Options::default(),
        &[],
        None,
        &tdl_verify::Control::default(),
    );
    report
        .results
        .into_iter()
        .find(|r| r.property == property)
        .expect("the built-in property")
        .verdict
}
