//! Seeded simulation (`tdl sim`): one random run of the program per seed, on virtual time.
//!
//! The run is a walk through the same abstract machine the search explores (`machine.rs`), but
//! instead of taking every transition, each choice is drawn from a ChaCha8 stream of the seed:
//! - each command, when it starts, is given an ending: it succeeds or fails (with one of the
//!   exceptions it may raise, with [`SimOptions::fail`]) after a duration drawn between
//!   [`SimOptions::min_duration`] and [`SimOptions::max_duration`], or, with [`SimOptions::hang`],
//!   runs until it is terminated; a command the [`CommandModel`] knows takes one of the model's
//!   endings;
//! - a condition the checker cannot evaluate takes a way drawn at random;
//! - commands that end at the same moment end in a random order;
//! - each external event is raised up to [`Options::events`] times, each with
//!   [`SimOptions::event_chance`], at a time drawn within [`SimOptions::event_window`] (and, when
//!   nothing else can happen, at once: the run is stuck only when no event is left to raise);
//! - time advances to the next deadline, command end or event.
//!
//! Each run's trace goes through the trace checker and the properties; a failing run is
//! reproduced from its seed alone, with the same trace to the byte.

use std::time::{Duration, Instant};

use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::{RngCore, SeedableRng};
use tcm_core::Time;
use tcm_trace::TraceEvent;

use crate::machine::{Action, Ctx, Fault, State, fmt_secs};
use crate::model::{CommandModel, Ending};
use crate::property::Props;
use crate::{
    Breaks, Builtin, Control, Counterexample, NO_STUCK, NO_UNHANDLED, Options, Program, Property,
    RUNS_END, Status, TRACES_CHECK, check_names,
};

/// What a simulation draws, and its bounds (docs/verification.md, "Seeded simulation").
#[derive(Clone, Debug)]
pub struct SimOptions {
    /// The bounds the runs share with [`crate::verify`]: loops, recursion, the depth (the longest
    /// run, in transitions), commands left running (`hangs`), external events (`events`: how many
    /// times each may be raised), allowed exceptions, unknown exceptions.
    pub bounds: Options,
    /// The shortest duration of a command.
    pub min_duration: Duration,
    /// The longest duration of a command.
    pub max_duration: Duration,
    /// The probability that a command fails (with one of the exceptions it may raise, each as
    /// likely).
    pub fail: f64,
    /// The probability that a command that something may terminate runs until it is.
    pub hang: f64,
    /// The probability of each of an external event's raises.
    pub event_chance: f64,
    /// External events are raised at times drawn from the start of the run to this.
    pub event_window: Duration,
    /// A run still going at this virtual time is reported (`every run ends`).
    pub max_time: Duration,
}

impl Default for SimOptions {
    fn default() -> Self {
        SimOptions {
            bounds: Options::default(),
            min_duration: Duration::ZERO,
            max_duration: Duration::from_secs(10),
            fail: 0.1,
            hang: 0.0,
            event_chance: 0.5,
            event_window: Duration::from_secs(60),
            max_time: Duration::from_secs(3600),
        }
    }
}

/// How one run ended.
#[derive(Debug)]
pub struct SimRun {
    /// Its seed.
    pub seed: u64,
    /// The transitions taken.
    pub transitions: usize,
    /// The virtual time at its end.
    pub end_time: Duration,
    /// The root task completed.
    pub finished: bool,
    /// A bound ended it (not a violation): why.
    pub cut: Option<String>,
    /// The property it broke (as [`SimResult::property`] names it) and how, if any.
    pub violation: Option<(String, Counterexample)>,
    /// A failure of the checker itself on this run.
    pub error: Option<String>,
    /// Stopped from outside (Ctrl-C) before it ended.
    pub interrupted: bool,
    /// Its trace (JSON-lines records, docs/trace-format.md).
    pub trace: Vec<TraceEvent>,
}

impl SimRun {
    /// Writes the trace as JSON lines, as `tdl trace story` reads it.
    pub fn write_trace(&self, w: &mut impl std::io::Write) -> std::io::Result<()> {
        for r in &self.trace {
            tcm_trace::write_line(r, w)?;
        }
        Ok(())
    }
}

