//! `tdl sim`: runs a TDL program many times on virtual time, one seeded random run per seed, and
//! checks every run (the `tdl-verify` crate's `simulate`; docs/verification.md, "Seeded
//! simulation: tdl sim").
//!
//! The program is given as to `tdl verify` (files, or `-p CRATE`). `--seeds N` runs the seeds
//! `--from` to `--from + N - 1`; `--seed S` runs that seed alone. The first run that breaks each
//! property is printed in words, its trace written under `--out` (`tdl trace story FILE` replays
//! it, and `tdl view FILE --at SEQ` opens it on the record where the property is broken), with
//! the command line that runs its seed again; a seed gives the same run, and the same
//! trace file, every time. Progress goes to standard error: a bar on a terminal (`indicatif`), a
//! plain line every second otherwise. Ctrl-C stops after the current run and prints what was
//! found so far (a second one exits at once). Exit status ([`EXIT_STATUS`]), as `tdl verify`'s:
//! 0 no run broke a property, 1 one did, 3 the runs were interrupted (or none was made) and none
//! broke one, 2 an error (bad input, the program has errors, I/O, a checker failure).

use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use tdl_verify::{Builtin, Control, Options, SimOptions, SimProgress, SimReport};

use crate::verify::{
    builtin, finish, hide_notes, load_program, load_properties, print_counterexample,
    print_errors_and_notes, print_hidden, print_unchecked, slug, stop_on_ctrl_c, write_trace,
};

/// The exit statuses of `tdl sim`, as `--help` gives them.
const EXIT_STATUS: &str = "Exit status (for CI), as tdl verify's:
  0  ok: no run of the seeds broke a property (a simulation proves nothing beyond its runs)
  1  violated: some run broke a property
  3  undecided: Ctrl-C stopped the runs (or none was made), and none broke a property
  2  error: bad input (options, a property that does not parse or names no node, a program with
     errors), I/O, or a failure of the checker itself";

