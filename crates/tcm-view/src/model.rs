//! The viewer's model of one run: the records themselves for the event list, their times, and the
//! one fold of the trace, [`tcm_trace::Replay`], which holds one [`Row`] per node with the moment
//! (record number and time) of each point it reached, the exception stories and the resource
//! restrictions, and each state variable's changes (`state.rs`); and what the page asks about a
//! node (its details, why it waits, its exceptions).
//! The model never matches on record kinds to build its state: the fold does.
//!
//! A row's *marks* are the record numbers (`seq`) at which the node was spawned, each facet reached
//! each point, it began terminating, terminated, was reclaimed, found dead, reserved. The state of
//! a node at a cursor `s` is then the last point of each facet whose mark is at most `s`: the page
//! scrubs through a run without replaying it. Marks are in `docs/viewer.md`, "Snapshot".

use std::collections::{BTreeMap, HashMap};

use serde::Serialize;
use tcm::{Expr, StateValue};
use tcm_trace::{Facet, NodeKind, Point, Replay, TraceEvent, TraceKind};

use crate::state::{StateLane, States, VarAt};

pub use tcm_trace::{
    ExceptionStory, Failure, M_DEAD, M_FAILED, M_RECLAIMED, M_RESERVED, M_SKIPPED, M_SPAWNED,
    M_TERMINATED, M_TERMINATING, MARKS, Mark, Restriction, Row, Step, m_point,
};

/// Why a trace could not be read to its end.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Problem {
    /// The file, or the run's name.
    pub source: String,
    /// Line, from 1 (0: not about one line).
    pub line: usize,
    /// What was wrong, and what to do.
    pub message: String,
}

impl std::fmt::Display for Problem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.line > 0 {
            write!(f, "{}:{}: {}", self.source, self.line, self.message)
        } else {
            write!(f, "{}: {}", self.source, self.message)
        }
    }
}

/// A node number further past the last one allocated than this is taken as a damaged trace, not
/// allocated (each `reserved` or `spawned` record allocates one number).
const NUMBER_SLACK: u64 = tcm_trace::NUMBER_SLACK;

/// Lines read (and parsed on every core) before they are applied.
const READ_BATCH: usize = 1 << 16;

/// Parses each line of `batch`, split among the machine's cores.
fn parse_all(batch: &[(usize, String)]) -> Vec<Result<TraceEvent, tcm_trace::ReadError>> {
    let parse = |part: &[(usize, String)]| -> Vec<_> {
        part.iter()
            .map(|(no, line)| tcm_trace::jsonl::parse_line(line, *no))
            .collect()
    };
    let cores = std::thread::available_parallelism().map_or(1, std::num::NonZero::get);
    if cores < 2 || batch.len() < 1024 {
        return parse(batch);
    }
    let chunk = batch.len().div_ceil(cores);
    std::thread::scope(|scope| {
        let parts: Vec<_> = batch
            .chunks(chunk)
            .map(|part| scope.spawn(move || parse(part)))
            .collect();
        parts
            .into_iter()
            .flat_map(|p| match p.join() {
                Ok(v) => v,
                Err(panic) => std::panic::resume_unwind(panic),
            })
            .collect()
    })
}

/// The model of one run.
#[derive(Debug)]
pub struct RunModel {
    /// The run's name in the selector.
    pub name: String,
    /// The trace's schema version, once its first record is read.
    pub version: Option<u32>,
    /// Every record, as the JSON line it is on the wire, with its time and node (for filters).
    lines: Vec<Box<str>>,
    index: Vec<(u64, Option<u64>)>,
    /// The one fold of the trace: the tree, each node's row, exception stories, restrictions.
    replay: Replay,
    /// `(seq, t)` at each record whose time differs from the record before's.
    times: Vec<(u64, u64)>,
    /// Per monitor, `(seq, activations, triggers)` at each record that changed its counts in the
    /// fold's row: the counts at a cursor (the row has the latest).
    counts: HashMap<u64, Vec<(u64, u32, u32)>>,
    /// Per node placed on an agent, `(seq, agent)` at each record that changed it in its row.
    placed: HashMap<u64, Vec<(u64, String)>>,
    /// Each state variable's changes, as the fold recorded its values.
    states: States,
    /// The first thing that stopped the reading, if any; everything before it is shown.
    pub problem: Option<Problem>,
    /// Whether the run ended (a file read to its end; a live run whose sinks were flushed).
    pub finished: bool,
    /// Whether a page may steer the run (`Viewer::steer`; docs/viewer.md, "Steering a run").
    pub control: bool,
}

