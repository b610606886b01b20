//! `tdl verify`: explores every behaviour of a TDL program within bounds and checks properties
//! (the `tdl-verify` crate; docs/verification.md).
//!
//! The program is a set of `.tdl` files, given by name or as a crate of the workspace
//! (`-p CRATE`: its `src/**/*.tdl`, found with `cargo metadata`, else under `crates/CRATE`). The
//! task verified is `--task`, else the only goal no task of the program spawns. Progress goes to
//! standard error: a spinner on a terminal (`indicatif`), a plain line every second otherwise.
//! Ctrl-C stops the search and prints what was found so far (a second one exits at once).
//! Each counterexample is written as a trace file (JSON lines) under `--out` as soon as it is
//! found, and printed (its path in words and the story of its trace, which `tdl trace story FILE`
//! replays, and the `tdl view FILE --at SEQ` command that opens it on the record where the
//! property is broken): a search cut short later, or killed, keeps it. The search stops at `--max-states`
//! distinct states or when it uses `--max-memory` (default: half of the machine's memory), as
//! at a bound: what it did not decide is undecided. Exit status ([`EXIT_STATUS`]): 0 every
//! property decided and holds, 1 one is broken, 3 none is broken but some was not decided (a bound
//! cut the search, or Ctrl-C), 2 an error (bad input, the program has errors, I/O, a checker
//! failure).

use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Context;
use tdl_verify::{
    Builtin, Control, Counterexample, Options, Program, Property, PropertyResult, Report, Status,
    Verdict,
};

/// The exit statuses of `tdl verify` (and `tdl sim`), as `--help` gives them.
pub(crate) const EXIT_STATUS: &str = "Exit status (for CI):
  0  ok: every property checked was decided and holds within the bounds
  1  violated: a property is broken (its counterexample is written as soon as it is found)
  3  undecided: nothing is broken, but a bound (--max-states, --max-memory, --depth) or Ctrl-C
     cut the search, or liveness met a cycle: some property was not decided
  2  error: bad input (options, a property that does not parse or names no node, a program with
     errors), I/O, or a failure of the checker itself";

/// A built-in property by its command-line name.
pub(crate) fn builtin(id: &str) -> Result<Builtin, String> {
    Builtin::from_id(id).ok_or_else(|| {
        format!(
            "`{id}` is no built-in property: the built-in properties are {}",
            Builtin::ALL.map(Builtin::id).join(", ")
        )
    })
}

/// Options of `tdl verify`.
#[derive(clap::Args)]
#[command(after_help = EXIT_STATUS)]
pub(crate) struct Args {
    /// The `.tdl` files of the program, checked as one program.
    #[arg(required_unless_present = "package", conflicts_with = "package")]
    files: Vec<PathBuf>,
    /// Verify the TDL program of this crate of the workspace (its `src/**/*.tdl`).
    #[arg(short = 'p', long = "package", value_name = "CRATE")]
    package: Option<String>,
    /// The task to start from (default: the only goal no task of the program spawns).
    #[arg(long)]
    task: Option<String>,
    /// A loop over a collection the checker cannot see runs 0 to this many times [default: 2].
    #[arg(long, value_name = "K")]
    loops: Option<u32>,
    /// Instances of one task nested on a branch of the tree; one more is a command of the
    /// checker's choice, and the path ends beyond that [default: 1].
    #[arg(long, value_name = "R")]
    recursion: Option<u32>,
    /// Deadlines a running command may outlast [default: 1].
    #[arg(long, value_name = "N")]
    ticks: Option<u32>,
    /// Times each external event may be raised [default: 1].
    #[arg(long, value_name = "N")]
    events: Option<u32>,
    /// Commands per run that may be left running until terminated [default: 1].
    #[arg(long, value_name = "N")]
    hangs: Option<u32>,
    /// The longest run explored, in transitions [default: 10000].
    #[arg(long, value_name = "N")]
    depth: Option<u32>,
    /// Stop after this many distinct states [default: 20000000].
    #[arg(long, value_name = "N")]
    max_states: Option<u64>,
    /// Stop when the search uses this much memory (the process's resident set), e.g. 512M, 8G
    /// [default: half of the machine's memory].
    #[arg(long, value_name = "SIZE", value_parser = tdl_verify::parse_size)]
    max_memory: Option<u64>,
    /// A built-in property not to check (repeat, or separate with commas): no-stuck-state,
    /// no-unhandled-exception, every-run-ends (for a program meant to run until it is shut
    /// down), trace-checker.
    #[arg(long = "no-builtin", value_name = "PROPERTY", value_delimiter = ',', value_parser = builtin)]
    no_builtin: Vec<Builtin>,
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
    /// A property to check besides the built-in ones (repeat), e.g.
    /// `never active(turn) and active(guarded_move)`, `completed(plan) before active(move)`.
    #[arg(short = 'P', long = "property", value_name = "PROPERTY")]
    property: Vec<String>,
    /// A file of properties, one per line (`#` comments).
    #[arg(long = "properties", value_name = "FILE")]
    properties: Option<PathBuf>,
    /// Where counterexample traces are written.
    #[arg(long, value_name = "DIR", default_value = "target/tdl-verify")]
    out: PathBuf,
    /// Do not print the notes on what the checker abstracts, only how many there are; the
    /// checker's errors are still printed.
    #[arg(short, long)]
    quiet: bool,
}

