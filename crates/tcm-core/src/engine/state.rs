//! State variables and conditions over them (docs/semantics.md, "State and conditions").
//!
//! A *state variable* has a name, a [`Type`] and a value ([`Value`], possibly unknown). It is
//! declared once ([`Engine::declare_state`], a `state_declared` record) and set as an input
//! ([`Engine::set_state`], a `state_set` record, whether or not the value changes). A *condition*
//! is an [`Expr`] over variables, registered once and interned by its text
//! ([`Engine::condition`]).
//!
//! A trigger on a condition ([`When::Condition`](crate::When)) leaves a *watch* on every variable
//! the condition reads. When a set changes a variable's value, its watches are looked at in the
//! order they were armed, each condition evaluated once for that change, and each watch acts:
//!
//! | then | acts when | and |
//! |---|---|---|
//! | enable a facet | the condition is true | is done (latched) |
//! | terminate | the condition is true | is done |
//! | activate | the condition becomes true (it was not) | stays |
//! | activate on change of `v` | `v` changes | stays |
//! | invariant | the condition is false while the node runs | is done |
//! | pause | the condition becomes true: suspend; stops being true: unsuspend | stays |
//!
//! When the trigger is applied, a condition that already holds acts at once (an activation as soon
//! as the monitor is active, as `activate` alone does; a pause suspends at once). `skip if` leaves
//! no watch: it is read when the node's turn comes (`progress.rs`, `start`); an invariant is read
//! again when its node starts. Watches of nodes that are gone are dropped as they are met, and
//! swept when the table grows.

use super::node::Node;
use super::{Engine, EngineError};
use crate::arena::Keep;
use crate::constraint::{Event, Then};
use crate::failure::Failure;
use crate::ids::{CondId, NodeId, StateId};
use std::collections::BTreeMap;
use tcm_expr::{Expr, Type, Value};
use tcm_trace::{Facet, Point, State, TraceConstraint, TraceKind, TraceThen, TraceWhen};

/// The exception of a node whose `with invariant` condition became false while it ran.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("invariant `{condition}` no longer holds ({values})")]
pub struct InvariantFailed {
    /// The condition, as TDL writes it.
    pub condition: String,
    /// The values it read, `name = value` each, comma separated.
    pub values: String,
}

/// One state variable.
#[derive(Clone, Debug)]
pub(super) struct Var {
    name: String,
    ty: Type,
    value: Value,
    // Watches on it, in the order they were armed: (slot, generation).
    watches: Vec<(u32, u32)>,
}

/// One registered condition.
#[derive(Clone, Debug)]
pub(super) struct Cond {
    expr: Expr,
    reads: Vec<StateId>,
}

/// What a watch does (see the module's table).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Act {
    Enable(Facet),
    Terminate,
    Activate,
    Changed,
    Invariant,
    Pause,
}

#[derive(Clone, Debug)]
struct Watch {
    target: NodeId,
    cond: Option<CondId>,
    // For `on change of`: the variable.
    var: Option<StateId>,
    act: Act,
    // For an activation or a pause: whether the condition held when last looked at.
    held: bool,
    generation: u32,
}

/// The engine's state variables, conditions and watches.
#[derive(Clone, Debug, Default)]
pub(super) struct States {
    vars: Vec<Var>,
    ids: BTreeMap<String, StateId>,
    conds: Vec<Cond>,
    cond_ids: BTreeMap<String, CondId>,
    watches: Vec<Option<Watch>>,
    free: Vec<u32>,
    generation: u32,
    // Live watches when the table was last swept (`sweep` runs when it doubles).
    swept_at: usize,
}

impl States {
    fn value_of(&self, name: &str) -> Option<Value> {
        self.ids
            .get(name)
            .map(|id| self.vars[id.0 as usize].value.clone())
    }

    fn eval(&self, c: CondId) -> Value {
        // Conditions are type-checked when registered, so evaluation cannot fail; were it to, the
        // condition would not hold.
        self.conds[c.0 as usize]
            .expr
            .eval(&|n| self.value_of(n))
            .unwrap_or(Value::Unknown)
    }

    /// `name = value` for each variable `c` reads.
    fn values_text(&self, c: CondId) -> String {
        self.conds[c.0 as usize]
            .reads
            .iter()
            .map(|v| {
                let v = &self.vars[v.0 as usize];
                format!("{} = {}", v.name, v.value)
            })
            .collect::<Vec<_>>()
            .join(", ")
    }