impl RunModel {
    /// An empty model.
    pub fn new(name: impl Into<String>) -> RunModel {
        RunModel {
            name: name.into(),
            version: None,
            lines: Vec::new(),
            index: Vec::new(),
            replay: Replay::with_history(),
            times: Vec::new(),
            counts: HashMap::new(),
            placed: HashMap::new(),
            states: States::default(),
            problem: None,
            finished: false,
            control: false,
        }
    }

    /// Reads a JSON-lines trace: every record up to the first line that is not one; that line
    /// becomes the model's [`Problem`] (with `source` and its line number), and the model keeps
    /// everything before it.
    pub fn read(
        name: impl Into<String>,
        source: &str,
        mut text: impl std::io::BufRead,
    ) -> RunModel {
        let mut model = RunModel::new(name);
        let mut line_no = 0;
        let mut batch: Vec<(usize, String)> = Vec::with_capacity(READ_BATCH);
        let mut end: Option<Result<(), std::io::Error>> = None;
        while end.is_none() {
            // A batch of lines, parsed on every core, then applied in order.
            batch.clear();
            while batch.len() < READ_BATCH {
                let mut line = String::new();
                match text.read_line(&mut line) {
                    Ok(0) => {
                        end = Some(Ok(()));
                        break;
                    }
                    Ok(_) => {
                        line_no += 1;
                        if !line.trim().is_empty() {
                            let kept = line.trim_end_matches(['\n', '\r']).len();
                            line.truncate(kept);
                            batch.push((line_no, line));
                        }
                    }
                    Err(e) => {
                        end = Some(Err(e));
                        break;
                    }
                }
            }
            let parsed = parse_all(&batch);
            for ((no, line), ev) in batch.drain(..).zip(parsed) {
                let ev = match ev {
                    Ok(ev) => ev,
                    Err(e) => {
                        let message = e.to_string();
                        let message = message
                            .strip_prefix(&format!("line {no}: "))
                            .unwrap_or(&message)
                            .to_string();
                        model.fail(
                            source,
                            no,
                            format!("{message} (the records before this line are shown)"),
                        );
                        return model.finish(source);
                    }
                };
                if let Err(message) = model.apply_line(&ev, line.into_boxed_str()) {
                    model.fail(source, no, message);
                    return model.finish(source);
                }
            }
        }
        if let Some(Err(e)) = end {
            model.fail(
                source,
                line_no + 1,
                format!("cannot read the file: {e} (the records before this line are shown)"),
            );
        }
        model.finish(source)
    }

    fn finish(mut self, source: &str) -> RunModel {
        if self.problem.is_none() && self.lines.is_empty() {
            self.fail(
                source,
                0,
                "the file holds no trace record (a trace is JSON lines, docs/trace-format.md)"
                    .to_string(),
            );
        }
        self.finished = true;
        self
    }

    fn fail(&mut self, source: &str, line: usize, message: String) {
        self.problem = Some(Problem {
            source: source.to_string(),
            line,
            message,
        });
    }

    /// Applies one record (live runs). A record that does not fit the model (a `seq` out of
    /// order, an implausible node number) is refused with the reason, and the model is unchanged.
    pub fn apply(&mut self, ev: &TraceEvent) -> Result<(), String> {
        self.apply_line(ev, tcm_trace::to_line(ev).into_boxed_str())
    }

