//! TCM's terminal log, rendered from trace records: the default logger's lines, and the TRACE
//! builds' lines in trace mode (docs/semantics.md, "TCM-compatible output").
//!
//! [`TextLog`] keeps a [`Replay`] and turns each record into the lines TCM's default logger would have
//! printed, with TCM's column layout, so logs can be compared textually with the original's:
//!
//! ```text
//! Goal                    A {1}:        TCM {0} --> ON HOLD         (Inactive)
//! Goal                    A {1}:  ON HOLD  --> TCM             (Sent)
//!   Success               A {1}:
//! ```
//!
//! Mapping from our records (TCM's words appear only here; docs/semantics.md, "Words"):
//!
//! - `spawned` prints the "ON HOLD (Inactive)" line.
//! - Handling entering *enabled* prints "ON HOLD --> TCM (Sent)": TCM printed it when the node was queued,
//!   which is our enabled point. Handling entering *completed* prints `  Success `, `  Failure ` (a
//!   `failed` record for the node came first) or ` Complete ` (monitors). Both are suppressed when the
//!   node is already terminating, as in TCM.
//! - `terminating`, `terminated`, `suspended`, `unsuspended` and `warning` print their TCM lines.
//! - In trace mode ([`TextLogOptions::trace`]), every facet transition also prints
//!   `<name> transitioning from <Old> to <New>` (before the standard line, if any), with TCM's words:
//!   handling Unhandled (disabled) / Handling (enabled, active) / Handled (completed); expansion
//!   Unplanned (disabled, enabled) / Planning (active) / Planned (completed); execution Unachieved
//!   (disabled, enabled) / Achieving (active) / Achieved (completed). A transition whose two states map to
//!   the same word (handling enabled to active) prints nothing. Termination prints
//!   `<name> transitioning from Alive to Terminating` and `... from Terminating to Terminated`,
//!   `failed` prints `Raising exception "<exception>" from <name>`, `reclaimed` prints `Deleting <name>`.
//!
//! Known differences from TCM:
//!
//! - Nodes released by the same event start in spawn order; TCM started them in reverse registration
//!   order (docs/semantics.md, "Agenda and release order"), so such lines may come in another
//!   order.
//! - Time (with [`TextLogOptions::time`]) is virtual time since the run started, rendered
//!   ` HHH:MM:SS.hh` (hours right-justified in 3), not the wall-clock time of day.
//! - TCM's `WARNING: _displayStatus` lines for odd transitions are not produced; the trace checker reports
//!   such transitions instead.
//! - Records TCM had no line for (`reserved`, `dead`, `constrained`, `constraint_void`, `external`) print
//!   nothing.
//! - Resource records (TCM had no resources) print short lines of our own: `Resource grant: base,
//!   arm(2) to drive {3}`, `Resource release: …`, `Resource denied: …`, `Resource request dropped:
//!   …`, reservations and locks; a request prints `Resource wait: drive {3} waits: base is held by
//!   plan {1}` only when it must wait, naming the holders, a lock or a reservation.
//! - A `log` record (a task's body writing to the run's log; TCM's tasks printed their own lines)
//!   prints `<name> {<number>}: <line>`.

use crate::event::{TraceEvent, TraceKind};
use crate::replay::{Replay, ReplayNode};
use crate::state::{Facet, NodeKind, State, Termination};
use std::io::{self, Write};

#[cfg(test)]
mod tests;

/// What the text log prints besides the standard lines.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TextLogOptions {
    /// Append the time since the run started, ` HHH:MM:SS.hh`, to every line.
    pub time: bool,
    /// Also print the lines of TCM's TRACE builds for every facet and termination transition.
    pub trace: bool,
}

/// Renders records as TCM's text log; feed it every record of a trace, in order.
#[derive(Clone, Debug, Default)]
pub struct TextLog {
    replay: Replay,
    options: TextLogOptions,
}

/// TCM's word for a facet state (see the module doc for the mapping).
pub fn tcm_state_word(facet: Facet, state: State) -> &'static str {
    match (facet, state) {
        (Facet::Handling, State::Disabled) => "Unhandled",
        (Facet::Handling, State::Enabled | State::Active) => "Handling",
        (Facet::Handling, State::Completed) => "Handled",
        (Facet::Expansion, State::Disabled | State::Enabled) => "Unplanned",
        (Facet::Expansion, State::Active) => "Planning",
        (Facet::Expansion, State::Completed) => "Planned",
        (Facet::Execution, State::Disabled | State::Enabled) => "Unachieved",
        (Facet::Execution, State::Active) => "Achieving",
        (Facet::Execution, State::Completed) => "Achieved",
    }
}

