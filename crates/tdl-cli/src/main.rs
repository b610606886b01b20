//! `tdl`: check TDL files, print the Rust they compile to, draw and document them, and read and
//! export trace files.
//!
//! - `tdl check FILE...` checks the files as one program (task and exception names resolve across
//!   them) and prints every diagnostic (errors and warnings) as rustc does (`error: message`,
//!   ` --> file:line:col`, the source with the span underlined, a hint), in colour on a terminal;
//!   with `--quiet` (as `graph` and `doc`), the errors only and a line with how many warnings it
//!   left out.
//! - `tdl expand FILE` prints the generated Rust, formatted, or the diagnostics.
//! - `tdl graph FILE...` prints the program's static structure as Graphviz `dot` or Mermaid
//!   (`graph.rs`, over the structure `model.rs` finds); `tdl doc FILE... -o DIR` writes its HTML
//!   documentation (`doc.rs`). Both first check the files as `tdl check` does and stop, printing
//!   the same diagnostics on standard error, when there are errors.
//! - `tdl trace check|log|tree|story TRACE.jsonl` reads a trace written by a run (for example
//!   `xavier --trace`): verifies it with the trace checker (exit 1 on violations), prints TCM's text
//!   log, the task tree of the whole run (or the live tree at `--at`), or the story of the run, one
//!   line per record with node numbers, filtered by kind, name, path, node and time (`view.rs`).
//!   `tdl trace export --mcap OUT.mcap TRACE.jsonl` writes it as MCAP (`export.rs`).
//!
//! - `tdl view TRACE.jsonl...` serves the task-tree viewer on the files (`serve.rs`); `--at SEQ`
//!   prints the address that opens the first with the time cursor on record SEQ.
//! - `tdl verify FILE.tdl...` / `tdl verify -p CRATE` explores every behaviour of a program within
//!   bounds and checks its properties (`verify.rs`, over the `tdl-verify` crate).
//! - `tdl sim FILE.tdl...` / `tdl sim -p CRATE` runs a program once per seed on virtual time with
//!   random durations, outcomes and events, and checks every run (`sim.rs`).
//! - `tdl certs --system NAME --out DIR MEMBER...` makes a system's authority and its members'
//!   certificates and keys for mutual TLS over zenoh (`certs.rs`).
//!
//! Exit codes (after ripgrep): 0 ok (warnings only or nothing), 1 errors found (or a property
//! violated), 2 usage or I/O error, 3 undecided (`tdl verify` and `tdl sim` only: nothing broken,
//! but a bound cut the search; docs/verification.md, "Exit status"). The front end is
//! `tdl-syntax`.

use std::io::{IsTerminal, Write};
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::{Parser, Subcommand};

#[cfg(test)]
mod agree;
#[cfg(feature = "net")]
mod certs;
mod debug;
mod doc;
#[cfg(feature = "net")]
mod executive;
mod export;
mod graph;
mod model;
mod replay;
mod run;
mod serve;
mod sim;
mod verify;

/// mimalloc: `tdl verify` allocates and frees an engine's nodes per transition, which the system
/// allocator made a third of its time (docs/verification.md, "Speed").
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;
mod view;