/// Options of `tdl sim`.
#[derive(clap::Args)]
#[command(after_help = EXIT_STATUS)]
pub(crate) struct Args {
    /// The `.tdl` files of the program, checked as one program.
    #[arg(required_unless_present = "package", conflicts_with = "package")]
    files: Vec<PathBuf>,
    /// Simulate the TDL program of this crate of the workspace (its `src/**/*.tdl`).
    #[arg(short = 'p', long = "package", value_name = "CRATE")]
    package: Option<String>,
    /// The task to start from (default: the only goal no task of the program spawns).
    #[arg(long)]
    task: Option<String>,
    /// How many runs: the seeds `--from` to `--from + N - 1`.
    #[arg(long, value_name = "N", default_value_t = 100, conflicts_with = "seed")]
    seeds: u64,
    /// The first seed of `--seeds`.
    #[arg(long, value_name = "S", default_value_t = 0, conflicts_with = "seed")]
    from: u64,
    /// Run this seed alone (to reproduce a failing run).
    #[arg(long, value_name = "S")]
    seed: Option<u64>,
    /// The shortest duration of a command, in seconds.
    #[arg(long, value_name = "SECONDS", default_value_t = 0.0)]
    min_duration: f64,
    /// The longest duration of a command, in seconds.
    #[arg(long, value_name = "SECONDS", default_value_t = 10.0)]
    max_duration: f64,
    /// The probability that a command fails (with one of the exceptions it may raise).
    #[arg(long, value_name = "P", default_value_t = 0.1)]
    fail: f64,
    /// The probability that a command something may terminate runs until it is (at most
    /// `--hangs` per run).
    #[arg(long, value_name = "P", default_value_t = 0.0)]
    hang: f64,
    /// The probability of each raise of an external event (at most `--events` per event).
    #[arg(long, value_name = "P", default_value_t = 0.5)]
    event_chance: f64,
    /// External events are raised at times drawn from 0 to this, in seconds.
    #[arg(long, value_name = "SECONDS", default_value_t = 60.0)]
    event_window: f64,
    /// A run still going at this virtual time is reported, in seconds.
    #[arg(long, value_name = "SECONDS", default_value_t = 3600.0)]
    max_time: f64,
    /// A loop over a collection the checker cannot see runs 0 to this many times [default: 2].
    #[arg(long, value_name = "K")]
    loops: Option<u32>,
    /// Instances of one task nested on a branch of the tree; one more is a command, and the run
    /// ends beyond that [default: 1].
    #[arg(long, value_name = "R")]
    recursion: Option<u32>,
    /// Times each external event may be raised [default: 1].
    #[arg(long, value_name = "N")]
    events: Option<u32>,
    /// Commands per run that may be left running until terminated [default: 1].
    #[arg(long, value_name = "N")]
    hangs: Option<u32>,
    /// The longest run, in transitions [default: 10000].
    #[arg(long, value_name = "N")]
    depth: Option<u32>,
    /// An exception allowed to go unhandled (repeat, or separate with commas).
    #[arg(long = "allow", value_name = "EXCEPTION", value_delimiter = ',')]
    allow: Vec<String>,
    /// Commands written in Rust may also fail with an exception nobody declares.
    #[arg(long)]
    unknown_exception: bool,
    /// Inject the faults of this file into every run: the nodes they match end as they say
    /// (docs/tools.md, "Steering `tdl run` from its terminal", for the format).
    #[arg(long, value_name = "FILE")]
    faults: Option<std::path::PathBuf>,
    /// A built-in property not to check (repeat, or separate with commas), as for `tdl verify`:
    /// no-stuck-state, no-unhandled-exception, every-run-ends (a run going on past `--depth` or
    /// `--max-time` then ends at a bound), trace-checker.
    #[arg(long = "no-builtin", value_name = "PROPERTY", value_delimiter = ',', value_parser = builtin)]
    no_builtin: Vec<Builtin>,
    /// A property to check besides the built-in ones (repeat), as for `tdl verify`.
    #[arg(short = 'P', long = "property", value_name = "PROPERTY")]
    property: Vec<String>,
    /// A file of properties, one per line (`#` comments).
    #[arg(long = "properties", value_name = "FILE")]
    properties: Option<PathBuf>,
    /// Where the traces of failing runs are written.
    #[arg(long, value_name = "DIR", default_value = "target/tdl-sim")]
    out: PathBuf,
    /// Do not print the notes on what the checker abstracts, only how many there are, as for
    /// `tdl verify`.
    #[arg(short, long)]
    quiet: bool,
}

/// Runs `tdl sim`: as [`crate::verify::run`] ([`EXIT_STATUS`]).
pub(crate) fn run(args: Args, out: &mut impl Write) -> anyhow::Result<u8> {
    let options = options(&args)?;
    let (files, program) = load_program(&args.files, args.package.as_deref(), out)?;
    let task = program.root_task(args.task.as_deref())?;
    let properties = load_properties(&args.property, args.properties.as_deref())?;
    tdl_verify::check_names(&program, &task, &properties)?;
    let seeds = match args.seed {
        Some(s) => s..s.saturating_add(1),
        None => args.from..args.from.saturating_add(args.seeds),
    };
    let b = &options.bounds;
    writeln!(
        out,
        "simulating `{task}` of {} (seeds {}..{}; durations {} to {} s, failures {}, events {} within {} s, loops {}, recursion {}, hangs {} with {}, depth {}, max time {} s)",
        files
            .iter()
            .map(|f| f.display().to_string())
            .collect::<Vec<_>>()
            .join(", "),
        seeds.start,
        seeds.end,
        args.min_duration,
        args.max_duration,
        args.fail,
        args.event_chance,
        args.event_window,
        b.loops,
        b.recursion,
        b.hangs,
        args.hang,
        b.depth,
        args.max_time
    )?;
    print_unchecked(b, out)?;
    out.flush()?;
    let control = Arc::new(Control::default());
    stop_on_ctrl_c(&control);
    let report = {
        let mut display = Display::new(seeds.end - seeds.start);
        tdl_verify::simulate(
            &program,
            &task,
            &options,
            &properties,
            None,
            seeds,
            &control,
            &mut |p| display.update(p),
        )
    };
    let mut report = report;
    let hidden = hide_notes(args.quiet, &mut report.notes);
    print_report(&report, &args.out, out)?;
    print_hidden(hidden, out)?;
    finish(report.status(), true, out)
}

