//! Each record kind's class and its text for people: what `tdl trace story` prints, kept with the
//! record type so that a new kind is described where it is defined.

use crate::event::{TraceConstraint, TraceEventRef, TraceKind, TraceThen, TraceWhen};
use crate::story::uses_text;

/// The class of a record, for filters (`tdl trace story --kind`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum RecordClass {
    /// Facet transitions.
    Transition,
    /// Spawns, reservations, dead reservations, reclamation, placement on an agent.
    Spawn,
    /// Constraints applied and void constraints.
    Constraint,
    /// Termination.
    Terminate,
    /// Suspension.
    Suspend,
    /// Failures.
    Fail,
    /// Handlers chosen and bypasses.
    Handler,
    /// Retries.
    Retry,
    /// Wiretap checks.
    Wiretap,
    /// Monitor parameters, activations and triggers.
    Monitor,
    /// External events, timer callbacks and control from outside the run.
    Event,
    /// Resources: declarations, requests, grants, releases, refusals, reservations and locks.
    Resource,
    /// State variables declared and set, and skipped nodes.
    State,
    /// Warnings.
    Warning,
    /// Lines a task's body wrote to the run's log.
    Log,
}

impl RecordClass {
    /// Every class, in the order above.
    pub const ALL: [RecordClass; 15] = [
        RecordClass::Transition,
        RecordClass::Spawn,
        RecordClass::Constraint,
        RecordClass::Terminate,
        RecordClass::Suspend,
        RecordClass::Fail,
        RecordClass::Handler,
        RecordClass::Retry,
        RecordClass::Wiretap,
        RecordClass::Monitor,
        RecordClass::Event,
        RecordClass::Resource,
        RecordClass::State,
        RecordClass::Warning,
        RecordClass::Log,
    ];

    /// Its name in lowercase, as a filter writes it: `transition`, `spawn`, …
    pub fn name(self) -> &'static str {
        match self {
            RecordClass::Transition => "transition",
            RecordClass::Spawn => "spawn",
            RecordClass::Constraint => "constraint",
            RecordClass::Terminate => "terminate",
            RecordClass::Suspend => "suspend",
            RecordClass::Fail => "fail",
            RecordClass::Handler => "handler",
            RecordClass::Retry => "retry",
            RecordClass::Wiretap => "wiretap",
            RecordClass::Monitor => "monitor",
            RecordClass::Event => "event",
            RecordClass::Resource => "resource",
            RecordClass::State => "state",
            RecordClass::Warning => "warning",
            RecordClass::Log => "log",
        }
    }
}

impl TraceConstraint {
    /// The constraint as TDL writes it, its nodes named by `name` with their numbers and its times
    /// since the run started: `disable execution until plan_path {7} execution completed`,
    /// `terminate in 30s after speak {9} handling active`, `terminate at 124s (run time)`.
    pub fn text(&self, name: impl Fn(u64) -> String) -> String {
        let event = |e: &TraceEventRef| {
            let point = match e.outcome {
                Some(outcome) => outcome.as_str().to_owned(),
                None => format!("{} {}", e.facet, e.point.as_str()),
            };
            format!("{} {{{}}} {point}", name(e.node), e.node)
        };
        let (head, at, within) = match self {
            TraceConstraint::ExpandFirst => return "expand first".into(),
            TraceConstraint::DelayExpansion => return "delay expansion".into(),
            TraceConstraint::Trigger { then, .. } => match then {
                TraceThen::Enable(facet) => (format!("disable {facet}"), "until", "for"),
                TraceThen::Terminate => ("terminate".to_owned(), "at", "in"),
                TraceThen::Activate => ("activate".to_owned(), "at", "in"),
                TraceThen::Skip => ("skip".to_owned(), "if", "in"),
                TraceThen::Invariant => ("with invariant".to_owned(), "", "in"),
                TraceThen::Pause => ("pause".to_owned(), "while", "in"),
            },
        };
        let TraceConstraint::Trigger { when, .. } = self else {
            return head;
        };
        match when {
            TraceWhen::Now => head,
            TraceWhen::At(t) => format!("{head} {at} {} (run time)", seconds(*t)),
            TraceWhen::Event(e) => format!("{head} {at} {}", event(e)),
            TraceWhen::After { delay_ns, event: e } => {
                format!("{head} {within} {} after {}", seconds(*delay_ns), event(e))
            }
            TraceWhen::External(name) => format!("{head} {at} external {name:?}"),
            TraceWhen::Condition(cond) => match self {
                TraceConstraint::Trigger {
                    then: TraceThen::Invariant,
                    ..
                } => format!("{head} {cond}"),
                TraceConstraint::Trigger {
                    then: TraceThen::Enable(_) | TraceThen::Terminate | TraceThen::Activate,
                    ..
                } => format!("{head} when {cond}"),
                _ => format!("{head} {at} {cond}"),
            },
            TraceWhen::Changed(var) => format!("{head} on change of {var}"),
            TraceWhen::All { events, delay_ns } => {
                let all: Vec<String> = events.iter().map(event).collect();
                let all = if all.is_empty() {
                    "nothing".to_owned()
                } else {
                    all.join(" and ")
                };
                match delay_ns {
                    Some(d) => format!("{head} {within} {} after all of {all}", seconds(*d)),
                    None => format!("{head} {at} all of {all}"),
                }
            }
        }
    }
}

