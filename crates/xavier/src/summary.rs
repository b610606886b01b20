//! The summary of a run, read from its trace and the mission's log: rooms delivered, rooms given
//! up and why, every exception raised and how it was handled (`failed`, `handler_chosen`,
//! `bypassed`, `retried` and unhandled-exception `warning` records), the waits for a resource
//! (`requested` to `granted`, with what held it: the motor monitor keeps the base while the motor
//! cools), and the times.

use crate::mission::Undeliverable;
use crate::{Done, Setup, secs};
use std::collections::BTreeMap;
use std::fmt;
use std::time::Duration;
use tdl::{FatalFailure, RunOutcome, TraceEvent, TraceKind};

/// One exception raised during the run and what became of it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ExceptionStory {
    /// When it was raised (simulated time).
    pub at: Duration,
    /// The room whose delivery it happened in, if any.
    pub room: Option<u32>,
    /// The failing node: `name {id}`.
    pub node: String,
    /// The exception type.
    pub exception: String,
    /// Its message.
    pub message: String,
    /// What happened, in order: `handler detour {33} (attached to navigate_to_locn {20})`,
    /// `bypassed by ...`, `retried as {n}`, `no handler`.
    pub recovery: Vec<String>,
}

impl ExceptionStory {
    /// Whether some handler took it (and did not pass it on to nobody).
    pub fn handled(&self) -> bool {
        self.recovery.iter().any(|h| h.starts_with("handler"))
            && !self.recovery.iter().any(|h| h == "no handler")
    }

    /// The name of the last handler chosen for it, if any.
    pub fn handler(&self) -> Option<&str> {
        self.recovery
            .iter()
            .rev()
            .find_map(|h| h.strip_prefix("handler "))
            .and_then(|h| h.split(' ').next())
    }
}

/// A node that waited, enabled, for a resource: from its request to its grant.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ResourceWait {
    /// The waiting node, as `name {id}`.
    pub node: String,
    /// What it asked for, as `base` or `arm(2), base`.
    pub uses: String,
    /// When it asked.
    pub from: Duration,
    /// When it was granted; `None` if never.
    pub until: Option<Duration>,
    /// Why, when it asked: the reservation or the holders in its way.
    pub why: String,
}

/// What a run achieved.
#[derive(Clone, Debug)]
pub struct Summary {
    /// The setup that ran.
    pub setup: Setup,
    /// The rooms of the round whose letter was taken, in the order taken.
    pub delivered: Vec<u32>,
    /// The rooms whose sender was notified.
    pub notified: Vec<u32>,
    /// The rooms given up, with the exception that made the robot give up.
    pub undeliverable: Vec<Undeliverable>,
    /// Rooms neither delivered nor given up (nobody took the letter in time).
    pub not_taken: Vec<u32>,
    /// Every exception raised, in order.
    pub exceptions: Vec<ExceptionStory>,
    /// Every wait of a node for a resource, in order of its grant (those never granted last).
    pub resource_waits: Vec<ResourceWait>,
    /// How the run ended.
    pub outcome: RunOutcome,
    /// Every failure no handler took (the run went on after each, as in TCM).
    pub unhandled: Vec<FatalFailure>,
    /// Nodes that failed, handled or not.
    pub failures: u64,
    /// Warnings of the run.
    pub warnings: u64,
    /// Simulated time of the run.
    pub simulated: Duration,
    /// How far the robot drove, in metres.
    pub distance: f64,
    /// How many trace records the run wrote.
    pub records: usize,
}

impl Summary {
    /// The summary of `done`, a run of `setup` whose trace is `trace`.
    pub fn new(setup: &Setup, done: &Done, trace: &[TraceEvent]) -> Summary {
        let world = done.mission.robot.summary();
        let delivered: Vec<u32> = world
            .delivered
            .iter()
            .copied()
            .filter(|r| setup.rooms.contains(r))
            .collect();
        let undeliverable = done.mission.undeliverable();
        let not_taken = setup
            .rooms
            .iter()
            .copied()
            .filter(|r| !delivered.contains(r) && !undeliverable.iter().any(|u| u.room == *r))
            .collect();
        let (exceptions, resource_waits) = read_trace(setup, trace);
        Summary {
            setup: setup.clone(),
            delivered,
            notified: done.mission.notifications(),
            undeliverable,
            not_taken,
            exceptions,
            resource_waits,
            outcome: done.report.outcome.clone(),
            unhandled: done.report.unhandled.clone(),
            failures: done.report.failures,
            warnings: done.report.warnings,
            simulated: done.report.elapsed,
            distance: world.distance_travelled,
            records: trace.len(),
        }
    }

    /// Whether the run ended well: the top-level task completed (rooms given up are fine).
    pub fn ok(&self) -> bool {
        self.outcome == RunOutcome::Completed
    }
}

