//! Watching a run: the live task tree, redrawn in place on a terminal, and the plain event log for
//! anything else (a pipe, a file, a CI log). Both are trace sinks that rebuild the tree from the
//! records with [`tcm_trace::Replay`], so they show exactly what the trace says.
//!
//! - [`LiveTree`]: after a batch of records, at most every [`REDRAW_EVERY`] of wall time (and once
//!   at the end), it moves the cursor back over its last drawing and draws the tree of live nodes
//!   again: indented, each node's state in colour (ANSI escapes), with the robot's state on top.
//!   Completed subtrees are reclaimed by the runtime and disappear.
//! - [`EventLog`]: one line per thing worth reading (a task starts, ends, fails, is terminated or
//!   suspended; a handler is chosen; a monitor triggers), indented by depth, no escapes. Sensor
//!   readings and monitor activations are left out; their failures are not.

use crate::secs;
use std::io::Write;
use std::time::{Duration, Instant};
use tcm_trace::{Facet, Replay, ReplayNode, State, Termination, TraceEvent, TraceKind};
use tdl::TraceSink;
use xavier_world::SharedWorld;

/// The live tree is redrawn at most this often (wall time).
pub const REDRAW_EVERY: Duration = Duration::from_millis(50);
/// At most this many tree lines are drawn; the rest is summed up in one line.
pub const MAX_TREE_LINES: usize = 30;

/// Commands that only read a sensor: left out of the event log.
const SENSOR_READINGS: [&str; 2] = ["mailGone", "motorTemperature"];

const RESET: &str = "\x1b[0m";
const DIM: &str = "\x1b[2m";
const BOLD: &str = "\x1b[1m";
const RED: &str = "\x1b[31m";
const GREEN: &str = "\x1b[32m";
const YELLOW: &str = "\x1b[33m";
const BLUE: &str = "\x1b[34m";
const MAGENTA: &str = "\x1b[35m";
const CYAN: &str = "\x1b[36m";

/// A node's state in one word, and its colour.
pub fn status(node: &ReplayNode) -> (&'static str, &'static str) {
    if node.is_failed() {
        return ("failed", RED);
    }
    match node.termination() {
        Termination::Terminating => return ("terminating", MAGENTA),
        Termination::Terminated => return ("terminated", MAGENTA),
        Termination::Alive => {}
    }
    if node.is_suspended() {
        return ("suspended", CYAN);
    }
    match node.state(Facet::Handling) {
        State::Disabled => ("waiting", DIM),
        State::Enabled => ("ready", YELLOW),
        State::Active => ("running", GREEN),
        State::Completed if node.state(Facet::Execution) == State::Completed => ("done", BLUE),
        State::Completed if node.expands() => ("children running", GREEN),
        State::Completed => ("finishing", GREEN),
    }
}

fn depth(replay: &Replay, node: &ReplayNode) -> usize {
    let mut d = 0;
    let mut cur = node.parent();
    while let Some(p) = cur {
        if p == 0 {
            break;
        }
        d += 1;
        cur = replay.node(p).and_then(ReplayNode::parent);
    }
    d
}

/// One line per live node, depth first in spawn order: `<indent><name> {id}  <state>[ details]`,
/// with ANSI colours when `colour`.
pub fn tree_lines(replay: &Replay, colour: bool) -> Vec<String> {
    let mut out = Vec::new();
    let mut stack: Vec<(u64, usize)> = replay
        .root()
        .children()
        .iter()
        .rev()
        .map(|&c| (c, 0))
        .collect();
    while let Some((id, d)) = stack.pop() {
        let Some(node) = replay.node(id) else {
            continue;
        };
        if !node.is_spawned() || node.is_reclaimed() {
            continue;
        }
        let (word, col) = status(node);
        let mut details = String::new();
        if let Some(m) = node.monitor() {
            details.push_str(&format!("  monitor: {} activations", m.activations));
            if let Some(max) = m.max_activations {
                details.push_str(&format!(" of {max}"));
            }
            details.push_str(&format!(", {} triggers", m.triggers));
        }
        if node.handler_for().is_some() {
            details.push_str("  exception handler");
        }
        let line = if colour {
            let name_style = if node.state(Facet::Handling) == State::Active {
                BOLD
            } else {
                ""
            };
            format!(
                "{:indent$}{name_style}{}{RESET} {DIM}{{{}}}{RESET}  {col}{word}{RESET}{DIM}{details}{RESET}",
                "",
                node.name(),
                node.number(),
                indent = 2 * d
            )
        } else {
            format!(
                "{:indent$}{} {{{}}}  {word}{details}",
                "",
                node.name(),
                node.number(),
                indent = 2 * d
            )
        };
        out.push(line);
        for &c in node.children().iter().rev() {
            stack.push((c, d + 1));
        }
    }
    out
}

