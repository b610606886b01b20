//! `xavier --distributed`: the mission with the robot's commands in a robot agent process and
//! `speak` in the Python agent, on 127.0.0.1. Its outcome and its tree match the single-process
//! run of the same seed, as far as a run on the real clock can (docs/distributed.md, "The
//! distributed Xavier"): the summary's rooms, notifications and exceptions; every node's name,
//! path and events, without times and agents, but for the activations of the periodic motor
//! monitor, whose number follows the length of the trip in time, and the pickup monitor's polls
//! that found the letter still there (a loaded machine can move the letter's taking across a
//! poll; the poll that finds it gone, and what it starts, are compared). The trace checker accepts the
//! distributed trace, and no agent process outlives the run.

use serde_json::Value;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// How long one run may take.
const BOUND: Duration = Duration::from_secs(180);

/// The periodic monitor's activations, which are not compared one for one.
const PERIODIC: &str = "ACT-watch_motor";
/// An activation of the pickup monitor, and the one command of a poll that found nothing.
const PICKUP: &str = "ACT-monitor_pickup";
const POLL: &str = "mailGone";

/// Runs xavier with `args`, bounded; its exit code and stdout, and its process id.
fn xavier(args: &[&str]) -> (Option<i32>, String, u32) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_xavier"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("xavier starts");
    let pid = child.id();
    let mut out = child.stdout.take().expect("its stdout");
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = std::io::Read::read_to_string(&mut out, &mut s);
        s
    });
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().expect("xavier runs") {
            break status;
        }
        if start.elapsed() > BOUND {
            let _ = child.kill();
            panic!("xavier {args:?} did not end within {BOUND:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    (status.code(), reader.join().expect("stdout read"), pid)
}

/// The summary's lines that must match: rooms, notifications, exceptions, failures, outcome.
fn outcome(stdout: &str) -> Vec<String> {
    const KEPT: [&str; 7] = [
        "delivered:",
        "senders told:",
        "undeliverable:",
        "letter not taken:",
        "exceptions:",
        "failures:",
        "run:",
    ];
    let summary = stdout
        .split("Xavier's mail round:")
        .nth(1)
        .expect("a summary");
    summary
        .lines()
        .map(str::trim)
        .filter(|l| KEPT.iter().any(|k| l.starts_with(k)))
        .map(String::from)
        .collect()
}

fn records(path: &Path) -> Vec<Value> {
    let text = std::fs::read_to_string(path).expect("the trace was written");
    text.lines()
        .map(|l| serde_json::from_str(l).expect("a JSON record"))
        .collect()
}

/// Keys of a record whose numbers name nodes.
const NODE_REFS: [&str; 3] = ["node", "parent", "monitor"];

fn renumber(
    v: &Value,
    key: Option<&str>,
    num: &BTreeMap<u64, usize>,
    skip: &BTreeSet<u64>,
) -> Value {
    match v {
        Value::Object(m) => Value::Object(
            m.iter()
                .map(|(k, x)| (k.clone(), renumber(x, Some(k), num, skip)))
                .collect(),
        ),
        Value::Array(xs) => Value::Array(xs.iter().map(|x| renumber(x, key, num, skip)).collect()),
        Value::Number(n) if key.is_some_and(|k| NODE_REFS.contains(&k)) => match n.as_u64() {
            Some(id) if skip.contains(&id) => Value::from("periodic activation"),
            Some(id) => num.get(&id).map_or(v.clone(), |&i| Value::from(i)),
            None => v.clone(),
        },
        _ => v.clone(),
    }
}

/// The tree of a trace: per node, in order of creation, its path of names and its records
/// without times, sequence numbers or agents (`placed` records left out), node ids renumbered in order of creation; the
/// periodic monitor's activations and the pickup monitor's idle polls (an activation whose only
/// child is the poll command), with their subtrees, are left out and counted, and activation
/// numbers, which count them, are dropped.
fn tree(trace: &[Value]) -> (Vec<(String, Vec<String>)>, usize) {
    let mut children: BTreeMap<u64, Vec<&str>> = BTreeMap::new();
    for r in trace {
        if let (Some("spawned"), Some(parent), Some(name)) =
            (r["ev"].as_str(), r["parent"].as_u64(), r["name"].as_str())
        {
            children.entry(parent).or_default().push(name);
        }
    }
    let idle_poll =
        |node: u64, name: &str| name == PICKUP && children.get(&node).is_some_and(|c| c == &[POLL]);
    let mut path: BTreeMap<u64, String> = BTreeMap::new();
    let mut skip = BTreeSet::new();
    let mut order = Vec::new();
    for r in trace {
        let (Some(node), Some(parent), Some(name)) =
            (r["node"].as_u64(), r["parent"].as_u64(), r["name"].as_str())
        else {
            continue;
        };
        if path.contains_key(&node) {
            continue;
        }
        let p = format!("{}/{name}", path.get(&parent).map_or("", String::as_str));
        path.insert(node, p);
        if name == PERIODIC || idle_poll(node, name) || skip.contains(&parent) {
            skip.insert(node);
        } else {
            order.push(node);
        }
    }
    let num: BTreeMap<u64, usize> = order.iter().enumerate().map(|(i, &n)| (n, i)).collect();
    let mut events: BTreeMap<u64, Vec<String>> = BTreeMap::new();
    for r in trace {
        let Some(node) = r["node"].as_u64() else {
            continue;
        };
        // Where a node ran is the one thing a single process cannot say.
        if !num.contains_key(&node) || r["ev"] == "placed" {
            continue;
        }
        let mut r = r.clone();
        if let Some(m) = r.as_object_mut() {
            for k in ["seq", "t", "node", "agent"] {
                m.remove(k);
            }
            if m.get("ev").and_then(Value::as_str) == Some("activated") {
                m.remove("number");
            }
        }
        events
            .entry(node)
            .or_default()
            .push(renumber(&r, None, &num, &skip).to_string());
    }
    let nodes = order
        .iter()
        .map(|n| (path[n].clone(), events.remove(n).unwrap_or_default()))
        .collect();
    (nodes, skip.len())
}

/// Processes whose command line names the system of the demo `pid`.
fn agents_of(pid: u32) -> Vec<String> {
    let system = format!("xavier-{pid}");
    let Ok(dir) = std::fs::read_dir("/proc") else {
        return Vec::new();
    };
    dir.filter_map(Result::ok)
        .filter_map(|e| std::fs::read(e.path().join("cmdline")).ok())
        .map(|c| String::from_utf8_lossy(&c).replace('\0', " "))
        .filter(|c| c.contains(&system))
        .collect()
}

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("xavier-dist-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a temporary directory");
    dir.join(name)
}

