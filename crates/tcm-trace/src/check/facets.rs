//! The checker's side of facets: each transition against the Figure 3 axioms (enablement, activity
//! and completion conditions, with the node's own constraints at enablement), termination and
//! reclamation.

use super::{Checker, Rule};
use crate::event::TraceEvent;
use crate::replay::ReplayNode;
use crate::state::{Facet, Outcome, State, Termination};

impl Checker {
    pub(super) fn check_transition(
        &mut self,
        ev: &TraceEvent,
        number: u64,
        facet: Facet,
        from: State,
        to: State,
    ) {
        let seq = ev.seq;
        self.report.n_transitions += 1;
        let Some(n) = self.replay.node(number) else {
            return;
        };
        let cur = n.state(facet);
        if from != cur {
            let msg = format!(
                "{} {facet} is recorded as moving from {from}, but it is {cur}",
                self.name(number)
            );
            self.flag(seq, Some(number), Rule::TransitionFrom, msg);
        }
        if to <= cur {
            let msg = format!(
                "{} {facet} moves back from {cur} to {to}",
                self.name(number)
            );
            self.flag(seq, Some(number), Rule::FacetForward, msg);
            return;
        }
        let Some(n) = self.replay.node(number) else {
            return;
        };
        let mut found: Vec<(Rule, String)> = Vec::new();
        let alive = n.termination() == Termination::Alive;
        // A facet pushed straight to completed by termination is exempt from enablement conditions.
        let exempt = to == State::Completed && !alive;
        let mut n_checked = 0;
        if cur == State::Disabled && !exempt {
            n_checked = self.enablement(ev, n, facet, &mut found);
        }
        if to == State::Active {
            self.activation(n, facet, cur, &mut found);
        }
        if to == State::Completed {
            self.completion(n, facet, &mut found);
            if let (Facet::Handling, Some(info), true) = (facet, n.monitor(), alive) {
                // A monitor that failed (an activation's failure failing it, `with propagate`)
                // activates no more.
                let reached = info.max_activations.is_some_and(|m| info.activations >= m)
                    || info.max_triggers.is_some_and(|m| info.triggers >= m)
                    || n.outcome() == Outcome::Failed;
                if !reached {
                    found.push((
                        Rule::MonitorComplete,
                        format!(
                            "the monitor completed after {} activations and {} triggers, below its maxima ({:?}, {:?})",
                            info.activations, info.triggers, info.max_activations, info.max_triggers
                        ),
                    ));
                }
            }
        }
        self.report.n_enablement_checks += n_checked;
        for (rule, msg) in found {
            let msg = format!("{} {facet} {cur} -> {to}: {msg}", self.name(number));
            self.flag(seq, Some(number), rule, msg);
        }
    }

    // Returns how many constraints were evaluated.
    fn enablement(
        &self,
        ev: &TraceEvent,
        n: &ReplayNode,
        facet: Facet,
        found: &mut Vec<(Rule, String)>,
    ) -> u64 {
        let parent = n.parent().and_then(|p| self.replay.node(p));
        match facet {
            Facet::Handling => {
                let (own, what) = if n.expands() {
                    (
                        Facet::Expansion,
                        "a goal-like node's handling needs its expansion enabled",
                    )
                } else {
                    (
                        Facet::Execution,
                        "a command-like node's handling needs its execution enabled",
                    )
                };
                if n.state(own) < State::Enabled {
                    found.push((
                        Rule::HandlingEnable,
                        format!("{what}, but it is {}", n.state(own)),
                    ));
                }
            }
            Facet::Expansion => {
                if let Some(p) = parent {
                    if n.expands() && p.state(Facet::Expansion) < State::Enabled {
                        let msg =
                            format!("the parent's expansion is {}", p.state(Facet::Expansion));
                        found.push((Rule::ExpansionEnable, msg));
                    }
                }
            }
            Facet::Execution => {
                if let Some(p) = parent {
                    if p.state(Facet::Execution) < State::Enabled {
                        let msg =
                            format!("the parent's execution is {}", p.state(Facet::Execution));
                        found.push((Rule::ExecutionEnable, msg));
                    }
                }
            }
        }
        let mut n_checked = 0;
        for c in n.constraints() {
            n_checked += 1;
            if let Some(problem) = self.constraint_blocks(ev, n, facet, c) {
                found.push(problem);
            }
        }
        n_checked
    }