/// Nanoseconds as seconds, as short as exact: `30s`, `1.5s`, `0.000001s`.
fn seconds(ns: u64) -> String {
    let whole = ns / 1_000_000_000;
    let frac = ns % 1_000_000_000;
    if frac == 0 {
        return format!("{whole}s");
    }
    let frac = format!("{frac:09}");
    format!("{whole}.{}s", frac.trim_end_matches('0'))
}

impl TraceKind {
    /// The record's class, the node it is told about (for a handler chosen, the failing node; for
    /// an activation or a trigger, the monitor), and what it says, e.g. `handling active`,
    /// `failed Blocked: no way through`; `None` for the run's first record. `name` names a node
    /// the text mentions besides its subject.
    pub fn describe(
        &self,
        name: impl Fn(u64) -> String,
    ) -> Option<(RecordClass, Option<u64>, String)> {
        use RecordClass as C;
        use TraceKind as K;
        let name = |n: &u64| name(*n);
        Some(match self {
            K::RunStarted { .. } => return None,
            K::Reserved { node, parent, .. } => (
                C::Spawn,
                Some(*node),
                format!("reserved under {{{parent}}}"),
            ),
            K::Spawned {
                node,
                parent,
                kind,
                args,
                ..
            } => {
                let mut text = format!("spawned ({kind:?}) under {{{parent}}}").to_lowercase();
                if let Some(args) = args {
                    text.push_str(" with ");
                    text.push_str(args);
                }
                (C::Spawn, Some(*node), text)
            }
            K::Constrained { node, constraint } => (
                C::Constraint,
                Some(*node),
                format!("constrained: {}", constraint.text(|n| name(&n))),
            ),
            K::ConstraintVoid { node, reason } => (
                C::Constraint,
                Some(*node),
                format!("constraint void: {reason}"),
            ),
            K::Transition {
                node, facet, to, ..
            } => (C::Transition, Some(*node), format!("{facet} {to}")),
            K::Terminating { node } => (C::Terminate, Some(*node), "terminating".into()),
            K::Terminated { node } => (C::Terminate, Some(*node), "terminated".into()),
            K::Suspended { node } => (C::Suspend, Some(*node), "suspended".into()),
            K::Unsuspended { node } => (C::Suspend, Some(*node), "unsuspended".into()),
            K::Failed {
                node,
                exception,
                message,
            } => (
                C::Fail,
                Some(*node),
                format!("failed {exception}: {message}"),
            ),
            K::Dead { node } => (C::Spawn, Some(*node), "dead".into()),
            K::Reclaimed { node } => (C::Spawn, Some(*node), "reclaimed".into()),
            K::External { name } => (C::Event, None, format!("external event {name}")),
            K::StateDeclared { var, ty, value } => {
                (C::State, None, format!("state {var}: {ty} = {value}"))
            }
            K::StateSet { var, value } => (C::State, None, format!("set {var} = {value}")),
            K::Skipped { node } => (C::State, Some(*node), "skipped".into()),
            K::MonitorParams {
                node,
                max_activations,
                max_triggers,
                period_ns,
                ..
            } => (
                C::Monitor,
                Some(*node),
                format!(
                    "monitor parameters: maximum activate {}, maximum trigger {}, period {}",
                    max_activations.map_or("-".into(), |it| it.to_string()),
                    max_triggers.map_or("-".into(), |it| it.to_string()),
                    period_ns.map_or("-".into(), |it| format!("{}s", it as f64 / 1e9)),
                ),
            ),
            K::Activated {
                monitor,
                node,
                number,
            } => (
                C::Monitor,
                Some(*monitor),
                format!("activation {number}: {} {{{node}}}", name(node)),
            ),
            K::Triggered { monitor, count } => {
                (C::Monitor, Some(*monitor), format!("triggered ({count})"))
            }
            K::HandlerChosen {
                node,
                failing,
                attached,
                exception,
                handler,
            } => (
                C::Handler,
                Some(*failing),
                format!(
                    "handler {handler} {{{node}}} chosen for {exception} (attached to {} {{{attached}}})",
                    name(attached)
                ),
            ),
            K::Bypassed { node, exception } => {
                (C::Handler, Some(*node), format!("bypasses {exception}"))
            }
            K::Retried { node, of } => (
                C::Retry,
                Some(*node),
                format!("retries {} {{{of}}}", name(of)),
            ),
            K::Tapped { node, tap, when } => (
                C::Wiretap,
                Some(*node),
                format!("wiretap {tap} checks {when}"),
            ),
            K::HandlerAttached {
                attach,
                task,
                handler,
                exception,
            } => (
                C::Handler,
                None,
                format!("handler {handler} ({exception}) attached to {task} as {attach}"),
            ),
            K::HandlerDetached { attach } => (
                C::Handler,
                None,
                format!("attached handler {attach} removed"),
            ),
            K::TapAdded {
                tap,
                task,
                instance,
                when,
            } => (
                C::Wiretap,
                None,
                format!(
                    "wiretap {tap} added on {} {task}, {when}",
                    if *instance { "instance" } else { "task" }
                ),
            ),
            K::TapRemoved { tap } => (C::Wiretap, None, format!("wiretap {tap} removed")),
            K::Control { what, by } => (C::Event, None, format!("control: {what} (by {by})")),
            K::Paused { node, why } => (C::Event, *node, format!("run paused: {why}")),
            K::Resumed { held_ns } => (
                C::Event,
                None,
                format!("run resumed, its timers {} later", seconds(*held_ns)),
            ),
            K::Injected { node, outcome } => {
                (C::Fail, Some(*node), format!("fault injected: {outcome}"))
            }
            K::Held { node } => (C::Event, Some(*node), "held for approval".to_string()),
            K::Approved { node, by } => (C::Event, Some(*node), format!("approved by {by}")),
            K::CallbackSet { name, node, .. } => (C::Event, *node, format!("callback {name} set")),
            K::CallbackRan { name, .. } => (C::Event, None, format!("callback {name} ran")),
            K::Resource {
                resource,
                capacity,
                pending_limit,
            } => {
                let pending = pending_limit.map_or(String::new(), |p| format!(", pending {p}"));
                let text = format!("resource {resource} capacity {capacity}{pending}");
                (C::Resource, None, text)
            }
            K::Requested {
                node,
                uses,
                priority,
            } => (
                C::Resource,
                Some(*node),
                format!("requests {} (priority {priority})", uses_text(uses)),
            ),
            K::Granted { node, uses } => (
                C::Resource,
                Some(*node),
                format!("granted {}", uses_text(uses)),
            ),
            K::Released { node, uses } => (
                C::Resource,
                Some(*node),
                format!("released {}", uses_text(uses)),
            ),
            K::Withdrawn { node } => (C::Resource, Some(*node), "withdraws its request".into()),
            K::Denied { node, resource } => {
                (C::Resource, Some(*node), format!("denied {resource}"))
            }
            K::Dropped { node, resource } => (
                C::Resource,
                Some(*node),
                format!("dropped from {resource}'s queue"),
            ),
            K::ResourceReserved { resource, holder } => (
                C::Resource,
                Some(*holder),
                format!("reserves {resource} for its subtree"),
            ),
            K::ResourceUnreserved { resource } => {
                (C::Resource, None, format!("{resource} unreserved"))
            }
            K::ResourceLocked { resource } => (C::Resource, None, format!("{resource} locked")),
            K::ResourceUnlocked { resource } => (C::Resource, None, format!("{resource} unlocked")),
            K::Placed { node, agent } => (C::Spawn, Some(*node), format!("runs on agent {agent}")),
            K::Warning { node, message } => (C::Warning, *node, format!("warning: {message}")),
            K::Log { node, message } => (C::Log, Some(*node), format!("log: {message}")),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_handler_choice_is_told_about_the_failing_node_and_names_the_attachment() {
        let kind = TraceKind::HandlerChosen {
            node: 9,
            failing: 7,
            attached: 2,
            exception: "Overheating".into(),
            handler: "cool".into(),
        };
        let (class, node, text) = kind
            .describe(|n| format!("n{n}"))
            .expect("a handler choice is described");
        assert_eq!((class, node), (RecordClass::Handler, Some(7)));
        assert_eq!(
            text,
            "handler cool {9} chosen for Overheating (attached to n2 {2})"
        );
        let start = TraceKind::RunStarted { version: 6, run: 0 };
        assert_eq!(start.describe(|_| String::new()), None);
    }

    #[test]
    fn a_spawn_is_told_with_the_arguments_its_record_carries() {
        let spawned = |args: Option<&str>| TraceKind::Spawned {
            node: 3,
            parent: 1,
            kind: crate::state::NodeKind::Command,
            name: "drive".into(),
            version: None,
            args: args.map(String::from),
        };
        let told = |k: TraceKind| k.describe(|n| format!("n{n}")).map(|(_, _, t)| t);
        assert_eq!(
            told(spawned(Some("room = 3, map = …"))).as_deref(),
            Some("spawned (command) under {1} with room = 3, map = …")
        );
        assert_eq!(
            told(spawned(None)).as_deref(),
            Some("spawned (command) under {1}")
        );
    }

    #[test]
    fn a_constraint_is_told_as_tdl_writes_it() {
        use crate::state::{Facet, Outcome, Point};
        let done = |node| TraceEventRef {
            node,
            facet: Facet::Execution,
            point: Point::Completed,
            outcome: None,
        };
        let name = |n: u64| format!("n{n}");
        let cases = [
            (
                TraceConstraint::trigger(
                    TraceWhen::Event(done(7)),
                    TraceThen::Enable(Facet::Execution),
                ),
                "disable execution until n7 {7} execution completed",
            ),
            (
                TraceConstraint::trigger(
                    TraceWhen::After {
                        delay_ns: 1_500_000_000,
                        event: TraceEventRef {
                            outcome: Some(Outcome::Failed),
                            ..done(3)
                        },
                    },
                    TraceThen::Terminate,
                ),
                "terminate in 1.5s after n3 {3} failed",
            ),
            (
                TraceConstraint::trigger(TraceWhen::At(124_000_000_000), TraceThen::Terminate),
                "terminate at 124s (run time)",
            ),
            (
                TraceConstraint::trigger(
                    TraceWhen::External("door open".into()),
                    TraceThen::Activate,
                ),
                "activate at external \"door open\"",
            ),
            (
                TraceConstraint::trigger(
                    TraceWhen::All {
                        events: vec![done(4), done(5)],
                        delay_ns: None,
                    },
                    TraceThen::Terminate,
                ),
                "terminate at all of n4 {4} execution completed and n5 {5} execution completed",
            ),
            (TraceConstraint::ExpandFirst, "expand first"),
        ];
        for (constraint, text) in cases {
            assert_eq!(constraint.text(name), text);
        }
        let record = TraceKind::Constrained {
            node: 8,
            constraint: TraceConstraint::trigger(TraceWhen::Now, TraceThen::Terminate),
        };
        let (_, _, text) = record.describe(name).expect("described");
        assert_eq!(text, "constrained: terminate");
    }
}