fn seconds(what: &str, s: f64) -> anyhow::Result<Duration> {
    Duration::try_from_secs_f64(s).map_err(|_| anyhow::anyhow!("--{what}: {s} is not a duration"))
}

fn probability(what: &str, p: f64) -> anyhow::Result<f64> {
    if (0.0..=1.0).contains(&p) {
        Ok(p)
    } else {
        anyhow::bail!("--{what}: {p} is not a probability (0 to 1)")
    }
}

fn options(args: &Args) -> anyhow::Result<SimOptions> {
    let d = Options::default();
    let min_duration = seconds("min-duration", args.min_duration)?;
    let max_duration = seconds("max-duration", args.max_duration)?;
    if min_duration > max_duration {
        anyhow::bail!("--min-duration is longer than --max-duration");
    }
    Ok(SimOptions {
        bounds: Options {
            loops: args.loops.unwrap_or(d.loops),
            recursion: args.recursion.unwrap_or(d.recursion),
            depth: args.depth.unwrap_or(d.depth),
            events: args.events.unwrap_or(d.events),
            hangs: args.hangs.unwrap_or(d.hangs),
            allowed: args.allow.clone(),
            unknown_exception: args.unknown_exception,
            unchecked: args.no_builtin.clone(),
            faults: match &args.faults {
                Some(path) => tdl::read_faults(path)?,
                None => Vec::new(),
            },
            ..d
        },
        min_duration,
        max_duration,
        fail: probability("fail", args.fail)?,
        hang: probability("hang", args.hang)?,
        event_chance: probability("event-chance", args.event_chance)?,
        event_window: seconds("event-window", args.event_window)?,
        max_time: seconds("max-time", args.max_time)?,
    })
}

/// Progress on standard error: a bar on a terminal, a line a second otherwise.
struct Display {
    bar: Option<indicatif::ProgressBar>,
    last: Instant,
}

impl Display {
    fn new(of: u64) -> Display {
        let bar = std::io::stderr().is_terminal().then(|| {
            let bar = indicatif::ProgressBar::new(of);
            if let Ok(style) = indicatif::ProgressStyle::with_template(
                "{bar:30} {pos}/{len} runs, {msg} (Ctrl-C stops)",
            ) {
                bar.set_style(style);
            }
            bar.enable_steady_tick(Duration::from_millis(120));
            bar
        });
        Display {
            bar,
            last: Instant::now(),
        }
    }

    fn update(&mut self, p: &SimProgress) {
        let rate = p.runs as f64 / p.elapsed.as_secs_f64().max(1e-9);
        let msg = format!(
            "{} failing, {rate:.0} runs/s, {:.0} s",
            p.failures,
            p.elapsed.as_secs_f64()
        );
        match &self.bar {
            Some(bar) => {
                bar.set_position(p.runs);
                bar.set_message(msg);
            }
            None => {
                if self.last.elapsed() >= Duration::from_secs(1) {
                    self.last = Instant::now();
                    eprintln!("tdl sim: {}/{} runs, {msg}", p.runs, p.of);
                }
            }
        }
    }
}

impl Drop for Display {
    fn drop(&mut self) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
    }
}

