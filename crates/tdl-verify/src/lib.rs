//! `tdl-verify`: a model checker for TDL programs (`tdl verify`).
//!
//! It explores every behaviour of a program's task tree within bounds, on the real engine
//! (`tcm_core::Engine`), and checks properties on every state: no stuck state, no unhandled
//! exception, every run ends, every trace passes the trace checker, and the user's own properties
//! ([`Property`]). A counterexample is the shortest path breaking a property, as a trace file that
//! `tdl trace story` replays. docs/verification.md says what is explored, how, and the limits.
//!
//! ```
//! // `grip` is a command written in Rust: it may succeed or fail with `Jammed`.
//! let src = "
//! exception Jammed;
//! goal pick() { spawn grip(); }
//! ";
//! let program = tdl_verify::Program::load(&[("pick.tdl".into(), src.into())]).expect("loads");
//! let options = tdl_verify::Options::default();
//! let report = tdl_verify::verify(&program, "pick", &options, &[], None, &Default::default());
//! let result = report.result(tdl_verify::NO_UNHANDLED).expect("a built-in property");
//! let counterexample = result.counterexample().expect("nothing handles `Jammed`");
//! assert_eq!(counterexample.steps, ["pick/grip fails with Jammed"]);
//! ```
//!
//! Key parts, in the order data flows through them:
//! - [`Program::load`] (`program.rs`): the files checked as `tdl check` does, then each body
//!   compiled to instructions (`ir.rs`), its Rust abstracted to what decides control flow
//!   (`value.rs`);
//! - the abstract machine (`machine.rs`): a state is the engine plus the suspended bodies, the
//!   running commands and the bounds used; its transitions are the choices (a command's ending,
//!   a condition the checker cannot evaluate, an external event, time passing);
//! - the search (`search.rs`): breadth-first, each canonical state once, then the cycles of the
//!   state graph (runs that never end);
//! - counterexamples rebuilt by replay with tracing on, checked by `tcm_trace::check` (here);
//! - the seeded simulation (`sim.rs`, [`simulate`], `tdl sim`): instead of the search, one walk
//!   through the machine per seed, each choice drawn from the seed's random stream, commands given
//!   random durations and outcomes, every run's trace checked.

#![warn(missing_docs)]

mod ir;
mod machine;
mod model;
mod program;
mod property;
mod search;
mod sim;
#[cfg(test)]
mod tests;
mod value;

use std::io::Write;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

pub use model::{Arg, CommandModel, Ending};
pub use program::{LoadError, Program};
pub use property::{Property, PropertyError};
pub use search::Progress;
pub use sim::{SimOptions, SimProgress, SimReport, SimResult, SimRun, simulate, simulate_seed};
use tcm_trace::TraceEvent;

use machine::{Action, Ctx, State};
use property::Props;
use search::{Found, path_to};

/// The exception a command of Rust may raise beyond those the program declares, with
/// [`Options::unknown_exception`].
pub const UNKNOWN_EXCEPTION: &str = "UnknownException";

/// The exception a task placed on an agent (`on`) may also fail with: its agent was lost while it
/// ran the task (`tcm_zenoh::AgentLost`).
pub const AGENT_LOST: &str = "AgentLost";

/// The bounds and choices of a verification (docs/verification.md, "Bounds").
#[derive(Clone, Debug)]
pub struct Options {
    /// How many times a loop over a collection the checker cannot see may run (0 to this).
    pub loops: u32,
    /// How many instances of one task may be nested on one branch of the tree: one more is
    /// spawned as a command of the checker's choice (its subtree not expanded), and a spawn
    /// beyond that ends the path (not a violation).
    pub recursion: u32,
    /// The longest run explored, in transitions; a run that could go on is reported.
    pub depth: u32,
    /// The most distinct states explored before the search stops (incomplete).
    pub max_states: u64,
    /// How many deadlines (timers firing) a running command may outlast: time advances past
    /// the next one only while every running command has outlasted fewer (commands left running
    /// until terminated aside).
    pub ticks: u32,
    /// How many times each external event may be raised.
    pub events: u32,
    /// How many commands per run may be left running until terminated (only commands that
    /// something may terminate).
    pub hangs: u32,
    /// Exceptions allowed to go unhandled.
    pub allowed: Vec<String>,
    /// Commands written in Rust may also fail with an exception no one declares
    /// ([`UNKNOWN_EXCEPTION`]).
    pub unknown_exception: bool,
    /// How many paths are replayed through the trace checker besides every counterexample: as
    /// many runs that ended (the first found), as many paths to states spread evenly over the
    /// order of discovery, and the path to the deepest state.
    pub samples: usize,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            loops: 2,
            recursion: 1,
            depth: 10_000,
            max_states: 20_000_000,
            ticks: 1,
            events: 1,
            hangs: 1,
            allowed: Vec::new(),
            unknown_exception: false,
            samples: 16,
        }
    }
}