#[derive(Parser)]
#[command(
    name = "tdl",
    version,
    about = "TDL for Rust: check, expand, draw and document .tdl files; read and export trace files"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Print every diagnostic of the files, checked as one program (names resolve across them);
    /// exit 1 if any is an error.
    Check {
        /// The `.tdl` files of the program.
        #[arg(required = true)]
        files: Vec<PathBuf>,
        /// Print errors only, and how many warnings were not shown.
        #[arg(short, long)]
        quiet: bool,
    },
    /// Print the Rust code a file compiles to (or its diagnostics, exit 1).
    Expand {
        /// The `.tdl` file.
        file: PathBuf,
    },
    /// Serve the viewer on trace files (one run per file) at http://127.0.0.1:7878/ (or a free
    /// port if that one is taken) until interrupted.
    View {
        /// The trace files (JSON lines).
        #[arg(required = true)]
        files: Vec<std::path::PathBuf>,
        /// Listen on this address instead (a warning is printed when it is not loopback).
        #[arg(long, value_name = "ADDR")]
        listen: Option<std::net::SocketAddr>,
        /// Print the address that opens the first file with the time cursor on its record SEQ
        /// (its `seq`, from 0), as `tdl verify` and `tdl sim` print for a failing run.
        #[arg(long, value_name = "SEQ")]
        at: Option<u64>,
    },
    /// Print the static structure of a program as a graph: a node per task (shape and colour by
    /// kind), a cluster per body with its spawns, constraints between spawns as labelled edges,
    /// exception handlers and exceptions. Exit 1, with the diagnostics `tdl check` prints, if the
    /// files have errors.
    Graph {
        /// The `.tdl` files of the program.
        #[arg(required = true)]
        files: Vec<PathBuf>,
        /// Only this task and what it reaches (what it spawns, its handlers, and so on down).
        #[arg(long)]
        task: Option<String>,
        /// Output format: Graphviz `dot` (render with `dot -Tsvg`) or a Mermaid flowchart.
        #[arg(long, value_enum, default_value = "dot")]
        format: graph::Format,
        /// Print the program's errors only, and how many warnings were not shown.
        #[arg(short, long)]
        quiet: bool,
    },
    /// Write HTML documentation of a program: `index.html` (tasks by kind, exceptions, the graph)
    /// and a page per task. The graph is an SVG when Graphviz's `dot` is on PATH, Mermaid text
    /// otherwise. Exit 1, with the diagnostics `tdl check` prints, if the files have errors.
    Doc {
        /// The `.tdl` files of the program.
        #[arg(required = true)]
        files: Vec<PathBuf>,
        /// The directory to write into (created if needed).
        #[arg(short, long, value_name = "DIR")]
        out: PathBuf,
        /// Print the program's errors only, and how many warnings were not shown.
        #[arg(short, long)]
        quiet: bool,
    },
    /// Explore every behaviour of a program within bounds and check its properties (no stuck
    /// state, no unhandled exception, every run ends, the trace checker, and `--property`);
    /// counterexamples are written as trace files (docs/verification.md).
    Verify(verify::Args),
    /// Run a program many times on virtual time, one seeded random run per seed (durations,
    /// outcomes, failures, external events), and check every run; a failing run is written as a
    /// trace file with the command line that runs its seed again (docs/verification.md).
    Sim(sim::Args),
    /// Load a program's `.tdl` files, check them, and run a task of it without a Rust build: the
    /// commands it does not write in TDL come from agents (Rust or Python) that connect to
    /// 127.0.0.1 (docs/language.md, "Running programs without compiling them"). Prints the run's
    /// report.
    Run(run::Args),
    /// Re-execute a recorded run from its journal (`tdl run --journal`) on the journal's time:
    /// the bodies run again, the commands' ends come from the journal, and the trace is the
    /// run's, record for record; with a changed program, the first difference is reported
    /// (docs/semantics.md, "Durable runs").
    Replay(replay::Args),
    /// Serve programs while the robot runs (docs/distributed.md, "A serving executive"): a
    /// long-lived executive on 127.0.0.1 that clients give programs to (`tdl load`), start tasks
    /// of (`tdl start`), stop, raise events in and ask about (`tdl status`), and that agents join
    /// with the tasks they offer. Each run's trace is a file of its own.
    #[cfg(feature = "net")]
    Serve(executive::ServeArgs),
    #[cfg(feature = "net")]
    #[command(flatten)]
    Ask(executive::Ask),
    /// Make a system's certificates for mutual TLS (docs/distributed.md, "Mutual TLS"): an
    /// authority (`authority.pem`, its key `authority.key`) and, for each member, a certificate
    /// it signed and its key (`<member>.pem`, `<member>.key`). Refuses to replace a file unless
    /// `--force`.
    #[cfg(feature = "net")]
    Certs(certs::Args),
    /// Read a trace file (JSON lines, as written by `--trace` or `tcm::JsonLines`).
    Trace {
        #[command(subcommand)]
        what: TraceCommand,
    },
}