/// The robot's state in one short line: time, position, heading, motor temperature, distance
/// driven, and which of `rooms` still have their letter on the tray.
pub fn robot_line(world: &SharedWorld, rooms: &[u32]) -> String {
    let s = world.snapshot();
    let left: Vec<String> = rooms
        .iter()
        .filter(|r| s.tray.contains(r))
        .map(u32::to_string)
        .collect();
    // `+ 0.0` turns -0.0 into 0.0.
    format!(
        "t {} | robot ({:.1}, {:.1}) {:.0}° | motor {:.1} °C | {:.0} m | letters for {}",
        secs(s.time),
        s.pose.x + 0.0,
        s.pose.y + 0.0,
        s.pose.heading.to_degrees() + 0.0,
        s.temperature,
        s.distance_travelled,
        if left.is_empty() {
            "none".to_string()
        } else {
            left.join(", ")
        },
    )
}

/// The live tree on a terminal (see the module documentation).
pub struct LiveTree<W: Write + Send> {
    out: W,
    replay: Replay,
    world: SharedWorld,
    rooms: Vec<u32>,
    title: String,
    drawn_lines: usize,
    last_draw: Option<Instant>,
    dirty: bool,
    /// Simulated seconds per wall second to pace the run at; `None`: as fast as it goes.
    pace: Option<f64>,
    started: Instant,
}

impl<W: Write + Send> LiveTree<W> {
    /// A live tree written to `out` (a terminal), titled `title`, showing `world`'s robot and
    /// which of `rooms` are still to be served. With `pace`, the run is slowed to that many
    /// simulated seconds per wall second, so the tree can be watched (the sink sleeps; the virtual
    /// clock does not move meanwhile).
    pub fn new(
        out: W,
        title: String,
        world: SharedWorld,
        rooms: Vec<u32>,
        pace: Option<f64>,
    ) -> LiveTree<W> {
        LiveTree {
            out,
            replay: Replay::new(),
            world,
            rooms,
            title,
            drawn_lines: 0,
            last_draw: None,
            dirty: false,
            pace,
            started: Instant::now(),
        }
    }

    fn draw_if_due(&mut self) {
        if self.last_draw.is_none_or(|t| t.elapsed() >= REDRAW_EVERY) {
            self.draw();
        }
    }

    fn draw(&mut self) {
        let mut lines = vec![
            format!("{BOLD}{}{RESET}", self.title),
            format!("{DIM}{}{RESET}", robot_line(&self.world, &self.rooms)),
        ];
        let mut tree = tree_lines(&self.replay, true);
        if tree.len() > MAX_TREE_LINES {
            let more = tree.len() - MAX_TREE_LINES;
            tree.truncate(MAX_TREE_LINES);
            tree.push(format!("{DIM}… and {more} more nodes{RESET}"));
        }
        lines.extend(tree);
        let mut buf = String::new();
        if self.drawn_lines > 0 {
            // Back to the first line of the last drawing, and clear from there down.
            buf.push_str(&format!("\x1b[{}F", self.drawn_lines));
        }
        buf.push_str("\x1b[J");
        for l in &lines {
            buf.push_str(l);
            buf.push_str("\x1b[K\n");
        }
        let _ = self.out.write_all(buf.as_bytes());
        let _ = self.out.flush();
        self.drawn_lines = lines.len();
        self.last_draw = Some(Instant::now());
        self.dirty = false;
    }
}

impl<W: Write + Send> TraceSink for LiveTree<W> {
    fn record(&mut self, ev: &TraceEvent) {
        // A record the replay refuses (it would be a runtime bug) is left out of the view; the
        // trace checker reports it.
        let _ = self.replay.apply(ev);
        self.dirty = true;
        if let Some(wait) = self
            .pace
            .and_then(|pace| pace_delay(self.started, pace, ev.t))
        {
            self.draw_if_due();
            std::thread::sleep(wait);
        }
        self.draw_if_due();
    }

    fn flush(&mut self) {
        if self.dirty || self.drawn_lines == 0 {
            self.draw();
        }
    }
}

/// How long to hold the driver so that the wall clock, run at `pace` simulated seconds per wall
/// second since `started`, catches up with the simulated time `t` (ns); `None` if it already did.
fn pace_delay(started: Instant, pace: f64, t: u64) -> Option<Duration> {
    let due = Duration::from_secs_f64(Duration::from_nanos(t).as_secs_f64() / pace);
    due.checked_sub(started.elapsed()).filter(|d| !d.is_zero())
}