/// Exceptions and resource waits from the trace.
fn read_trace(setup: &Setup, trace: &[TraceEvent]) -> (Vec<ExceptionStory>, Vec<ResourceWait>) {
    let mut names: BTreeMap<u64, (String, u64)> = BTreeMap::new();
    // Delivery nodes are spawned in the order of the rooms.
    let mut deliveries: BTreeMap<u64, u32> = BTreeMap::new();
    let mut stories: Vec<ExceptionStory> = Vec::new();
    // Failing node -> its story; handler node -> the story it handles.
    let mut by_failing: BTreeMap<u64, usize> = BTreeMap::new();
    let mut by_handler: BTreeMap<u64, usize> = BTreeMap::new();
    // Resource -> the node it is reserved for; node -> what it holds; node -> its open wait.
    let mut reserved: BTreeMap<String, u64> = BTreeMap::new();
    let mut held: BTreeMap<u64, Vec<String>> = BTreeMap::new();
    let mut asked: BTreeMap<u64, (Duration, String, String)> = BTreeMap::new();
    let mut waits: Vec<ResourceWait> = Vec::new();
    let label = |names: &BTreeMap<u64, (String, u64)>, id: u64| match names.get(&id) {
        Some((name, _)) => format!("{name} {{{id}}}"),
        None => format!("{{{id}}}"),
    };
    let room_of = |names: &BTreeMap<u64, (String, u64)>, deliveries: &BTreeMap<u64, u32>, id| {
        let mut cur = Some(id);
        while let Some(n) = cur {
            if let Some(room) = deliveries.get(&n) {
                return Some(*room);
            }
            cur = names.get(&n).map(|(_, p)| *p).filter(|&p| p != n && p != 0);
        }
        None
    };
    for ev in trace {
        let at = Duration::from_nanos(ev.t);
        match &ev.kind {
            TraceKind::Spawned {
                node, parent, name, ..
            } => {
                names.insert(*node, (name.clone(), *parent));
                if name == "deliver_mail" {
                    if let Some(room) = setup.rooms.get(deliveries.len()) {
                        deliveries.insert(*node, *room);
                    }
                }
            }
            TraceKind::Failed {
                node,
                exception,
                message,
            } => {
                by_failing.insert(*node, stories.len());
                stories.push(ExceptionStory {
                    at,
                    room: room_of(&names, &deliveries, *node),
                    node: label(&names, *node),
                    exception: exception.clone(),
                    message: message.clone(),
                    recovery: Vec::new(),
                });
            }
            TraceKind::HandlerChosen {
                node,
                failing,
                attached,
                handler,
                ..
            } => {
                if let Some(&i) = by_failing.get(failing) {
                    by_handler.insert(*node, i);
                    stories[i].recovery.push(format!(
                        "handler {handler} {{{node}}} (attached to {})",
                        label(&names, *attached)
                    ));
                }
            }
            TraceKind::Bypassed { node, .. } => {
                if let Some(&i) = by_handler.get(node) {
                    stories[i]
                        .recovery
                        .push(format!("bypassed by {}", label(&names, *node)));
                }
            }
            TraceKind::Retried { node, of } => {
                if let Some(&i) = by_failing.get(of) {
                    stories[i].recovery.push(format!("retried as {{{node}}}"));
                }
            }
            TraceKind::Warning {
                node: Some(node),
                message,
            } if message.starts_with("No exception handler found") => {
                if let Some(&i) = by_failing.get(node) {
                    stories[i].recovery.push("no handler".to_string());
                }
            }
            TraceKind::Requested { node, uses, .. } => {
                let mut why = Vec::new();
                for u in uses {
                    if let Some(holder) = reserved.get(&u.resource) {
                        why.push(format!(
                            "{} reserved for {}",
                            u.resource,
                            label(&names, *holder)
                        ));
                    }
                    let holders: Vec<String> = held
                        .iter()
                        .filter(|(_, rs)| rs.contains(&u.resource))
                        .map(|(n, _)| label(&names, *n))
                        .collect();
                    if !holders.is_empty() {
                        why.push(format!("{} held by {}", u.resource, holders.join(", ")));
                    }
                }
                let text = tcm_trace::story::uses_text(uses);
                asked.insert(*node, (at, text, why.join("; ")));
            }
            TraceKind::Granted { node, uses } => {
                held.insert(*node, uses.iter().map(|u| u.resource.clone()).collect());
                if let Some((from, uses, why)) = asked.remove(node) {
                    if at > from {
                        waits.push(ResourceWait {
                            node: label(&names, *node),
                            uses,
                            from,
                            until: Some(at),
                            why,
                        });
                    }
                }
            }
            TraceKind::Released { node, .. } => {
                held.remove(node);
            }
            TraceKind::Withdrawn { node }
            | TraceKind::Denied { node, .. }
            | TraceKind::Dropped { node, .. } => {
                asked.remove(node);
            }
            TraceKind::ResourceReserved { resource, holder } => {
                reserved.insert(resource.clone(), *holder);
            }
            TraceKind::ResourceUnreserved { resource } => {
                reserved.remove(resource);
            }
            _ => {}
        }
    }
    // Waits still open at the end of the run.
    for (node, (from, uses, why)) in asked {
        waits.push(ResourceWait {
            node: label(&names, node),
            uses,
            from,
            until: None,
            why,
        });
    }
    (stories, waits)
}

