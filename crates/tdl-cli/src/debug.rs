//! Steering `tdl run` from its terminal, for a headless robot (docs/semantics.md, "Steering a
//! run"; docs/tools.md, "tdl run"): faults from a file, approval rules, breakpoints, and commands
//! read from standard input while the run runs. What the run does about it (paused, held,
//! injected, resumed) is printed on standard error as it happens.

use std::io::BufRead;
use std::path::PathBuf;

use anyhow::Context as _;
use tdl::{Approval, BreakAt, Breakpoint, Control, Failure, Fault, FaultOutcome, Matcher};

/// The commands, as `help` prints them.
const HELP: &str = "commands: c (continue), s (step), n (to the next start), p (pause), \
b TASK (break before its start), e TASK (break after its end), x TASK EXCEPTION (inject), \
d ID (remove a breakpoint or rule), h (held nodes), a N (approve node N), r N [WHY] (refuse), \
ev EVENT [JSON] (raise an external event, with data), help";

/// The steering options of `tdl run`.
#[derive(clap::Args, Default)]
pub(crate) struct Steer {
    /// Inject the faults of this file (a JSON list of rules; docs/tools.md, "tdl run").
    #[arg(long, value_name = "FILE")]
    faults: Option<PathBuf>,
    /// Hold each node of this task until it is approved from standard input (`a N`).
    #[arg(long, value_name = "TASK")]
    approve: Vec<String>,
    /// Pause before each node of this task starts; commands come from standard input.
    #[arg(long = "break", value_name = "TASK")]
    breaks: Vec<String>,
    /// Read steering commands from standard input even without `--break` or `--approve`.
    #[arg(long)]
    debug: bool,
}

impl Steer {
    /// Whether the run is steered from standard input (then it runs as a session).
    pub(crate) fn interactive(&self) -> bool {
        self.debug || !self.breaks.is_empty() || !self.approve.is_empty()
    }

    /// The faults and approval rules, given to the runtime before the run starts.
    pub(crate) fn prepare(&self, mut rt: tdl::Runtime) -> anyhow::Result<tdl::Runtime> {
        if let Some(path) = &self.faults {
            for fault in tdl::read_faults(path)? {
                rt = rt.inject(fault);
            }
        }
        for task in &self.approve {
            rt = rt.require_approval(Approval {
                on: Matcher::Task(task.clone().into()),
                timeout: None,
            });
        }
        if self.interactive() {
            rt = rt.with_sink(Announce::default());
        }
        Ok(rt)
    }

    /// The breakpoints, set once the session started (not again in a resumed run: its journal
    /// gives them), and the command reader on a thread of its own. When standard input ends, the
    /// run is released (breakpoints and approval rules gone, held nodes approved), so that it
    /// cannot wait for nobody.
    pub(crate) fn start(&self, control: &Control, resumed: bool) -> anyhow::Result<()> {
        let breaks: &[String] = if resumed { &[] } else { &self.breaks };
        for task in breaks {
            let bp = Breakpoint {
                at: BreakAt::Start,
                on: Matcher::Task(task.clone().into()),
            };
            control
                .add_breakpoint(bp, "terminal")
                .context("cannot set the breakpoint")?;
        }
        eprintln!("{HELP}");
        // The lines are read on a thread of their own and carried out by a task of the run's
        // runtime: between the polls of the run's actions, never in the middle of one, so that a
        // journal of the run gives each operation where a replay can give it again.
        let (lines, mut read) = tokio::sync::mpsc::unbounded_channel::<Option<String>>();
        let control = control.clone();
        tokio::spawn(async move {
            while let Some(Some(line)) = read.recv().await {
                match command(&control, line.trim()) {
                    Ok(Some(said)) => eprintln!("> {said}"),
                    Ok(None) => {}
                    Err(e) => eprintln!("> {e}"),
                }
            }
            // A resumed run takes no operation before it goes on live: the release waits.
            while let Err(tdl::Error::Replaying) =
                control.release("terminal (standard input closed)")
            {
                tokio::time::sleep(std::time::Duration::from_millis(20)).await;
            }
        });
        std::thread::Builder::new()
            .name("tdl-steer".into())
            .spawn(move || {
                let stdin = std::io::stdin();
                for line in stdin.lock().lines() {
                    let Ok(line) = line else { break };
                    if lines.send(Some(line)).is_err() {
                        return;
                    }
                }
                let _ = lines.send(None);
            })
            .context("cannot start the command reader")?;
        Ok(())
    }
}

