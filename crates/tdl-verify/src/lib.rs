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
//! - counterexamples rebuilt by replay with tracing on, checked by `tcm_trace::check` (here),
//!   each with the record of its trace at which it breaks its property (`failing.rs`,
//!   [`Counterexample::failing_seq`]);
//! - the seeded simulation (`sim.rs`, [`simulate`], `tdl sim`): instead of the search, one walk
//!   through the machine per seed, each choice drawn from the seed's random stream, commands given
//!   random durations and outcomes, every run's trace checked.

#![warn(missing_docs)]

mod failing;
mod ir;
mod machine;
mod memory;
mod model;
mod names;
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

pub use failing::Breaks;
pub use memory::{default_max_memory, fmt_bytes, parse_size};
pub use model::{Arg, CommandModel, Ending};
pub use names::{UnknownName, check_names};
pub use program::{LoadError, Program};
pub use property::{Property, PropertyError};
pub use search::Progress;
pub use sim::{SimOptions, SimProgress, SimReport, SimResult, SimRun, simulate, simulate_seed};
use tcm_trace::TraceEvent;

use machine::{Action, Ctx, State};
use property::Props;
use search::{Found, Key, path_to};

/// The exception a command of Rust may raise beyond those the program declares, with
/// [`Options::unknown_exception`].
pub const UNKNOWN_EXCEPTION: &str = "UnknownException";

/// The exception a task placed on an agent (`on`) may also fail with: its agent was lost while it
/// ran the task (`tcm_zenoh::AgentLost`).
pub const AGENT_LOST: &str = "AgentLost";

/// The bounds and choices of a verification (docs/verification.md, "Bounds, memory, and a search
/// cut short").
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
    /// The most memory the search may use, in bytes, before it stops (incomplete): the process's
    /// resident set where the system says (Linux), else an estimate of the state store
    /// (docs/verification.md, "Bounds, memory, and a search cut short"). Default:
    /// [`default_max_memory`], half of the machine's.
    pub max_memory: u64,
    /// Built-in properties not checked (e.g. [`Builtin::RunsEnd`] for a program meant to run
    /// until it is shut down).
    pub unchecked: Vec<Builtin>,
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
    /// Faults injected from the start of every run (docs/semantics.md, "Steering a run", rule 4):
    /// the nodes they match end as they say, and only that way (`--faults FILE`).
    pub faults: Vec<tcm_core::Fault>,
}

impl Options {
    /// Whether the built-in property `b` is checked.
    pub fn checks(&self, b: Builtin) -> bool {
        !self.unchecked.contains(&b)
    }
}

/// A built-in property, each of which can be left unchecked ([`Options::unchecked`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Builtin {
    /// [`NO_STUCK`].
    NoStuck,
    /// [`NO_UNHANDLED`].
    NoUnhandled,
    /// [`RUNS_END`].
    RunsEnd,
    /// [`TRACES_CHECK`].
    TracesCheck,
}

impl Builtin {
    /// Every built-in property, in the order of a report.
    pub const ALL: [Builtin; 4] = [
        Builtin::NoStuck,
        Builtin::NoUnhandled,
        Builtin::RunsEnd,
        Builtin::TracesCheck,
    ];

    /// The property's name in a report ([`PropertyResult::property`]).
    pub fn property(self) -> &'static str {
        match self {
            Builtin::NoStuck => NO_STUCK,
            Builtin::NoUnhandled => NO_UNHANDLED,
            Builtin::RunsEnd => RUNS_END,
            Builtin::TracesCheck => TRACES_CHECK,
        }
    }

    /// Its name on a command line: `no-stuck-state`, `no-unhandled-exception`, `every-run-ends`,
    /// `trace-checker`.
    pub fn id(self) -> &'static str {
        match self {
            Builtin::NoStuck => "no-stuck-state",
            Builtin::NoUnhandled => "no-unhandled-exception",
            Builtin::RunsEnd => "every-run-ends",
            Builtin::TracesCheck => "trace-checker",
        }
    }

    /// The built-in property of a command-line name ([`Builtin::id`]).
    pub fn from_id(id: &str) -> Option<Builtin> {
        Builtin::ALL.into_iter().find(|b| b.id() == id)
    }
}