#[derive(Subcommand)]
enum TraceCommand {
    /// Verify the trace with the trace checker; exit 1 and list the violations if any. A valid
    /// trace of a run that did not end (stuck, or cut) is said to be so, with the innermost nodes
    /// still open.
    Check {
        /// The trace file.
        file: PathBuf,
    },
    /// Print TCM's text log of the run (`--time` appends the time of each line).
    Log {
        /// The trace file.
        file: PathBuf,
        /// Append the time since the run started to every line.
        #[arg(long)]
        time: bool,
        /// Also print TCM's TRACE lines for every facet transition.
        #[arg(long)]
        all: bool,
    },
    /// Print the task tree of the whole run, every node spawned (reclaimed ones marked), or the
    /// live tree at `--at` seconds.
    Tree {
        /// The trace file.
        file: PathBuf,
        /// Show the nodes alive at this moment, in seconds since the run started, instead of the
        /// whole run.
        #[arg(long)]
        at: Option<f64>,
        /// Show the nodes alive at the end of the trace instead of the whole run.
        #[arg(long, conflicts_with = "at")]
        live: bool,
        /// TCM's dump format (`name {id} [h|a|p|t]`) of the live tree (at `--at`, or at the end).
        #[arg(long)]
        tcm: bool,
    },
    /// Write the trace in another format: `--mcap OUT.mcap` writes MCAP, one channel per kind of
    /// record (`/tdl/trace/<kind>`), JSON messages with a JSON Schema per kind, log time = `t`.
    Export {
        /// The trace file.
        file: PathBuf,
        /// Write MCAP to this file (replaced only once the export is complete).
        #[arg(long, value_name = "OUT.mcap", required = true)]
        mcap: PathBuf,
    },
    /// Print one line per record: `<seconds> {id} <name> <what>`: transitions, spawns,
    /// termination, failures, handlers chosen, bypasses, retries, wiretap checks, monitor
    /// activations, events and warnings (constraints with `--kind constraint`).
    Story {
        /// The trace file.
        file: PathBuf,
        /// Only these kinds of record (repeat, or separate with commas).
        #[arg(long, value_enum, value_delimiter = ',')]
        kind: Vec<view::Kind>,
        /// Only records about nodes of this instance name.
        #[arg(long)]
        name: Option<String>,
        /// Only records about the node at this path of instance names from the top-level task
        /// (`deliver_all/deliver_mail`), and its subtree.
        #[arg(long)]
        path: Option<String>,
        /// Only records about this node number and its subtree.
        #[arg(long)]
        node: Option<u64>,
        /// Only records at or after this time, in seconds since the run started.
        #[arg(long)]
        from: Option<f64>,
        /// Only records at or before this time, in seconds since the run started.
        #[arg(long)]
        to: Option<f64>,
    },
}

/// The commands that need zenoh (the feature `net`): built without it, each says how to build
/// it in rather than being unknown.
#[cfg(not(feature = "net"))]
const NET_COMMANDS: [&str; 9] = [
    "serve", "load", "unload", "programs", "start", "stop", "raise", "status", "certs",
];

fn main() -> ExitCode {
    #[cfg(not(feature = "net"))]
    if let Some(cmd) = std::env::args()
        .nth(1)
        .filter(|a| NET_COMMANDS.contains(&a.as_str()))
    {
        eprintln!(
            "tdl: `tdl {cmd}` needs zenoh, and this tdl was built without the feature `net`: \
             install it with `cargo install --path crates/tdl-cli --features net` \
             (docs/tools.md)"
        );
        return ExitCode::from(2);
    }
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(err) => {
            let _ = err.print();
            return ExitCode::from(if err.use_stderr() { 2 } else { 0 });
        }
    };
    match run(cli) {
        Ok(status) => ExitCode::from(status),
        Err(err) => {
            if err
                .downcast_ref::<std::io::Error>()
                .map(std::io::Error::kind)
                == Some(std::io::ErrorKind::BrokenPipe)
            {
                return ExitCode::SUCCESS;
            }
            eprintln!("tdl: {err:#}");
            ExitCode::from(2)
        }
    }
}