/// Paces a run on virtual time at some simulated seconds per wall second, so it can be watched
/// (in the viewer) while it runs: the sink sleeps, the virtual clock does not move meanwhile.
pub struct Pace {
    pace: f64,
    started: Instant,
}

impl Pace {
    /// `pace` simulated seconds per wall second, from now.
    pub fn new(pace: f64) -> Pace {
        Pace {
            pace,
            started: Instant::now(),
        }
    }
}

impl TraceSink for Pace {
    fn record(&mut self, ev: &TraceEvent) {
        if let Some(wait) = pace_delay(self.started, self.pace, ev.t) {
            std::thread::sleep(wait);
        }
    }
}

/// The plain event log (see the module documentation).
pub struct EventLog<W: Write + Send> {
    out: W,
    replay: Replay,
}

impl<W: Write + Send> EventLog<W> {
    /// An event log written to `out`.
    pub fn new(out: W) -> EventLog<W> {
        EventLog {
            out,
            replay: Replay::new(),
        }
    }

    /// The log line for `ev`, if it is worth one; call after applying `ev` to the replay.
    fn line(&self, ev: &TraceEvent) -> Option<String> {
        let node_of = |id: u64| self.replay.node(id);
        let quiet =
            |n: &ReplayNode| n.activation_of().is_some() || SENSOR_READINGS.contains(&n.name());
        let parent_of = |n: &ReplayNode| n.parent().and_then(|p| self.replay.node(p));
        let (node, what) = match &ev.kind {
            TraceKind::Transition {
                node, facet, to, ..
            } => {
                let n = node_of(*node)?;
                if quiet(n) || n.termination() != Termination::Alive {
                    return None;
                }
                match (facet, to) {
                    (Facet::Handling, State::Active) => (n, "started".to_string()),
                    (Facet::Execution, State::Completed) if !n.is_failed() => {
                        (n, "done".to_string())
                    }
                    _ => return None,
                }
            }
            TraceKind::Failed {
                node,
                exception,
                message,
            } => (node_of(*node)?, format!("FAILED {exception}: {message}")),
            TraceKind::HandlerChosen {
                node,
                exception,
                attached,
                ..
            } => {
                let attached = node_of(*attached)
                    .map(|a| format!("{} {{{}}}", a.name(), a.number()))
                    .unwrap_or_default();
                (
                    node_of(*node)?,
                    format!("handles {exception} (attached to {attached})"),
                )
            }
            TraceKind::Bypassed { node, exception } => {
                (node_of(*node)?, format!("bypasses {exception}"))
            }
            TraceKind::Retried { node, of } => (node_of(*node)?, format!("retries {{{of}}}")),
            TraceKind::Terminating { node } => {
                let n = node_of(*node)?;
                let top = parent_of(n).is_none_or(|p| p.termination() == Termination::Alive);
                if !top || quiet(n) {
                    return None;
                }
                (n, "terminated".to_string())
            }
            TraceKind::Suspended { node } => {
                let n = node_of(*node)?;
                if parent_of(n).is_some_and(ReplayNode::is_suspended) {
                    return None;
                }
                (n, "SUSPENDED".to_string())
            }
            TraceKind::Unsuspended { node } => {
                let n = node_of(*node)?;
                if parent_of(n).is_some_and(ReplayNode::is_suspended)
                    || n.termination() != Termination::Alive
                {
                    return None;
                }
                (n, "unsuspended".to_string())
            }
            TraceKind::Triggered { monitor, count } => {
                (node_of(*monitor)?, format!("triggered ({count})"))
            }
            TraceKind::Warning {
                node: Some(node),
                message,
            } => (node_of(*node)?, format!("warning: {message}")),
            _ => return None,
        };
        let t = Duration::from_nanos(ev.t).as_secs_f64();
        Some(format!(
            "{t:>8.1} s  {:indent$}{} {{{}}} {what}",
            "",
            node.name(),
            node.number(),
            indent = 2 * depth(&self.replay, node)
        ))
    }
}

impl<W: Write + Send> TraceSink for EventLog<W> {
    fn record(&mut self, ev: &TraceEvent) {
        if self.replay.apply(ev).is_err() {
            return;
        }
        if let Some(line) = self.line(ev) {
            let _ = writeln!(self.out, "{line}");
        }
    }

    fn flush(&mut self) {
        let _ = self.out.flush();
    }
}