    // Whether constraint `c` of node `n` still forbade `facet` from becoming enabled at `ev`.
    fn activation(
        &self,
        n: &ReplayNode,
        facet: Facet,
        cur: State,
        found: &mut Vec<(Rule, String)>,
    ) {
        match facet {
            Facet::Handling => {
                if cur != State::Enabled {
                    found.push((
                        Rule::HandlingSkipsEnabled,
                        "handling must be enabled before it is active".into(),
                    ));
                }
                if n.termination() != Termination::Alive {
                    found.push((
                        Rule::ActiveWhileTerminating,
                        "a terminating node never starts its action".into(),
                    ));
                }
                if n.is_suspended() {
                    found.push((Rule::ActiveWhileSuspended, "the node is suspended".into()));
                }
                if let Some(why) = self.replay.paused() {
                    found.push((
                        Rule::ActiveWhilePaused,
                        format!("the run is paused ({why})"),
                    ));
                }
                if self.replay.held().any(|h| h == n.number()) {
                    found.push((
                        Rule::ActiveWhileHeld,
                        "the node is held for approval and was not approved".into(),
                    ));
                }
            }
            Facet::Expansion => {
                if !n.goal_started_below {
                    found.push((
                        Rule::ExpansionActive,
                        "no goal-like node of its subtree has started handling".into(),
                    ));
                }
            }
            Facet::Execution => {
                if !n.command_started_below {
                    found.push((
                        Rule::ExecutionActive,
                        "no command-like node of its subtree has started handling".into(),
                    ));
                }
            }
        }
    }

    fn completion(&self, n: &ReplayNode, facet: Facet, found: &mut Vec<(Rule, String)>) {
        match facet {
            Facet::Handling => {}
            Facet::Expansion => {
                if !n.goals_done() {
                    let msg = if n.expands() && n.state(Facet::Handling) != State::Completed {
                        format!("its own handling is {}", n.state(Facet::Handling))
                    } else {
                        format!(
                            "{} child subtree(s) still have goals not handled",
                            n.n_children_goals_open
                        )
                    };
                    found.push((Rule::ExpansionComplete, msg));
                }
            }
            Facet::Execution => {
                let mut open = Vec::new();
                for f in [Facet::Handling, Facet::Expansion] {
                    if n.state(f) != State::Completed {
                        open.push(format!("its {f} is {}", n.state(f)));
                    }
                }
                if n.n_children_exec_open > 0 {
                    open.push(format!(
                        "{} child(ren) have not completed execution",
                        n.n_children_exec_open
                    ));
                }
                if !open.is_empty() {
                    found.push((Rule::ExecutionComplete, open.join(", ")));
                }
            }
        }
    }

    pub(super) fn check_terminated(&mut self, seq: u64, node: u64) {
        let Some(n) = self.replay.node(node) else {
            return;
        };
        if n.termination() != Termination::Terminating {
            let msg = format!(
                "{} is terminated without terminating first ({:?})",
                self.name(node),
                n.termination()
            );
            self.flag(seq, Some(node), Rule::TerminationOrder, msg);
            return;
        }
        let mut open = Vec::new();
        for f in Facet::ALL {
            if n.state(f) != State::Completed {
                open.push(format!("its {f} is {}", n.state(f)));
            }
        }
        if n.n_children_unsettled > 0 {
            open.push(format!(
                "{} child(ren) are neither terminated nor execution-completed",
                n.n_children_unsettled
            ));
        }
        if !open.is_empty() {
            let msg = format!("{} is terminated but {}", self.name(node), open.join(", "));
            self.flag(seq, Some(node), Rule::TerminatedEarly, msg);
        }
    }

    pub(super) fn check_reclaimed(&mut self, seq: u64, node: u64) {
        let Some(n) = self.replay.node(node) else {
            return;
        };
        let mut open = Vec::new();
        if n.state(Facet::Execution) != State::Completed {
            open.push(format!("its execution is {}", n.state(Facet::Execution)));
        }
        if n.termination() == Termination::Terminating {
            open.push("it is terminating but not terminated".to_string());
        }
        if n.n_children_live > 0 {
            open.push(format!(
                "{} child(ren) are not reclaimed",
                n.n_children_live
            ));
        }
        if !open.is_empty() {
            let msg = format!("{} is reclaimed but {}", self.name(node), open.join(", "));
            self.flag(seq, Some(node), Rule::ReclaimEarly, msg);
        }
    }
}