    pub(crate) fn apply_line(&mut self, ev: &TraceEvent, line: Box<str>) -> Result<(), String> {
        let expected = self.lines.len() as u64;
        if ev.seq != expected {
            return Err(format!(
                "record number {} where {expected} was expected (the trace is cut or reordered)",
                ev.seq
            ));
        }
        if let Some(&(_, last)) = self.times.last() {
            if ev.t < last {
                return Err(format!("time goes backwards: {} ns after {last} ns", ev.t));
            }
        }
        if let Some(n) = ev.kind.node() {
            if n > self.rows().len() as u64 + NUMBER_SLACK {
                return Err(format!("node number {n} is implausible (damaged trace?)"));
            }
        }
        if ev.seq == 0 {
            match ev.kind {
                TraceKind::RunStarted { version, .. } => self.version = Some(version),
                _ => {
                    return Err(
                        "the first record is not `run_started` (is this a trace file?)".to_string(),
                    );
                }
            }
        }
        if self.times.last().is_none_or(|&(_, t)| t != ev.t) {
            self.times.push((ev.seq, ev.t));
        }
        // A record the fold refuses (a malformed trace) is kept for the event list; the trace
        // checker is the tool that says what is wrong with it.
        let _ = self.replay.apply(ev);
        self.keep_changes(ev.seq);
        self.states.keep(&self.replay);
        self.index.push((ev.t, ev.kind.node()));
        self.lines.push(line);
        Ok(())
    }

    /// Notes when the rows record `seq` changed got their counts and agent, which their rows hold
    /// only as of the last record.
    fn keep_changes(&mut self, seq: u64) {
        for &n in self.replay.changed_rows() {
            let Some(row) = self.replay.row(n) else {
                continue;
            };
            if row.kind == Some(NodeKind::Monitor) {
                let list = self.counts.entry(n).or_default();
                let now = (row.activations, row.triggers);
                if list.last().map_or((0, 0), |&(_, a, t)| (a, t)) != now {
                    list.push((seq, now.0, now.1));
                }
            }
            if let Some(agent) = &row.agent {
                let list = self.placed.entry(n).or_default();
                if list.last().map(|(_, a)| a) != Some(agent) {
                    list.push((seq, agent.clone()));
                }
            }
        }
    }

    /// A monitor's activations and triggers after record `seq`.
    pub fn counts_at(&self, n: u64, seq: u64) -> (u32, u32) {
        let Some(list) = self.counts.get(&n) else {
            return (0, 0);
        };
        match list.partition_point(|&(s, _, _)| s <= seq) {
            0 => (0, 0),
            i => (list[i - 1].1, list[i - 1].2),
        }
    }

    /// The agent node `n` runs on after record `seq`, if it was placed on one by then.
    pub fn agent_at(&self, n: u64, seq: u64) -> Option<&str> {
        let list = self.placed.get(&n)?;
        match list.partition_point(|&(s, _)| s <= seq) {
            0 => None,
            i => Some(list[i - 1].1.as_str()),
        }
    }

    /// Every state variable declared so far, in the order declared, with its changes.
    pub fn state_lanes(&self) -> &[StateLane] {
        self.states.lanes()
    }

    /// The variable the last record applied declared or changed, if it did.
    pub fn state_changed(&self) -> Option<&StateLane> {
        self.states.changed()
    }

    /// A state variable's value after record `seq`, with the moment it got it (its declaration or
    /// the change to it); `None` before its declaration.
    pub fn state_at(&self, name: &str, seq: u64) -> Option<(&StateValue, Mark)> {
        self.states.value_at(name, seq)
    }

    /// A condition's value after record `seq`, three-valued (the text of the error for one that
    /// cannot be evaluated then).
    pub fn eval_at(&self, cond: &Expr, seq: u64) -> Result<StateValue, String> {
        self.states.eval_at(cond, seq)
    }

    /// The first moment from `from` (when it was applied) to record `to` at which `cond` held.
    pub fn first_held(&self, cond: &Expr, from: Mark, to: u64) -> Option<Mark> {
        self.states.first_held(cond, from, to)
    }

    /// Each variable `cond` reads, with its value after record `seq` and since when.
    pub fn reading(&self, cond: &Expr, seq: u64) -> Vec<VarAt> {
        self.states.reading(cond, seq)
    }

    /// Number of records.
    pub fn len(&self) -> u64 {
        self.lines.len() as u64
    }

    /// Whether no record was read.
    pub fn is_empty(&self) -> bool {
        self.lines.is_empty()
    }

    /// Time of the last record, ns.
    pub fn last_t(&self) -> u64 {
        self.times.last().map_or(0, |&(_, t)| t)
    }

    /// Time of record `seq` (of the last one if past the end).
    pub fn t_of(&self, seq: u64) -> u64 {
        match self.times.partition_point(|&(s, _)| s <= seq) {
            0 => 0,
            i => self.times[i - 1].1,
        }
    }

