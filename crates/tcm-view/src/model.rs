//! The viewer's model of one run, rebuilt from its trace records: one row per node with the
//! moment (record number and time) of each point it reached, the records themselves for the event
//! list, and what the page asks about a node (its details, why it waits, its exceptions).
//!
//! A row's *marks* are the record numbers (`seq`) at which the node was spawned, each facet reached
//! each point, it began terminating, terminated, was reclaimed, found dead, reserved. The state of
//! a node at a cursor `s` is then the last point of each facet whose mark is at most `s`: the page
//! scrubs through a run without replaying it. Marks are in `docs/viewer.md`, "Snapshot".

use std::collections::BTreeMap;

use serde::Serialize;
use tcm_trace::{Facet, NodeKind, Point, ResourceUse, TraceConstraint, TraceEvent, TraceKind};

/// Index of the spawn mark in a row's marks.
pub const M_SPAWNED: usize = 0;
/// Index of the mark where `facet` reached `point`: 1 + 3 × facet + point (enabled 0, active 1,
/// completed 2).
pub fn m_point(facet: Facet, point: Point) -> usize {
    1 + 3 * facet.index() + point_index(point)
}
/// Index of the mark where the node began terminating.
pub const M_TERMINATING: usize = 10;
/// Index of the mark where the node was terminated.
pub const M_TERMINATED: usize = 11;
/// Index of the mark where the node was reclaimed.
pub const M_RECLAIMED: usize = 12;
/// Index of the mark where the reserved node was found dead.
pub const M_DEAD: usize = 13;
/// Index of the mark where the node's number was reserved.
pub const M_RESERVED: usize = 14;
/// Index of the mark of the node's first failure.
pub const M_FAILED: usize = 15;
/// Marks per row.
pub const MARKS: usize = 16;

fn point_index(p: Point) -> usize {
    match p {
        Point::Enabled => 0,
        Point::Active => 1,
        Point::Completed => 2,
    }
}

/// A moment of the run: a record's number and its time.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Mark {
    /// The record's `seq`.
    pub seq: u64,
    /// The record's time, ns.
    pub t: u64,
}

/// One failure of a node.
#[derive(Clone, Debug, Serialize)]
pub struct Failure {
    /// When.
    pub at: Mark,
    /// The exception's type.
    pub exception: String,
    /// For people.
    pub message: String,
}

/// One node of the run.
#[derive(Clone, Debug)]
pub struct Row {
    /// Display number.
    pub number: u64,
    /// Parent's number (none for the root).
    pub parent: Option<u64>,
    /// Kind, once spawned (the root's is `Root`).
    pub kind: Option<NodeKind>,
    /// Name.
    pub name: String,
    /// Children, in spawn (or reservation) order.
    pub children: Vec<u64>,
    /// See the module's documentation.
    pub marks: [Option<Mark>; MARKS],
    /// Constraints applied to it, with when.
    pub constraints: Vec<(Mark, TraceConstraint)>,
    /// Failures, in order.
    pub failures: Vec<Failure>,
    /// Suspensions: from, and until (if resumed).
    pub suspensions: Vec<(Mark, Option<Mark>)>,
    /// A monitor's activations so far.
    pub activations: u32,
    /// A monitor's triggers so far.
    pub triggers: u32,
    /// For an activation: its monitor.
    pub activation_of: Option<u64>,
    /// For a handler node: the node whose failure it handles, and the handler's name.
    pub handles: Option<(u64, String)>,
    /// For a retry: the node it runs again.
    pub retry_of: Option<u64>,
    /// Its request for resources, if it made one: when, and what.
    pub request: Option<(Mark, Vec<ResourceUse>)>,
    /// When the request was granted.
    pub granted: Option<Mark>,
    /// When it gave the resources back.
    pub released: Option<Mark>,
    /// When the request ended without a grant (withdrawn, denied, dropped), and how.
    pub refused: Option<(Mark, &'static str)>,
    /// The agent its action runs on, for a node placed on one (a `placed` record).
    pub agent: Option<String>,
}

impl Row {
    fn new(number: u64) -> Row {
        Row {
            number,
            parent: None,
            kind: None,
            name: String::new(),
            children: Vec::new(),
            marks: [None; MARKS],
            constraints: Vec::new(),
            failures: Vec::new(),
            suspensions: Vec::new(),
            activations: 0,
            triggers: 0,
            activation_of: None,
            handles: None,
            retry_of: None,
            agent: None,
            request: None,
            granted: None,
            released: None,
            refused: None,
        }
    }

