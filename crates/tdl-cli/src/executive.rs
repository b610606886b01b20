//! `tdl serve` and its clients (docs/distributed.md, "A serving executive"): a long-lived
//! executive that holds programs loaded at run time and runs their tasks (crate `tdl-serve`), and
//! `tdl load`, `tdl unload`, `tdl programs`, `tdl start`, `tdl stop`, `tdl raise`, `tdl status`,
//! each one request to an executive named on the command line.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::Context as _;
use tdl_serve::{Client, File, Reply, Request, Response, Swap};

const CLIENT_STATUS: &str = "Exit status: 0 when the executive did what was asked; 1 when it \
refused (its reason, with a program's diagnostics, is printed; nothing changed); 2 when no \
executive answered.";

/// Where the executive is, for its clients.
#[derive(clap::Args)]
pub(crate) struct To {
    /// The executive's name.
    #[arg(long = "to", default_value = "main")]
    executive: String,
    /// The system it belongs to.
    #[arg(long, default_value = "tdl")]
    system: String,
    /// The port of 127.0.0.1 it listens on.
    #[arg(long, default_value_t = 7447)]
    port: u16,
    /// This client's name, which the executive records as who asked (default: the user's).
    #[arg(long)]
    client: Option<String>,
    /// How long to wait for the answer, in seconds.
    #[arg(long, value_name = "SECONDS", default_value_t = 10.0)]
    timeout: f64,
    /// Speak over mutual TLS with the certificates `tdl certs` wrote in DIR: its
    /// `authority.pem`, and the client's `<client>.pem` and `<client>.key`.
    #[arg(long, value_name = "DIR")]
    tls: Option<PathBuf>,
}

/// Options of `tdl serve`.
#[derive(clap::Args)]
pub(crate) struct ServeArgs {
    /// The executive's name, which clients give with `--to`.
    #[arg(long, default_value = "main")]
    name: String,
    /// The system it serves (agents join it by this name).
    #[arg(long, default_value = "tdl")]
    system: String,
    /// The port of 127.0.0.1 it listens on, for agents and clients.
    #[arg(long, default_value_t = 7447)]
    port: u16,
    /// Where each run's trace is written (`run-<n>.jsonl`).
    #[arg(long, value_name = "DIR", default_value = "tdl-runs")]
    traces: PathBuf,
    /// Listen over mutual TLS only, with the certificates `tdl certs` wrote in DIR (its
    /// `authority.pem`, and `<name>.pem`, `<name>.key` of this executive), and apply the
    /// system's access rules: only the members named by `--agents` and `--clients` are let in,
    /// and only clients may send requests, each under its own name.
    #[arg(long, value_name = "DIR")]
    tls: Option<PathBuf>,
    /// With `--tls`: the agents that may join.
    #[arg(long, value_delimiter = ',')]
    agents: Vec<String>,
    /// The clients whose requests are taken (default: any client's; with `--tls`, none but
    /// these may even ask).
    #[arg(long, value_delimiter = ',')]
    clients: Vec<String>,
}

/// The certificates of `member` in `dir`, as `tdl certs` writes them.
fn certs(dir: &std::path::Path, member: &str) -> tcm_zenoh::config::Certs {
    tcm_zenoh::config::Certs {
        authority: dir.join("authority.pem"),
        certificate: dir.join(format!("{member}.pem")),
        key: dir.join(format!("{member}.key")),
    }
}