/// The exit status: 0 when the command found nothing wrong, 1 when it did (errors in a program, a
/// bad trace, a violated property), 3 when `tdl verify` or `tdl sim` decided nothing wrong but not
/// everything; an error is 2 (main's).
fn run(cli: Cli) -> anyhow::Result<u8> {
    let found = |clean: bool| if clean { 0 } else { 1 };
    let mut out = std::io::stdout().lock();
    match cli.command {
        Command::Check { files, quiet } => {
            let (rendered, clean) = compile_checked(&files, stdout_colour(), quiet, |_| Ok(()))?;
            out.write_all(rendered.as_bytes())?;
            Ok(found(clean.is_some()))
        }
        Command::Graph {
            files,
            task,
            format,
            quiet,
        } => {
            let text = with_checked_program(&files, quiet, |program| {
                let program = model::Program::new(program);
                let options = graph::Options {
                    task: task.as_deref(),
                    links: false,
                };
                graph::render(&program, format, options).map_err(anyhow::Error::msg)
            })?;
            let Some(text) = text else {
                return Ok(1);
            };
            out.write_all(text.as_bytes())?;
            Ok(0)
        }
        Command::Doc {
            files,
            out: dir,
            quiet,
        } => {
            let written = with_checked_program(&files, quiet, |program| {
                let names: Vec<String> = program
                    .files()
                    .iter()
                    .map(|it| it.name.to_owned())
                    .collect();
                doc::write(&model::Program::new(program), &names, &dir)
            })?;
            let Some(written) = written else {
                return Ok(1);
            };
            writeln!(out, "wrote {} pages to {}", written.len(), dir.display())?;
            Ok(0)
        }
        Command::Trace { what } => trace(what, &mut out).map(found),
        Command::Verify(args) => verify::run(args, &mut out),
        Command::Sim(args) => sim::run(args, &mut out),
        Command::Run(args) => run::run(args),
        Command::Replay(args) => replay::run(args),
        #[cfg(feature = "net")]
        Command::Serve(args) => executive::serve(args),
        #[cfg(feature = "net")]
        Command::Ask(ask) => executive::ask(ask),
        #[cfg(feature = "net")]
        Command::Certs(args) => certs::run(args, &mut out),
        Command::View { files, listen, at } => serve::view(&files, listen, at).map(found),
        Command::Expand { file } => {
            let (name, src) = read(&file)?;
            let (code, diagnostics) = tdl_syntax::compile_str(&name, &src);
            let rendered = render(&diagnostics, &name, &src, stdout_colour());
            match code {
                Some(code) => {
                    eprint!("{rendered}");
                    out.write_all(tdl_syntax::pretty(&code).as_bytes())?;
                    Ok(0)
                }
                None => {
                    out.write_all(rendered.as_bytes())?;
                    Ok(1)
                }
            }
        }
    }
}

/// Ok(true) when the trace is clean (for `check`; the others always succeed once read).
fn trace(what: TraceCommand, out: &mut impl Write) -> anyhow::Result<bool> {
    let load = |file: &PathBuf| -> anyhow::Result<Vec<tcm_trace::TraceEvent>> {
        let f =
            std::fs::File::open(file).with_context(|| format!("cannot read {}", file.display()))?;
        // The reader's message already names the line and the cause: no second copy of the cause.
        tcm_trace::read_jsonl(std::io::BufReader::new(f))
            .map_err(|e| anyhow::anyhow!("{} is not a trace: {e}", file.display()))
    };
    match what {
        TraceCommand::Check { file } => {
            let trace = load(&file)?;
            match tcm_trace::check(&trace) {
                Ok(r) => {
                    writeln!(
                        out,
                        "{}: ok ({} records, {} nodes, {} transitions, {} constraints)",
                        file.display(),
                        r.n_records,
                        r.n_nodes,
                        r.n_transitions,
                        r.n_constraints
                    )?;
                    out.write_all(view::unfinished(&trace).as_bytes())?;
                    Ok(true)
                }
                Err(violations) => {
                    for v in &violations {
                        writeln!(out, "{}: {v}", file.display())?;
                    }
                    Ok(false)
                }
            }
        }
        TraceCommand::Export { file, mcap } => {
            let trace = load(&file)?;
            let written = export::mcap(&trace, &mcap)?;
            writeln!(
                out,
                "{}: wrote {} records on {} channels to {}",
                file.display(),
                written.messages,
                written.channels,
                mcap.display()
            )?;
            Ok(true)
        }
        TraceCommand::Log { file, time, all } => {
            let options = tcm_trace::TextLogOptions { time, trace: all };
            out.write_all(tcm_trace::TextLog::render(options, &load(&file)?).as_bytes())?;
            Ok(true)
        }
        TraceCommand::Tree {
            file,
            tcm,
            at,
            live,
        } => {
            let mut replay = tcm_trace::Replay::new();
            let until = at.map_or(u64::MAX, |s| (s.max(0.0) * 1e9) as u64);
            for ev in load(&file)?.into_iter().take_while(|ev| ev.t <= until) {
                replay
                    .apply(&ev)
                    .with_context(|| format!("record {} of {}", ev.seq, file.display()))?;
            }
            let text = if tcm {
                tcm_trace::dump_tcm(&replay)
            } else if live || at.is_some() {
                tcm_trace::dump_modern(&replay)
            } else {
                view::whole_tree(&replay)
            };
            out.write_all(text.as_bytes())?;
            Ok(true)
        }
        TraceCommand::Story {
            file,
            kind,
            name,
            path,
            node,
            from,
            to,
        } => {
            let filter = view::Filter {
                kinds: kind,
                name,
                path,
                node,
                from,
                to,
            };
            for line in view::story(&load(&file)?, &filter) {
                writeln!(out, "{line}")?;
            }
            Ok(true)
        }
    }
}

