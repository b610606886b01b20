//! `tdl run`: a program's `.tdl` files loaded, checked and run without a Rust build
//! (docs/language.md, "Running programs without compiling them"). The commands it spawns that it
//! does not write in TDL come from agents: an executive listens on 127.0.0.1, the agents (Rust or
//! Python) connect, and every task they offer is registered for the program, its arguments and
//! value crossing as JSON. The run's trace goes to a file and to the viewer, live, if asked; the
//! report is printed, and the exit status says how the run ended.

use std::path::PathBuf;
#[cfg(feature = "net")]
use std::time::Duration;

use anyhow::Context;
#[cfg(not(feature = "net"))]
use anyhow::bail;
use tdl_interp::{Program, Registry};

const EXIT_STATUS: &str = "Exit status: 0 when the task completed and nothing failed unhandled; \
1 when the program was refused (its diagnostics are printed, nothing was started); 3 when the run \
ended with an unhandled failure or stuck; 2 when the run could not start.";

/// Options of `tdl run`.
#[derive(clap::Args)]
#[command(after_help = EXIT_STATUS)]
pub(crate) struct Args {
    /// The `.tdl` files of the program, checked as one program.
    #[arg(required = true)]
    files: Vec<PathBuf>,
    /// The task to run (default: the only goal or command no task of the program spawns).
    #[arg(long)]
    task: Option<String>,
    /// The task's arguments, as JSON: an array of one value per parameter, or the value of a
    /// task of one parameter.
    #[arg(long, value_name = "JSON")]
    args: Option<String>,
    /// The system agents join (their `Agent(system, name)`).
    #[arg(long, default_value = "tdl")]
    system: String,
    /// The port of 127.0.0.1 the executive listens on for agents.
    #[arg(long, default_value_t = 7447)]
    port: u16,
    /// Wait for these agents before starting (default: wait until every task the program needs
    /// from outside is offered).
    #[arg(long, value_delimiter = ',')]
    agents: Vec<String>,
    /// How long to wait for agents, in seconds.
    #[arg(long, value_name = "SECONDS", default_value_t = 10.0)]
    wait: f64,
    /// Write the run's trace to this file (JSON lines).
    #[arg(long, value_name = "FILE")]
    trace: Option<PathBuf>,
    /// Serve the viewer on the run, live (and after it, until interrupted).
    #[arg(long)]
    view: bool,
    /// The most loop iterations a body may take without ending (its node fails past them).
    #[arg(long, value_name = "N")]
    max_steps: Option<u64>,
    #[command(flatten)]
    steer: crate::debug::Steer,
    /// Keep a journal of the run's inputs in this file (a new file; docs/semantics.md, "Durable
    /// runs").
    #[arg(long, value_name = "FILE", conflicts_with = "resume")]
    journal: Option<PathBuf>,
    /// Resume the run this journal recorded, after a crash: the run is rebuilt from the journal
    /// (bodies run again, commands' ends come from it), then goes on live, journaling on into
    /// the same file; a command that was running at the crash fails with `Interrupted` unless
    /// its task is `idempotent`. The task and its arguments are the journal's.
    #[arg(long, value_name = "JOURNAL")]
    resume: Option<PathBuf>,
    /// How the journal reaches the disk: `every` record synced; `group:MS`, synced together at
    /// most MS milliseconds after they were written; or `acting:MS`, as `group:MS` and everything
    /// synced before a command starts or is cancelled (the default).
    #[arg(
        long,
        value_name = "every|group:MS|acting:MS",
        default_value = "acting:10"
    )]
    journal_sync: String,
}

/// An interpreted program's value as the journal writes it (JSON), or a value that is JSON
/// already (a task from an agent).
pub(crate) fn interpreted_value(value: &(dyn std::any::Any + Send)) -> Option<serde_json::Value> {
    match value.downcast_ref::<tdl_interp::Value>() {
        Some(v) => v.to_json().ok(),
        None => tdl::json_values(value),
    }
}

/// `--journal-sync` read.
fn durability(text: &str) -> anyhow::Result<tcm_journal::Durability> {
    text.parse().map_err(anyhow::Error::msg)
}

/// The files, read.
pub(crate) fn read(files: &[PathBuf]) -> anyhow::Result<Vec<(String, String)>> {
    files
        .iter()
        .map(|p| {
            let text = std::fs::read_to_string(p)
                .with_context(|| format!("cannot read {}", p.display()))?;
            Ok((p.display().to_string(), text))
        })
        .collect()
}