    fn live_watches(&self) -> usize {
        self.watches.len() - self.free.len()
    }

    /// The variables a node is held by: those read by the conditions an enablement or a
    /// termination waits for, and by a pause that holds. For a model checker, which tells a run
    /// stuck for good from one that only its environment's bound holds.
    pub(super) fn waited_on(&self) -> Vec<StateId> {
        let mut out: Vec<StateId> = Vec::new();
        for w in self.watches.iter().flatten() {
            let holds = match w.act {
                Act::Enable(_) | Act::Terminate => true,
                Act::Pause => w.held,
                Act::Activate | Act::Changed | Act::Invariant => false,
            };
            if let (true, Some(c)) = (holds, w.cond) {
                for v in &self.conds[c.0 as usize].reads {
                    if !out.contains(v) {
                        out.push(*v);
                    }
                }
            }
        }
        out
    }

    /// Removes the enabling watches of the nodes `forced` says, for their release (a node
    /// terminated before it started waits for no condition); returns what they would enable.
    pub(super) fn take_enables(&mut self, forced: impl Fn(NodeId) -> bool) -> Vec<(NodeId, Then)> {
        let mut out = Vec::new();
        for slot in 0..self.watches.len() {
            let Some(w) = &self.watches[slot] else {
                continue;
            };
            if let Act::Enable(f) = w.act {
                if forced(w.target) {
                    out.push((w.target, Then::Enable(f)));
                    self.watches[slot] = None;
                    self.free.push(slot as u32);
                }
            }
        }
        out
    }

    /// What the watches wait for, for a stuck run's report: the node, the facet an enabling
    /// watch holds (`None` for an activation) and the text (`` `battery_ok && !fault` (battery_ok
    /// = false, fault = false) ``).
    pub(super) fn waiting(&self) -> Vec<(NodeId, Option<Facet>, String)> {
        let mut out = Vec::new();
        for w in self.watches.iter().flatten() {
            let cond = w.cond.map(|c| {
                format!(
                    "`{}` ({})",
                    self.conds[c.0 as usize].expr,
                    self.values_text(c)
                )
            });
            match (w.act, cond) {
                (Act::Enable(f), Some(c)) => {
                    out.push((w.target, Some(f), format!("condition {c}")))
                }
                (Act::Activate, Some(c)) => out.push((
                    w.target,
                    None,
                    format!("an activation when {c} becomes true"),
                )),
                (Act::Changed, _) => {
                    let var = w
                        .var
                        .and_then(|v| self.vars.get(v.0 as usize))
                        .map_or("a state variable", |v| v.name.as_str());
                    out.push((
                        w.target,
                        None,
                        format!("an activation when `{var}` changes"),
                    ));
                }
                _ => {}
            }
        }
        out
    }

    /// Feeds `h` the variables by name (their type, value and live watches in order) for the
    /// model checker's canonical state (`canon.rs`); `node` hashes a node by its canonical
    /// number. Conditions are named by their text.
    pub(super) fn hash_canonical<H: std::hash::Hasher>(
        &self,
        h: &mut H,
        node: &mut dyn FnMut(NodeId, &mut H),
    ) {
        use std::hash::Hash;
        self.ids.len().hash(h);
        for id in self.ids.values() {
            let var = &self.vars[id.0 as usize];
            var.name.hash(h);
            var.ty.hash(h);
            // Values have no `Hash` (floats); their text is exact.
            var.value.to_string().hash(h);
            for &(slot, generation) in &var.watches {
                let Some(w) = self.watches[slot as usize].as_ref() else {
                    continue;
                };
                if w.generation != generation {
                    continue;
                }
                node(w.target, h);
                w.cond
                    .map(|c| self.conds[c.0 as usize].expr.to_string())
                    .hash(h);
                w.act.hash(h);
                w.held.hash(h);
            }
        }
    }
}