/// Whether to colour what goes to standard output: a terminal, and `NO_COLOR` not set
/// (<https://no-color.org>).
fn stdout_colour() -> bool {
    std::io::stdout().is_terminal() && std::env::var_os("NO_COLOR").is_none()
}

/// The same for standard error.
fn stderr_colour() -> bool {
    std::io::stderr().is_terminal() && std::env::var_os("NO_COLOR").is_none()
}

/// The diagnostics as text, in colour if asked.
fn render(diagnostics: &[tdl_syntax::Diagnostic], name: &str, src: &str, colour: bool) -> String {
    if colour {
        tdl_syntax::render_all_styled(diagnostics, name, Some(src))
    } else {
        tdl_syntax::render_all(diagnostics, name, Some(src))
    }
}

/// The files of a program compiled as one program, as `tdl check` does: every diagnostic rendered
/// (files separated by a blank line), and what `then` makes of the resolved program when no file
/// has an error. With `quiet`, warnings are left out, and a last line says how many.
fn compile_checked<R>(
    files: &[PathBuf],
    colour: bool,
    quiet: bool,
    then: impl FnOnce(&tdl_syntax::hir::Program<'_>) -> anyhow::Result<R>,
) -> anyhow::Result<(String, Option<R>)> {
    let sources = files.iter().map(read).collect::<anyhow::Result<Vec<_>>>()?;
    // The files are one program: names resolve across all of them.
    let named: Vec<(&str, &str)> = sources
        .iter()
        .map(|(name, src)| (name.as_str(), src.as_str()))
        .collect();
    tdl_syntax::compile_program_with(&named, |program, results| {
        let mut clean = true;
        let mut hidden = 0;
        let mut rendered = String::new();
        for ((name, src), (_, mut diagnostics)) in named.iter().zip(results) {
            clean &= !diagnostics.iter().any(tdl_syntax::Diagnostic::is_error);
            if quiet {
                let all = diagnostics.len();
                diagnostics.retain(tdl_syntax::Diagnostic::is_error);
                hidden += all - diagnostics.len();
            }
            if diagnostics.is_empty() {
                continue;
            }
            if !rendered.is_empty() {
                rendered.push('\n');
            }
            rendered.push_str(&render(&diagnostics, name, src, colour));
        }
        if hidden > 0 {
            if !rendered.is_empty() {
                rendered.push('\n');
            }
            let s = if hidden == 1 { "" } else { "s" };
            rendered.push_str(&format!("{hidden} warning{s} not shown (--quiet)\n"));
        }
        let made = if clean { Some(then(program)?) } else { None };
        Ok((rendered, made))
    })
}

/// What `then` makes of a program for `graph` and `doc`, after printing its diagnostics on
/// standard error (errors only with `quiet`); `None` when there are errors.
fn with_checked_program<R>(
    files: &[PathBuf],
    quiet: bool,
    then: impl FnOnce(&tdl_syntax::hir::Program<'_>) -> anyhow::Result<R>,
) -> anyhow::Result<Option<R>> {
    let (rendered, made) = compile_checked(files, stderr_colour(), quiet, then)?;
    eprint!("{rendered}");
    Ok(made)
}

fn read(file: &PathBuf) -> anyhow::Result<(String, String)> {
    let src =
        std::fs::read_to_string(file).with_context(|| format!("cannot read {}", file.display()))?;
    Ok((file.display().to_string(), src))
}