/// What made a search incomplete: its properties not broken are then undecided.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cut {
    /// Stopped from outside ([`Control::stop`], Ctrl-C).
    Interrupted,
    /// [`Options::max_states`] distinct states were reached.
    MaxStates(u64),
    /// The memory in use reached [`Options::max_memory`].
    MaxMemory {
        /// The memory in use, in bytes, when the search stopped.
        used: u64,
        /// The bound.
        limit: u64,
    },
    /// Some run was still going at [`Options::depth`] transitions (the search went on with the
    /// others).
    Depth(u32),
}

impl std::fmt::Display for Cut {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Cut::Interrupted => write!(f, "the search was interrupted"),
            Cut::MaxStates(n) => write!(
                f,
                "the search stopped at the bound of {n} distinct states (--max-states)"
            ),
            Cut::MaxMemory { used, limit } => write!(
                f,
                "the search stopped at the memory bound of {} ({} in use; --max-memory)",
                fmt_bytes(*limit),
                fmt_bytes(*used)
            ),
            Cut::Depth(n) => write!(
                f,
                "a run was still going at the bound of {n} transitions (--depth)"
            ),
        }
    }
}

/// The outcome of a verification as a whole, for a shell or a CI step (docs/verification.md,
/// "Exit status").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Status {
    /// Every property checked was decided and holds within the bounds.
    Ok,
    /// Some property is broken.
    Violated,
    /// Nothing is broken, but some property was not decided (a bound cut the search, it was
    /// interrupted, or liveness on a graph with a cycle).
    Undecided,
    /// The input or the checker failed: nothing can be concluded.
    Error,
}

impl Status {
    /// The exit status of `tdl verify` and `tdl sim`: 0 ok, 1 violated, 2 error, 3 undecided.
    pub fn code(self) -> u8 {
        match self {
            Status::Ok => 0,
            Status::Violated => 1,
            Status::Error => 2,
            Status::Undecided => 3,
        }
    }
}

