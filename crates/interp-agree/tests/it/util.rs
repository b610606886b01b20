//! Running a program of `test_data/ok` compiled and interpreted side by side, and comparing
//! what the two runs did: their traces (JSON lines, the run's number left out, both passed by
//! the trace checker), how the runs ended, and the notes the Rust items they call wrote.
//!
//! The Rust items a program calls live in its test module, once: the compiled program calls them
//! directly, the interpreted one through the [`Registry`] entries that wrap the same functions.
//! What they remember during a run (a counter of calls, a note) is kept per thread and cleared
//! when a run starts: `#[tokio::test]` runs each test on a thread of its own, and both runs of a
//! case on it, one after the other.

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::time::Duration;

use tdl::{Attached, NodeKind, Recorder, Runtime, Task, TraceEvent};
use tdl_interp::{LoadError, Program, Registry, Value};

thread_local! {
    static NOTES: RefCell<Vec<String>> = const { RefCell::new(Vec::new()) };
    static COUNTS: RefCell<BTreeMap<&'static str, u32>> = const { RefCell::new(BTreeMap::new()) };
}

/// Writes a note of the current run (what a `log` function of a program says).
pub(crate) fn note(text: impl Into<String>) {
    NOTES.with(|n| n.borrow_mut().push(text.into()));
}

/// How many times `key` was counted in the current run before this call (0 the first time).
pub(crate) fn tick(key: &'static str) -> u32 {
    COUNTS.with(|c| {
        let mut c = c.borrow_mut();
        let n = c.entry(key).or_insert(0);
        *n += 1;
        *n - 1
    })
}

fn reset() -> Vec<String> {
    COUNTS.with(|c| c.borrow_mut().clear());
    NOTES.with(|n| std::mem::take(&mut *n.borrow_mut()))
}

/// A command built in Rust, for a task the program spawns without declaring it: it waits
/// `millis` of virtual time and succeeds. The compiled program spawns it by calling the test
/// module's function, the interpreted one through `Registry::task` wrapping the same function.
pub(crate) fn command(name: &'static str, millis: u64) -> Task {
    Task::new(NodeKind::Command, name, move |_ctx| async move {
        tokio::time::sleep(Duration::from_millis(millis)).await;
        Ok::<(), tdl::Failure>(())
    })
}

/// The virtual time a run may take.
const LIMIT: Duration = Duration::from_secs(3600);

/// What a run did.
#[derive(Debug)]
pub(crate) struct Run {
    /// The trace, one JSON line per record, without the run's first record.
    pub(crate) trace: Vec<String>,
    /// How the run ended.
    pub(crate) outcome: String,
    /// The notes the Rust items wrote.
    pub(crate) notes: Vec<String>,
}

/// `text` with the digits after each `marker` replaced by `#`.
fn mask_after(text: &str, marker: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(at) = rest.find(marker) {
        let (before, after) = rest.split_at(at + marker.len());
        out.push_str(before);
        let digits = after.len() - after.trim_start_matches(|c: char| c.is_ascii_digit()).len();
        if digits > 0 {
            out.push('#');
        }
        rest = &after[digits..];
    }
    out.push_str(rest);
    out
}

/// The run's number counts the process's runs, the one thing two runs never share: the record
/// that carries it is left out (`tdl::testing::lines`), and it is masked where a message or a
/// note prints a node (`node#2.0@run116`, `NodeId { run: 116, .. }`).
fn without_run(text: &str) -> String {
    mask_after(&mask_after(text, "@run"), "run: ")
}

/// Runs `task` on `rt`, recording its trace, and passes the trace through the trace checker.
pub(crate) async fn run(rt: Runtime, task: Task) -> Run {
    reset();
    let rec = Recorder::new();
    // A run that never ends (a monitor polling forever) fails the test instead of hanging it.
    let report = tokio::time::timeout(LIMIT, rt.with_sink(rec.clone()).run(task))
        .await
        .expect("the run ends within an hour of virtual time")
        .expect("the run ends");
    let trace: Vec<TraceEvent> = rec.events();
    tdl::testing::assert_checked(&trace);
    tdl::testing::assert_no_panics(&report, &trace);
    let trace = tdl::testing::lines(&trace)
        .iter()
        .map(|it| without_run(it))
        .collect();
    Run {
        trace,
        outcome: without_run(&format!("{:?}", report.outcome)),
        notes: reset().iter().map(|it| without_run(it)).collect(),
    }
}

/// The text of `test_data/ok/<stem>.tdl`, or of this crate's `drivers/<stem>.tdl`, named as a
/// diagnostic shows it.
pub(crate) fn source(stem: &str) -> (String, String) {
    let ok = format!(
        "{}/../tdl-syntax/test_data/ok/{stem}.tdl",
        env!("CARGO_MANIFEST_DIR")
    );
    let (name, path) = if std::path::Path::new(&ok).exists() {
        (format!("ok/{stem}.tdl"), ok)
    } else {
        (
            format!("drivers/{stem}.tdl"),
            format!("{}/drivers/{stem}.tdl", env!("CARGO_MANIFEST_DIR")),
        )
    };
    let text = std::fs::read_to_string(&path).expect("the program's file reads");
    (name, text)
}

/// Loads the program of the files `stems` (`test_data/ok` first, then drivers) with `registry`.
pub(crate) fn try_load(stems: &[&str], registry: &Registry) -> Result<Program, LoadError> {
    let files: Vec<(String, String)> = stems.iter().map(|s| source(s)).collect();
    Program::from_sources(&files, registry)
}

