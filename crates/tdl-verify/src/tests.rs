//! The search's counterexamples against a brute force: for each seeded bug of `test_data/`, no
//! path shorter than the one the breadth-first search reports breaks the property (every
//! sequence of transitions up to that length is tried, without merging states).

use std::path::Path;
use std::time::Duration;

use crate::machine::{Action, Ctx, State};
use crate::model::{Arg, CommandModel, Ending};
use crate::property::{Property, Props};
use crate::{Options, Program};

fn load(name: &str) -> Program {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("test_data")
        .join(name);
    let src = std::fs::read_to_string(&path).expect("the file reads");
    Program::load(&[(name.to_owned(), src)]).expect("the program loads")
}

fn small() -> Options {
    Options {
        loops: 1,
        hangs: 0,
        ticks: 0,
        ..Options::default()
    }
}

/// Whether some path of at most `len` transitions reaches a state where `bad` holds.
fn bad_within(
    cx: &Ctx<'_>,
    s: &mut State,
    len: usize,
    bad: &dyn Fn(&mut State, &Ctx<'_>) -> bool,
) -> bool {
    if bad(s, cx) {
        return true;
    }
    if len == 0 || s.stopped() {
        return false;
    }
    let mut actions: Vec<Action> = Vec::new();
    s.actions(cx, &mut actions);
    actions.iter().any(|a| {
        let mut next = s.step(cx, a);
        bad_within(cx, &mut next, len - 1, bad)
    })
}

fn shortest(
    file: &str,
    options: &Options,
    props: &Props,
    model: Option<&dyn CommandModel>,
    bad: &dyn Fn(&mut State, &Ctx<'_>) -> bool,
    found: usize,
) {
    let program = load(file);
    let cx = Ctx {
        prog: &program,
        opts: options,
        model,
        props,
        sim: false,
    };
    let mut init = State::init(&cx, "deliver_all", !props.is_empty());
    assert!(
        !bad_within(&cx, &mut init, found - 1, bad),
        "{file}: a shorter path exists"
    );
    assert!(
        bad_within(&cx, &mut init, found, bad),
        "{file}: no path of {found}"
    );
}

fn stuck(s: &mut State, cx: &Ctx<'_>) -> bool {
    let mut actions = Vec::new();
    s.actions(cx, &mut actions);
    actions.is_empty() && !s.finished() && !s.stopped()
}

#[test]
fn no_shorter_unhandled_exception() {
    shortest(
        "removed_handler.tdl",
        &small(),
        &Props::default(),
        None,
        &|s, _| s.fault.is_some(),
        2,
    );
}

#[test]
fn no_shorter_stuck_run() {
    shortest(
        "constraint_cycle.tdl",
        &small(),
        &Props::default(),
        None,
        &stuck,
        5,
    );
}

struct AllSucceed;

impl CommandModel for AllSucceed {
    fn endings(&self, _task: &str, _args: &[Arg]) -> Option<Vec<Ending>> {
        Some(vec![Ending::Succeeds(Duration::ZERO)])
    }
}

#[test]
fn no_shorter_broken_property() {
    let motion = Property::parse("never active(turn) and active(guarded_move)").expect("parses");
    let props = Props::new(vec![motion]).expect("one property");
    let options = Options {
        loops: 2,
        ..small()
    };
    shortest(
        "concurrent_motion.tdl",
        &options,
        &props,
        Some(&AllSucceed),
        &|s, _| s.broken.is_some(),
        10,
    );
}