fn rooms(rooms: &[u32]) -> String {
    if rooms.is_empty() {
        return "none".to_string();
    }
    rooms
        .iter()
        .map(u32::to_string)
        .collect::<Vec<_>>()
        .join(", ")
}

impl fmt::Display for Summary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = &self.setup;
        writeln!(
            f,
            "Xavier's mail round: seed {}, scenario {}, rooms {}",
            s.seed,
            s.scenario,
            rooms(&s.rooms)
        )?;
        writeln!(f, "  delivered:       {}", rooms(&self.delivered))?;
        writeln!(f, "  senders told:    {}", rooms(&self.notified))?;
        if self.undeliverable.is_empty() {
            writeln!(f, "  undeliverable:   none")?;
        } else {
            writeln!(f, "  undeliverable:")?;
            for u in &self.undeliverable {
                writeln!(f, "    room {}: {} ({})", u.room, u.exception, u.reason)?;
            }
        }
        if !self.not_taken.is_empty() {
            writeln!(
                f,
                "  letter not taken: {} (nobody came within the pickup monitor's 15 polls)",
                rooms(&self.not_taken)
            )?;
        }
        writeln!(f, "  exceptions:      {}", self.exceptions.len())?;
        for e in &self.exceptions {
            let room = e.room.map(|r| format!("room {r}: ")).unwrap_or_default();
            writeln!(
                f,
                "    {:>7}  {room}{} failed {}: {}",
                secs(e.at),
                e.node,
                e.exception,
                e.message
            )?;
            for h in &e.recovery {
                writeln!(f, "             -> {h}")?;
            }
            if e.recovery.is_empty() {
                writeln!(f, "             -> ended with its task (no handler search)")?;
            }
        }
        if self.resource_waits.is_empty() {
            writeln!(f, "  resource waits:  none")?;
        } else {
            writeln!(f, "  resource waits:  {}", self.resource_waits.len())?;
            for w in &self.resource_waits {
                let until = w.until.map_or("the end".to_string(), secs);
                let why = if w.why.is_empty() {
                    String::new()
                } else {
                    format!(" ({})", w.why)
                };
                writeln!(
                    f,
                    "    {} waited for {} from {} to {until}{why}",
                    w.node,
                    w.uses,
                    secs(w.from)
                )?;
            }
        }
        writeln!(
            f,
            "  failures:        {} ({} unhandled), {} warning(s)",
            self.failures,
            self.unhandled.len(),
            self.warnings
        )?;
        for u in &self.unhandled {
            writeln!(f, "    UNHANDLED {u}")?;
        }
        writeln!(
            f,
            "  simulated time:  {} ({:.1} m driven, {} trace records)",
            secs(self.simulated),
            self.distance,
            self.records
        )?;
        let outcome = match &self.outcome {
            RunOutcome::Completed => "completed".to_string(),
            other => format!("{other:?}"),
        };
        write!(f, "  run:             {outcome}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tdl::Failure;
    use xavier_world::Scenario;

    #[test]
    fn the_summary_prints_each_unhandled_failure_and_the_counts() {
        let summary = Summary {
            setup: Setup {
                seed: 1,
                scenario: Scenario::Nominal,
                rooms: vec![3],
            },
            delivered: vec![3],
            notified: Vec::new(),
            undeliverable: Vec::new(),
            not_taken: Vec::new(),
            exceptions: Vec::new(),
            resource_waits: Vec::new(),
            outcome: RunOutcome::Completed,
            unhandled: vec![FatalFailure {
                failure: Failure::new("NoPath", "every route to room 3 is blocked"),
                node: 4,
                path: "deliver_mail/plan".to_string(),
            }],
            failures: 2,
            warnings: 1,
            simulated: Duration::from_secs(1),
            distance: 0.0,
            records: 0,
        };
        let text = summary.to_string();
        assert!(
            text.contains("failures:        2 (1 unhandled), 1 warning(s)"),
            "{text}"
        );
        assert!(
            text.contains(
                "UNHANDLED unhandled exception NoPath in deliver_mail/plan {4}: every route to room 3 is blocked"
            ),
            "{text}"
        );
    }
}