/// Virtual time since the start as TCM's ` HHH:MM:SS.hh` suffix (with its leading space).
pub fn time_suffix(t_ns: u64) -> String {
    let hundredths = t_ns / 10_000_000;
    let (h, rest) = (hundredths / 360_000, hundredths % 360_000);
    let (m, rest) = (rest / 6_000, rest % 6_000);
    let (s, cs) = (rest / 100, rest % 100);
    format!(" {h:>3}:{m:02}:{s:02}.{cs:02}")
}

fn class(node: &ReplayNode) -> &'static str {
    node.kind().map_or("Node", NodeKind::tcm_class)
}

impl TextLog {
    /// A text log with the given options.
    pub fn new(options: TextLogOptions) -> TextLog {
        TextLog {
            replay: Replay::new(),
            options,
        }
    }

    /// The tree as rebuilt from the records pushed so far.
    pub fn replay(&self) -> &Replay {
        &self.replay
    }

    /// Renders one record: the lines it prints, joined by `\n` without a final newline, or `None`.
    pub fn push(&mut self, ev: &TraceEvent) -> Option<String> {
        let lines = self.lines(ev);
        // A record the replay refuses (a malformed trace) still got its best-effort lines; the checker
        // is the tool that says what is wrong with it.
        let _ = self.replay.apply(ev);
        if lines.is_empty() {
            return None;
        }
        let suffix = if self.options.time {
            time_suffix(ev.t)
        } else {
            String::new()
        };
        let mut out = String::new();
        for (i, line) in lines.iter().enumerate() {
            if i > 0 {
                out.push('\n');
            }
            out.push_str(line);
            out.push_str(&suffix);
        }
        Some(out)
    }

    /// Renders one record and writes its lines, each with a newline.
    pub fn write(&mut self, ev: &TraceEvent, w: &mut impl Write) -> io::Result<()> {
        match self.push(ev) {
            Some(mut text) => {
                text.push('\n');
                w.write_all(text.as_bytes())
            }
            None => Ok(()),
        }
    }

    /// Renders a whole trace.
    pub fn render(options: TextLogOptions, trace: &[TraceEvent]) -> String {
        let mut log = TextLog::new(options);
        let mut out = String::new();
        for ev in trace {
            if let Some(text) = log.push(ev) {
                out.push_str(&text);
                out.push('\n');
            }
        }
        out
    }

    fn lines(&self, ev: &TraceEvent) -> Vec<String> {
        let trace = self.options.trace;
        let node = ev.kind.node().and_then(|n| self.replay.node(n));
        let mut lines = Vec::new();
        match (&ev.kind, node) {
            (
                TraceKind::Spawned {
                    node,
                    parent,
                    kind,
                    name,
                    ..
                },
                _,
            ) => lines.push(format!(
                "{:<9} {:>15} {{{node}}}: {:>10} {{{parent}}} --> ON HOLD         (Inactive)",
                kind.tcm_class(),
                name,
                "TCM"
            )),
            (
                TraceKind::Transition {
                    node: number,
                    facet,
                    from,
                    to,
                },
                Some(n),
            ) => {
                let (old, new) = (tcm_state_word(*facet, *from), tcm_state_word(*facet, *to));
                if trace && old != new {
                    lines.push(format!("{} transitioning from {old} to {new}", n.name()));
                }
                let alive = n.termination() == Termination::Alive;
                if *facet == Facet::Handling && alive {
                    if *from < State::Enabled && State::Enabled <= *to && *to < State::Completed {
                        lines.push(format!(
                            "{:<9} {:>15} {{{number}}}:  ON HOLD  --> {:<15} (Sent)",
                            class(n),
                            n.name(),
                            "TCM"
                        ));
                    }
                    if *to == State::Completed {
                        let word = if n.is_failed() {
                            "  Failure "
                        } else if n.kind() == Some(NodeKind::Monitor) {
                            " Complete "
                        } else {
                            "  Success "
                        };
                        lines.push(format!("{word}{:>15} {{{number}}}:", n.name()));
                    }
                }
            }
            (TraceKind::Terminating { node: number }, Some(n)) => {
                if trace {
                    lines.push(format!(
                        "{} transitioning from Alive to Terminating",
                        n.name()
                    ));
                }
                lines.push(format!(
                    "Will Terminate {} {{{number}}} when all references to it are released",
                    n.name()
                ));
            }
            (TraceKind::Terminated { node: number }, Some(n)) => {
                if trace {
                    lines.push(format!(
                        "{} transitioning from Terminating to Terminated",
                        n.name()
                    ));
                }
                lines.push(format!("Terminated {} {{{number}}}", n.name()));
            }
            (TraceKind::Suspended { node: number }, Some(n)) => {
                lines.push(format!("Suspended {} {{{number}}}", n.name()));
            }
            (TraceKind::Unsuspended { node: number }, Some(n)) => {
                lines.push(format!("Unsuspended {} {{{number}}}", n.name()));
            }
            (TraceKind::Failed { exception, .. }, Some(n)) if trace => {
                lines.push(format!(
                    "Raising exception \"{exception}\" from {}",
                    n.name()
                ));
            }
            (TraceKind::Reclaimed { .. }, Some(n)) if trace => {
                lines.push(format!("Deleting {}", n.name()));
            }
            (
                TraceKind::Placed {
                    node: number,
                    agent,
                },
                Some(n),
            ) if trace => {
                lines.push(format!(
                    "Placing {} {{{number}}} on agent {agent}",
                    n.name()
                ));
            }
            (TraceKind::Warning { message, .. }, _) => lines.push(format!("WARNING: {message}")),
            (
                TraceKind::Log {
                    node: number,
                    message,
                },
                Some(n),
            ) => lines.push(format!("{} {{{number}}}: {message}", n.name())),
            (kind, node) => {
                if let Some(line) = self.resource_line(kind, node) {
                    lines.push(line);
                }
            }
        }
        lines
    }