    /// The point `facet` had reached by record `seq`, if any.
    pub fn point_at(&self, facet: Facet, seq: u64) -> Option<Point> {
        [Point::Completed, Point::Active, Point::Enabled]
            .into_iter()
            .find(|p| self.reached(m_point(facet, *p), seq))
    }

    /// Whether the mark `m` is set at or before record `seq`.
    pub fn reached(&self, m: usize, seq: u64) -> bool {
        self.marks[m].is_some_and(|mark| mark.seq <= seq)
    }

    /// Whether the node is goal-like (its handling belongs to its expansion).
    pub fn goal_like(&self) -> bool {
        matches!(
            self.kind,
            Some(NodeKind::Goal | NodeKind::Handler | NodeKind::Root)
        )
    }
}

/// How one exception went: where it was raised, the handlers chosen in order, bypasses, retries.
#[derive(Clone, Debug, Serialize)]
pub struct ExceptionStory {
    /// The failing node.
    pub node: u64,
    /// Its path.
    pub path: String,
    /// The exception's type.
    pub exception: String,
    /// For people.
    pub message: String,
    /// When it was raised.
    pub at: Mark,
    /// What happened next, in order.
    pub steps: Vec<Step>,
}

/// One step of an exception's story.
#[derive(Clone, Debug, Serialize)]
pub struct Step {
    /// `chosen`, `bypassed`, `retried`, `unhandled` or `warning`.
    pub what: &'static str,
    /// The node concerned (the handler node, the retry), if any.
    pub node: Option<u64>,
    /// For people: the handler's name, the warning.
    pub detail: String,
    /// When.
    pub at: Mark,
}

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
const NUMBER_SLACK: u64 = 1 << 16;

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
    rows: Vec<Row>,
    /// `(seq, t)` at each record whose time differs from the record before's.
    times: Vec<(u64, u64)>,
    externals: Vec<(Mark, String)>,
    exceptions: Vec<ExceptionStory>,
    /// Reservations and locks of resources, with when they began and ended.
    restrictions: Vec<Restriction>,
    /// The first thing that stopped the reading, if any; everything before it is shown.
    pub problem: Option<Problem>,
    /// Whether the run ended (a file read to its end; a live run whose sinks were flushed).
    pub finished: bool,
}