/// What stops a verification early, and what it reports on the way.
#[derive(Default)]
pub struct Control {
    /// Set (from another thread, e.g. on Ctrl-C) to stop the search; the report then gives what
    /// was found so far.
    pub stop: AtomicBool,
}

/// The verdict on one property.
#[derive(Debug)]
pub enum Verdict {
    /// No violation in the whole state space within the bounds.
    Holds,
    /// Broken: the shortest counterexample found.
    Violated(Box<Counterexample>),
    /// Not decided, and why (the search stopped early, or a liveness property on a graph with
    /// cycles).
    Unknown(String),
}

/// One property and its verdict.
#[derive(Debug)]
pub struct PropertyResult {
    /// The property, in words.
    pub property: String,
    /// The verdict.
    pub verdict: Verdict,
}

impl PropertyResult {
    /// Whether a counterexample was found.
    pub fn is_violated(&self) -> bool {
        matches!(self.verdict, Verdict::Violated(_))
    }

    /// The counterexample, if any.
    pub fn counterexample(&self) -> Option<&Counterexample> {
        match &self.verdict {
            Verdict::Violated(c) => Some(c),
            _ => None,
        }
    }
}

/// A path that breaks a property.
#[derive(Debug, Clone)]
pub struct Counterexample {
    /// What went wrong, in words.
    pub summary: String,
    /// The transitions taken, in words, from the start.
    pub steps: Vec<String>,
    /// For a run that never ends: the step from which the last ones repeat forever.
    pub repeats_from: Option<usize>,
    /// Some choice on the path is a condition of the program's Rust code the checker does not
    /// evaluate: the path exists only if that condition can go that way.
    pub depends_on_conditions: bool,
    /// Commands the path leaves running until they are terminated.
    pub hung: Vec<String>,
    /// Details: what a stuck run waits for, the exception and where.
    pub details: Vec<String>,
    /// The run's trace (JSON-lines records, `docs/trace-format.md`).
    pub trace: Vec<TraceEvent>,
    /// The trace checker's complaints about it, if any.
    pub trace_violations: Vec<String>,
}

impl Counterexample {
    /// The number of transitions.
    pub fn len(&self) -> usize {
        self.steps.len()
    }

    /// Whether the path is the first state alone.
    pub fn is_empty(&self) -> bool {
        self.steps.is_empty()
    }

    /// Writes the trace as JSON lines, as `tdl trace story` reads it.
    pub fn write_trace(&self, w: &mut impl Write) -> std::io::Result<()> {
        for r in &self.trace {
            tcm_trace::write_line(r, w)?;
        }
        Ok(())
    }

    /// The trace's story, one line per transition (`tcm_trace::story`).
    pub fn story(&self) -> Vec<String> {
        tcm_trace::story::story(&self.trace)
    }
}

/// The result of a verification.
#[derive(Debug)]
pub struct Report {
    /// The task verified.
    pub task: String,
    /// Transitions computed (states generated, counting each time a state is reached again).
    pub explored: u64,
    /// Distinct states.
    pub unique: u64,
    /// The longest of the shortest paths to a state.
    pub depth: u32,
    /// How long the search took.
    pub elapsed: Duration,
    /// The whole state space within the bounds was explored.
    pub complete: bool,
    /// Stopped from outside (Ctrl-C).
    pub interrupted: bool,
    /// Paths ended by the loop or recursion bound, and one of them in words.
    pub cut: u64,
    /// Why a path was cut, for the first one.
    pub cut_example: Option<String>,
    /// States where the run ended.
    pub ended: u64,
    /// Traces replayed through the trace checker (counterexamples and samples).
    pub traces_checked: usize,
    /// Every property and its verdict: the built-in ones first.
    pub results: Vec<PropertyResult>,
    /// What the checker abstracts in this program.
    pub notes: Vec<String>,
    /// Failures of the checker itself, if any (a bug to report).
    pub errors: Vec<String>,
}

impl Report {
    /// The result of the property named `name` (as [`PropertyResult::property`] writes it).
    pub fn result(&self, name: &str) -> Option<&PropertyResult> {
        self.results.iter().find(|r| r.property == name)
    }