    /// The line of a resource record (TCM had no resources; these lines are ours). A request
    /// prints a line only when it must wait, naming why: the holders of a resource without
    /// enough room left, a lock, a reservation for another subtree.
    fn resource_line(&self, kind: &TraceKind, node: Option<&ReplayNode>) -> Option<String> {
        let who = |n: &ReplayNode| format!("{} {{{}}}", n.name(), n.number());
        let uses = |uses: &[crate::event::ResourceUse]| {
            let parts: Vec<String> = uses
                .iter()
                .map(|u| match u.amount {
                    1 => u.resource.clone(),
                    n => format!("{}({n})", u.resource),
                })
                .collect();
            parts.join(", ")
        };
        let holder = |number: u64| match self.replay.node(number) {
            Some(n) => who(n),
            None => format!("{{{number}}}"),
        };
        Some(match (kind, node) {
            (TraceKind::Requested { uses: asked, .. }, Some(n)) => {
                let mut why = Vec::new();
                for u in asked {
                    let Some(r) = self.replay.resource(&u.resource) else {
                        continue;
                    };
                    if r.is_locked() {
                        why.push(format!("{} is locked", u.resource));
                    }
                    if let Some(h) = r.reserved_for() {
                        if !self.replay.is_in_subtree(n.number(), h) {
                            why.push(format!("{} is reserved for {}", u.resource, holder(h)));
                        }
                    }
                    if r.in_use() + u64::from(u.amount) > u64::from(r.capacity()) {
                        let held: Vec<String> =
                            r.holders().iter().map(|(h, _)| holder(*h)).collect();
                        why.push(format!("{} is held by {}", u.resource, held.join(", ")));
                    }
                }
                if why.is_empty() {
                    return None;
                }
                format!("Resource wait: {} waits: {}", who(n), why.join("; "))
            }
            (TraceKind::Granted { uses: got, .. }, Some(n)) => {
                format!("Resource grant: {} to {}", uses(got), who(n))
            }
            (TraceKind::Released { uses: gave, .. }, Some(n)) => {
                format!("Resource release: {} from {}", uses(gave), who(n))
            }
            (TraceKind::Withdrawn { .. }, Some(n)) => {
                format!("Resource request withdrawn: {}", who(n))
            }
            (TraceKind::Denied { resource, .. }, Some(n)) => {
                format!("Resource denied: {resource} to {}", who(n))
            }
            (TraceKind::Dropped { resource, .. }, Some(n)) => {
                format!("Resource request dropped: {resource} for {}", who(n))
            }
            (
                TraceKind::ResourceReserved {
                    resource,
                    holder: h,
                },
                _,
            ) => {
                format!("Resource reserved: {resource} for {}", holder(*h))
            }
            (TraceKind::ResourceUnreserved { resource }, _) => {
                format!("Resource unreserved: {resource}")
            }
            (TraceKind::ResourceLocked { resource }, _) => format!("Resource locked: {resource}"),
            (TraceKind::ResourceUnlocked { resource }, _) => {
                format!("Resource unlocked: {resource}")
            }
            _ => return None,
        })
    }
}