impl Default for Options {
    fn default() -> Self {
        Options {
            loops: 2,
            recursion: 1,
            depth: 10_000,
            max_states: 20_000_000,
            max_memory: default_max_memory(),
            unchecked: Vec::new(),
            ticks: 1,
            events: 1,
            hangs: 1,
            allowed: Vec::new(),
            unknown_exception: false,
            samples: 16,
            faults: Vec::new(),
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
    /// What the path ends on, for the record at which the property is broken
    /// ([`Counterexample::failing_seq`]).
    pub breaks: Breaks,
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
    /// What made the search incomplete (empty when it is complete).
    pub cuts: Vec<Cut>,
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

    /// Violated if some property is broken, else error if the checker failed, else undecided if
    /// some property was not decided, else ok.
    pub fn status(&self) -> Status {
        if self.results.iter().any(PropertyResult::is_violated) {
            Status::Violated
        } else if !self.errors.is_empty() {
            Status::Error
        } else if self.interrupted
            || self
                .results
                .iter()
                .any(|r| matches!(r.verdict, Verdict::Unknown(_)))
        {
            Status::Undecided
        } else {
            Status::Ok
        }
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
    verify_observed(
        program,
        task,
        options,
        properties,
        model,
        control,
        progress,
        &mut |_| {},
    )
}

/// [`verify_with_progress`], also calling `violated` with each property broken as soon as its
/// counterexample is found (during the search: a search cut short later, or a process killed,
/// keeps it), before the report gives it again.
#[allow(clippy::too_many_arguments)]
pub fn verify_observed(
    program: &Program,
    task: &str,
    options: &Options,
    properties: &[Property],
    model: Option<&dyn CommandModel>,
    control: &Control,
    progress: &mut dyn FnMut(&Progress),
    violated: &mut dyn FnMut(&PropertyResult),
) -> Report {
    let failed = |e: String| Report {
        task: task.to_owned(),
        explored: 0,
        unique: 0,
        depth: 0,
        elapsed: Duration::ZERO,
        complete: false,
        interrupted: false,
        cuts: Vec::new(),
        cut: 0,
        cut_example: None,
        ended: 0,
        traces_checked: 0,
        results: Vec::new(),
        notes: Vec::new(),
        errors: vec![e],
    };
    if let Err(e) = check_names(program, task, properties) {
        return failed(e.to_string());
    }
    let props = match Props::new(properties.to_vec()) {
        Ok(p) => p,
        Err(e) => return failed(e),
    };
    let cx = Ctx {
        prog: program,
        opts: options,
        model,
        props: &props,
        sim: false,
    };
    let traces = options.checks(Builtin::TracesCheck);
    // The violations, in the order found, each reported at once.
    let mut found: Vec<(Key, PropertyResult)> = Vec::new();
    let mut traces_checked = 0;
    let out = search::run(&cx, task, &control.stop, progress, &mut |f, seen| {
        let key = f.property();
        let (property, summary) = match key {
            Key::Builtin(Builtin::NoStuck) => (
                NO_STUCK.to_owned(),
                "stuck: nothing can happen any more, and the task has not completed".to_owned(),
            ),
            Key::Builtin(Builtin::NoUnhandled) => {
                (NO_UNHANDLED.to_owned(), "a failure no handler takes".into())
            }
            Key::Builtin(b) => (
                b.property().to_owned(),
                "a run that never ends: the last transitions repeat forever".into(),
            ),
            Key::User(k) => {
                let text = props.list[k].text();
                (text.to_owned(), format!("`{text}` is broken"))
            }
        };
        let (path, repeats_from) = match f {
            Found::Stuck(id)
            | Found::Unhandled(id)
            | Found::User(_, id)
            | Found::NotEventually(_, id) => (path_to(seen, *id), None),
            Found::Cycle { entry, cycle } => {
                let mut p = path_to(seen, *entry);
                let from = p.len();
                p.extend(cycle.iter().copied());
                (p, Some(from))
            }
        };
        let unhandled = matches!(f, Found::Unhandled(_));
        let (c, complaint) = replay(&cx, task, &path, summary, repeats_from, unhandled);
        traces_checked += 1;
        let bad_trace = traces
            && !c.trace_violations.is_empty()
            && !found
                .iter()
                .any(|(k, _)| *k == Key::Builtin(Builtin::TracesCheck));
        let first = c.summary.clone();
        let result = PropertyResult {
            property,
            verdict: Verdict::Violated(Box::new(c)),
        };
        violated(&result);
        if bad_trace {
            if let Verdict::Violated(c) = &result.verdict {
                let mut c = c.clone();
                c.summary = format!("the trace checker rejects the trace of {first}");
                c.breaks = complaint.map_or(Breaks::AtEnd, |seq| Breaks::TraceChecker { seq });
                let r = PropertyResult {
                    property: TRACES_CHECK.into(),
                    verdict: Verdict::Violated(c),
                };
                violated(&r);
                found.push((Key::Builtin(Builtin::TracesCheck), r));
            }
        }
        found.push((key, result));
    });
    let undecided = |out: &search::Outcome| {
        let why: Vec<String> = out.cuts.iter().map(ToString::to_string).collect();
        format!("not decided: {}", why.join("; "))
    };
    // Sampled runs through the trace checker.
    if traces {
        for id in &out.samples {
            let path = path_to(&out.seen, *id);
            let (mut c, complaint) = replay(&cx, task, &path, "a sampled run".into(), None, false);
            traces_checked += 1;
            let first = !found
                .iter()
                .any(|(k, _)| *k == Key::Builtin(Builtin::TracesCheck));
            if !c.trace_violations.is_empty() && first {
                c.summary = format!("the trace checker rejects the trace of {}", c.summary);
                c.breaks = complaint.map_or(Breaks::AtEnd, |seq| Breaks::TraceChecker { seq });
                let r = PropertyResult {
                    property: TRACES_CHECK.into(),
                    verdict: Verdict::Violated(Box::new(c)),
                };
                violated(&r);
                found.push((Key::Builtin(Builtin::TracesCheck), r));
            }
        }
    }
    let mut take = |key: Key| {
        found
            .iter()
            .position(|(k, _)| *k == key)
            .map(|i| found.remove(i).1.verdict)
    };
    let mut results: Vec<PropertyResult> = Vec::new();
    for b in Builtin::ALL {
        if !options.checks(b) {
            continue;
        }
        let verdict = match take(Key::Builtin(b)) {
            Some(v) => v,
            None if out.complete || b == Builtin::TracesCheck => Verdict::Holds,
            None => Verdict::Unknown(undecided(&out)),
        };
        results.push(PropertyResult {
            property: b.property().into(),
            verdict,
        });
    }
    for (k, p) in props.list.iter().enumerate() {
        let verdict = match take(Key::User(k)) {
            Some(v) => v,
            None if p.is_liveness() && out.cyclic => Verdict::Unknown(format!(
                "refused: the state graph has a cycle (a run that never ends), on which `eventually` cannot be decided soundly{}",
                if options.checks(Builtin::RunsEnd) {
                    "; fix `every run ends` first"
                } else {
                    ""
                }
            )),
            None if out.complete => Verdict::Holds,
            None => Verdict::Unknown(undecided(&out)),
        };
        results.push(PropertyResult {
            property: p.text().to_owned(),
            verdict,
        });
    }
    Report {
        task: task.to_owned(),
        explored: out.progress.explored,
        unique: out.progress.unique,
        depth: out.progress.depth,
        elapsed: out.progress.elapsed,
        complete: out.complete,
        interrupted: out.interrupted,
        cuts: out.cuts.clone(),
        cut: out.cut,
        cut_example: out.cut_example.clone(),
        ended: out.ended,
        traces_checked,
        results,
        notes: program.notes.clone(),
        errors: out.errors.clone(),
    }
}

/// Replays `path` from the first state with tracing on: the counterexample, and the `seq` of the
/// first record the trace checker complains about, if it does. Its last transitions repeat
/// forever from the one numbered `repeats_from`, if given; with `unhandled`, the path ends on a
/// failure no handler takes.
fn replay(
    cx: &Ctx<'_>,
    task: &str,
    path: &[u16],
    summary: String,
    repeats_from: Option<usize>,
    unhandled: bool,
) -> (Counterexample, Option<u64>) {
    let mut s = State::init(cx, task, true);
    let mut trace: Vec<TraceEvent> = std::mem::take(&mut s.records);
    let mut steps = Vec::new();
    let mut picks = false;
    let mut actions: Vec<Action> = Vec::new();
    // Where the repeating part's records start.
    let mut repeats_at = None;
    for (step, &i) in path.iter().enumerate() {
        if repeats_from == Some(step) {
            repeats_at = Some(trace.len());
        }
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
    let complaint = failing::first_complaint(&checked);
    let trace_violations = match checked {
        Ok(_) => Vec::new(),
        Err(v) => v.iter().map(ToString::to_string).collect(),
    };
    let breaks = match repeats_from {
        Some(_) => Breaks::Repeats {
            record: repeats_at.unwrap_or(trace.len()),
        },
        None if unhandled => failing::unhandled(&s),
        None => Breaks::AtEnd,
    };
    let c = Counterexample {
        summary,
        steps,
        repeats_from,
        depends_on_conditions: picks,
        hung: s.hung(),
        details,
        trace,
        trace_violations,
        breaks,
    };
    (c, complaint)
}