#[test]
fn the_distributed_run_matches_the_single_process_run_of_the_same_seed() {
    let python = test_support::find_on_path("python3").is_some();
    if python {
        // The venv the demo finds its Python in (target/test-venv).
        test_support::python_venv(&["eclipse-zenoh==1.10.2"]).unwrap_or_else(|why| panic!("{why}"));
    } else {
        println!("python3 is not on PATH: speak is served by the robot agent");
    }
    let (single, dist) = (temp("single.jsonl"), temp("distributed.jsonl"));
    let (code, out1, _) = xavier(&["--seed", "1", "--trace", &single.to_string_lossy()]);
    assert_eq!(code, Some(0), "{out1}");
    // Slower than the default 40, for a margin on a loaded machine (see the docs).
    let (code, out2, pid) = xavier(&[
        "--seed",
        "1",
        "--distributed",
        "--speed",
        "20",
        "--trace",
        &dist.to_string_lossy(),
    ]);
    assert_eq!(code, Some(0), "{out2}");
    if python {
        assert!(out2.contains("speak on the Python agent `voice`"), "{out2}");
    }
    assert_eq!(outcome(&out2), outcome(&out1), "{out2}");
    assert!(
        outcome(&out1).contains(&"delivered:       3, 7, 12".to_string()),
        "{out1}"
    );
    let (t1, t2) = (records(&single), records(&dist));
    let (tree1, periodic1) = tree(&t1);
    let (tree2, periodic2) = tree(&t2);
    assert_eq!(tree1.len(), tree2.len());
    for (a, b) in tree1.iter().zip(&tree2) {
        assert_eq!(a, b, "the trees part here");
    }
    assert!(periodic1 > 0 && periodic2 > 0, "{periodic1} {periodic2}");
    eprintln!(
        "{} nodes compared; periodic activations and idle polls: {periodic1} single, {periodic2} distributed",
        tree1.len()
    );
    let events = tcm_trace::read_jsonl(std::io::BufReader::new(
        std::fs::File::open(&dist).expect("the distributed trace"),
    ))
    .expect("the distributed trace reads");
    if let Err(vs) = tcm_trace::check(&events) {
        panic!("the trace checker refuses the distributed trace: {vs:?}");
    }
    // Each of the robot's commands ran on the robot agent, `speak` on the voice when Python
    // serves it, and the trace says so: a `placed` record per remote node, nothing else placed.
    // A node terminated before its action was sent (a poll of the motor's temperature spawned as
    // the round ends, on a loaded machine) ran nowhere and has none.
    let mut names = BTreeMap::new();
    let mut placed = BTreeMap::new();
    let mut terminated = std::collections::BTreeSet::new();
    for r in &t2 {
        match (r["ev"].as_str(), r["node"].as_u64()) {
            (Some("spawned"), Some(n)) => {
                names.insert(n, r["name"].as_str().unwrap_or_default().to_string());
            }
            (Some("placed"), Some(n)) => {
                placed.insert(n, r["agent"].as_str().unwrap_or_default().to_string());
            }
            (Some("terminated"), Some(n)) => {
                terminated.insert(n);
            }
            _ => {}
        }
    }
    let robot = [
        "planPath",
        "turn",
        "guardedMove",
        "lookForDoor",
        "mailGone",
        "motorTemperature",
    ];
    let mut by_agent: BTreeMap<&str, usize> = BTreeMap::new();
    for (n, name) in &names {
        let want = if robot.contains(&name.as_str()) {
            Some("robot")
        } else if name == "speak" {
            Some(if python { "voice" } else { "robot" })
        } else {
            None
        };
        let got = placed.get(n).map(String::as_str);
        if got.is_none() && terminated.contains(n) {
            continue;
        }
        assert_eq!(got, want, "{name} {{{n}}}");
        if let Some(agent) = want {
            *by_agent.entry(agent).or_default() += 1;
        }
    }
    assert!(
        by_agent.get("robot").is_some_and(|n| *n > 20),
        "{by_agent:?}"
    );
    assert_eq!(agents_of(pid), Vec::<String>::new(), "agents left behind");
}

#[test]
fn without_python_the_robot_agent_speaks() {
    let trace = temp("no-python.jsonl");
    let (code, out, pid) = xavier(&[
        "--rooms",
        "3",
        "--distributed",
        "--no-python",
        "--trace",
        &trace.to_string_lossy(),
    ]);
    assert_eq!(code, Some(0), "{out}");
    assert!(
        out.contains("speak on the robot agent (--no-python)"),
        "{out}"
    );
    assert!(out.contains("delivered:       3\n"), "{out}");
    assert!(out.contains("senders told:    3\n"), "{out}");
    assert_eq!(agents_of(pid), Vec::<String>::new(), "agents left behind");
}