impl<A, F: Clone, S: Keep<Node<A, F>>> Engine<A, F, S> {
    /// Declares a state variable with its type and initial value (a `state_declared` record). A
    /// variable already declared with the same type keeps its current value (a program declares
    /// its variables where it first uses them, after the shell may have set them); with another
    /// type it is an error.
    pub fn declare_state(
        &mut self,
        name: &str,
        ty: Type,
        initial: Value,
    ) -> Result<StateId, EngineError> {
        if let Some(&id) = self.states.ids.get(name) {
            let was = self.states.vars[id.0 as usize].ty;
            if was != ty {
                return Err(EngineError::StateRedeclared {
                    var: name.to_string(),
                    was,
                    now: ty,
                });
            }
            return Ok(id);
        }
        let value = initial
            .coerce(ty)
            .map_err(|e| EngineError::StateType(name.to_string(), e))?;
        let id = StateId(self.states.vars.len() as u32);
        emit!(
            self,
            TraceKind::StateDeclared {
                var: name.to_string(),
                ty,
                value: value.clone(),
            }
        );
        self.states.vars.push(Var {
            name: name.to_string(),
            ty,
            value,
            watches: Vec::new(),
        });
        self.states.ids.insert(name.to_string(), id);
        Ok(id)
    }

    /// The variable declared under `name`.
    pub fn state_id(&self, name: &str) -> Option<StateId> {
        self.states.ids.get(name).copied()
    }

    /// A variable's name, type and current value.
    pub fn state(&self, id: StateId) -> Option<(&str, Type, &Value)> {
        self.states
            .vars
            .get(id.0 as usize)
            .map(|v| (v.name.as_str(), v.ty, &v.value))
    }

    /// Input: a state variable is set (a `state_set` record). An integer given to a `float`
    /// variable becomes a float; another type is an error. If the value differs from the one it
    /// had, the conditions that read it are evaluated and their triggers act (the module's table).
    pub fn set_state(
        &mut self,
        now: crate::Time,
        id: StateId,
        value: Value,
    ) -> Result<(), EngineError> {
        self.advance(now);
        let Some(var) = self.states.vars.get(id.0 as usize) else {
            return Err(EngineError::UnknownState(format!("#{}", id.0)));
        };
        let value = value
            .coerce(var.ty)
            .map_err(|e| EngineError::StateType(var.name.clone(), e))?;
        let changed = var.value != value;
        let name = var.name.clone();
        self.record(|_| super::InputRecord::State {
            name,
            value: value.clone(),
        });
        let Some(var) = self.states.vars.get(id.0 as usize) else {
            return Err(EngineError::UnknownState(format!("#{}", id.0)));
        };
        emit!(
            self,
            TraceKind::StateSet {
                var: var.name.clone(),
                value: value.clone(),
            }
        );
        if changed {
            self.states.vars[id.0 as usize].value = value;
            self.state_changed(id);
        }
        self.settle();
        Ok(())
    }

    /// Registers a condition (interned by its text): every variable it reads must be declared,
    /// and it must be a `bool`.
    pub fn condition(&mut self, expr: &Expr) -> Result<CondId, EngineError> {
        let text = expr.to_string();
        if let Some(&id) = self.states.cond_ids.get(&text) {
            return Ok(id);
        }
        let states = &self.states;
        let ty = expr
            .type_of(&|n| states.ids.get(n).map(|id| states.vars[id.0 as usize].ty))
            .map_err(|error| EngineError::BadCondition {
                condition: text.clone(),
                error,
            })?;
        if ty != Type::Bool {
            return Err(EngineError::NotACondition {
                condition: text,
                ty,
            });
        }
        let reads = expr
            .vars()
            .into_iter()
            .filter_map(|n| self.states.ids.get(n).copied())
            .collect();
        let id = CondId(self.states.conds.len() as u32);
        self.states.conds.push(Cond {
            expr: expr.clone(),
            reads,
        });
        self.states.cond_ids.insert(text, id);
        Ok(id)
    }

    /// The variables whose change could release a node: read by a condition an enablement or a
    /// termination waits for, or by a pause that holds (for a model checker: a run that waits
    /// only on these is held by its environment, not stuck by itself).
    pub fn states_waited_on(&self) -> Vec<StateId> {
        self.states.waited_on()
    }

    /// The condition's value now.
    pub fn condition_value(&self, c: CondId) -> Option<Value> {
        (c.0 < self.states.conds.len() as u32).then(|| self.states.eval(c))
    }

    /// The condition's expression.
    pub fn condition_expr(&self, c: CondId) -> Option<&Expr> {
        self.states.conds.get(c.0 as usize).map(|c| &c.expr)
    }