/// Runs `tdl verify`: the exit status, 0 ok, 1 violated or 3 undecided, or an error (exit 2,
/// main's) ([`EXIT_STATUS`], [`finish`]).
pub(crate) fn run(args: Args, out: &mut impl Write) -> anyhow::Result<u8> {
    let (files, program) = load_program(&args.files, args.package.as_deref(), out)?;
    let task = program.root_task(args.task.as_deref())?;
    let properties = load_properties(&args.property, args.properties.as_deref())?;
    tdl_verify::check_names(&program, &task, &properties)?;
    let options = options(&args)?;
    writeln!(
        out,
        "verifying `{task}` of {} (loops {}, recursion {}, ticks {}, events {}, hangs {}, depth {}, max states {}, max memory {})",
        files
            .iter()
            .map(|f| f.display().to_string())
            .collect::<Vec<_>>()
            .join(", "),
        options.loops,
        options.recursion,
        options.ticks,
        options.events,
        options.hangs,
        options.depth,
        options.max_states,
        tdl_verify::fmt_bytes(options.max_memory)
    )?;
    print_unchecked(&options, out)?;
    out.flush()?;
    let control = Arc::new(Control::default());
    stop_on_ctrl_c(&control);
    let mut written: Vec<(String, PathBuf)> = Vec::new();
    let mut failed: Option<anyhow::Error> = None;
    let report = {
        let mut display = Display::new();
        let bar = display.bar.clone();
        let mut on_violation = |r: &PropertyResult| {
            if failed.is_some() {
                return;
            }
            let Verdict::Violated(c) = &r.verdict else {
                return;
            };
            let file = args.out.join(slug(&task, &r.property));
            let mut print = || -> anyhow::Result<()> {
                write_trace(c, &file)?;
                writeln!(out, "  VIOLATED   {}: {}", r.property, c.summary)?;
                print_counterexample(c, &file, out)?;
                out.flush()?;
                Ok(())
            };
            let printed = match &bar {
                Some(bar) => bar.suspend(print),
                None => print(),
            };
            match printed {
                Ok(()) => written.push((r.property.clone(), file)),
                Err(e) => failed = Some(e),
            }
        };
        tdl_verify::verify_observed(
            &program,
            &task,
            &options,
            &properties,
            None,
            &control,
            &mut |p| display.update(p),
            &mut on_violation,
        )
    };
    if let Some(e) = failed {
        return Err(e);
    }
    let mut report = report;
    let hidden = hide_notes(args.quiet, &mut report.notes);
    print_report(&report, &written, out)?;
    print_hidden(hidden, out)?;
    finish(report.status(), false, out)
}

/// With `--quiet`, takes the notes on what the checker abstracts out of a report (its errors
/// stay): how many there were.
pub(crate) fn hide_notes(quiet: bool, notes: &mut Vec<String>) -> usize {
    if !quiet {
        return 0;
    }
    std::mem::take(notes).len()
}

/// The one line that says how many notes `--quiet` hid, if any.
pub(crate) fn print_hidden(hidden: usize, out: &mut impl Write) -> anyhow::Result<()> {
    match hidden {
        0 => Ok(()),
        1 => Ok(writeln!(
            out,
            "1 note on what the checker abstracts not shown (--quiet)"
        )?),
        n => Ok(writeln!(
            out,
            "{n} notes on what the checker abstracts not shown (--quiet)"
        )?),
    }
}

/// Ends `tdl verify` or `tdl sim` (`sim`) with `status` ([`EXIT_STATUS`]) after a line that says it:
/// the exit status, or an error (exit 2, main's, as for every command).
pub(crate) fn finish(status: Status, sim: bool, out: &mut impl Write) -> anyhow::Result<u8> {
    writeln!(out, "{}", status_line(status, sim))?;
    match status {
        Status::Error => anyhow::bail!("the checker failed: see its errors above"),
        Status::Ok | Status::Violated | Status::Undecided => Ok(status.code()),
    }
}