    /// Whether every property holds (or was not decided) and nothing broke.
    pub fn ok(&self) -> bool {
        self.results.iter().all(|r| !r.is_violated()) && self.errors.is_empty()
    }

    /// States explored per second.
    pub fn rate(&self) -> f64 {
        self.explored as f64 / self.elapsed.as_secs_f64().max(1e-9)
    }
}

/// The built-in properties, by the name results use.
pub const NO_STUCK: &str = "no stuck state";
/// See [`NO_STUCK`].
pub const NO_UNHANDLED: &str = "no unhandled exception";
/// See [`NO_STUCK`].
pub const RUNS_END: &str = "every run ends";
/// See [`NO_STUCK`].
pub const TRACES_CHECK: &str = "every trace passes the trace checker";

/// Verifies `program` from the task `task` with `properties` besides the built-in ones, and the
/// commands' `model` if any.
pub fn verify(
    program: &Program,
    task: &str,
    options: &Options,
    properties: &[Property],
    model: Option<&dyn CommandModel>,
    control: &Control,
) -> Report {
    verify_with_progress(
        program,
        task,
        options,
        properties,
        model,
        control,
        &mut |_| {},
    )
}

/// [`verify`], calling `progress` every fifth of a second or so.
pub fn verify_with_progress(
    program: &Program,
    task: &str,
    options: &Options,
    properties: &[Property],
    model: Option<&dyn CommandModel>,
    control: &Control,
    progress: &mut dyn FnMut(&Progress),
) -> Report {
    let props = match Props::new(properties.to_vec()) {
        Ok(p) => p,
        Err(e) => {
            return Report {
                task: task.to_owned(),
                explored: 0,
                unique: 0,
                depth: 0,
                elapsed: Duration::ZERO,
                complete: false,
                interrupted: false,
                cut: 0,
                cut_example: None,
                ended: 0,
                traces_checked: 0,
                results: Vec::new(),
                notes: Vec::new(),
                errors: vec![e],
            };
        }
    };
    let cx = Ctx {
        prog: program,
        opts: options,
        model,
        props: &props,
        sim: false,
    };
    let out = search::run(&cx, task, &control.stop, progress);
    let mut results: Vec<PropertyResult> = Vec::new();
    let undecided = |out: &search::Outcome| {
        if out.interrupted {
            "not decided: the search was interrupted".to_owned()
        } else {
            format!(
                "not decided: the search stopped at {} distinct states (--max-states)",
                out.unique()
            )
        }
    };
    let mut traces_checked = 0;
    let mut bad_traces: Vec<Counterexample> = Vec::new();
    let mut cex = |found: &Found, what: String, traces_checked: &mut usize| {
        let (path, repeats_from) = match found {
            Found::Stuck(id)
            | Found::Unhandled(id)
            | Found::User(_, id)
            | Found::TooLong(id)
            | Found::NotEventually(_, id) => (path_to(&out.seen, *id), None),
            Found::Cycle { entry, cycle } => {
                let mut p = path_to(&out.seen, *entry);
                let from = p.len();
                p.extend(cycle.iter().copied());
                (p, Some(from))
            }
        };
        let mut c = replay(&cx, task, &path, what);
        c.repeats_from = repeats_from;
        if matches!(found, Found::TooLong(_)) {
            c.details.push(format!(
                "the run is still going after {} transitions (--depth)",
                options.depth
            ));
        }
        *traces_checked += 1;
        if !c.trace_violations.is_empty() {
            bad_traces.push(c.clone());
        }
        c
    };
    // No stuck state.
    let stuck = out.found.iter().find(|f| matches!(f, Found::Stuck(_)));
    results.push(PropertyResult {
        property: NO_STUCK.into(),
        verdict: match stuck {
            Some(f) => Verdict::Violated(Box::new(cex(
                f,
                "stuck: nothing can happen any more, and the task has not completed".into(),
                &mut traces_checked,
            ))),
            None if out.complete => Verdict::Holds,
            None => Verdict::Unknown(undecided(&out)),
        },
    });
    let unhandled = out.found.iter().find(|f| matches!(f, Found::Unhandled(_)));
    results.push(PropertyResult {
        property: NO_UNHANDLED.into(),
        verdict: match unhandled {
            Some(f) => Verdict::Violated(Box::new(cex(
                f,
                "a failure no handler takes".into(),
                &mut traces_checked,
            ))),
            None if out.complete => Verdict::Holds,
            None => Verdict::Unknown(undecided(&out)),
        },
    });
    let never_ends = out
        .found
        .iter()
        .find(|f| matches!(f, Found::Cycle { .. }))
        .or_else(|| out.found.iter().find(|f| matches!(f, Found::TooLong(_))));
    results.push(PropertyResult {
        property: RUNS_END.into(),
        verdict: match never_ends {
            Some(f @ Found::Cycle { .. }) => Verdict::Violated(Box::new(cex(
                f,
                "a run that never ends: the last transitions repeat forever".into(),
                &mut traces_checked,
            ))),
            Some(f) => Verdict::Violated(Box::new(cex(
                f,
                format!(
                    "a run longer than the bound of {} transitions",
                    options.depth
                ),
                &mut traces_checked,
            ))),
            None if out.complete => Verdict::Holds,
            None => Verdict::Unknown(undecided(&out)),
        },
    });
    for (k, p) in props.list.iter().enumerate() {
        let f = out
            .found
            .iter()
            .find(|f| matches!(f, Found::User(j, _) | Found::NotEventually(j, _) if *j == k));
        let verdict = match f {
            Some(f) => Verdict::Violated(Box::new(cex(
                f,
                format!("`{}` is broken", p.text()),
                &mut traces_checked,
            ))),
            None if p.is_liveness() && out.cyclic => Verdict::Unknown(
                "refused: the state graph has a cycle (a run that never ends), on which `eventually` cannot be decided soundly; fix `every run ends` first".into(),
            ),
            None if out.complete => Verdict::Holds,
            None => Verdict::Unknown(undecided(&out)),
        };
        results.push(PropertyResult {
            property: p.text().to_owned(),
            verdict,
        });
    }
    // Sampled runs through the trace checker.
    for id in &out.samples {
        let path = path_to(&out.seen, *id);
        let c = replay(&cx, task, &path, "a sampled run".into());
        traces_checked += 1;
        if !c.trace_violations.is_empty() {
            bad_traces.push(c);
        }
    }
    results.insert(
        3,
        PropertyResult {
            property: TRACES_CHECK.into(),
            verdict: match bad_traces.into_iter().next() {
                Some(mut c) => {
                    c.summary = format!("the trace checker rejects the trace of {}", c.summary);
                    Verdict::Violated(Box::new(c))
                }
                None => Verdict::Holds,
            },
        },
    );
    Report {
        task: task.to_owned(),
        explored: out.progress.explored,
        unique: out.progress.unique,
        depth: out.progress.depth,
        elapsed: out.progress.elapsed,
        complete: out.complete,
        interrupted: out.interrupted,
        cut: out.cut,
        cut_example: out.cut_example.clone(),
        ended: out.ended,
        traces_checked,
        results,
        notes: program.notes.clone(),
        errors: out.errors.clone(),
    }
}