/// How two runs are compared.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(crate) enum Compare {
    /// Trace record for record, outcome, notes.
    All,
    /// Trace record for record and outcome; not the notes (for a case whose notes differ for a
    /// reason reported by another test).
    TraceOnly,
    /// Each node's records in order, outcome, notes: for a program whose compiled trace
    /// interleaves nodes differently from one run to the next (blocking commands run on threads
    /// of their own, outside virtual time's order).
    PerNode,
}

/// A program the interpreter runs, and how its runs are set up.
pub(crate) struct Case {
    program: Program,
    /// The compiled program's `for` handlers, made afresh for each run.
    attached: fn() -> Vec<Attached>,
    /// The compiled program's wiretaps, made afresh for each run.
    taps: fn() -> Vec<tdl::Tap>,
    /// External events raised during each run: (virtual time in milliseconds, name).
    events: Vec<(u64, String)>,
    /// Sets up the Rust items' world before each run.
    before: Box<dyn Fn()>,
    compare: Compare,
}

impl Case {
    /// The program of `stems`, loaded with `registry`; a refusal fails the test with its
    /// diagnostics.
    pub(crate) fn new(stems: &[&str], registry: &Registry) -> Case {
        let program = match try_load(stems, registry) {
            Ok(p) => p,
            Err(e) => panic!("the interpreter refuses the program: {e}"),
        };
        Case {
            program,
            attached: Vec::new,
            taps: Vec::new,
            events: Vec::new(),
            before: Box::new(|| {}),
            compare: Compare::All,
        }
    }

    /// The compiled program's `for` handlers (the interpreted program's are its own).
    /// Gives the compiled runs the program's wiretaps (the interpreted ones get the program's).
    pub(crate) fn taps(mut self, taps: fn() -> Vec<tdl::Tap>) -> Case {
        self.taps = taps;
        self
    }

    pub(crate) fn attached(mut self, attached: fn() -> Vec<Attached>) -> Case {
        self.attached = attached;
        self
    }

    /// External events raised at these virtual times (milliseconds from the start) in each run.
    pub(crate) fn events(mut self, events: &[(u64, &str)]) -> Case {
        self.events = events.iter().map(|(t, n)| (*t, (*n).to_string())).collect();
        self
    }

    /// Sets up the Rust items' world before each run (both start from the same).
    pub(crate) fn before(mut self, before: impl Fn() + 'static) -> Case {
        self.before = Box::new(before);
        self
    }

    /// Compares the runs so.
    pub(crate) fn compare(mut self, compare: Compare) -> Case {
        self.compare = compare;
        self
    }

    fn runtime(&self, attached: Vec<Attached>, taps: Vec<tdl::Tap>) -> Runtime {
        (self.before)();
        let mut rt = Runtime::new();
        for t in taps {
            rt = rt.tap(t);
        }
        for a in attached {
            rt = rt.attach(a);
        }
        if !self.events.is_empty() {
            let handle = rt.events();
            let events = self.events.clone();
            tokio::spawn(async move {
                let start = tokio::time::Instant::now();
                for (at, name) in events {
                    tokio::time::sleep_until(start + Duration::from_millis(at)).await;
                    // A run that already ended refuses the event: nothing more to raise.
                    if handle.raise(&name).is_err() {
                        break;
                    }
                }
            });
        }
        rt
    }

    /// Runs `compiled`, then the interpreted task `name(args)`, and asserts they did the same.
    pub(crate) async fn alike(&self, compiled: Task, name: &str, args: Vec<Value>) {
        let c = run(self.runtime((self.attached)(), (self.taps)()), compiled).await;
        let task = match self.program.task(name, args) {
            Ok(t) => t,
            Err(e) => panic!("the interpreted task `{name}`: {e}"),
        };
        let i = run(
            self.runtime(self.program.attached(), self.program.taps()),
            task,
        )
        .await;
        match self.compare {
            Compare::All | Compare::TraceOnly => assert_same(name, &c.trace, &i.trace),
            Compare::PerNode => assert_same(name, &per_node(&c.trace), &per_node(&i.trace)),
        }
        assert_eq!(
            c.outcome, i.outcome,
            "`{name}`: the runs ended differently (left compiled, right interpreted)"
        );
        if self.compare != Compare::TraceOnly {
            assert_eq!(
                c.notes, i.notes,
                "`{name}`: the Rust items were called differently (left compiled, right interpreted)"
            );
        }
    }
}

/// The records of `trace` grouped by node (records of no node first), each group in the order
/// of the trace, without their sequence numbers.
fn per_node(trace: &[String]) -> Vec<String> {
    let mut nodes: BTreeMap<i64, Vec<String>> = BTreeMap::new();
    for line in trace {
        let mut json: serde_json::Value = serde_json::from_str(line).expect("a record parses");
        let node = json
            .get("node")
            .and_then(serde_json::Value::as_i64)
            .unwrap_or(-1);
        if let Some(obj) = json.as_object_mut() {
            obj.remove("seq");
        }
        nodes.entry(node).or_default().push(json.to_string());
    }
    nodes.into_values().flatten().collect()
}

/// Asserts two traces are the same, showing the first differing record.
#[track_caller]
pub(crate) fn assert_same(name: &str, compiled: &[String], interpreted: &[String]) {
    for (i, (c, n)) in compiled.iter().zip(interpreted).enumerate() {
        assert_eq!(
            c, n,
            "`{name}`: record {i} differs (left compiled, right interpreted)"
        );
    }
    assert_eq!(
        compiled.len(),
        interpreted.len(),
        "`{name}`: the traces have different lengths (left compiled, right interpreted); the \
         longer one goes on with {:?}",
        if compiled.len() > interpreted.len() {
            compiled.get(interpreted.len())
        } else {
            interpreted.get(compiled.len())
        }
    );
}
