//! `tdl`: check TDL files and print the Rust they compile to.
//!
//! - `tdl check FILE...` prints every diagnostic (errors and warnings) as
//!   `file:line:col: severity: message`, the source line, a caret and a hint.
//! - `tdl expand FILE` prints the generated Rust, formatted, or the diagnostics.
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
    about = "TDL for Rust: check and expand .tdl files"
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

fn read(file: &PathBuf) -> anyhow::Result<(String, String)> {
    let src =
        std::fs::read_to_string(file).with_context(|| format!("cannot read {}", file.display()))?;
    Ok((file.display().to_string(), src))
}