/// The diagnostics of the files checked as one program, rendered, when any is an error.
pub(crate) fn errors(files: &[(String, String)]) -> Option<String> {
    let named: Vec<(&str, &str)> = files
        .iter()
        .map(|(n, s)| (n.as_str(), s.as_str()))
        .collect();
    let results = tdl_syntax::compile_program(&named);
    let mut out = String::new();
    for ((name, src), (_, diags)) in named.iter().zip(results) {
        let errors: Vec<_> = diags.into_iter().filter(|d| d.is_error()).collect();
        if !errors.is_empty() {
            out.push_str(&tdl_syntax::render_all(&errors, name, Some(src)));
            out.push('\n');
        }
    }
    (!out.is_empty()).then_some(out)
}

/// The task to run: the one asked for, else the program's only goal no other task spawns.
fn root(
    program: &Program,
    files: &[(String, String)],
    asked: Option<&str>,
) -> anyhow::Result<String> {
    match asked {
        Some(t) => Ok(t.to_string()),
        None => tdl_interp::default_task(program, files)
            .map_err(|why| anyhow::anyhow!("{why} with --task")),
    }
}

/// Runs the program: its exit status (see [`EXIT_STATUS`]).
pub(crate) fn run(a: Args) -> anyhow::Result<u8> {
    let files = read(&a.files)?;
    if let Some(text) = errors(&files) {
        eprint!("{text}");
        eprintln!("tdl: the program has errors: nothing was started");
        return Ok(1);
    }
    let outside = tdl_interp::outside(&files);
    // A journaled run drives its tree on one thread: its bodies then ask the engine in an order
    // that the inputs decide, which a replay reproduces (docs/semantics.md, "Durable runs").
    let rt = if a.journal.is_some() || a.resume.is_some() {
        tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
    } else {
        tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .enable_all()
            .build()
    }
    .context("cannot start the async runtime")?;
    rt.block_on(async move {
        let mut registry = Registry::new();
        let exec = if outside.is_empty() && a.agents.is_empty() {
            None
        } else {
            Some(connect(&a, &outside, &mut registry).await?)
        };
        let mut program = match Program::from_sources(&files, &registry) {
            Ok(p) => p,
            Err(e) => {
                eprintln!("{e}");
                eprintln!("tdl: the program was refused: nothing was started");
                return Ok(1);
            }
        };
        if let Some(max) = a.max_steps {
            program = program.with_budget(tdl_interp::Budget {
                max_steps: max,
                ..tdl_interp::Budget::default()
            });
        }
        let resumed = match &a.resume {
            Some(path) => Some(resumed(path, &program)?),
            None => None,
        };
        let (name, args) = match resumed.as_ref().and_then(|j| started(&j.header)) {
            Some(start) => start,
            None => {
                let name = root(&program, &files, a.task.as_deref())?;
                let args: serde_json::Value = match &a.args {
                    Some(text) => serde_json::from_str(text).context("--args is not JSON")?,
                    None => serde_json::Value::Null,
                };
                (name, args)
            }
        };
        let task = program.task_json(&name, &args)?;
        let mut runtime = a.steer.prepare(tdl::Runtime::new())?;
        let sync = durability(&a.journal_sync)?;
        if let (Some(path), Some(journal)) = (&a.resume, resumed) {
            let writer = tcm_journal::Writer::reopen(path, &journal, sync)?;
            eprintln!(
                "resuming from {} ({} inputs)",
                path.display(),
                journal.entries.len()
            );
            runtime = runtime
                .journal_with(writer, interpreted_value)
                .resume(journal)
                .replay_values(interpreted_value, tdl::json_decoded);
        } else if let Some(path) = &a.journal {
            let header = tcm_journal::Header::new(program.hash())
                .starting(serde_json::json!({ "task": name, "args": args }));
            let writer = tcm_journal::Writer::create_with(path, header, sync)?;
            runtime = runtime.journal_with(writer, interpreted_value);
        }
        runtime = equip(runtime, &program);
        #[cfg(feature = "net")]
        if let Some(exec) = &exec {
            runtime = runtime.placer(exec.clone());
        }
        let (runtime, viewer) = sinks(runtime, a.trace.as_deref(), a.view, &name)?;
        eprintln!("running {name}");
        let report = if a.steer.interactive() {
            let session = runtime.start()?;
            a.steer.start(&session.control(), a.resume.is_some())?;
            session.spawn(task)?;
            session.finish().await?
        } else {
            runtime.run(task).await?
        };
        println!("{report}");
        #[cfg(feature = "net")]
        if let Some(exec) = exec {
            exec.close().await;
        }
        #[cfg(not(feature = "net"))]
        let _: Option<NoAgents> = exec;
        if let Some(viewer) = viewer {
            eprintln!("the run ended; the viewer serves it until interrupted");
            viewer.wait();
        }
        Ok(
            if report.outcome == tdl::RunOutcome::Completed && report.is_clean() {
                0
            } else {
                3
            },
        )
    })
}