/// The last line of a report: the verdict as a whole and its exit status.
fn status_line(status: Status, sim: bool) -> String {
    let words = match status {
        Status::Ok if sim => "ok: no run broke a property",
        Status::Ok => "ok: every property checked holds within the bounds",
        Status::Violated => "violated: a property is broken",
        Status::Undecided => "undecided: nothing is broken, but not every property was decided",
        Status::Error => "error: nothing can be concluded",
    };
    format!("{words} (exit status {})", status.code())
}

/// The built-in properties left unchecked, one line, if any.
pub(crate) fn print_unchecked(options: &Options, out: &mut impl Write) -> anyhow::Result<()> {
    let off: Vec<&str> = options.unchecked.iter().map(|b| b.property()).collect();
    if !off.is_empty() {
        writeln!(out, "not checked (--no-builtin): {}", off.join(", "))?;
    }
    Ok(())
}

/// The program of `tdl verify` and `tdl sim`: the files given, or a crate's; an error (after
/// printing the diagnostics) when it has errors.
pub(crate) fn load_program(
    files: &[PathBuf],
    package: Option<&str>,
    out: &mut impl Write,
) -> anyhow::Result<(Vec<PathBuf>, Program)> {
    let files = match package {
        Some(name) => package_files(name)?,
        None => files.to_vec(),
    };
    let mut sources = Vec::new();
    for f in &files {
        let src =
            std::fs::read_to_string(f).with_context(|| format!("cannot read {}", f.display()))?;
        sources.push((f.display().to_string(), src));
    }
    match Program::load(&sources) {
        Ok(p) => Ok((files, p)),
        Err(tdl_verify::LoadError::Invalid(rendered)) => {
            out.write_all(rendered.as_bytes())?;
            anyhow::bail!("the program has errors (see `tdl check`)")
        }
        Err(e) => Err(e.into()),
    }
}

/// The `--property` and `--properties FILE` properties.
pub(crate) fn load_properties(
    texts: &[String],
    file: Option<&Path>,
) -> anyhow::Result<Vec<Property>> {
    let mut properties = Vec::new();
    for p in texts {
        properties.push(Property::parse(p)?);
    }
    if let Some(f) = file {
        let text =
            std::fs::read_to_string(f).with_context(|| format!("cannot read {}", f.display()))?;
        properties.extend(
            Property::parse_file(&f.display().to_string(), &text).map_err(anyhow::Error::msg)?,
        );
    }
    Ok(properties)
}

/// The first Ctrl-C sets `control.stop` (the report follows); a second exits at once.
pub(crate) fn stop_on_ctrl_c(control: &Arc<Control>) {
    let control = Arc::clone(control);
    let _ = ctrlc::set_handler(move || {
        if control
            .stop
            .swap(true, std::sync::atomic::Ordering::Relaxed)
        {
            std::process::exit(130);
        }
    });
}

fn options(args: &Args) -> anyhow::Result<Options> {
    let d = Options::default();
    Ok(Options {
        loops: args.loops.unwrap_or(d.loops),
        recursion: args.recursion.unwrap_or(d.recursion),
        depth: args.depth.unwrap_or(d.depth),
        max_states: args.max_states.unwrap_or(d.max_states),
        max_memory: args.max_memory.unwrap_or(d.max_memory),
        unchecked: args.no_builtin.clone(),
        ticks: args.ticks.unwrap_or(d.ticks),
        events: args.events.unwrap_or(d.events),
        hangs: args.hangs.unwrap_or(d.hangs),
        allowed: args.allow.clone(),
        unknown_exception: args.unknown_exception,
        samples: d.samples,
        faults: match &args.faults {
            Some(path) => tdl::read_faults(path)?,
            None => Vec::new(),
        },
    })
}

/// Progress on standard error: a spinner on a terminal, a line a second otherwise.
struct Display {
    bar: Option<indicatif::ProgressBar>,
    last: Instant,
}

impl Display {
    fn new() -> Display {
        let bar = std::io::stderr().is_terminal().then(|| {
            let bar = indicatif::ProgressBar::new_spinner();
            bar.enable_steady_tick(Duration::from_millis(120));
            bar
        });
        Display {
            bar,
            last: Instant::now(),
        }
    }

