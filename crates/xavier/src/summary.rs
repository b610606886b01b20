//! The summary of a run, read from its trace and the mission's log: rooms delivered, rooms given
//! up and why, every exception raised and how it was handled, the waits for a resource (from the
//! request to the grant, with what held it: the motor monitor keeps the base while the motor
//! cools), and the times. The trace is read through its one fold, [`tcm_trace::Replay`]: its
//! exception stories and each node's row; nothing here matches on record kinds.

use crate::mission::Undeliverable;
use crate::{Done, Setup, secs};
use std::collections::BTreeMap;
use std::fmt;
use std::time::Duration;
use tcm_trace::{ExceptionStory, M_SPAWNED, Replay, Row};
use tdl::{FatalFailure, RunOutcome, TraceEvent};

/// One exception raised during the run, as the trace's fold tells it ([`ExceptionStory`]), with
/// the room whose delivery it happened in and what became of it in words.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RoomException {
    /// The exception's story: the failing node, the exception, its message, what followed.
    pub story: ExceptionStory,
    /// The room whose delivery it happened in, if any.
    pub room: Option<u32>,
    /// The failing node: `name {id}`.
    pub node: String,
    /// What happened, in order: `handler detour {33} (attached to navigate_to_locn {20})`,
    /// `bypassed by ...`, `retried as {n}`, `no handler`.
    pub recovery: Vec<String>,
}

impl RoomException {
    /// When it was raised (simulated time).
    pub fn at(&self) -> Duration {
        Duration::from_nanos(self.story.at.t)
    }

    /// Whether some handler took it (and did not pass it on to nobody).
    pub fn handled(&self) -> bool {
        let steps = &self.story.steps;
        steps.iter().any(|s| s.what == "chosen") && !steps.iter().any(|s| s.what == "unhandled")
    }

    /// The name of the last handler chosen for it, if any.
    pub fn handler(&self) -> Option<&str> {
        self.story
            .steps
            .iter()
            .rev()
            .find(|s| s.what == "chosen")
            .map(|s| s.detail.as_str())
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
    pub exceptions: Vec<RoomException>,
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

/// Exceptions and resource waits from the trace, read from its fold ([`Replay`]).
fn read_trace(setup: &Setup, trace: &[TraceEvent]) -> (Vec<RoomException>, Vec<ResourceWait>) {
    let mut replay = Replay::with_history();
    for ev in trace {
        // A record the fold refuses is left out; the run's trace checker names it.
        let _ = replay.apply(ev);
    }
    let spawned = |id: u64| replay.row(id).filter(|r| id != 0 && r.kind.is_some());
    let label = |id: u64| match spawned(id) {
        Some(r) => format!("{} {{{id}}}", r.name),
        None => format!("{{{id}}}"),
    };
    // Delivery nodes are spawned in the order of the rooms.
    let mut deliveries: Vec<&Row> = replay
        .rows()
        .iter()
        .filter(|r| r.name == "deliver_mail" && r.marks[M_SPAWNED].is_some())
        .collect();
    deliveries.sort_by_key(|r| r.marks[M_SPAWNED].map(|m| m.seq));
    let deliveries: BTreeMap<u64, u32> = deliveries
        .iter()
        .zip(&setup.rooms)
        .map(|(r, room)| (r.number, *room))
        .collect();
    let room_of = |id: u64| {
        let mut cur = Some(id);
        while let Some(n) = cur {
            if let Some(room) = deliveries.get(&n) {
                return Some(*room);
            }
            cur = spawned(n)
                .and_then(|r| r.parent)
                .filter(|&p| p != n && p != 0);
        }
        None
    };
    let stories = replay
        .exceptions()
        .iter()
        .map(|story| {
            let recovery = story
                .steps
                .iter()
                .filter_map(|step| {
                    let node = step.node.unwrap_or_default();
                    Some(match step.what {
                        "chosen" => format!(
                            "handler {} {{{node}}} (attached to {})",
                            step.detail,
                            label(step.attached.unwrap_or_default())
                        ),
                        "bypassed" => format!("bypassed by {}", label(node)),
                        "retried" => format!("retried as {{{node}}}"),
                        "unhandled" => "no handler".to_string(),
                        _ => return None,
                    })
                })
                .collect();
            RoomException {
                story: story.clone(),
                room: room_of(story.node),
                node: label(story.node),
                recovery,
            }
        })
        .collect();
    // Each request: why it waited when it was made (a reservation, the holders in its way).
    let mut granted: Vec<(u64, ResourceWait)> = Vec::new();
    let mut open: Vec<ResourceWait> = Vec::new();
    for r in replay.rows() {
        let Some((asked, uses)) = &r.request else {
            continue;
        };
        let mut why = Vec::new();
        for u in uses {
            let reservation =
                replay.restrictions().iter().rev().find(|x| {
                    x.resource == u.resource && x.holder.is_some() && x.holds_at(asked.seq)
                });
            if let Some(holder) = reservation.and_then(|x| x.holder) {
                why.push(format!("{} reserved for {}", u.resource, label(holder)));
            }
            let holders: Vec<String> = replay
                .holders_at(&u.resource, asked.seq)
                .map(label)
                .collect();
            if !holders.is_empty() {
                why.push(format!("{} held by {}", u.resource, holders.join(", ")));
            }
        }
        let wait = |until: Option<Duration>| ResourceWait {
            node: label(r.number),
            uses: tcm_trace::story::uses_text(uses),
            from: Duration::from_nanos(asked.t),
            until,
            why: why.join("; "),
        };
        match (r.granted, r.refused) {
            (Some(g), _) if g.t > asked.t => {
                granted.push((g.seq, wait(Some(Duration::from_nanos(g.t)))));
            }
            (None, None) => open.push(wait(None)),
            _ => {}
        }
    }
    // In order of the grant; waits still open at the end of the run last.
    granted.sort_by_key(|(seq, _)| *seq);
    let mut waits: Vec<ResourceWait> = granted.into_iter().map(|(_, w)| w).collect();
    waits.append(&mut open);
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
                secs(e.at()),
                e.node,
                e.story.exception,
                e.story.message
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