    /// Step 3 and 4 of arming (`arm.rs`) for a trigger on a condition.
    pub(super) fn arm_condition(&mut self, node: NodeId, c: CondId, then: Then) {
        let Some(cond) = self.states.conds.get(c.0 as usize) else {
            return self.void(node, || "unknown condition".into());
        };
        let expr = cond.expr.clone();
        self.constrained(node, || {
            TraceConstraint::trigger(TraceWhen::Condition(expr), then.traced())
        });
        let value = self.states.eval(c);
        let holds = value.is_true();
        match then {
            Then::Enable(_) | Then::Terminate => {
                if holds {
                    self.fire_trigger(node, then, false);
                } else {
                    self.block(node, then);
                    let act = match then {
                        Then::Enable(f) => Act::Enable(f),
                        _ => Act::Terminate,
                    };
                    self.add_watch(node, Some(c), act, false);
                }
            }
            // `Then::ActivateWith` is void on a condition (`arm`, step 1).
            Then::Activate | Then::ActivateWith(_) => {
                self.add_watch(node, Some(c), Act::Activate, holds);
                if holds {
                    // As `activate` alone: once the monitor's handling is active.
                    let event = Event::on(node, Facet::Handling, Point::Active);
                    self.arm_event(node, node, event, then, None);
                }
            }
            Then::Skip => {
                self.node_mut(node).cold_mut().skip_if.push(c);
                // A goal-like node would start (expand) as soon as its expansion is enabled,
                // ahead of its execution's turn: one that may be skipped waits for that turn, so
                // the condition is read when the plan reaches it (`delay expansion`, traced).
                let n = self.node(node);
                if n.kind.expands()
                    && !n.delay_expansion
                    && n.state(Facet::Expansion) == State::Disabled
                {
                    let parent = n.parent.unwrap_or(self.root);
                    self.apply(node, parent, None, crate::Constraint::DelayExpansion);
                }
            }
            Then::Invariant => {
                self.node_mut(node).cold_mut().invariants.push(c);
                self.add_watch(node, Some(c), Act::Invariant, false);
                if value == Value::Bool(false) && self.runs(node) {
                    self.invariant_failed(node, c);
                }
            }
            Then::Pause => {
                self.add_watch(node, Some(c), Act::Pause, holds);
                if holds {
                    self.suspend_subtree(node, true);
                }
            }
        }
    }

    /// Arming `activate on change of v`.
    pub(super) fn arm_changed(&mut self, node: NodeId, v: StateId, then: Then) {
        let Some(var) = self.states.vars.get(v.0 as usize) else {
            return self.void(node, || "unknown state variable".into());
        };
        // (`Then::ActivateWith` was made void before: `arm`, step 1.)
        if then != Then::Activate {
            return self.void(node, || {
                "`on change of` applies to `activate` (monitors) only".into()
            });
        }
        let name = var.name.clone();
        self.constrained(node, || {
            TraceConstraint::trigger(TraceWhen::Changed(name), TraceThen::Activate)
        });
        self.add_watch_on(node, None, Act::Changed, false, &[v]);
    }

    fn add_watch(&mut self, target: NodeId, cond: Option<CondId>, act: Act, held: bool) {
        let reads = cond.map_or_else(Vec::new, |c| self.states.conds[c.0 as usize].reads.clone());
        self.add_watch_on(target, cond, act, held, &reads);
    }

    fn add_watch_on(
        &mut self,
        target: NodeId,
        cond: Option<CondId>,
        act: Act,
        held: bool,
        vars: &[StateId],
    ) {
        if vars.is_empty() {
            // A condition over no variable never changes: nothing to watch.
            return;
        }
        if self.states.live_watches() >= 64
            && self.states.live_watches() >= 2 * self.states.swept_at
        {
            self.sweep_watches();
        }
        let st = &mut self.states;
        st.generation = st.generation.wrapping_add(1);
        let watch = Watch {
            target,
            cond,
            var: (cond.is_none()).then(|| vars[0]),
            act,
            held,
            generation: st.generation,
        };
        let slot = match st.free.pop() {
            Some(slot) => {
                st.watches[slot as usize] = Some(watch);
                slot
            }
            None => {
                st.watches.push(Some(watch));
                (st.watches.len() - 1) as u32
            }
        };
        for v in vars {
            st.vars[v.0 as usize].watches.push((slot, st.generation));
        }
    }

    /// Drops the watches of nodes that are gone (their entries in the variables' lists go when
    /// next met, by their generation).
    fn sweep_watches(&mut self) {
        for slot in 0..self.states.watches.len() {
            let gone = self.states.watches[slot]
                .as_ref()
                .is_some_and(|w| self.nodes.get(w.target).is_none());
            if gone {
                self.states.watches[slot] = None;
                self.states.free.push(slot as u32);
            }
        }
        for var in &mut self.states.vars {
            let watches = &self.states.watches;
            var.watches.retain(|&(slot, g)| {
                watches[slot as usize]
                    .as_ref()
                    .is_some_and(|w| w.generation == g)
            });
        }
        self.states.swept_at = self.states.live_watches();
    }