/// A client request, as the command line gives it.
#[derive(clap::Subcommand)]
pub(crate) enum Ask {
    /// Load a program (or a new version of one) into a serving executive: checked there, refused
    /// with its diagnostics if it has errors (nothing changes then).
    #[command(after_help = CLIENT_STATUS)]
    Load {
        /// The program's `.tdl` files.
        #[arg(required = true)]
        files: Vec<PathBuf>,
        /// Its name (default: the first file's stem).
        #[arg(long)]
        name: Option<String>,
        /// How runs of an older version take this one: `spawns` (new spawns use it; refused if a
        /// task changes parameters), `now` (their top-level task restarts), `after:TASK` (it
        /// restarts when a node of TASK completes).
        #[arg(long, default_value = "spawns", value_parser = parse_swap)]
        swap: Swap,
        /// Model-check the program there first (`tdl verify`, from its default task or
        /// `--verify-task`): refused if a property is broken within `--max-states`.
        #[arg(long)]
        verify: bool,
        /// The task the model check starts from.
        #[arg(long, value_name = "TASK", requires = "verify")]
        verify_task: Option<String>,
        /// The model check's bound on distinct states.
        #[arg(long, value_name = "N", default_value_t = 100_000, requires = "verify")]
        max_states: u64,
        /// The program runs until stopped: the model check does not ask that every run ends.
        #[arg(long, requires = "verify")]
        runs_forever: bool,
        #[command(flatten)]
        to: To,
    },
    /// Remove a program (refused while a run runs it); its attached handlers leave every run.
    #[command(after_help = CLIENT_STATUS)]
    Unload {
        /// The program's name.
        name: String,
        #[command(flatten)]
        to: To,
    },
    /// List the programs an executive holds, with their versions.
    #[command(after_help = CLIENT_STATUS)]
    Programs {
        #[command(flatten)]
        to: To,
    },
    /// Start a task of a loaded program, in a run of its own; prints the run's number.
    #[command(after_help = CLIENT_STATUS)]
    Start {
        /// The program's name.
        program: String,
        /// The task (default: the program's only goal or command no task of it spawns).
        #[arg(long)]
        task: Option<String>,
        /// Its arguments as JSON (as `tdl run --args`).
        #[arg(long, value_name = "JSON")]
        args: Option<String>,
        #[command(flatten)]
        to: To,
    },
    /// Stop a run: its top-level task is terminated, and its cleanup runs.
    #[command(after_help = CLIENT_STATUS)]
    Stop {
        /// The run's number.
        run: u64,
        #[command(flatten)]
        to: To,
    },
    /// Raise an external event in a run.
    #[command(after_help = CLIENT_STATUS)]
    Raise {
        /// The run's number.
        run: u64,
        /// The event's name.
        event: String,
        #[command(flatten)]
        to: To,
    },
    /// The runs of an executive (or one): task, version, outcome, live nodes, trace file.
    #[command(after_help = CLIENT_STATUS)]
    Status {
        /// Only this run.
        run: Option<u64>,
        #[command(flatten)]
        to: To,
    },
}

fn parse_swap(s: &str) -> Result<Swap, String> {
    match s {
        "spawns" => Ok(Swap::Spawns),
        "now" => Ok(Swap::Now),
        _ => match s.strip_prefix("after:") {
            Some(task) if !task.is_empty() => Ok(Swap::After { task: task.into() }),
            _ => Err(format!("`{s}`: write `spawns`, `now` or `after:TASK`")),
        },
    }
}

fn runtime() -> anyhow::Result<tokio::runtime::Runtime> {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("cannot start the async runtime")
}

/// `tdl serve`: serves until interrupted.
pub(crate) fn serve(a: ServeArgs) -> anyhow::Result<u8> {
    runtime()?.block_on(async move {
        let config = match &a.tls {
            None => tcm_zenoh::config::loopback_listen(a.port)?,
            Some(dir) => {
                let roster = tcm_zenoh::config::Roster {
                    executives: vec![a.name.clone()],
                    agents: a.agents.clone(),
                    clients: a.clients.clone(),
                };
                let config =
                    tcm_zenoh::config::loopback_tls_listen(a.port, &certs(dir, &a.name))?;
                tcm_zenoh::config::with_access(config, &a.system, &roster)?
            }
        };
        let exec = tcm_zenoh::Executive::open(&a.system, config)
            .await
            .with_context(|| format!("cannot listen on 127.0.0.1:{}", a.port))?;
        let server =
            tdl_serve::Server::new(tdl_interp::Registry::new(), Some(exec.clone()), &a.traces)
                .clients(a.clients.clone());
        let serving = tdl_serve::serve(server, exec.session(), &a.system, &a.name).await?;
        eprintln!(
            "tdl serve: executive `{}` of system `{}` on tcp/127.0.0.1:{}; traces in {} (Ctrl-C to stop)",
            a.name,
            a.system,
            a.port,
            a.traces.display()
        );
        tokio::signal::ctrl_c()
            .await
            .context("cannot wait for Ctrl-C")?;
        serving.close();
        exec.close().await;
        Ok(0)
    })
}