    /// The last record at or before time `t` (0 when none).
    pub fn seq_at(&self, t: u64) -> u64 {
        match self.times.partition_point(|&(_, tt)| tt <= t) {
            0 => 0,
            i if i == self.times.len() => self.len().saturating_sub(1),
            i => self.times[i].0.saturating_sub(1),
        }
    }

    /// The one fold of the trace, as of the last record applied.
    pub fn replay(&self) -> &Replay {
        &self.replay
    }

    /// The rows, indexed by node number (numbers never allocated are empty rows).
    pub fn rows(&self) -> &[Row] {
        self.replay.rows()
    }

    /// One row.
    pub fn node(&self, n: u64) -> Option<&Row> {
        self.replay.row(n)
    }

    /// The names from the root's child down to `n`, joined by `/`.
    pub fn path(&self, n: u64) -> String {
        self.replay.path(n)
    }

    /// `name {n}` for people.
    pub fn label(&self, n: u64) -> String {
        self.replay.label(n)
    }

    /// The rows the last record applied changed, by node number (the fold's
    /// [`Replay::changed_rows`]): what a live page is sent with the record.
    pub fn changed_rows(&self) -> &[u64] {
        self.replay.changed_rows()
    }

    /// The record lines, for the event list.
    pub fn line(&self, seq: u64) -> Option<&str> {
        self.lines.get(seq as usize).map(|l| &**l)
    }

    /// Each external event raised, with when.
    pub fn externals(&self) -> &[(Mark, String)] {
        self.replay.externals()
    }

    /// Every exception raised, in order, each with what followed, as the fold has them.
    pub fn exceptions(&self) -> &[ExceptionStory] {
        self.replay.exceptions()
    }

    /// The exceptions as the page tells them: the fold's stories, and for a failure that no
    /// handler took and that was not reported unhandled, a `taken` step naming the parent that
    /// took it (docs/semantics.md, "Waited values" and "Failing the parent"): one whose body
    /// waited for its value, or one it fails (`with propagate`), fails with the same exception
    /// (`detail`: `failed with it`); one that waited for how it ended, or caught the failure in
    /// its code, goes on (`waited for it and did not fail with it`). For a retry, the parent of
    /// its first run takes it.
    pub fn stories(&self) -> Vec<ExceptionStory> {
        let all = self.exceptions();
        let mut out = all.to_vec();
        for (i, story) in out.iter_mut().enumerate() {
            if !story.steps.is_empty() {
                continue;
            }
            let Some(taker) = self.taker(story.node).filter(|&p| p != 0) else {
                continue;
            };
            let failed = all[i + 1..].iter().find(|later| {
                later.node == taker
                    && later.exception == story.exception
                    && later.message == story.message
            });
            let ended = self
                .node(story.node)
                .and_then(|r| r.marks[m_point(Facet::Handling, Point::Completed)]);
            let (detail, at) = match (failed, ended) {
                (Some(later), _) => ("failed with it", later.at),
                (None, Some(at)) => ("waited for it and did not fail with it", at),
                (None, None) => continue,
            };
            story.steps.push(Step {
                what: "taken",
                node: Some(taker),
                detail: detail.to_string(),
                at,
                attached: None,
            });
        }
        out
    }

    /// The node that takes the failure of `n` when its search stops at it: the parent of its
    /// first run (a retry's failure is its task's).
    fn taker(&self, n: u64) -> Option<u64> {
        let mut first = self.node(n)?;
        for _ in 0..self.rows().len() {
            match first.retry_of.and_then(|r| self.node(r)) {
                Some(earlier) => first = earlier,
                None => break,
            }
        }
        first.parent
    }

    /// The `(seq, t)` table of time changes.
    pub fn times(&self) -> &[(u64, u64)] {
        &self.times
    }

