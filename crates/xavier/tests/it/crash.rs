//! The crash campaign (docs/semantics.md, "Durable runs"; docs/distributed.md, "An executive that
//! comes back"): the executive of a distributed Xavier round, journaling its run, is killed with
//! SIGKILL at seeded points of the round, on the real clock scaled ×40, while its robot agent, a
//! process of its own, outlives it and holds the commands it was running. `xavier --resume` then
//! resumes the run from the journal. A replay may stop at a difference it finds between the run
//! and itself (`Diverged`, said, nothing run live): those are counted, at most one in 25 (one in
//! 250 was seen; docs/semantics.md, "Durable runs", item 9). Each other resumed run must end as
//! the uncrashed run of the same seed and scenario ended (the rooms delivered and given up and
//! why, the exceptions, the distance driven, the run's outcome); its whole trace (the run replayed
//! from the journal, then the rest) must pass the checker; the agent must have aborted no body for
//! want of its executive; and over the campaign, commands in flight at a kill must have been
//! re-attached (each node ends once: the checker holds every node to one end).
//!
//! `TDL_CRASH_POINTS` sets the number of kill points (50 by default, spread over five seeds and
//! three scenarios).

use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// How long one xavier process may take.
const BOUND: Duration = Duration::from_secs(120);

/// The setups of the campaign: seed and scenario.
const SETUPS: [(u64, &str); 5] = [
    (1, "nominal"),
    (2, "blocked-corridor"),
    (3, "no-path"),
    (4, "nominal"),
    (5, "blocked-corridor"),
];

fn exe() -> &'static str {
    env!("CARGO_BIN_EXE_xavier")
}

fn dir() -> PathBuf {
    let d = std::env::temp_dir().join(format!("xavier-crash-{}", std::process::id()));
    std::fs::create_dir_all(&d).expect("a temporary directory");
    d
}

/// A robot agent process, listening on its port; its standard input held, its output read.
struct RobotAgent {
    child: Child,
    stdin: Option<ChildStdin>,
    lines: mpsc::Receiver<String>,
}

impl RobotAgent {
    fn start(system: &str, port: u16, seed: u64, scenario: &str) -> RobotAgent {
        let mut child = Command::new(exe())
            .args(["robot-agent", "--system", system, "--listen"])
            .arg(port.to_string())
            .args(["--seed", &seed.to_string(), "--scenario", scenario])
            .args(["--speed", "40", "--hold", "60"])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("the robot agent starts");
        let stdin = child.stdin.take();
        let out = child.stdout.take().expect("its stdout");
        let (tx, lines) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(out).lines().map_while(Result::ok) {
                let _ = tx.send(line);
            }
        });
        let agent = RobotAgent {
            child,
            stdin,
            lines,
        };
        match agent.lines.recv_timeout(Duration::from_secs(30)) {
            Ok(l) if l == "ready" => agent,
            other => panic!("the robot agent did not say ready: {other:?}"),
        }
    }

    /// Stops the agent (its standard input closes); the line in which it says what it did.
    fn stop(mut self) -> String {
        drop(self.stdin.take());
        let deadline = Instant::now() + Duration::from_secs(30);
        let mut said = String::new();
        while let Ok(line) = self
            .lines
            .recv_timeout(deadline.saturating_duration_since(Instant::now()))
        {
            if line.starts_with("agent:") {
                said = line;
            }
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
        said
    }
}