impl RunModel {
    /// An empty model.
    pub fn new(name: impl Into<String>) -> RunModel {
        let mut root = Row::new(0);
        root.kind = Some(NodeKind::Root);
        root.name = "root".to_string();
        let origin = Some(Mark { seq: 0, t: 0 });
        root.marks[M_SPAWNED] = origin;
        for f in Facet::ALL {
            for p in [Point::Enabled, Point::Active] {
                root.marks[m_point(f, p)] = origin;
            }
        }
        RunModel {
            name: name.into(),
            version: None,
            lines: Vec::new(),
            index: Vec::new(),
            rows: vec![root],
            times: Vec::new(),
            externals: Vec::new(),
            exceptions: Vec::new(),
            restrictions: Vec::new(),
            problem: None,
            finished: false,
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
            if n > self.rows.len() as u64 + NUMBER_SLACK {
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
        let at = Mark {
            seq: ev.seq,
            t: ev.t,
        };
        if self.times.last().is_none_or(|&(_, t)| t != ev.t) {
            self.times.push((ev.seq, ev.t));
        }
        self.record(at, &ev.kind);
        self.index.push((ev.t, ev.kind.node()));
        self.lines.push(line);
        Ok(())
    }

    fn row(&mut self, n: u64) -> &mut Row {
        let i = n as usize;
        if i >= self.rows.len() {
            let start = self.rows.len() as u64;
            self.rows.extend((start..=n).map(Row::new));
        }
        &mut self.rows[i]
    }

    fn link(&mut self, node: u64, parent: u64) {
        if self
            .rows
            .get(node as usize)
            .is_some_and(|r| r.parent == Some(parent))
        {
            return;
        }
        self.row(node).parent = Some(parent);
        self.row(parent).children.push(node);
    }

    fn record(&mut self, at: Mark, kind: &TraceKind) {
        use TraceKind as K;
        let set = |row: &mut Row, m: usize| {
            if row.marks[m].is_none() {
                row.marks[m] = Some(at);
            }
        };
        match kind {
            K::Reserved { node, parent, name } => {
                self.link(*node, *parent);
                let row = self.row(*node);
                row.name = name.clone();
                set(row, M_RESERVED);
            }
            K::Spawned {
                node,
                parent,
                kind,
                name,
            } => {
                self.link(*node, *parent);
                let row = self.row(*node);
                row.name = name.clone();
                row.kind = Some(*kind);
                set(row, M_SPAWNED);
                if !row.goal_like() {
                    set(row, m_point(Facet::Expansion, Point::Completed));
                }
            }
            K::Constrained { node, constraint } => {
                self.row(*node).constraints.push((at, constraint.clone()));
            }
            K::Transition {
                node, facet, to, ..
            } => {
                let point = match to {
                    tcm_trace::State::Enabled => Some(Point::Enabled),
                    tcm_trace::State::Active => Some(Point::Active),
                    tcm_trace::State::Completed => Some(Point::Completed),
                    tcm_trace::State::Disabled => None,
                };
                if let Some(p) = point {
                    set(self.row(*node), m_point(*facet, p));
                }
            }
            K::Terminating { node } => set(self.row(*node), M_TERMINATING),
            K::Terminated { node } => set(self.row(*node), M_TERMINATED),
            K::Reclaimed { node } => set(self.row(*node), M_RECLAIMED),
            K::Dead { node } => set(self.row(*node), M_DEAD),
            K::Suspended { node } => self.row(*node).suspensions.push((at, None)),
            K::Unsuspended { node } => {
                if let Some(open) = self
                    .row(*node)
                    .suspensions
                    .iter_mut()
                    .rev()
                    .find(|s| s.1.is_none())
                {
                    open.1 = Some(at);
                }
            }
            K::Failed {
                node,
                exception,
                message,
            } => {
                set(self.row(*node), M_FAILED);
                self.row(*node).failures.push(Failure {
                    at,
                    exception: exception.clone(),
                    message: message.clone(),
                });
                let path = self.path(*node);
                self.exceptions.push(ExceptionStory {
                    node: *node,
                    path,
                    exception: exception.clone(),
                    message: message.clone(),
                    at,
                    steps: Vec::new(),
                });
            }
            K::External { name } => self.externals.push((at, name.clone())),
            K::Activated {
                monitor,
                node,
                number,
            } => {
                self.row(*monitor).activations = *number;
                self.row(*node).activation_of = Some(*monitor);
            }
            K::Triggered { monitor, count } => self.row(*monitor).triggers = *count,
            K::HandlerChosen {
                node,
                failing,
                handler,
                ..
            } => {
                self.row(*node).handles = Some((*failing, handler.clone()));
                let detail = handler.clone();
                self.step_for(*failing, "chosen", Some(*node), detail, at);
            }
            K::Bypassed { node, exception } => {
                let failing = self
                    .rows
                    .get(*node as usize)
                    .and_then(|r| r.handles.clone());
                if let Some((failing, _)) = failing {
                    let detail = format!("passed {exception} on");
                    self.step_for(failing, "bypassed", Some(*node), detail, at);
                }
            }
            K::Retried { node, of } => {
                self.row(*node).retry_of = Some(*of);
                self.step_for(*of, "retried", Some(*node), String::new(), at);
            }
            K::Requested { node, uses, .. } => {
                let row = self.row(*node);
                row.request = Some((at, uses.clone()));
                row.granted = None;
                row.released = None;
                row.refused = None;
            }
            K::Granted { node, .. } => self.row(*node).granted = Some(at),
            K::Released { node, .. } => self.row(*node).released = Some(at),
            K::Withdrawn { node } => self.row(*node).refused = Some((at, "withdrawn")),
            K::Denied { node, .. } => self.row(*node).refused = Some((at, "denied")),
            K::Dropped { node, .. } => self.row(*node).refused = Some((at, "dropped")),
            K::ResourceReserved { resource, holder } => self.restrictions.push(Restriction {
                resource: resource.clone(),
                holder: Some(*holder),
                from: at,
                until: None,
            }),
            K::ResourceLocked { resource } => self.restrictions.push(Restriction {
                resource: resource.clone(),
                holder: None,
                from: at,
                until: None,
            }),
            K::ResourceUnreserved { resource } | K::ResourceUnlocked { resource } => {
                let lock = matches!(kind, K::ResourceUnlocked { .. });
                if let Some(r) = self.restrictions.iter_mut().rev().find(|r| {
                    &r.resource == resource && r.until.is_none() && r.holder.is_none() == lock
                }) {
                    r.until = Some(at);
                }
            }
            K::Placed { node, agent } => self.row(*node).agent = Some(agent.clone()),
            K::Warning {
                node: Some(node),
                message,
            } => {
                let what = if message.starts_with("No exception handler found") {
                    "unhandled"
                } else {
                    "warning"
                };
                self.step_for(*node, what, None, message.clone(), at);
            }
            _ => {}
        }
    }

    /// Adds a step to the last exception raised by `failing`, if it has one.
    fn step_for(
        &mut self,
        failing: u64,
        what: &'static str,
        node: Option<u64>,
        detail: String,
        at: Mark,
    ) {
        if let Some(story) = self.exceptions.iter_mut().rev().find(|s| s.node == failing) {
            story.steps.push(Step {
                what,
                node,
                detail,
                at,
            });
        }
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

    /// The rows, indexed by node number (numbers never allocated are empty rows).
    pub fn rows(&self) -> &[Row] {
        &self.rows
    }

    /// One row.
    pub fn node(&self, n: u64) -> Option<&Row> {
        self.rows
            .get(n as usize)
            .filter(|r| r.number == 0 || r.parent.is_some())
    }

    /// The names from the root's child down to `n`, joined by `/`.
    pub fn path(&self, n: u64) -> String {
        let mut names = Vec::new();
        let mut at = Some(n);
        while let Some(i) = at {
            if i == 0 {
                break;
            }
            match self.rows.get(i as usize) {
                Some(r) => {
                    names.push(r.name.as_str());
                    at = r.parent;
                }
                None => break,
            }
            if names.len() > self.rows.len() {
                break;
            }
        }
        names.reverse();
        names.join("/")
    }

    /// `name {n}` for people.
    pub fn label(&self, n: u64) -> String {
        match self.rows.get(n as usize) {
            Some(r) if n == 0 => format!("{} {{0}}", r.name),
            Some(r) => format!("{} {{{n}}}", r.name),
            None => format!("{{{n}}}"),
        }
    }

    /// The record lines, for the event list.
    pub fn line(&self, seq: u64) -> Option<&str> {
        self.lines.get(seq as usize).map(|l| &**l)
    }

    /// Each external event raised, with when.
    pub fn externals(&self) -> &[(Mark, String)] {
        &self.externals
    }

    /// Every exception raised, in order, each with what followed.
    pub fn exceptions(&self) -> &[ExceptionStory] {
        &self.exceptions
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
                        .and_then(|n| self.rows.get(n as usize))
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
        for r in &self.rows[1..] {
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

/// A reservation (for a holder's subtree) or a lock (against all) of a resource.
#[derive(Clone, Debug)]
pub struct Restriction {
    /// The resource.
    pub resource: String,
    /// The node whose subtree may still be granted it; `None` for a lock.
    pub holder: Option<u64>,
    /// When it began.
    pub from: Mark,
    /// When it ended, if it did.
    pub until: Option<Mark>,
}

impl RunModel {
    /// The reservations and locks of the run, in order.
    pub fn restrictions(&self) -> &[Restriction] {
        &self.restrictions
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
    /// Ended well.
    pub succeeded: u64,
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
