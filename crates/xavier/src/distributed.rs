//! `xavier --distributed`: the executive in this process, the robot's commands in a robot agent
//! process (this binary in its `robot-agent` mode, with the same seed and scenario), and `speak`
//! in the Python agent (`python/examples/xavier_voice.py`) when a Python with the `eclipse-zenoh`
//! package is found, else in the robot agent, with the reason printed. Both processes are children
//! of this one, started here and killed when [`Agents`] is dropped; they also exit by themselves
//! when their standard input, held here, closes.

use anyhow::{Context as _, bail};
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::time::Duration;
use tcm_zenoh::Executive;
use xavier::Setup;
use xavier::robot::Robot;

/// How long an agent process may take to start and be seen.
const JOIN: Duration = Duration::from_secs(30);

/// The zenoh release of the Python package, the Rust side's.
const ZENOH_VERSION: &str = "1.10.2";

/// The agent processes of a distributed run; dropped, they are killed and reaped.
pub(crate) struct Agents {
    children: Vec<(Child, Option<ChildStdin>)>,
}

impl Drop for Agents {
    fn drop(&mut self) {
        for (child, stdin) in &mut self.children {
            drop(stdin.take());
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

/// A distributed run's executive, robot and agents.
pub(crate) struct Distributed {
    pub(crate) exec: Executive,
    pub(crate) robot: Robot,
    // Held for the run: dropped, the agent processes are stopped.
    _agents: Agents,
    /// Who speaks, and why, for the title.
    pub(crate) voice: String,
}

/// Opens the executive on 127.0.0.1, starts the robot agent (and the Python voice unless
/// `python` is false or none is found) and waits until the executive sees them.
pub(crate) async fn start(setup: &Setup, speed: f64, python: bool) -> anyhow::Result<Distributed> {
    let system = format!("xavier-{}", std::process::id());
    let (exec, port) = Executive::open_loopback(&system)
        .await
        .context("cannot open the executive")?;
    let mut agents = Agents {
        children: Vec::new(),
    };
    let exe = std::env::current_exe().context("cannot find this program to start the robot")?;
    // The robot agent listens too, for the voice's queries: peers route nothing for each other.
    let robot_port = tcm_zenoh::config::free_port().context("no free port for the robot agent")?;
    let mut robot = Command::new(exe);
    robot
        .arg("robot-agent")
        .args(["--system", &system, "--port", &port.to_string()])
        .args(["--listen", &robot_port.to_string()])
        .args(["--seed", &setup.seed.to_string()])
        .args(["--scenario", &setup.scenario.to_string()])
        .args(["--speed", &speed.to_string()]);
    spawn_agent(&mut agents, robot, "the robot agent")?;
    exec.wait_for("robot", Some("planPath"), JOIN)
        .await
        .context("the robot agent did not join")?;
    let (voice, note) = if python {
        match python_voice() {
            Ok((interpreter, script, path)) => {
                let mut cmd = Command::new(interpreter);
                cmd.arg(script)
                    .args([&system, &port.to_string(), &robot_port.to_string()])
                    .env("PYTHONPATH", path);
                spawn_agent(&mut agents, cmd, "the Python voice agent")?;
                exec.wait_for("voice", Some("speak"), JOIN)
                    .await
                    .context("the Python voice agent did not join")?;
                ("voice", "speak on the Python agent `voice`".to_string())
            }
            Err(why) => {
                println!("xavier: speak is served by the robot agent: {why}");
                ("robot", format!("speak on the robot agent ({why})"))
            }
        }
    } else {
        (
            "robot",
            "speak on the robot agent (--no-python)".to_string(),
        )
    };
    let robot = Robot::remote(exec.clone(), "robot", voice);
    Ok(Distributed {
        exec,
        robot,
        _agents: agents,
        voice: format!("system {system} on tcp/127.0.0.1:{port}, {note}"),
    })
}

/// Joins the robot agent of `system` listening on `port` of 127.0.0.1 (started apart, and
/// outliving this run) as the executive `id`, and waits until it is seen; `speak` is the robot
/// agent's.
pub(crate) async fn join(system: &str, port: u16, id: &str) -> anyhow::Result<Distributed> {
    let config = tcm_zenoh::config::peer(&[], &[tcm_zenoh::config::endpoint(port)])
        .context("cannot configure the executive")?;
    let exec = Executive::open_as(system, id, config, tcm_zenoh::RemoteOptions::default())
        .await
        .context("cannot open the executive")?;
    exec.wait_for("robot", Some("planPath"), JOIN)
        .await
        .context("the robot agent is not live")?;
    let robot = Robot::remote(exec.clone(), "robot", "robot");
    Ok(Distributed {
        exec,
        robot,
        _agents: Agents {
            children: Vec::new(),
        },
        voice: format!(
            "system {system}, the robot agent on tcp/127.0.0.1:{port}, executive {id}, speak on the              robot agent"
        ),
    })
}

/// Starts `cmd` with piped stdin and stdout and waits for its `ready` line.
fn spawn_agent(agents: &mut Agents, mut cmd: Command, what: &str) -> anyhow::Result<()> {
    let mut child = cmd
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .with_context(|| format!("cannot start {what}"))?;
    let stdin = child.stdin.take();
    let stdout = child.stdout.take();
    agents.children.push((child, stdin));
    let Some(stdout) = stdout else {
        bail!("{what} has no stdout");
    };
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let mut lines = BufReader::new(stdout).lines();
        let ready = lines.by_ref().map_while(Result::ok).any(|l| l == "ready");
        let _ = tx.send(ready);
        // Keep reading, so the agent never blocks on a full pipe.
        for _ in lines {}
    });
    match rx.recv_timeout(JOIN) {
        Ok(true) => Ok(()),
        Ok(false) => bail!("{what} exited before it was ready"),
        Err(_) => bail!("{what} was not ready within {JOIN:?}"),
    }
}

/// The Python interpreter, voice script and module path for the voice agent, or why there is
/// none. Tried in order: `$TDL_PYTHON`, the workspace's test venv (`target/test-venv`, made by
/// the tests), `python3` on the path; the first that imports `zenoh` in release
/// [`ZENOH_VERSION`] and `tdl_agent` is taken.
fn python_voice() -> Result<(PathBuf, PathBuf, PathBuf), String> {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let path = repo.join("python");
    let script = path.join("examples/xavier_voice.py");
    if !script.is_file() {
        return Err(format!("{} is missing", script.display()));
    }
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| repo.join("target"));
    let mut candidates: Vec<PathBuf> = Vec::new();
    if let Some(p) = std::env::var_os("TDL_PYTHON") {
        candidates.push(PathBuf::from(p));
    }
    candidates.push(target.join("test-venv/bin/python3"));
    candidates.push(PathBuf::from("python3"));
    let check = format!(
        "import importlib.metadata as m, zenoh, tdl_agent\n\
         assert m.version('eclipse-zenoh') == '{ZENOH_VERSION}'"
    );
    for python in &candidates {
        let ok = Command::new(python)
            .args(["-c", &check])
            .env("PYTHONPATH", &path)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success());
        if ok {
            return Ok((python.clone(), script, path));
        }
    }
    Err(format!(
        "no Python with eclipse-zenoh {ZENOH_VERSION} (tried $TDL_PYTHON, {}, python3 on PATH; \
         `pip install eclipse-zenoh=={ZENOH_VERSION}`, or run `cargo test -p tcm-zenoh` once to make the venv)",
        target.join("test-venv").display()
    ))
}