impl Drop for RobotAgent {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The executive's command line for a round of `seed` and `scenario` on the agent at `port`.
fn executive(system: &str, port: u16, seed: u64, scenario: &str) -> Command {
    let mut cmd = Command::new(exe());
    cmd.args(["--distributed", "--agent-port", &port.to_string()])
        .args(["--system", system, "--seed", &seed.to_string()])
        .args(["--scenario", scenario])
        .stdin(Stdio::null());
    cmd
}

/// Runs `cmd` to its end, bounded; its exit code and standard output.
fn finish(mut cmd: Command) -> (Option<i32>, String) {
    let out = tempfile(&cmd);
    let err = out.with_extension("err");
    let mut child = cmd
        .stdout(std::fs::File::create(&out).expect("an output file"))
        .stderr(std::fs::File::create(&err).expect("an error file"))
        .spawn()
        .expect("xavier starts");
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().expect("xavier runs") {
            break status;
        }
        if start.elapsed() > BOUND {
            let _ = child.kill();
            panic!("xavier did not end within {BOUND:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut text = std::fs::read_to_string(&out).unwrap_or_default();
    let log = std::fs::read_to_string(&err).unwrap_or_default();
    if !log.trim().is_empty() {
        text.push_str("\n--- its standard error:\n");
        text.push_str(&log);
    }
    (status.code(), text)
}

fn tempfile(cmd: &Command) -> PathBuf {
    let name: Vec<String> = cmd
        .get_args()
        .map(|a| a.to_string_lossy().replace(['/', ' '], "_"))
        .collect();
    let mut h: u64 = 1469598103934665603;
    for b in name.join(" ").bytes() {
        h = (h ^ u64::from(b)).wrapping_mul(1099511628211);
    }
    dir().join(format!("out-{h:016x}.txt"))
}

/// What must match between a resumed run and the uncrashed one: the summary's rooms, exceptions
/// and failures, the distance driven, and the run's outcome.
fn outcome(stdout: &str) -> Vec<String> {
    let Some(summary) = stdout.split("Xavier's mail round:").nth(1) else {
        return vec![format!("no summary in:\n{stdout}")];
    };
    let mut kept = Vec::new();
    for line in summary.lines().map(str::trim) {
        if [
            "delivered:",
            "undeliverable:",
            "room ",
            "exceptions:",
            "run:",
        ]
        .iter()
        .any(|k| line.starts_with(k))
        {
            kept.push(line.to_string());
        }
        if let Some(at) = line.find(" m driven") {
            let before = &line[..at];
            let metres = before.rsplit('(').next().unwrap_or(before);
            kept.push(format!("driven: {metres} m"));
        }
    }
    kept
}

/// The difference a replay stopped at, if it did.
fn diverged(stdout: &str) -> Option<String> {
    stdout
        .lines()
        .map(str::trim)
        .find_map(|l| l.strip_prefix("run:"))
        .map(str::trim)
        .filter(|r| r.starts_with("Diverged"))
        .map(String::from)
}

/// The wall time of a round, from its summary.
fn wall_time(stdout: &str) -> Duration {
    stdout
        .lines()
        .find_map(|l| l.trim().strip_prefix("wall time:"))
        .and_then(|t| t.trim().trim_end_matches(" s").parse::<f64>().ok())
        .map(Duration::from_secs_f64)
        .unwrap_or_else(|| panic!("no wall time in:\n{stdout}"))
}

/// A number from a line `agent: started 12, …, reattached 2, orphaned 0, …`.
fn count(said: &str, what: &str) -> u64 {
    said.split(", ")
        .find_map(|part| {
            let part = part.trim_start_matches("agent: ");
            part.strip_prefix(what)?.trim().parse().ok()
        })
        .unwrap_or_else(|| panic!("no `{what}` in {said:?}"))
}

/// A small seeded generator for the kill points (xorshift).
struct Seeded(u64);

impl Seeded {
    fn fraction(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn check_trace(path: &Path) -> usize {
    let events = tcm_trace::read_jsonl(BufReader::new(
        std::fs::File::open(path).expect("the resumed run's trace"),
    ))
    .expect("the resumed run's trace reads");
    if let Err(vs) = tcm_trace::check(&events) {
        panic!(
            "the trace checker refuses {}: {:?}",
            path.display(),
            &vs[..vs.len().min(5)]
        );
    }
    events.len()
}

#[test]
fn a_round_killed_at_seeded_points_resumes_and_ends_as_the_uncrashed_round() {
    let points: usize = std::env::var("TDL_CRASH_POINTS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(50);
    let mut seeded = Seeded(0x46_4a_4f_55_52_4e_41_4c);
    let mut reattached = 0;
    let mut divergences: Vec<String> = Vec::new();
    let mut resumed_mid_round = 0;
    let per_setup = points.div_ceil(SETUPS.len());
    let mut done = 0;
    for (k, &(seed, scenario)) in SETUPS.iter().enumerate() {
        if done >= points {
            break;
        }
        // The uncrashed round, on an agent of its own.
        let system = format!("crash-{}-{k}-ref", std::process::id());
        let port = tcm_zenoh::config::free_port().expect("a port");
        let agent = RobotAgent::start(&system, port, seed, scenario);
        let (code, reference) = finish(executive(&system, port, seed, scenario));
        agent.stop();
        assert_eq!(code, Some(0), "the uncrashed round failed:\n{reference}");
        let want = outcome(&reference);
        let round = wall_time(&reference);
        for i in 0..per_setup.min(points - done) {
            done += 1;
            let system = format!("crash-{}-{k}-{i}", std::process::id());
            let port = tcm_zenoh::config::free_port().expect("a port");
            let journal = dir().join(format!("{system}.journal"));
            let trace = dir().join(format!("{system}.jsonl"));
            // The crashed run's own trace, up to the kill: kept with the journal when the replay
            // differs from the run, to see where.
            let before = dir().join(format!("{system}-before.jsonl"));
            let _ = std::fs::remove_file(&journal);
            let agent = RobotAgent::start(&system, port, seed, scenario);
            let mut first = executive(&system, port, seed, scenario);
            first
                .arg("--journal")
                .arg(&journal)
                .arg("--trace")
                .arg(&before)
                .stdout(Stdio::null())
                .stderr(Stdio::null());
            let mut first = first.spawn().expect("the executive starts");
            // A point of the round: after its start, before its end.
            let kill_at = round.mul_f64(0.05 + 0.9 * seeded.fraction());
            std::thread::sleep(kill_at);
            let crashed = first.try_wait().expect("the executive runs").is_none();
            let _ = first.kill();
            let _ = first.wait();
            if crashed {
                resumed_mid_round += 1;
            }
            let mut again = executive(&system, port, seed, scenario);
            again
                .arg("--resume")
                .arg(&journal)
                .arg("--trace")
                .arg(&trace);
            let (code, out) = finish(again);
            let said = agent.stop();
            let at = format!(
                "seed {seed}, {scenario}, killed after {} ms",
                kill_at.as_millis()
            );
            if let Some(why) = diverged(&out) {
                // The replay stopped at a difference and said so (exit status 1, nothing run
                // live): counted, and bounded below.
                eprintln!(
                    "{at}: the replay diverged: {why}\n  kept: the journal {}, the crashed run's \
                     trace {}, the resumed run's {}",
                    journal.display(),
                    before.display(),
                    trace.display()
                );
                divergences.push(format!("{at}: {why}"));
                continue;
            }
            assert_eq!(code, Some(0), "{at}: the resumed round failed:\n{out}");
            assert_eq!(
                outcome(&out),
                want,
                "{at}: the resumed round ended otherwise:\n{out}"
            );
            check_trace(&trace);
            assert_eq!(
                count(&said, "orphaned"),
                0,
                "{at}: the agent aborted bodies of the executive: {said}"
            );
            reattached += count(&said, "reattached");
            let _ = std::fs::remove_file(&journal);
            let _ = std::fs::remove_file(&trace);
            let _ = std::fs::remove_file(&before);
        }
    }
    eprintln!(
        "{done} kill points, {resumed_mid_round} in the middle of a round, {reattached} commands \
         re-attached, {} replays diverged",
        divergences.len()
    );
    assert!(resumed_mid_round * 2 >= done, "most kills land in a round");
    // A replay that reports a difference never goes on silently; it happened once in 250 kill
    // points in the last long campaign (docs/semantics.md, "Durable runs", item 9).
    assert!(
        divergences.len() * 25 <= done,
        "more than one in 25 resumed rounds diverged: {divergences:#?}"
    );
    assert!(reattached > 0, "no kill found a command in flight");
    let _ = std::io::stderr().flush();
}