/// The journal at `path`, read for `program` (refused if another program wrote it); its warning,
/// if any, printed.
fn resumed(path: &std::path::Path, program: &Program) -> anyhow::Result<tcm_journal::Journal> {
    let journal = tcm_journal::read(path, Some(program.hash()))?;
    if let Some(w) = &journal.warning {
        eprintln!("tdl: {w}");
    }
    Ok(journal)
}

/// The task and arguments a journal says its run started, if it says.
pub(crate) fn started(header: &tcm_journal::Header) -> Option<(String, serde_json::Value)> {
    let start = header.start.as_ref()?;
    let task = start.get("task")?.as_str()?.to_string();
    let args = start.get("args").cloned().unwrap_or_default();
    Some((task, args))
}

/// A runtime given its sinks: the trace to a file (JSON lines), and the viewer, live, if asked.
pub(crate) fn sinks(
    mut runtime: tdl::Runtime,
    trace: Option<&std::path::Path>,
    view: bool,
    name: &str,
) -> anyhow::Result<(tdl::Runtime, Option<tcm_view::Viewer>)> {
    if let Some(path) = trace {
        let file = std::fs::File::create(path)
            .with_context(|| format!("cannot write the trace {}", path.display()))?;
        runtime = runtime.with_sink(tdl::JsonLines(std::io::BufWriter::new(file)));
    }
    let viewer = if view {
        let viewer = tcm_view::Viewer::start(None)?;
        eprintln!("viewer: {}", viewer.url());
        runtime = runtime.with_sink(viewer.live(name.to_string()));
        Some(viewer)
    } else {
        None
    };
    Ok((runtime, viewer))
}

/// A runtime given what the program declares beside its tasks: its attached handlers.
pub(crate) fn equip(mut runtime: tdl::Runtime, program: &Program) -> tdl::Runtime {
    for h in program.attached() {
        runtime = runtime.attach(h);
    }
    runtime
}

/// Without the feature `net`, no agent can be reached.
#[cfg(not(feature = "net"))]
enum NoAgents {}

#[cfg(not(feature = "net"))]
async fn connect(
    _a: &Args,
    outside: &[(String, tdl::NodeKind)],
    _registry: &mut Registry,
) -> anyhow::Result<NoAgents> {
    let names: Vec<&str> = outside.iter().map(|(n, _)| n.as_str()).collect();
    bail!(
        "the program needs tasks from agents ({}), and this tdl was built without the feature \
         `net` (zenoh): install it with `cargo install --path crates/tdl-cli --features net`",
        names.join(", ")
    )
}

/// Opens the executive, waits for the agents (those named, or until every task the program
/// needs is offered), and registers every task they offer.
#[cfg(feature = "net")]
async fn connect(
    a: &Args,
    outside: &[(String, tdl::NodeKind)],
    registry: &mut Registry,
) -> anyhow::Result<tcm_zenoh::Executive> {
    let config = tcm_zenoh::config::loopback_listen(a.port)?;
    let exec = tcm_zenoh::Executive::open(&a.system, config)
        .await
        .with_context(|| format!("cannot listen on 127.0.0.1:{} for agents", a.port))?;
    eprintln!(
        "executive of system `{}` on tcp/127.0.0.1:{}: waiting for agents",
        a.system, a.port
    );
    let wait = Duration::from_secs_f64(a.wait.max(0.0));
    for agent in &a.agents {
        exec.wait_for(agent, None, wait)
            .await
            .with_context(|| format!("the agent `{agent}` did not come"))?;
    }
    let deadline = tokio::time::Instant::now() + wait;
    loop {
        let offers = exec.offers();
        let missing: Vec<&str> = outside
            .iter()
            .map(|(n, _)| n.as_str())
            .filter(|n| !offers.contains_key(*n))
            .collect();
        if missing.is_empty() || tokio::time::Instant::now() >= deadline {
            if !missing.is_empty() {
                eprintln!("no agent offers {} after {wait:?}", missing.join(", "));
            }
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    for (task, agent) in tdl_serve::register_offers(&exec, registry, outside) {
        eprintln!("  {task} on {agent}");
    }
    Ok(exec)
}