/// Quotes a word for a POSIX shell when it needs it.
pub(crate) fn shell_word(w: &str) -> String {
    let plain = !w.is_empty()
        && w.chars()
            .all(|c| c.is_ascii_alphanumeric() || "-_./=:,+@%".contains(c));
    if plain {
        w.to_owned()
    } else {
        format!("'{}'", w.replace('\'', r"'\''"))
    }
}

/// The command line that runs `seed` alone: this one without its seed options, and `--seed S`.
fn reproduce(seed: u64) -> String {
    let mut words = vec!["tdl".to_owned()];
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        if ["--seeds", "--seed", "--from"].contains(&a.as_str()) {
            args.next();
            continue;
        }
        if ["--seeds=", "--seed=", "--from="]
            .iter()
            .any(|p| a.starts_with(p))
        {
            continue;
        }
        words.push(shell_word(&a));
    }
    words.push("--seed".into());
    words.push(seed.to_string());
    words.join(" ")
}

fn print_report(report: &SimReport, dir: &Path, out: &mut impl Write) -> anyhow::Result<()> {
    writeln!(
        out,
        "{} runs ({} ended, {} ended at a bound), {} transitions, the longest {:.3} s of virtual time; {:.2} s",
        report.runs,
        report.finished,
        report.cut,
        report.transitions,
        report.longest.as_secs_f64(),
        report.elapsed.as_secs_f64()
    )?;
    if report.interrupted {
        writeln!(out, "interrupted: what was found so far")?;
    }
    if let Some(c) = &report.cut_example {
        writeln!(out, "a run ended at a bound, e.g. {c}")?;
    }
    for r in &report.results {
        if r.failures == 0 {
            writeln!(out, "  ok         {}", r.property)?;
            continue;
        }
        let seeds: Vec<String> = r.seeds.iter().map(ToString::to_string).collect();
        writeln!(
            out,
            "  VIOLATED   {}: in {} of {} runs (seeds {}{})",
            r.property,
            r.failures,
            report.runs,
            seeds.join(", "),
            if r.failures as usize > r.seeds.len() {
                ", …"
            } else {
                ""
            }
        )?;
        if let Some((seed, c)) = &r.first {
            writeln!(out, "             seed {seed}: {}", c.summary)?;
            writeln!(out, "             reproduce: {}", reproduce(*seed))?;
            let file = dir.join(slug(&format!("{}-seed-{seed}", report.task), &r.property));
            write_trace(c, &file)?;
            print_counterexample(c, &file, out)?;
        }
    }
    print_errors_and_notes(&report.errors, &report.notes, out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn words_are_quoted_for_the_shell_when_they_need_it() {
        assert_eq!(shell_word("-p"), "-p");
        assert_eq!(shell_word("crates/x.tdl"), "crates/x.tdl");
        assert_eq!(
            shell_word("never active(a) and active(b)"),
            "'never active(a) and active(b)'"
        );
        assert_eq!(shell_word("it's"), r"'it'\''s'");
    }

    /// The help text writes the defaults out; they must be the library's.
    #[test]
    fn the_defaults_in_the_help_are_the_librarys() {
        use clap::Parser;
        #[derive(clap::Parser)]
        struct Cli {
            #[command(flatten)]
            args: Args,
        }
        let cli = Cli::parse_from(["tdl", "x.tdl"]);
        let o = options(&cli.args).expect("the defaults are valid");
        let d = SimOptions::default();
        assert_eq!(
            (o.min_duration, o.max_duration, o.event_window, o.max_time),
            (d.min_duration, d.max_duration, d.event_window, d.max_time)
        );
        assert_eq!(
            (o.fail, o.hang, o.event_chance),
            (d.fail, d.hang, d.event_chance)
        );
        assert_eq!(
            (
                o.bounds.loops,
                o.bounds.recursion,
                o.bounds.events,
                o.bounds.hangs,
                o.bounds.depth
            ),
            (2, 1, 1, 1, 10_000)
        );
    }
}