impl search::Outcome {
    fn unique(&self) -> usize {
        self.seen.len()
    }
}

/// Replays `path` from the first state with tracing on.
fn replay(cx: &Ctx<'_>, task: &str, path: &[u16], summary: String) -> Counterexample {
    let mut s = State::init(cx, task, true);
    let mut trace: Vec<TraceEvent> = std::mem::take(&mut s.records);
    let mut steps = Vec::new();
    let mut picks = false;
    let mut actions: Vec<Action> = Vec::new();
    for &i in path {
        s.actions(cx, &mut actions);
        let Some(a) = actions.get(i as usize).cloned() else {
            steps.push(format!(
                "(transition {i} is gone: the replay differs from the search)"
            ));
            break;
        };
        picks |= matches!(a, Action::Pick(_));
        steps.push(s.describe(cx, &a));
        s = s.step(cx, &a);
        trace.append(&mut s.records);
    }
    let mut details = Vec::new();
    if let Some(machine::Fault::Unhandled { exception, path }) = &s.fault {
        details.push(format!(
            "{exception} raised at {path} is taken by no handler"
        ));
    }
    s.actions(cx, &mut actions);
    if actions.is_empty() && !s.finished() && !s.stopped() {
        details.extend(s.stuck_report());
    }
    let checked = if s.finished() {
        tcm_trace::check(&trace)
    } else {
        tcm_trace::check_prefix(&trace)
    };
    let trace_violations = match checked {
        Ok(_) => Vec::new(),
        Err(v) => v.iter().map(ToString::to_string).collect(),
    };
    Counterexample {
        summary,
        steps,
        repeats_from: None,
        depends_on_conditions: picks,
        hung: s.hung(),
        details,
        trace,
        trace_violations,
    }
}