/// A client request: its exit status (see [`CLIENT_STATUS`]).
pub(crate) fn ask(ask: Ask) -> anyhow::Result<u8> {
    let (request, to) = match ask {
        Ask::Load {
            files,
            name,
            swap,
            verify,
            verify_task,
            max_states,
            runs_forever,
            to,
        } => {
            let verify = verify.then_some(tdl_serve::Verify {
                task: verify_task,
                max_states,
                runs_forever,
            });
            let name = match name {
                Some(n) => n,
                None => files
                    .first()
                    .and_then(|p| p.file_stem())
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or_default(),
            };
            let mut read = Vec::new();
            for p in &files {
                let text = std::fs::read_to_string(p)
                    .with_context(|| format!("cannot read {}", p.display()))?;
                read.push(File {
                    name: p.display().to_string(),
                    text,
                });
            }
            (
                Request::Load {
                    name,
                    files: read,
                    swap,
                    verify,
                },
                to,
            )
        }
        Ask::Unload { name, to } => (Request::Unload { name }, to),
        Ask::Programs { to } => (Request::List, to),
        Ask::Start {
            program,
            task,
            args,
            to,
        } => {
            let args = match args {
                Some(text) => serde_json::from_str(&text).context("--args is not JSON")?,
                None => serde_json::Value::Null,
            };
            (
                Request::Start {
                    program,
                    task,
                    args,
                },
                to,
            )
        }
        Ask::Stop { run, to } => (Request::Stop { run }, to),
        Ask::Raise { run, event, to } => (Request::Raise { run, event }, to),
        Ask::Status { run, to } => (Request::Status { run }, to),
    };
    let client_name = to
        .client
        .clone()
        .or_else(|| std::env::var("USER").ok())
        .unwrap_or_else(|| "tdl".into());
    runtime()?.block_on(async move {
        let config = match &to.tls {
            None => tcm_zenoh::config::loopback_connect(to.port)?,
            Some(dir) => {
                tcm_zenoh::config::loopback_tls_connect(to.port, &certs(dir, &client_name))?
            }
        };
        let client = Client::open(&to.system, &client_name, config)
            .await?
            .with_timeout(Duration::from_secs_f64(to.timeout.max(0.1)));
        // The link to the executive comes up within milliseconds of opening: a first query sent
        // before it would find no one, so one unanswered query is asked again.
        let mut answer = client.request(&to.executive, &request).await;
        if matches!(answer, Err(tdl_serve::Error::NoAnswer { .. })) {
            answer = client.request(&to.executive, &request).await;
        }
        client.close().await;
        Ok(match answer {
            Ok(Response::Ok(reply)) => {
                print!("{}", describe(&reply));
                0
            }
            Ok(Response::Refused(why)) => {
                eprintln!("{why}");
                1
            }
            Err(e) => {
                eprintln!("tdl: {e}");
                2
            }
        })
    })
}

/// A reply, for people.
fn describe(reply: &Reply) -> String {
    match reply {
        Reply::Loaded {
            version,
            unchanged: true,
            ..
        } => format!("{version} was loaded already: nothing changed\n"),
        Reply::Loaded {
            version,
            swapped,
            verified,
            ..
        } => format!(
            "loaded {version}{}{}\n",
            verified
                .as_ref()
                .map(|v| format!(" (model check {v})"))
                .unwrap_or_default(),
            if swapped.is_empty() {
                String::new()
            } else {
                format!(
                    "; run(s) {} take it",
                    swapped
                        .iter()
                        .map(ToString::to_string)
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            }
        ),
        Reply::Unloaded => "unloaded\n".into(),
        Reply::Programs(programs) => programs
            .iter()
            .map(|p| {
                let attaches = if p.attaches_to.is_empty() {
                    String::new()
                } else {
                    format!("; handlers for {}", p.attaches_to.join(", "))
                };
                format!(
                    "{}  tasks: {}{attaches}  (loaded by {})\n",
                    p.version,
                    p.tasks.join(", "),
                    p.loaded_by
                )
            })
            .collect(),
        Reply::Started { run, trace } => format!("run {run} started; its trace: {trace}\n"),
        Reply::Done => "done\n".into(),
        Reply::Runs(runs) => runs
            .iter()
            .map(|r| {
                let state = match (&r.outcome, r.running) {
                    (_, true) => format!("running, {} live node(s)", r.live_nodes),
                    (Some(o), false) => o.clone(),
                    (None, false) => "ending".into(),
                };
                format!(
                    "run {}  {} of {}  {state}  trace: {}\n",
                    r.run, r.task, r.version, r.trace
                )
            })
            .collect(),
    }
}