    /// The records matching a filter, `offset` and at most `limit` of them, with the number
    /// matching in all.
    pub fn events(&self, filter: &EventFilter, offset: usize, limit: usize) -> (usize, Vec<&str>) {
        let needle = filter.name.as_deref().map(str::to_lowercase);
        let matches = |seq: usize| {
            let (t, node) = self.index[seq];
            if filter.from.is_some_and(|f| t < f) || filter.to.is_some_and(|to| t > to) {
                return false;
            }
            if let Some(want) = filter.node {
                if node != Some(want) {
                    return false;
                }
            }
            match &needle {
                None => true,
                Some(needle) => {
                    let named = node
                        .and_then(|n| self.rows().get(n as usize))
                        .is_some_and(|r| r.name.to_lowercase().contains(needle.as_str()));
                    named || self.lines[seq].to_lowercase().contains(needle.as_str())
                }
            }
        };
        let mut total = 0;
        let mut out = Vec::new();
        for seq in 0..self.lines.len() {
            if matches(seq) {
                if total >= offset && out.len() < limit {
                    out.push(&*self.lines[seq]);
                }
                total += 1;
            }
        }
        (total, out)
    }

    /// Counts and durations per task name, longest total first.
    pub fn stats(&self) -> Vec<NameStats> {
        let mut by_name: BTreeMap<(&str, &'static str), NameStats> = BTreeMap::new();
        for r in self.rows().iter().skip(1) {
            let Some(kind) = r.kind else { continue };
            let entry = by_name
                .entry((r.name.as_str(), kind_str(kind)))
                .or_insert_with(|| NameStats {
                    name: r.name.clone(),
                    kind: kind_str(kind),
                    ..NameStats::default()
                });
            entry.count += 1;
            let started = r.marks[m_point(Facet::Handling, Point::Active)];
            let ended = r.marks[m_point(Facet::Execution, Point::Completed)];
            if r.marks[M_TERMINATING].is_some() {
                entry.terminated += 1;
            } else if !r.failures.is_empty() {
                entry.failed += 1;
            } else if r.marks[M_SKIPPED].is_some() {
                entry.skipped += 1;
            } else if ended.is_some() {
                entry.succeeded += 1;
            } else {
                entry.unfinished += 1;
            }
            if let Some(done) = r.marks[m_point(Facet::Handling, Point::Completed)] {
                if let Some(s) = started {
                    let d = done.t.saturating_sub(s.t);
                    entry.ran += 1;
                    entry.total_ns += d;
                    entry.max_ns = entry.max_ns.max(d);
                }
            }
        }
        let mut out: Vec<NameStats> = by_name.into_values().collect();
        for s in &mut out {
            s.mean_ns = s.total_ns.checked_div(s.ran).unwrap_or(0);
        }
        out.sort_by(|a, b| b.total_ns.cmp(&a.total_ns).then(a.name.cmp(&b.name)));
        out
    }
}

impl RunModel {
    /// The reservations and locks of the run, in order.
    pub fn restrictions(&self) -> &[Restriction] {
        self.replay.restrictions()
    }
}

/// A filter of the event list.
#[derive(Clone, Debug, Default)]
pub struct EventFilter {
    /// Part of the node's name or of the record (case-insensitive).
    pub name: Option<String>,
    /// From this time, ns.
    pub from: Option<u64>,
    /// Up to this time, ns.
    pub to: Option<u64>,
    /// Only records naming this node.
    pub node: Option<u64>,
}

/// Counts and durations of the nodes of one name.
#[derive(Clone, Debug, Default, Serialize)]
pub struct NameStats {
    /// Task name.
    pub name: String,
    /// Kind.
    pub kind: &'static str,
    /// Nodes spawned.
    pub count: u64,
    /// Ended well (having run: a skipped node is counted in `skipped`).
    pub succeeded: u64,
    /// Skipped: completed without running, a `skip if` condition holding when its turn came.
    pub skipped: u64,
    /// Failed (at least once).
    pub failed: u64,
    /// Terminated.
    pub terminated: u64,
    /// Not ended when the trace ends.
    pub unfinished: u64,
    /// Nodes whose action ran to its end (these make the durations).
    pub ran: u64,
    /// Sum of their action's durations, ns.
    pub total_ns: u64,
    /// Mean, ns.
    pub mean_ns: u64,
    /// Longest, ns.
    pub max_ns: u64,
}

/// The kind as the trace spells it.
pub(crate) fn kind_str(kind: NodeKind) -> &'static str {
    match kind {
        NodeKind::Root => "root",
        NodeKind::Goal => "goal",
        NodeKind::Command => "command",
        NodeKind::Monitor => "monitor",
        NodeKind::Handler => "handler",
    }
}
