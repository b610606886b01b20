//! `tdl replay`: a recorded run re-executed from its journal (docs/semantics.md, "Durable runs";
//! docs/tools.md): the program's bodies run again, its commands' ends come from the journal, its
//! time is the journal's, so that the trace is the run's, record for record. With a changed
//! program the replay stops at the first difference and says where: a field failure becomes a
//! test. Nothing leaves the process: the commands, from agents or not, are not run.

use std::path::PathBuf;

use anyhow::Context;
use tdl_interp::{Program, Registry};

const EXIT_STATUS: &str = "Exit status: 0 when the run was replayed to the journal's end (or to \
its own end) as recorded; 3 when the program did otherwise than the run (the first difference is \
printed); 1 when the program was refused; 2 when the replay could not start (an unreadable or \
damaged journal).";

/// Options of `tdl replay`.
#[derive(clap::Args)]
#[command(after_help = EXIT_STATUS)]
pub(crate) struct Args {
    /// The journal of the run (`tdl run --journal`).
    journal: PathBuf,
    /// The `.tdl` files of the program: the run's, or a changed one to try against the run.
    #[arg(required = true)]
    files: Vec<PathBuf>,
    /// Write the replay's trace to this file (JSON lines): the run's trace, record for record.
    #[arg(long, value_name = "FILE")]
    trace: Option<PathBuf>,
    /// Serve the viewer on the replay (and after it, until interrupted).
    #[arg(long)]
    view: bool,
}

/// Replays the journal: its exit status (see [`EXIT_STATUS`]).
pub(crate) fn run(a: Args) -> anyhow::Result<u8> {
    let files = crate::run::read(&a.files)?;
    if let Some(text) = crate::run::errors(&files) {
        eprint!("{text}");
        eprintln!("tdl: the program has errors: nothing was replayed");
        return Ok(1);
    }
    let journal = tcm_journal::read(&a.journal, None)?;
    if let Some(w) = &journal.warning {
        eprintln!("tdl: {w}");
    }
    // The commands are not run: those from agents stand in the registry, unreachable.
    let mut registry = Registry::new();
    for (name, kind) in tdl_interp::outside(&files) {
        let task = name.clone();
        registry.task_dynamic(&name, move |_| {
            let task = task.clone();
            Ok(tdl::Task::new(kind, task.clone(), move |_| async move {
                Err::<(), _>(tdl::Failure::new(
                    "NotReplayed",
                    format!("`{task}` comes from an agent, which a replay does not reach"),
                ))
            }))
        });
    }
    let program = match Program::from_sources(&files, &registry) {
        Ok(p) => p,
        Err(e) => {
            eprintln!("{e}");
            eprintln!("tdl: the program was refused: nothing was replayed");
            return Ok(1);
        }
    };
    if program.hash() != journal.header.program {
        eprintln!(
            "tdl: the journal is of program {}, and this is {}: the replay stops at the first \
             difference",
            journal.header.program,
            program.hash()
        );
    }
    let Some((name, args)) = crate::run::started(&journal.header) else {
        anyhow::bail!(
            "{}: the journal does not say which task its run started",
            a.journal.display()
        );
    };
    let task = program.task_json(&name, &args)?;
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("cannot start the async runtime")?;
    let inputs = journal.entries.len();
    rt.block_on(async move {
        let runtime = tdl::Runtime::new()
            .replay(journal)
            .replay_values(crate::run::interpreted_value, tdl::json_decoded);
        let runtime = crate::run::equip(runtime, &program);
        let (runtime, viewer) = crate::run::sinks(runtime, a.trace.as_deref(), a.view, &name)?;
        eprintln!(
            "replaying {name} from {} ({inputs} entries)",
            a.journal.display()
        );
        let report = runtime.run(task).await?;
        println!("{report}");
        if let Some(viewer) = viewer {
            eprintln!("the replay ended; the viewer serves it until interrupted");
            viewer.wait();
        }
        Ok(match report.outcome {
            tdl::RunOutcome::Diverged(_) => 3,
            _ => 0,
        })
    })
}