/// One property over all the runs.
#[derive(Debug)]
pub struct SimResult {
    /// The property, in words.
    pub property: String,
    /// How many runs broke it.
    pub failures: u64,
    /// The first seeds that broke it (at most 10).
    pub seeds: Vec<u64>,
    /// The first run that broke it: its seed and the run in words, with its trace.
    pub first: Option<(u64, Counterexample)>,
}

/// The result of a simulation.
#[derive(Debug)]
pub struct SimReport {
    /// The task simulated.
    pub task: String,
    /// Runs made.
    pub runs: u64,
    /// Runs where the root task completed.
    pub finished: u64,
    /// Runs a bound ended (loops, recursion), and why for the first.
    pub cut: u64,
    /// See [`SimReport::cut`].
    pub cut_example: Option<String>,
    /// Transitions taken over all runs.
    pub transitions: u64,
    /// The longest run's virtual time.
    pub longest: Duration,
    /// Wall time.
    pub elapsed: Duration,
    /// Stopped from outside (Ctrl-C) before the last seed.
    pub interrupted: bool,
    /// Every property and how the runs went: the built-in ones first.
    pub results: Vec<SimResult>,
    /// What the checker abstracts in this program.
    pub notes: Vec<String>,
    /// Failures of the checker itself, if any (a bug to report).
    pub errors: Vec<String>,
}

impl SimReport {
    /// Whether no run broke a property and nothing broke.
    pub fn ok(&self) -> bool {
        self.results.iter().all(|r| r.failures == 0) && self.errors.is_empty()
    }

    /// Violated if some run broke a property, else error if the input or the checker failed,
    /// else undecided if the runs were interrupted (or none was made), else ok: no run of the
    /// seeds broke a property (a simulation proves nothing beyond its runs).
    pub fn status(&self) -> Status {
        if self.results.iter().any(|r| r.failures > 0) {
            Status::Violated
        } else if !self.errors.is_empty() {
            Status::Error
        } else if self.interrupted || self.runs == 0 {
            Status::Undecided
        } else {
            Status::Ok
        }
    }

    /// The result of the property named `name`.
    pub fn result(&self, name: &str) -> Option<&SimResult> {
        self.results.iter().find(|r| r.property == name)
    }
}

/// Progress of a simulation, for a display.
#[derive(Clone, Copy, Debug, Default)]
pub struct SimProgress {
    /// Runs made.
    pub runs: u64,
    /// Runs to make.
    pub of: u64,
    /// Runs that broke a property.
    pub failures: u64,
    /// Wall time since the start.
    pub elapsed: Duration,
}