/// Carries out one command line; what to say about it.
fn command(control: &Control, line: &str) -> anyhow::Result<Option<String>> {
    let mut words = line.split_whitespace();
    let Some(verb) = words.next() else {
        return Ok(None);
    };
    let rest: Vec<&str> = words.collect();
    let by = "terminal";
    let said = match (verb, rest.as_slice()) {
        ("c" | "continue", []) => yes(control.resume(by)?, "continue", "not paused"),
        ("s" | "step", []) => yes(control.step(by)?, "step", "not paused"),
        ("n" | "next", []) => yes(
            control.step_to_start(by)?,
            "to the next start",
            "not paused",
        ),
        ("p" | "pause", []) => yes(control.pause(by)?, "paused", "already paused"),
        ("b" | "break", [task]) | ("e" | "break-after", [task]) => {
            let at = if verb.starts_with('b') {
                BreakAt::Start
            } else {
                BreakAt::End
            };
            let on = Matcher::Task((*task).to_string().into());
            let id = control.add_breakpoint(Breakpoint { at, on }, by)?;
            format!("breakpoint #{}", id.0)
        }
        ("x" | "inject", [task, exception]) => {
            let fault = Fault {
                on: Matcher::Task((*task).to_string().into()),
                times: 1,
                outcome: FaultOutcome::Fail(Failure::new(
                    (*exception).to_string(),
                    "injected from the terminal",
                )),
            };
            format!("fault #{}", control.inject(fault, by)?.0)
        }
        ("d" | "delete", [id]) => {
            let id = tdl::SteerId(id.parse().context("`d ID`: ID is a number")?);
            yes(
                control.remove(id, by)?,
                "removed",
                "no such breakpoint or rule",
            )
        }
        ("h" | "held", []) => {
            let held = control.held()?;
            let numbers: Vec<String> = held
                .iter()
                .filter_map(|n| control.info(*n).ok().flatten())
                .map(|i| format!("{} {{{}}}", i.name, i.display))
                .collect();
            if numbers.is_empty() {
                "nothing held".into()
            } else {
                format!("held: {}", numbers.join(", "))
            }
        }
        ("a" | "approve", [n]) => {
            control.approve(node(control, n)?, by)?;
            "approved".into()
        }
        ("r" | "refuse", [n, why @ ..]) => {
            let why = if why.is_empty() {
                "refused from the terminal".to_string()
            } else {
                why.join(" ")
            };
            control.refuse(node(control, n)?, by, &why)?;
            "refused".into()
        }
        ("ev" | "raise", [event, data @ ..]) => {
            if data.is_empty() {
                control.raise(event)?;
            } else {
                let data: serde_json::Value = serde_json::from_str(&data.join(" "))
                    .context("`ev EVENT JSON`: the data is not JSON")?;
                control.note_input(&format!("raise {event} with {data}"), by)?;
                control.raise_with(event, data)?;
            }
            format!("raised {event}")
        }
        ("help" | "?", _) => HELP.into(),
        _ => anyhow::bail!("`{line}`: not a command; {HELP}"),
    };
    Ok(Some(said))
}

fn yes(done: bool, said: &str, not: &str) -> String {
    if done { said } else { not }.to_string()
}

/// The live node numbered `n`, as the trace and the announcements number it.
fn node(control: &Control, n: &str) -> anyhow::Result<tdl::NodeId> {
    let number: u64 = n.parse().context("a node is named by its number")?;
    control
        .node_by_number(number)?
        .with_context(|| format!("no live node numbered {number}"))
}

/// Prints what the steering does to the run, as it happens.
#[derive(Default)]
struct Announce {
    names: std::collections::BTreeMap<u64, String>,
}

impl tdl::TraceSink for Announce {
    fn record(&mut self, ev: &tdl::TraceEvent) {
        use tdl::TraceKind as K;
        match &ev.kind {
            K::Spawned { node, name, .. } => {
                self.names.insert(*node, name.clone());
            }
            K::Paused { .. } | K::Resumed { .. } | K::Held { .. } | K::Injected { .. } => {
                let names = &self.names;
                let name = |n: u64| names.get(&n).cloned().unwrap_or_default();
                if let Some((_, node, text)) = ev.kind.describe(name) {
                    let at = ev.t as f64 / 1e9;
                    let node = node
                        .map(|n| format!("{} {{{n}}}: ", name(n)))
                        .unwrap_or_default();
                    eprintln!("[{at:.3}s] {node}{text}");
                }
            }
            _ => {}
        }
    }
}