    fn update(&mut self, p: &tdl_verify::Progress) {
        let rate = p.explored as f64 / p.elapsed.as_secs_f64().max(1e-9);
        let line = format!(
            "{} states explored, {} distinct, depth {}, {} waiting, {:.0} states/s, {} violation(s), {:.0} s (Ctrl-C stops)",
            p.explored,
            p.unique,
            p.depth,
            p.frontier,
            rate,
            p.violations,
            p.elapsed.as_secs_f64()
        );
        match &self.bar {
            Some(bar) => bar.set_message(line),
            None => {
                if self.last.elapsed() >= Duration::from_secs(1) {
                    self.last = Instant::now();
                    eprintln!("tdl verify: {line}");
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

/// A file name for a property's counterexample.
pub(crate) fn slug(task: &str, property: &str) -> String {
    let mut s = String::new();
    for ch in format!("{task}-{property}").chars() {
        if ch.is_ascii_alphanumeric() || ch == '_' {
            s.push(ch);
        } else if !s.ends_with('-') {
            s.push('-');
        }
    }
    format!("{}.jsonl", s.trim_end_matches('-'))
}

/// The report once the search is over; the counterexamples were printed when found, and their
/// files are in `written`.
fn print_report(
    report: &Report,
    written: &[(String, PathBuf)],
    out: &mut impl Write,
) -> anyhow::Result<()> {
    writeln!(
        out,
        "{} states explored ({} distinct), depth {}, {:.2} s, {:.0} states/s",
        report.explored,
        report.unique,
        report.depth,
        report.elapsed.as_secs_f64(),
        report.rate()
    )?;
    if report.interrupted {
        writeln!(out, "interrupted: what was found so far")?;
    }
    if report.complete {
        writeln!(out, "every state within the bounds was explored")?;
    }
    for cut in &report.cuts {
        if *cut != tdl_verify::Cut::Interrupted {
            writeln!(out, "not every state was explored: {cut}")?;
        }
    }
    if report.cut > 0 {
        writeln!(
            out,
            "{} paths ended at a bound{}",
            report.cut,
            report
                .cut_example
                .as_ref()
                .map(|c| format!(", e.g. {c}"))
                .unwrap_or_default()
        )?;
    }
    writeln!(
        out,
        "{} traces replayed through the trace checker",
        report.traces_checked
    )?;
    for r in &report.results {
        match &r.verdict {
            Verdict::Holds => writeln!(out, "  ok         {}", r.property)?,
            Verdict::Unknown(why) => writeln!(out, "  undecided  {}: {why}", r.property)?,
            Verdict::Violated(c) => {
                writeln!(out, "  VIOLATED   {}: {}", r.property, c.summary)?;
                if let Some((_, file)) = written.iter().find(|(p, _)| *p == r.property) {
                    writeln!(
                        out,
                        "             a path of {} transitions, printed above; trace: {}",
                        c.len(),
                        file.display()
                    )?;
                }
            }
        }
    }
    print_errors_and_notes(&report.errors, &report.notes, out)
}

/// The end of a report, as `tdl verify` and `tdl sim` print it: the checker's own errors, then
/// what it abstracts in this program.
pub(crate) fn print_errors_and_notes(
    errors: &[String],
    notes: &[String],
    out: &mut impl Write,
) -> anyhow::Result<()> {
    for e in errors {
        writeln!(out, "checker error (please report): {e}")?;
    }
    if !notes.is_empty() {
        writeln!(out, "what the checker abstracts here:")?;
        for n in notes {
            writeln!(out, "  {n}")?;
        }
    }
    Ok(())
}

/// Writes a counterexample's trace to `file` (its directory created if needed).
pub(crate) fn write_trace(c: &Counterexample, file: &Path) -> anyhow::Result<()> {
    if let Some(dir) = file.parent() {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    let mut w = std::io::BufWriter::new(
        std::fs::File::create(file).with_context(|| format!("cannot write {}", file.display()))?,
    );
    c.write_trace(&mut w)?;
    w.flush()?;
    Ok(())
}

/// A counterexample in words: its length, its trace file, the `tdl view` command that opens it at
/// the record where the property is broken ([`Counterexample::failing_seq`]), the transitions,
/// the details, and the story of its trace.
pub(crate) fn print_counterexample(
    c: &Counterexample,
    file: &Path,
    out: &mut impl Write,
) -> anyhow::Result<()> {
    let repeats = match c.repeats_from {
        Some(from) => format!(", the last {} repeating forever", c.len() - from),
        None => String::new(),
    };
    writeln!(
        out,
        "             a path of {} transitions{repeats}; trace: {} (`tdl trace story {}`)",
        c.len(),
        file.display(),
        file.display()
    )?;
    if let Some(seq) = c.failing_seq() {
        writeln!(
            out,
            "             open it at the failing step: {}",
            view_command(file, seq)
        )?;
    }
    if c.depends_on_conditions {
        writeln!(
            out,
            "             it takes branches of conditions the checker does not evaluate: check they can go that way"
        )?;
    }
    for h in &c.hung {
        writeln!(
            out,
            "             {h} is left running until it is terminated"
        )?;
    }
    for (i, s) in c.steps.iter().enumerate() {
        let mark = if c.repeats_from == Some(i) {
            "↻"
        } else {
            " "
        };
        writeln!(out, "           {mark}{:>3}. {s}", i + 1)?;
    }
    for d in &c.details {
        writeln!(out, "             {d}")?;
    }
    for v in &c.trace_violations {
        writeln!(out, "             trace checker: {v}")?;
    }
    writeln!(out, "             story:")?;
    for line in crate::view::story(&c.trace, &crate::view::Filter::default()) {
        writeln!(out, "               {line}")?;
    }
    Ok(())
}

/// `tdl view FILE --at SEQ`, the file quoted for a shell if it needs it.
fn view_command(file: &Path, seq: u64) -> String {
    format!(
        "tdl view {} --at {seq}",
        crate::sim::shell_word(&file.display().to_string())
    )
}

/// The `.tdl` files of a crate of the workspace: its `src/**/*.tdl`, in path order.
pub(crate) fn package_files(name: &str) -> anyhow::Result<Vec<PathBuf>> {
    let dir = package_dir(name)?;
    let mut files = Vec::new();
    collect_tdl(&dir.join("src"), &mut files);
    files.sort();
    // Relative to where the command runs, when below it: shorter messages.
    if let Ok(here) = std::env::current_dir() {
        for f in &mut files {
            if let Ok(rel) = f.strip_prefix(&here) {
                *f = rel.to_path_buf();
            }
        }
    }
    if files.is_empty() {
        anyhow::bail!(
            "crate `{name}` has no .tdl file under {}",
            dir.join("src").display()
        );
    }
    Ok(files)
}

fn collect_tdl(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() {
            collect_tdl(&p, out);
        } else if p.extension().is_some_and(|x| x == "tdl") {
            out.push(p);
        }
    }
}

/// The directory of the crate `name`: from `cargo metadata`, else `crates/NAME` in this
/// directory or one above.
fn package_dir(name: &str) -> anyhow::Result<PathBuf> {
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let meta = std::process::Command::new(cargo)
        .args([
            "metadata",
            "--format-version",
            "1",
            "--no-deps",
            "--offline",
        ])
        .stderr(std::process::Stdio::null())
        .output();
    if let Ok(meta) = meta {
        if meta.status.success() {
            let v: serde_json::Value = serde_json::from_slice(&meta.stdout)
                .context("cannot read the output of `cargo metadata`")?;
            let found = v["packages"].as_array().and_then(|ps| {
                ps.iter()
                    .find(|p| p["name"].as_str() == Some(name))
                    .and_then(|p| {
                        p["manifest_path"]
                            .as_str()
                            .and_then(|m| Path::new(m).parent().map(Path::to_path_buf))
                    })
            });
            if let Some(dir) = found {
                return Ok(dir);
            }
        }
    }
    let mut here = std::env::current_dir()?;
    loop {
        let dir = here.join("crates").join(name);
        if dir.join("Cargo.toml").is_file() {
            return Ok(dir);
        }
        if !here.pop() {
            anyhow::bail!(
                "no crate `{name}` in this workspace (looked with `cargo metadata` and under crates/)"
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The help text writes the defaults out; they must be the library's.
    #[test]
    fn the_defaults_in_the_help_are_the_librarys() {
        let d = Options::default();
        assert_eq!(
            (
                d.loops,
                d.recursion,
                d.ticks,
                d.events,
                d.hangs,
                d.depth,
                d.max_states
            ),
            (2, 1, 1, 1, 1, 10_000, 20_000_000)
        );
    }

    #[test]
    fn counterexample_files_are_named_after_the_property() {
        assert_eq!(
            slug("deliver_all", "never active(turn) and active(guarded_move)"),
            "deliver_all-never-active-turn-and-active-guarded_move.jsonl"
        );
        assert_eq!(slug("t", "no stuck state"), "t-no-stuck-state.jsonl");
    }
}