/// Runs `program` from `task` once per seed of `seeds`, checking the built-in properties and
/// `properties` on each run; `progress` is called after each run.
#[allow(clippy::too_many_arguments)]
pub fn simulate(
    program: &Program,
    task: &str,
    options: &SimOptions,
    properties: &[Property],
    model: Option<&dyn CommandModel>,
    seeds: std::ops::Range<u64>,
    control: &Control,
    progress: &mut dyn FnMut(&SimProgress),
) -> SimReport {
    let started = Instant::now();
    let mut report = SimReport {
        task: task.to_owned(),
        runs: 0,
        finished: 0,
        cut: 0,
        cut_example: None,
        transitions: 0,
        longest: Duration::ZERO,
        elapsed: Duration::ZERO,
        interrupted: false,
        results: Vec::new(),
        notes: program.notes.clone(),
        errors: Vec::new(),
    };
    if let Err(e) = check_names(program, task, properties) {
        report.errors.push(e.to_string());
        return report;
    }
    let props = match Props::new(properties.to_vec()) {
        Ok(p) => p,
        Err(e) => {
            report.errors.push(e);
            return report;
        }
    };
    let cx = Ctx {
        prog: program,
        opts: &options.bounds,
        model,
        props: &props,
        sim: true,
    };
    let mut names: Vec<String> = Builtin::ALL
        .into_iter()
        .filter(|b| options.bounds.checks(*b))
        .map(|b| b.property().to_owned())
        .collect();
    names.extend(props.list.iter().map(|p| p.text().to_owned()));
    report.results = names
        .into_iter()
        .map(|property| SimResult {
            property,
            failures: 0,
            seeds: Vec::new(),
            first: None,
        })
        .collect();
    let of = seeds.end.saturating_sub(seeds.start);
    let mut failures = 0;
    let mut last = Instant::now();
    for seed in seeds {
        if control.stop.load(std::sync::atomic::Ordering::Relaxed) {
            report.interrupted = true;
            break;
        }
        let run = walk(&cx, task, options, seed, false, control);
        if run.interrupted {
            report.interrupted = true;
            break;
        }
        report.runs += 1;
        report.transitions += run.transitions as u64;
        report.longest = report.longest.max(run.end_time);
        report.finished += u64::from(run.finished);
        if let Some(why) = run.cut {
            report.cut += 1;
            report.cut_example.get_or_insert(why);
        }
        if let Some(e) = run.error {
            if report.errors.len() < 8 {
                report.errors.push(format!("seed {seed}: {e}"));
            }
        }
        if let Some((property, _)) = &run.violation {
            failures += 1;
            if let Some(r) = report.results.iter_mut().find(|r| r.property == *property) {
                r.failures += 1;
                if r.seeds.len() < 10 {
                    r.seeds.push(seed);
                }
                if r.first.is_none() {
                    // Again with each transition in words; the trace must be the same.
                    let again = walk(&cx, task, options, seed, true, control);
                    if again.trace != run.trace {
                        report.errors.push(format!(
                            "seed {seed}: a second run of the seed gave another trace"
                        ));
                    }
                    if let Some((_, c)) = again.violation {
                        r.first = Some((seed, c));
                    }
                }
            }
        }
        if last.elapsed() >= Duration::from_millis(200) {
            last = Instant::now();
            progress(&SimProgress {
                runs: report.runs,
                of,
                failures,
                elapsed: started.elapsed(),
            });
        }
    }
    report.elapsed = started.elapsed();
    progress(&SimProgress {
        runs: report.runs,
        of,
        failures,
        elapsed: report.elapsed,
    });
    report
}

/// Runs `program` from `task` with the seed `seed` alone: the run of [`simulate`] for that seed,
/// with each transition in words (in the counterexample, if the run breaks a property).
pub fn simulate_seed(
    program: &Program,
    task: &str,
    options: &SimOptions,
    properties: &[Property],
    model: Option<&dyn CommandModel>,
    seed: u64,
) -> Result<SimRun, String> {
    check_names(program, task, properties).map_err(|e| e.to_string())?;
    let props = Props::new(properties.to_vec())?;
    let cx = Ctx {
        prog: program,
        opts: &options.bounds,
        model,
        props: &props,
        sim: true,
    };
    Ok(walk(&cx, task, options, seed, true, &Control::default()))
}

/// The seed's random stream.
struct Draw(ChaCha8Rng);

impl Draw {
    /// A number in `0..n` (`n` > 0).
    fn below(&mut self, n: usize) -> usize {
        ((u128::from(self.0.next_u64()) * n as u128) >> 64) as usize
    }

    /// True with probability `p`.
    fn chance(&mut self, p: f64) -> bool {
        ((self.0.next_u64() >> 11) as f64 / (1u64 << 53) as f64) < p
    }

    /// A duration in `lo..=hi`, to the millisecond.
    fn between(&mut self, lo: Duration, hi: Duration) -> Duration {
        let span = hi.saturating_sub(lo).as_millis();
        let span = u64::try_from(span).unwrap_or(u64::MAX - 1);
        lo + Duration::from_millis(self.0.next_u64() % (span + 1))
    }
}

