//! `tdl`: check TDL files and print the Rust they compile to.
//!
//! - `tdl check FILE...` prints every diagnostic (errors and warnings) as
//!   `file:line:col: severity: message`, the source line, a caret and a hint.
//! - `tdl expand FILE` prints the generated Rust, formatted, or the diagnostics.
//! - `tdl trace check|log|tree|story TRACE.jsonl` reads a trace written by a run (for example
//!   `xavier --trace`): verifies it with the trace checker (exit 1 on violations), prints TCM's text
//!   log, the final task tree, or one line per transition.
//!
//! Exit codes (after ripgrep): 0 ok (warnings only or nothing), 1 errors found, 2 usage or I/O
//! error. All the work is done by `tdl-syntax`.

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "tdl",
    version,
    about = "TDL for Rust: check and expand .tdl files, read trace files"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Print every diagnostic of the files; exit 1 if any is an error.
    Check {
        /// The `.tdl` files.
        #[arg(required = true)]
        files: Vec<PathBuf>,
    },
    /// Print the Rust code a file compiles to (or its diagnostics, exit 1).
    Expand {
        /// The `.tdl` file.
        file: PathBuf,
    },
    /// Read a trace file (JSON lines, as written by `--trace` or `tcm::JsonLines`).
    Trace {
        #[command(subcommand)]
        what: TraceCommand,
    },
}

#[derive(Subcommand)]
enum TraceCommand {
    /// Verify the trace with the trace checker; exit 1 and list the violations if any.
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
    /// Print the task tree as it stands at the end of the trace, or at `--at` seconds.
    Tree {
        /// The trace file.
        file: PathBuf,
        /// The moment to show, in seconds since the run started (default: the end).
        #[arg(long)]
        at: Option<f64>,
        /// TCM's dump format (`name {id} [h|a|p|t]`) instead of ours.
        #[arg(long)]
        tcm: bool,
    },
    /// Print one line per transition: `<seconds> <name> <what>`.
    Story {
        /// The trace file.
        file: PathBuf,
    },
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(err) => {
            let _ = err.print();
            return ExitCode::from(if err.use_stderr() { 2 } else { 0 });
        }
    };
    match run(cli) {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::from(1),
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

/// Ok(true) when no file has errors.
fn run(cli: Cli) -> anyhow::Result<bool> {
    let mut out = std::io::stdout().lock();
    match cli.command {
        Command::Check { files } => {
            let mut clean = true;
            for file in files {
                let (name, src) = read(&file)?;
                let (_, diagnostics) = tdl_syntax::compile_str(&name, &src);
                clean &= !diagnostics.iter().any(tdl_syntax::Diagnostic::is_error);
                out.write_all(tdl_syntax::render_all(&diagnostics, &name, Some(&src)).as_bytes())?;
            }
            Ok(clean)
        }
        Command::Trace { what } => trace(what, &mut out),
        Command::Expand { file } => {
            let (name, src) = read(&file)?;
            let (code, diagnostics) = tdl_syntax::compile_str(&name, &src);
            let rendered = tdl_syntax::render_all(&diagnostics, &name, Some(&src));
            match code {
                Some(code) => {
                    eprint!("{rendered}");
                    out.write_all(tdl_syntax::pretty(&code).as_bytes())?;
                    Ok(true)
                }
                None => {
                    out.write_all(rendered.as_bytes())?;
                    Ok(false)
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
        TraceCommand::Check { file } => match tcm_trace::check(&load(&file)?) {
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
                Ok(true)
            }
            Err(violations) => {
                for v in &violations {
                    writeln!(out, "{}: {v}", file.display())?;
                }
                Ok(false)
            }
        },
        TraceCommand::Log { file, time, all } => {
            let options = tcm_trace::TextLogOptions { time, trace: all };
            out.write_all(tcm_trace::TextLog::render(options, &load(&file)?).as_bytes())?;
            Ok(true)
        }
        TraceCommand::Tree { file, tcm, at } => {
            let mut replay = tcm_trace::Replay::new();
            let until = at.map_or(u64::MAX, |s| (s.max(0.0) * 1e9) as u64);
            for ev in load(&file)?.into_iter().take_while(|ev| ev.t <= until) {
                replay
                    .apply(&ev)
                    .with_context(|| format!("record {} of {}", ev.seq, file.display()))?;
            }
            let text = if tcm {
                tcm_trace::dump_tcm(&replay)
            } else {
                tcm_trace::dump_modern(&replay)
            };
            out.write_all(text.as_bytes())?;
            Ok(true)
        }
        TraceCommand::Story { file } => {
            for line in tcm_trace::story::story(&load(&file)?) {
                writeln!(out, "{line}")?;
            }
            Ok(true)
        }
    }
}

fn read(file: &PathBuf) -> anyhow::Result<(String, String)> {
    let src =
        std::fs::read_to_string(file).with_context(|| format!("cannot read {}", file.display()))?;
    Ok((file.display().to_string(), src))
}