    /// `var` changed value: its watches act, in the order they were armed.
    fn state_changed(&mut self, var: StateId) {
        let list = std::mem::take(&mut self.states.vars[var.0 as usize].watches);
        let mut keep = Vec::with_capacity(list.len());
        // Each condition is evaluated once per change.
        let mut values: BTreeMap<CondId, Value> = BTreeMap::new();
        for (slot, generation) in list {
            let Some(w) = self.states.watches[slot as usize].clone() else {
                continue;
            };
            if w.generation != generation {
                continue;
            }
            if self.nodes.get(w.target).is_none() {
                self.drop_watch(slot);
                continue;
            }
            let value = match w.cond {
                Some(c) => values
                    .entry(c)
                    .or_insert_with(|| self.states.eval(c))
                    .clone(),
                None => Value::Unknown,
            };
            let holds = value.is_true();
            let done = match w.act {
                Act::Enable(f) => {
                    if holds {
                        self.fire_trigger(w.target, Then::Enable(f), true);
                    }
                    holds
                }
                Act::Terminate => {
                    if holds {
                        self.fire_trigger(w.target, Then::Terminate, true);
                    }
                    holds
                }
                Act::Activate => {
                    if holds && !w.held {
                        let _ = self.activation_due(w.target);
                    }
                    self.set_held(slot, holds);
                    false
                }
                Act::Changed => {
                    let _ = self.activation_due(w.target);
                    false
                }
                Act::Invariant => {
                    let n = self.node(w.target);
                    let over = n.state(Facet::Execution) == State::Completed || !n.alive();
                    if over {
                        true
                    } else if value == Value::Bool(false) && self.runs(w.target) {
                        if let Some(c) = w.cond {
                            self.invariant_failed(w.target, c);
                        }
                        true
                    } else {
                        false
                    }
                }
                Act::Pause => {
                    if holds != w.held {
                        self.suspend_subtree(w.target, holds);
                        self.set_held(slot, holds);
                    }
                    false
                }
            };
            if done {
                self.drop_watch(slot);
            } else {
                keep.push((slot, generation));
            }
        }
        // Watches armed while these acted (none are: acting only queues work) go after.
        let v = &mut self.states.vars[var.0 as usize];
        keep.append(&mut v.watches);
        v.watches = keep;
    }

    fn set_held(&mut self, slot: u32, held: bool) {
        if let Some(w) = self.states.watches[slot as usize].as_mut() {
            w.held = held;
        }
    }

    fn drop_watch(&mut self, slot: u32) {
        self.states.watches[slot as usize] = None;
        self.states.free.push(slot);
    }

    /// Whether `node` runs, for its invariants: alive, its handling active or completed, its
    /// execution not completed, not failed yet.
    fn runs(&self, node: NodeId) -> bool {
        let n = self.node(node);
        n.alive()
            && n.state(Facet::Handling) >= State::Active
            && n.state(Facet::Execution) != State::Completed
            && n.failure().is_none()
    }

    /// The node's turn came: whether one of its `skip if` conditions holds.
    pub(super) fn skips(&self, node: NodeId) -> bool {
        let n = self.node(node);
        n.skip_conditions()
            .iter()
            .any(|&c| self.states.eval(c).is_true())
    }

    /// The node started: an invariant already false fails it at once.
    pub(super) fn check_invariants(&mut self, node: NodeId) {
        let conds = self.node(node).invariant_conditions().to_vec();
        for c in conds {
            if self.states.eval(c) == Value::Bool(false) && self.runs(node) {
                self.invariant_failed(node, c);
                return;
            }
        }
    }

    fn invariant_failed(&mut self, node: NodeId, c: CondId) {
        let failure = Failure::from(InvariantFailed {
            condition: self.states.conds[c.0 as usize].expr.to_string(),
            values: self.states.values_text(c),
        });
        self.fail_from_outside(node, failure, None);
    }

    /// Suspends (or unsuspends) `id`'s subtree, for a pause.
    fn suspend_subtree(&mut self, id: NodeId, on: bool) {
        self.suspend_now(id, on);
    }
}