/// One run: the seed's walk through the machine.
fn walk(
    cx: &Ctx<'_>,
    task: &str,
    options: &SimOptions,
    seed: u64,
    describe: bool,
    control: &Control,
) -> SimRun {
    let mut rng = Draw(ChaCha8Rng::seed_from_u64(seed));
    let mut s = State::init(cx, task, true);
    let mut trace: Vec<TraceEvent> = std::mem::take(&mut s.records);
    // The external events' raises, in time order: (time, event); with an environment
    // declaration, its entries' uses instead (an event of the program's numbers, or
    // `ENV + entry`), each drawn among what the entry may do then.
    const ENV: u16 = 1 << 15;
    let mut events: Vec<(Time, u16)> = Vec::new();
    let n_events = cx.prog.external_events.len();
    let draws: Vec<(u16, u32)> = match &cx.prog.environment {
        None => (0..n_events).map(|i| (i as u16, cx.opts.events)).collect(),
        Some(env) => (0..env.len())
            .map(|i| (ENV + i as u16, env[i].at_most))
            .collect(),
    };
    for (i, n) in draws {
        for _ in 0..n {
            if rng.chance(options.event_chance) {
                let at = rng.between(Duration::ZERO, options.event_window);
                events.push((Time::ZERO.saturating_add(at), i));
            }
        }
    }
    events.sort();
    let mut events: std::collections::VecDeque<(Time, u16)> = events.into();
    let mut raised = vec![0u32; n_events];
    let mut steps: Vec<String> = Vec::new();
    let mut picks = false;
    let mut actions: Vec<Action> = Vec::new();
    let mut transitions = 0usize;
    let mut too_long: Option<String> = None;
    let max_time = Time::ZERO.saturating_add(options.max_time);
    loop {
        if s.stopped() || control.stop.load(std::sync::atomic::Ordering::Relaxed) {
            break;
        }
        // Endings for the commands that started.
        for u in s.undrawn(cx) {
            let ending = match &u.endings {
                Some(list) if !list.is_empty() => list[rng.below(list.len())].clone(),
                _ => {
                    let d = rng.between(options.min_duration, options.max_duration);
                    if u.may_hang && rng.chance(options.hang) {
                        Ending::Never
                    } else if !u.raises.is_empty() && rng.chance(options.fail) {
                        Ending::Fails(u.raises[rng.below(u.raises.len())].to_owned(), d)
                    } else {
                        Ending::Succeeds(d)
                    }
                }
            };
            s.draw(u.node, ending);
        }
        if s.finished() {
            break;
        }
        s.actions(cx, &mut actions);
        // Raises and the environment's changes are the walk's to schedule, not choices to draw.
        let env_now: Vec<Action> = actions
            .iter()
            .filter(|a| matches!(a, Action::Env { .. }))
            .cloned()
            .collect();
        actions.retain(|a| !matches!(a, Action::Raise(_) | Action::Env { .. }));
        if actions.is_empty() && events.is_empty() {
            // Nothing can happen: an event not raised yet comes now, if any is left (with an
            // environment declaration, what it may still do).
            if cx.prog.environment.is_some() {
                match env_now.first() {
                    Some(Action::Env { entry, .. }) if !s.finished() => {
                        events.push_back((s.engine.now(), ENV + *entry))
                    }
                    _ => break,
                }
            } else {
                match (0..n_events).find(|i| raised[*i] < cx.opts.events) {
                    Some(i) if !s.finished() => events.push_back((s.engine.now(), i as u16)),
                    _ => break,
                }
            }
        }
        if transitions >= cx.opts.depth as usize {
            too_long = Some(format!(
                "the run is still going after {} transitions (--depth)",
                cx.opts.depth
            ));
            break;
        }
        let action = if actions.iter().any(|a| matches!(a, Action::Pick(_))) {
            actions[rng.below(actions.len())].clone()
        } else {
            let due: Vec<&Action> = actions
                .iter()
                .filter(|a| matches!(a, Action::End { .. }))
                .collect();
            if !due.is_empty() {
                due[rng.below(due.len())].clone()
            } else {
                let tick = actions
                    .contains(&Action::Tick)
                    .then(|| s.next_tick())
                    .flatten();
                match (events.front().copied(), tick) {
                    // An event before the next deadline (one at the same time comes after it).
                    (Some((at, i)), t) if t.is_none_or(|t| at < t) => {
                        events.pop_front();
                        if at > s.engine.now() {
                            s.engine.handle_timeout(at);
                        }
                        if i >= ENV {
                            // What the entry may do now (its condition, its uses left, the
                            // values other than the current one), drawn.
                            let mut can: Vec<Action> = Vec::new();
                            s.actions(cx, &mut can);
                            can.retain(
                                |a| matches!(a, Action::Env { entry, .. } if *entry == i - ENV),
                            );
                            if can.is_empty() {
                                continue;
                            }
                            can.swap_remove(rng.below(can.len()))
                        } else {
                            if raised[i as usize] >= cx.opts.events {
                                continue;
                            }
                            raised[i as usize] += 1;
                            Action::Raise(i)
                        }
                    }
                    (_, Some(_)) => Action::Tick,
                    // A run the search would call stuck: nothing is due and no time can pass.
                    (_, None) => break,
                }
            }
        };
        if let Action::Tick = action {
            if s.next_tick().is_some_and(|t| t > max_time) {
                too_long = Some(format!(
                    "the run is still going at {} of virtual time (--max-time)",
                    fmt_secs(max_time)
                ));
                break;
            }
        }
        picks |= matches!(action, Action::Pick(_));
        if describe {
            let words = s.describe(cx, &action);
            steps.push(format!("[{}] {words}", fmt_secs(s.engine.now())));
        }
        s = s.step_owned(cx, &action);
        trace.append(&mut s.records);
        transitions += 1;
    }
    let finished = s.finished();
    let stopped_outside = !s.stopped()
        && !finished
        && too_long.is_none()
        && control.stop.load(std::sync::atomic::Ordering::Relaxed);
    let checked = if finished {
        tcm_trace::check(&trace)
    } else {
        tcm_trace::check_prefix(&trace)
    };
    let complaint = crate::failing::first_complaint(&checked);
    let trace_violations: Vec<String> = match checked {
        Ok(_) => Vec::new(),
        Err(v) => v.iter().map(ToString::to_string).collect(),
    };
    let mut details = Vec::new();
    let checks = |b: Builtin| cx.opts.checks(b);
    // A run `every run ends` is not checked on ends at the bound, as a run cut by one.
    let mut cut = s.cut.clone();
    // Waiting on the outside, which has used up what its declaration allows: the run is not
    // stuck (as in the search), it ends there, counted with the runs a bound ended.
    if !finished && cut.is_none() && s.fault.is_none() {
        cut = s.held_by_environment(cx);
    }
    if !checks(Builtin::RunsEnd) {
        if let Some(why) = too_long.take() {
            cut.get_or_insert(why);
        }
    }
    // The property broken, how, and where the run breaks it (`Breaks::AtEnd` unless said).
    let mut breaks = Breaks::AtEnd;
    let violation: Option<(&str, String)> = if let Some(Fault::Unhandled { exception, path }) =
        s.fault.as_ref().filter(|_| checks(Builtin::NoUnhandled))
    {
        details.push(format!(
            "{exception} raised at {path} is taken by no handler"
        ));
        breaks = crate::failing::unhandled(&s);
        Some((NO_UNHANDLED, "a failure no handler takes".into()))
    } else if let Some(k) = s.broken {
        let text = cx.props.list[k].text();
        Some((text, format!("`{text}` is broken")))
    } else if let Some(why) = too_long.take() {
        details.push(why);
        Some((RUNS_END, "a run that does not end within the bounds".into()))
    } else if stopped_outside || cut.is_some() || s.error.is_some() {
        None
    } else if !finished && s.fault.is_none() && checks(Builtin::NoStuck) {
        details.extend(s.stuck_report());
        Some((
            NO_STUCK,
            "stuck: nothing can happen any more, and the task has not completed".into(),
        ))
    } else if let Some(k) = s.watch.as_ref().and_then(|w| cx.props.at_end(w)) {
        let text = cx.props.list[k].text();
        Some((
            text,
            format!("`{text}` is broken: the run ended without it"),
        ))
    } else if !trace_violations.is_empty() && checks(Builtin::TracesCheck) {
        breaks = complaint.map_or(Breaks::AtEnd, |seq| Breaks::TraceChecker { seq });
        Some((
            TRACES_CHECK,
            "the trace checker rejects the trace of the run".into(),
        ))
    } else {
        None
    };
    let violation = violation.map(|(property, summary)| {
        (
            property.to_owned(),
            Counterexample {
                summary,
                steps: std::mem::take(&mut steps),
                repeats_from: None,
                depends_on_conditions: picks,
                hung: s.hung(),
                details,
                trace: trace.clone(),
                trace_violations: trace_violations.clone(),
                breaks,
            },
        )
    });
    SimRun {
        seed,
        transitions,
        end_time: s.engine.now().since_start(),
        finished,
        cut,
        violation,
        error: s.error.clone(),
        interrupted: stopped_outside,
        trace,
    }
}
