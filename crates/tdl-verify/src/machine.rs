//! The abstract machine: one state of a TDL program's run, and its transitions.
//!
//! A state is the real engine (`tcm_core::Engine`, cloned per state) plus what the generated code
//! and the shell would hold: each body suspended in a wait or at a choice (a continuation: its
//! position in the compiled body and its locals), the commands running, the external events
//! raised so far and the bounds used. Transitions are the choices of docs/verification.md:
//!
//! - a body at a choice (an `if` on a condition the checker does not know, a loop over an unknown
//!   collection, a `match`, a `return` or `break` a Rust statement may take) picks one way;
//! - a running command ends: succeeds, fails with each exception it may raise, or is left running
//!   until it is terminated;
//! - an external event the program names is raised;
//! - time advances to the engine's next deadline, as long as no running command would outlast the
//!   duration bound.
//!
//! After each transition the machine *settles* as the runtime does: it carries out the engine's
//! effects (start an action, run a handler or a monitor activation, cancel, notify a waiting body)
//! and runs every body that can go on, each until it waits, ends or reaches a choice. A body runs
//! without interruption from its start or a wait to its next wait or end (as TCM ran one action at
//! a time), and bodies released together run in the order the engine started them.

use std::collections::VecDeque;
use std::hash::{Hash, Hasher};
use std::sync::Arc;
use std::time::Duration;

use tcm_core::{
    Canonical, Constraint, Effect, Engine, Event, Facet, Failure, HandlerSpec, MonitorSpec, NodeId,
    NodeKind, NodeRef, OnTerminate, Point, Spawn, Then, Time, WatchOutcome, WatchToken, When,
};
use tdl_syntax::ast::TaskKind;

use crate::Options;
use crate::ir::{
    Body, CIr, Callee, EventIr, GroupId, IndexIr, Iter, LoopId, Op, ResOp, StmtOp, TagKind, TagRef,
    TaskId, TimeIr, UsesIr, Wait, WhenIr,
};
use crate::model::{CommandModel, Ending};
use crate::program::{Program, TaskDef, duration};
use crate::property::{Props, Watch};
use crate::value::{Env, Value};
use tcm_trace::TraceEvent;

/// What the engine is asked to run: a task with its arguments.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub(crate) struct Act {
    pub(crate) callee: Callee,
    pub(crate) args: Arc<[Value]>,
    /// Nested beyond the recursion bound: run as a command of the checker's choice.
    pub(crate) abstracted: bool,
    /// Placed on an agent (`on`): a command of the checker's choice that may lose its agent.
    pub(crate) remote: bool,
}

/// What the engine runs again and again: monitor activations, handlers, retries.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub(crate) enum Fac {
    Activation(TaskId, Arc<[Value]>),
    Handler(TaskId, Arc<[Value]>),
    Retry(Act),
}

pub(crate) type Eng = Engine<Act, Fac, tcm_core::Shared>;

/// A transition.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum Action {
    /// The body at a choice takes way `i`.
    Pick(u8),
    /// A running command ends: `outcome` 0 succeeds, `k` fails with its `k-1`th exception.
    End { node: NodeId, outcome: u16 },
    /// A running command is left running until it is terminated.
    Hang(NodeId),
    /// A modelled command's model decides its ending `i`.
    Decide { node: NodeId, i: u16 },
    /// An external event is raised.
    Raise(u16),
    /// Time advances to the next deadline.
    Tick,
}

/// A built-in property broken by the last transition.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub(crate) enum Fault {
    /// A failure no handler took.
    Unhandled { exception: String, path: String },
}

#[derive(Clone, Debug, PartialEq, Eq, Hash)]
enum TagVal {
    Unset,
    One(NodeId),
    Map(Vec<(Vec<i64>, NodeId)>),
    Members(Vec<NodeId>),
}

#[derive(Clone, Debug, PartialEq, Eq, Hash)]
struct LoopState {
    count: u32,
    /// How many times it runs, when known.
    n: Option<u32>,
    start: i64,
}

#[derive(Clone, Debug)]
struct Frame {
    gid: GroupId,
    members: Vec<NodeId>,
    /// `previous` for this group's constraints while a nested group runs.
    snapshot: Option<Option<Vec<NodeId>>>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum WaitFor {
    Plain,
    Value,
    Outcome,
}

#[derive(Clone, Debug)]
struct Waiting {
    token: u64,
    node: NodeId,
    kind: WaitFor,
    /// Nodes still to wait for after this one (`X wait;` on a group).
    rest: Vec<NodeId>,
}

/// A body that has started and not ended.
#[derive(Clone, Debug)]
struct Cont {
    node: NodeId,
    task: TaskId,
    pc: u32,
    env: Env,
    loops: Vec<LoopState>,
    tags: Vec<TagVal>,
    prev: Option<Vec<NodeId>>,
    frames: Vec<Frame>,
    wait: Option<Waiting>,
    resume: Option<WatchOutcome>,
    /// At a choice with this many ways.
    choice: Option<u8>,
}

/// A running command.
#[derive(Clone, Debug)]
struct Cmd {
    node: NodeId,
    callee: Callee,
    /// A task nested beyond the recursion bound, run as a command.
    abstracted: bool,
    /// Placed on an agent: it may also fail with `AgentLost`.
    remote: bool,
    args: Arc<[Value]>,
    start: Time,
    /// Deadlines it outlasted.
    ticks: u8,
    hung: bool,
    /// A modelled command: its endings, then the one chosen with its time.
    model: Option<Modelled>,
}

#[derive(Clone, Debug, PartialEq)]
enum Modelled {
    Undecided(Vec<Ending>),
    Decided(Time, Ending),
}

/// A command waiting for the seeded simulation to draw its ending ([`State::undrawn`]).
pub(crate) struct Undrawn<'p> {
    pub(crate) node: NodeId,
    /// The exceptions it may fail with.
    pub(crate) raises: Vec<&'p str>,
    /// It may be left running until it is terminated (something may terminate it, and the bound
    /// of such commands is not reached).
    pub(crate) may_hang: bool,
    /// The endings its model gives, if it has one.
    pub(crate) endings: Option<Vec<Ending>>,
}

/// A state of the run.
#[derive(Clone)]
pub(crate) struct State {
    pub(crate) engine: Eng,
    root: Option<NodeId>,
    conts: Vec<Cont>,
    runq: VecDeque<NodeId>,
    choice: Option<NodeId>,
    cmds: Vec<Cmd>,
    stops: VecDeque<NodeId>,
    next_token: u64,
    raised: Vec<u8>,
    hangs: u16,
    /// Nodes a termination constraint or statement names.
    terminable: Vec<NodeId>,
    /// The path stops here: a bound was reached (not a violation).
    pub(crate) cut: Option<String>,
    /// A built-in property broken by the transition that led here.
    pub(crate) fault: Option<Fault>,
    /// A failure of the checker itself on this path (an engine call refused where the generated
    /// code could not have been refused).
    pub(crate) error: Option<String>,
    /// What the user properties followed so far (when there are some; tracing is on then).
    pub(crate) watch: Option<Watch>,
    /// The user property the last transition broke.
    pub(crate) broken: Option<usize>,
    /// The trace records of the last transition, when tracing.
    pub(crate) records: Vec<TraceEvent>,
    /// The root task's execution completed.
    done: bool,
}

/// What a state knows of the program and the options.
pub(crate) struct Ctx<'a> {
    pub(crate) prog: &'a Program,
    pub(crate) opts: &'a Options,
    pub(crate) model: Option<&'a dyn CommandModel>,
    pub(crate) props: &'a Props,
    /// A seeded simulation (`sim.rs`) draws the commands' endings: its traces say so.
    pub(crate) sim: bool,
}

fn failure(prog: &Program, exception: &str, message: impl Into<String>) -> Failure {
    let (name, ancestry): (tcm_core::Name, Vec<tcm_core::Name>) =
        match prog.exceptions.get_key_value(exception) {
            Some((_, a)) => {
                let name = prog
                    .raisable
                    .iter()
                    .find(|r| **r == exception)
                    .map_or_else(|| exception.to_owned().into(), |r| (*r).into());
                (name, a.iter().map(|s| (*s).into()).collect())
            }
            None => match prog.raisable.iter().find(|r| **r == exception) {
                Some(r) => ((*r).into(), Vec::new()),
                None => (exception.to_owned().into(), Vec::new()),
            },
        };
    Failure::new(name, message).with_ancestry(ancestry)
}

/// The failure of a body whose engine call was refused (`?` on a `tdl::Error`).
fn error_failure(e: &tcm_core::EngineError) -> Failure {
    Failure::new("Error", e.to_string())
}

fn time_plus(t: Time, d: Duration) -> Time {
    t.saturating_add(d)
}

enum Nodes {
    Ref(NodeRef),
    Entity(Option<Vec<NodeId>>),
    None,
}

/// A constraint lowered for one spawn: applied per node, or an entity trigger armed after it.
enum Lowered {
    Each(Vec<Constraint>),
    Entity {
        members: Option<Vec<NodeId>>,
        facet: Facet,
        point: Point,
        delay: Option<Duration>,
        then: Then,
    },
}

impl State {
    /// The state before anything happened: the root task spawned and settled.
    pub(crate) fn init(cx: &Ctx<'_>, task: &str, tracing: bool) -> State {
        let mut engine: Eng = Engine::new(1);
        engine.set_tracing(tracing);
        engine.hold_by_default(true);
        let prog = cx.prog;
        // The declared resources (the generated code declares each on its first use; declared
        // first here, in order, they behave the same).
        let mut error = None;
        for r in &prog.resources {
            if let Err(e) = engine.declare_resource(r.name, r.capacity, r.pending) {
                error = Some(format!("cannot declare resource `{}`: {e}", r.name));
            }
        }
        // Handlers declared `for T` are attached to T on the run.
        for (i, t) in prog.tasks.iter().enumerate() {
            if let (Some(target), Some(exc)) = (&t.for_task, &t.handles) {
                let max = t
                    .max_activations
                    .as_ref()
                    .and_then(|e| count(&e.eval(&Env::default())));
                engine.handler_for(
                    target.clone(),
                    HandlerSpec {
                        name: t.name.into(),
                        exception: (*exc).into(),
                        max_activations: max,
                        body: Fac::Handler(i as TaskId, Arc::from(Vec::new())),
                    },
                );
            }
        }
        let mut s = State {
            engine,
            root: None,
            conts: Vec::new(),
            runq: VecDeque::new(),
            choice: None,
            cmds: Vec::new(),
            stops: VecDeque::new(),
            next_token: 0,
            raised: vec![0; prog.external_events.len()],
            hangs: 0,
            terminable: Vec::new(),
            cut: None,
            fault: None,
            error,
            watch: (!cx.props.is_empty()).then(Watch::default),
            broken: None,
            records: Vec::new(),
            done: false,
        };
        let callee = match prog.by_name.get(task) {
            Some(id) => Callee::Task(*id),
            None => Callee::Extern(0),
        };
        let n_params = match callee {
            Callee::Task(id) => prog.task(id).params.len(),
            Callee::Extern(_) => 0,
        };
        let args: Arc<[Value]> = vec![Value::Unknown; n_params].into();
        let root = s.engine.root();
        let act = Act {
            callee,
            args,
            abstracted: false,
            remote: false,
        };
        let spec = s.task_spec(cx, root, act, None);
        let now = s.engine.now();
        match s.engine.spawn(now, spec) {
            Ok(id) => s.root = Some(id),
            Err(e) => s.error = Some(format!("cannot spawn the root task: {e}")),
        }
        s.settle(cx);
        s.observe(cx);
        s.done = s.compute_finished();
        s
    }

    /// Takes the transition's trace records (when tracing) and follows the user properties.
    fn observe(&mut self, cx: &Ctx<'_>) {
        self.records.clear();
        while let Some(r) = self.engine.poll_trace() {
            self.records.push(r);
        }
        if let Some(w) = self.watch.as_mut() {
            if self.broken.is_none() {
                self.broken = cx.props.follow(w, &self.records);
            }
        }
    }

    /// Whether no command runs, but those left running until terminated: a loop through such a
    /// state is one the program takes by itself (docs/verification.md, "Runs that never end").
    pub(crate) fn quiet(&self) -> bool {
        self.cmds.iter().all(|c| c.hung)
    }

    /// Whether the root task's execution completed (as of the last transition).
    pub(crate) fn finished(&self) -> bool {
        self.done
    }

    fn compute_finished(&self) -> bool {
        match self.root {
            Some(r) => self
                .engine
                .info(r)
                .is_none_or(|i| i.states[Facet::Execution.index()] == tcm_core::State::Completed),
            None => true,
        }
    }

    /// Whether nothing more can happen on this path for a reason that is not the program's: a
    /// bound, a fault already found, or an error of the checker.
    pub(crate) fn stopped(&self) -> bool {
        self.cut.is_some() || self.fault.is_some() || self.error.is_some() || self.broken.is_some()
    }

    /// The transitions from here, in a fixed order.
    pub(crate) fn actions(&mut self, cx: &Ctx<'_>, out: &mut Vec<Action>) {
        out.clear();
        if self.stopped() || self.finished() {
            return;
        }
        if let Some(node) = self.choice {
            if let Some(c) = self.conts.iter().find(|c| c.node == node) {
                for i in 0..c.choice.unwrap_or(0) {
                    out.push(Action::Pick(i));
                }
            }
            return;
        }
        let now = self.engine.now();
        let opts = cx.opts;
        for cmd in &self.cmds {
            if cmd.hung {
                continue;
            }
            match &cmd.model {
                Some(Modelled::Undecided(endings)) => {
                    for i in 0..endings.len() {
                        out.push(Action::Decide {
                            node: cmd.node,
                            i: i as u16,
                        });
                    }
                }
                Some(Modelled::Decided(at, _)) => {
                    if *at <= now {
                        out.push(Action::End {
                            node: cmd.node,
                            outcome: 0,
                        });
                    }
                }
                None => {
                    let n = 1 + self
                        .raises(cx, cmd.callee, cmd.abstracted, cmd.remote)
                        .len();
                    for k in 0..n {
                        out.push(Action::End {
                            node: cmd.node,
                            outcome: k as u16,
                        });
                    }
                    if u32::from(self.hangs) < opts.hangs && self.is_terminable(cmd.node) {
                        out.push(Action::Hang(cmd.node));
                    }
                }
            }
        }
        for (i, n) in self.raised.iter().enumerate() {
            if u32::from(*n) < opts.events {
                out.push(Action::Raise(i as u16));
            }
        }
        if let Some(t) = self.next_tick() {
            // Time may pass only as long as no running command outlasts the duration bound, and
            // no modelled command's end is skipped.
            let ok = self.cmds.iter().all(|c| match &c.model {
                _ if c.hung => true,
                None => u32::from(c.ticks) < opts.ticks,
                Some(Modelled::Decided(at, _)) => *at >= t,
                Some(Modelled::Undecided(_)) => false,
            });
            if ok {
                out.push(Action::Tick);
            }
        }
    }

    /// The next time something is due: a timer of the engine or a modelled command's end.
    pub(crate) fn next_tick(&mut self) -> Option<Time> {
        let mut e = self.engine.poll_timeout();
        for c in &self.cmds {
            if let Some(Modelled::Decided(at, _)) = &c.model {
                if *at > self.engine.now() {
                    e = Some(e.map_or(*at, |t: Time| t.min(*at)));
                }
            }
        }
        e
    }

    /// The exceptions a command may raise: a TDL command's `fail`s, else every exception the
    /// program declares or handles (and, with the option, one nobody declares).
    pub(crate) fn raises<'p>(
        &self,
        cx: &'p Ctx<'_>,
        callee: Callee,
        abstracted: bool,
        remote: bool,
    ) -> Vec<&'p str> {
        let mut out: Vec<&str> = match (callee, abstracted || remote) {
            (Callee::Task(id), false) => {
                cx.prog.task(id).raises.iter().map(String::as_str).collect()
            }
            _ => cx.prog.raisable.to_vec(),
        };
        if cx.opts.unknown_exception && (abstracted || matches!(callee, Callee::Extern(_))) {
            out.push(crate::UNKNOWN_EXCEPTION);
        }
        // Placed on an agent: the agent may be lost while it runs the task.
        if remote {
            out.push(crate::AGENT_LOST);
        }
        out
    }

    /// The commands started and not yet given their ending by the seeded simulation (`sim.rs`),
    /// in the order they started.
    pub(crate) fn undrawn<'p>(&self, cx: &'p Ctx<'_>) -> Vec<Undrawn<'p>> {
        let mut out = Vec::new();
        for c in &self.cmds {
            if c.hung {
                continue;
            }
            let endings = match &c.model {
                Some(Modelled::Decided(..)) => continue,
                Some(Modelled::Undecided(e)) => Some(e.clone()),
                None => None,
            };
            out.push(Undrawn {
                node: c.node,
                raises: self.raises(cx, c.callee, c.abstracted, c.remote),
                may_hang: u32::from(self.hangs) < cx.opts.hangs && self.is_terminable(c.node),
                endings,
            });
        }
        out
    }

    /// Gives a command its ending, as the seeded simulation drew it: it ends (succeeds or fails)
    /// once its duration has passed since it started, or runs until it is terminated.
    pub(crate) fn draw(&mut self, node: NodeId, ending: Ending) {
        let Some(c) = self.cmds.iter_mut().find(|c| c.node == node) else {
            return;
        };
        match ending {
            Ending::Never => {
                c.hung = true;
                c.model = None;
                self.hangs = self.hangs.saturating_add(1);
            }
            e => c.model = Some(Modelled::Decided(time_plus(c.start, e.after()), e)),
        }
    }

    fn is_terminable(&self, node: NodeId) -> bool {
        let mut cur = Some(node);
        while let Some(n) = cur {
            if self.terminable.contains(&n) {
                return true;
            }
            cur = self.engine.parent(n);
        }
        false
    }

    /// The state after `action`.
    pub(crate) fn step(&self, cx: &Ctx<'_>, action: &Action) -> State {
        self.clone().step_owned(cx, action)
    }

    /// [`State::step`], taking the state instead of copying it.
    pub(crate) fn step_owned(self, cx: &Ctx<'_>, action: &Action) -> State {
        let mut s = self;
        let before = s.engine.unhandled().len();
        let now = s.engine.now();
        match action {
            Action::Pick(i) => {
                if let Some(node) = s.choice.take() {
                    s.pick(cx, node, *i);
                }
            }
            Action::End { node, outcome } => {
                if let Some(pos) = s.cmds.iter().position(|c| c.node == *node) {
                    let cmd = s.cmds.remove(pos);
                    let result = match &cmd.model {
                        Some(Modelled::Decided(_, Ending::Succeeds(_))) => Ok(()),
                        Some(Modelled::Decided(_, Ending::Fails(e, _))) => Err(failure(
                            cx.prog,
                            e,
                            if cx.sim {
                                "drawn by tdl sim"
                            } else {
                                "chosen by the command's model"
                            },
                        )),
                        _ if *outcome == 0 => Ok(()),
                        _ => {
                            let raises = s.raises(cx, cmd.callee, cmd.abstracted, cmd.remote);
                            let e = raises
                                .get(*outcome as usize - 1)
                                .copied()
                                .unwrap_or("Error");
                            Err(failure(cx.prog, e, "chosen by tdl verify"))
                        }
                    };
                    if let Err(e) = s.engine.handle_action_finished(now, *node, result) {
                        s.error = Some(format!("the end of a command was refused: {e}"));
                    }
                }
            }
            Action::Hang(node) => {
                if let Some(c) = s.cmds.iter_mut().find(|c| c.node == *node) {
                    c.hung = true;
                    s.hangs += 1;
                }
            }
            Action::Decide { node, i } => {
                if let Some(c) = s.cmds.iter_mut().find(|c| c.node == *node) {
                    if let Some(Modelled::Undecided(endings)) = &c.model {
                        match endings.get(*i as usize).cloned() {
                            Some(Ending::Never) | None => {
                                c.hung = true;
                                c.model = None;
                            }
                            Some(e) => {
                                let at = time_plus(c.start, e.after());
                                c.model = Some(Modelled::Decided(at, e));
                            }
                        }
                    }
                }
            }
            Action::Raise(i) => {
                if let Some(n) = s.raised.get_mut(*i as usize) {
                    *n += 1;
                }
                if let Some(name) = cx.prog.external_events.get(*i as usize) {
                    let id = s.engine.external(name);
                    s.engine.handle_external(now, id);
                }
            }
            Action::Tick => {
                if let Some(t) = s.next_tick() {
                    for c in &mut s.cmds {
                        if !c.hung && c.model.is_none() {
                            c.ticks = c.ticks.saturating_add(1);
                        }
                    }
                    s.engine.handle_timeout(t);
                }
            }
        }
        s.settle(cx);
        s.observe(cx);
        s.done = s.compute_finished();
        let unhandled = s.engine.unhandled();
        if unhandled.len() > before && s.fault.is_none() {
            for f in &unhandled[before..] {
                let name = f.failure.exception.to_string();
                if !cx.opts.allowed.iter().any(|a| a == &name) {
                    s.fault = Some(Fault::Unhandled {
                        exception: name,
                        path: f.path.clone(),
                    });
                    break;
                }
            }
        }
        s
    }

    /// Carries out the engine's effects and runs the bodies that can go on, until a body reaches
    /// a choice or nothing is left to do.
    fn settle(&mut self, cx: &Ctx<'_>) {
        loop {
            self.effects(cx);
            if let Some(node) = self.stops.pop_front() {
                let now = self.engine.now();
                self.engine.handle_action_stopped(now, node);
                continue;
            }
            if self.choice.is_some() || self.stopped() {
                return;
            }
            if let Some(node) = self.runq.pop_front() {
                self.run(cx, node);
                continue;
            }
            return;
        }
    }

    fn effects(&mut self, cx: &Ctx<'_>) {
        while let Some(effect) = self.engine.poll_effect() {
            match effect {
                Effect::Start { node, action } => self.start_action(cx, node, action),
                Effect::Invoke { job, body, .. } => {
                    let node = job.node();
                    match body {
                        Fac::Activation(task, args) | Fac::Handler(task, args) => {
                            self.start_body(cx, node, task, &args);
                        }
                        Fac::Retry(act) => self.start_action(cx, node, act),
                    }
                }
                Effect::Cancel { node } => {
                    self.conts.retain(|c| c.node != node);
                    self.runq.retain(|n| *n != node);
                    if self.choice == Some(node) {
                        self.choice = None;
                    }
                    self.cmds.retain(|c| c.node != node);
                    self.stops.push_back(node);
                }
                Effect::Notify { token, outcome } => {
                    if let Some(c) = self
                        .conts
                        .iter_mut()
                        .find(|c| c.wait.as_ref().is_some_and(|w| w.token == token.0))
                    {
                        c.resume = Some(*outcome);
                        let node = c.node;
                        self.runq.push_back(node);
                    }
                }
            }
        }
    }

    fn start_action(&mut self, cx: &Ctx<'_>, node: NodeId, act: Act) {
        if let (Callee::Task(id), false) = (act.callee, act.abstracted || act.remote) {
            let def = cx.prog.task(id);
            if matches!(
                def.kind,
                TaskKind::Goal | TaskKind::Handler | TaskKind::Monitor
            ) {
                self.start_body(cx, node, id, &act.args);
                return;
            }
        }
        let model = cx.model.and_then(|m| {
            let name = cx.prog.callee_name(act.callee);
            m.endings(name, &act.args.iter().map(public_value).collect::<Vec<_>>())
        });
        let mut cmd = Cmd {
            node,
            callee: act.callee,
            abstracted: act.abstracted,
            remote: act.remote,
            args: act.args,
            start: self.engine.now(),
            ticks: 0,
            hung: false,
            model: model.map(Modelled::Undecided),
        };
        // One ending only: decided at once.
        if let Some(Modelled::Undecided(e)) = &cmd.model {
            if let [one] = e.as_slice() {
                let one = one.clone();
                cmd.model = match one {
                    Ending::Never => {
                        cmd.hung = true;
                        None
                    }
                    e => Some(Modelled::Decided(time_plus(cmd.start, e.after()), e)),
                };
            }
        }
        self.cmds.push(cmd);
    }

    fn start_body(&mut self, cx: &Ctx<'_>, node: NodeId, task: TaskId, args: &[Value]) {
        let def = cx.prog.task(task);
        let mut env = Env::default();
        for (p, v) in def.params.iter().zip(args) {
            env.set(*p, v.clone());
        }
        let body = &def.body;
        let now = self.engine.now();
        let mut tags = Vec::with_capacity(body.tags.len());
        for t in &body.tags {
            let v = match t.kind {
                TagKind::Spawn | TagKind::OnTerminate if t.loops.is_empty() => {
                    match self.engine.reserve(now, node, t.reserve_as.clone()) {
                        Ok(id) => TagVal::One(id),
                        Err(_) => TagVal::Unset,
                    }
                }
                TagKind::Spawn | TagKind::OnTerminate => TagVal::Map(Vec::new()),
                TagKind::Group => TagVal::Members(Vec::new()),
                TagKind::Bound => TagVal::Unset,
            };
            tags.push(v);
        }
        self.conts.push(Cont {
            node,
            task,
            pc: 0,
            env,
            loops: vec![
                LoopState {
                    count: 0,
                    n: None,
                    start: 0
                };
                body.n_loops as usize
            ],
            tags,
            prev: None,
            frames: Vec::new(),
            wait: None,
            resume: None,
            choice: None,
        });
        self.runq.push_back(node);
    }

    /// The engine's spawn request for `callee` under `parent`, with everything the task itself
    /// says (the generated `into_task`): kind, handlers, on-terminate tasks, monitor parameters,
    /// `expand first`, `delay expansion`, the retry factory.
    fn task_spec(
        &mut self,
        cx: &Ctx<'_>,
        parent: NodeId,
        act: Act,
        name: Option<String>,
    ) -> Spawn<Act, Fac> {
        let prog = cx.prog;
        let (callee, abstracted, remote) = (act.callee, act.abstracted, act.remote);
        let args = act.args.clone();
        let task_name = prog.callee_name(callee);
        // A task placed on an agent runs there, not its body here: a command, as below.
        if abstracted || (remote && matches!(callee, Callee::Task(_))) {
            // Nested beyond the recursion bound: a command of the checker's choice, with the
            // task's name and none of its own handlers (its failures go up as the subtree's
            // would; docs/verification.md, "Bounds").
            let mut s = Spawn::new(parent, NodeKind::Command, task_name, act.clone());
            s.retry = Some(Fac::Retry(act));
            if let Some(n) = name.filter(|n| *n != task_name) {
                s.name = n.into();
                s.task = Some(task_name.into());
            }
            return s;
        }
        let env_of = |def: &TaskDef| {
            let mut env = Env::default();
            for (p, v) in def.params.iter().zip(args.iter()) {
                env.set(*p, v.clone());
            }
            env
        };
        let mut spec = match callee {
            Callee::Task(id) => {
                let def = prog.task(id);
                let env = env_of(def);
                let mut spec = match def.kind {
                    TaskKind::Monitor => {
                        let mut m = MonitorSpec::new(Fac::Activation(id, args.clone()));
                        m.max_activations = def
                            .max_activations
                            .as_ref()
                            .and_then(|e| count(&e.eval(&env)));
                        m.max_triggers =
                            def.max_triggers.as_ref().and_then(|e| count(&e.eval(&env)));
                        m.period = def.period.as_ref().map(|t| time_or_second(t, &env));
                        m.initial_wait = def.initial_wait;
                        m.each = def.each;
                        Spawn::monitor(parent, task_name, m)
                    }
                    TaskKind::Goal | TaskKind::Handler => {
                        let mut s = Spawn::new(parent, NodeKind::Goal, task_name, act.clone());
                        s.retry = Some(Fac::Retry(act.clone()));
                        s
                    }
                    TaskKind::Command => {
                        let mut s = Spawn::new(parent, NodeKind::Command, task_name, act.clone());
                        s.retry = Some(Fac::Retry(act.clone()));
                        s
                    }
                };
                if def.expand_first {
                    spec.constraints.push(Constraint::ExpandFirst);
                }
                if def.delay_expansion {
                    spec.constraints.push(Constraint::DelayExpansion);
                }
                spec.persistent = def.persistent;
                add_uses(&self.engine, prog, &mut spec, &def.uses, &env);
                for h in &def.handlers {
                    spec.handlers.push(handler_spec(prog, h, &env));
                }
                for c in &def.on_terminate {
                    let a: Arc<[Value]> = c.args.iter().map(|e| e.eval(&env)).collect();
                    spec.on_terminate.push(OnTerminate {
                        kind: kind_of(prog, c.callee),
                        name: prog.callee_name(c.callee).into(),
                        action: Act {
                            callee: c.callee,
                            args: a,
                            abstracted: false,
                            remote: false,
                        },
                        fulfils: None,
                    });
                }
                spec
            }
            Callee::Extern(_) => {
                let mut s = Spawn::new(parent, NodeKind::Command, task_name, act.clone());
                s.retry = Some(Fac::Retry(act));
                s
            }
        };
        if let Some(n) = name {
            if n != task_name {
                spec.name = n.into();
                spec.task = Some(task_name.into());
            }
        }
        spec
    }

    // ----- bodies -----

    fn cont_index(&self, node: NodeId) -> Option<usize> {
        self.conts.iter().position(|c| c.node == node)
    }

    /// The body at a choice takes way `i`, then runs on.
    fn pick(&mut self, cx: &Ctx<'_>, node: NodeId, i: u8) {
        let Some(ix) = self.cont_index(node) else {
            return;
        };
        let mut c = self.conts.swap_remove(ix);
        c.choice = None;
        let body = &cx.prog.task(c.task).body;
        let Some(op) = body.ops.get(c.pc as usize) else {
            return;
        };
        match op {
            Op::If { else_pc, .. } => c.pc = if i == 0 { c.pc + 1 } else { *else_pc },
            Op::Match(arms) => c.pc = arms.get(i as usize).copied().unwrap_or(c.pc + 1),
            Op::LoopTest { id, exit } => {
                if i == 0 {
                    c.pc = *exit;
                } else {
                    let var = loop_var(body, *id);
                    let l = &mut c.loops[*id as usize];
                    l.count += 1;
                    if let Some(v) = var {
                        c.env.set(v, Value::Unknown);
                    }
                    c.pc += 1;
                }
            }
            Op::Exit(x) => {
                // The ways: on, then return, break and continue as the statement may take them.
                let mut ways: Vec<u8> = vec![0];
                if x.ret {
                    ways.push(1);
                }
                if x.brk.is_some() {
                    ways.push(2);
                }
                if x.cont.is_some() {
                    ways.push(3);
                }
                match ways.get(i as usize).copied().unwrap_or(0) {
                    1 => {
                        self.conts.push(c);
                        self.finish(cx, node, Ok(()));
                        return;
                    }
                    2 => c.pc = x.brk.map_or(c.pc + 1, |(_, pc)| pc),
                    3 => c.pc = x.cont.map_or(c.pc + 1, |(_, pc)| pc),
                    _ => c.pc += 1,
                }
            }
            _ => c.pc += 1,
        }
        self.conts.push(c);
        self.run(cx, node);
    }

    /// Ends a body: its node's action finished with `result`.
    fn finish(&mut self, _cx: &Ctx<'_>, node: NodeId, result: Result<(), Failure>) {
        self.conts.retain(|c| c.node != node);
        self.runq.retain(|n| *n != node);
        let now = self.engine.now();
        let _ = self.engine.handle_action_finished(now, node, result);
    }

    /// Parks the body until `target`'s execution completes.
    fn wait_on(&mut self, c: &mut Cont, target: NodeId, kind: WaitFor, rest: Vec<NodeId>) {
        let now = self.engine.now();
        let _ = self.engine.hold_children(now, c.node, false);
        let token = self.next_token;
        self.next_token += 1;
        c.wait = Some(Waiting {
            token,
            node: target,
            kind,
            rest,
        });
        let ev = Event::on(target, Facet::Execution, Point::Completed);
        if self.engine.watch(now, ev, WatchToken(token)).is_err() {
            // A node of another run cannot be named here; treat as ended.
            c.resume = Some(WatchOutcome::Dead);
        }
    }

    /// Runs the body of `node` until it waits, ends or reaches a choice.
    fn run(&mut self, cx: &Ctx<'_>, node: NodeId) {
        let Some(ix) = self.cont_index(node) else {
            return;
        };
        let mut c = self.conts.swap_remove(ix);
        let prog = cx.prog;
        let body: &Body = &prog.task(c.task).body;
        // Back from a wait.
        if let Some(outcome) = c.resume.take() {
            let now = self.engine.now();
            let _ = self.engine.hold_children(now, c.node, true);
            let Some(w) = c.wait.take() else {
                self.conts.push(c);
                return;
            };
            match (w.kind, &outcome) {
                (WaitFor::Value, WatchOutcome::Failed(f) | WatchOutcome::Handled(f)) => {
                    let f = f.clone();
                    self.conts.push(c);
                    self.finish(cx, node, Err(f));
                    return;
                }
                (WaitFor::Value, WatchOutcome::Terminated | WatchOutcome::Dead) => {
                    self.conts.push(c);
                    self.finish(
                        cx,
                        node,
                        Err(Failure::new(
                            "Error",
                            "the child was terminated before it gave its value",
                        )),
                    );
                    return;
                }
                _ => {}
            }
            if let Some((next, rest)) = w.rest.split_first() {
                let rest = rest.to_vec();
                self.wait_on(&mut c, *next, w.kind, rest);
                self.conts.push(c);
                if self.conts.last().is_some_and(|c| c.resume.is_some()) {
                    self.runq.push_back(node);
                }
                return;
            }
        }
        loop {
            let Some(op) = body.ops.get(c.pc as usize) else {
                self.conts.push(c);
                self.finish(cx, node, Ok(()));
                return;
            };
            let now = self.engine.now();
            match op {
                Op::Let(s, e) => {
                    let v = e.eval(&c.env);
                    c.env.set(*s, v);
                    c.pc += 1;
                }
                Op::Forget(syms) => {
                    for s in syms {
                        c.env.set(*s, Value::Unknown);
                    }
                    c.pc += 1;
                }
                Op::Exit(x) => {
                    let n = 1
                        + u8::from(x.ret)
                        + u8::from(x.brk.is_some())
                        + u8::from(x.cont.is_some());
                    c.choice = Some(n);
                    self.choice = Some(node);
                    self.conts.push(c);
                    return;
                }
                Op::Spawn(sid) => {
                    let sp = &body.spawns[*sid as usize];
                    match self.spawn(cx, &mut c, body, *sid) {
                        Ok(id) => {
                            c.pc += 1;
                            let kind = match sp.wait {
                                Wait::No => None,
                                Wait::Plain => Some(WaitFor::Plain),
                                Wait::Value => Some(WaitFor::Value),
                                Wait::Outcome => Some(WaitFor::Outcome),
                            };
                            if let Some(kind) = kind {
                                if kind != WaitFor::Plain {
                                    let _ = self.engine.propagate(id);
                                }
                                self.wait_on(&mut c, id, kind, Vec::new());
                                let resumed = c.resume.is_some();
                                self.conts.push(c);
                                if resumed {
                                    self.runq.push_back(node);
                                }
                                return;
                            }
                        }
                        Err(Stop::Fail(f)) => {
                            self.conts.push(c);
                            self.finish(cx, node, Err(f));
                            return;
                        }
                        Err(Stop::Cut(why)) => {
                            self.cut = Some(why);
                            self.conts.push(c);
                            return;
                        }
                    }
                }
                Op::Stmt(i) => {
                    let st = &body.stmts[*i as usize];
                    let prev = c.prev.clone();
                    let targets: Vec<NodeId> = match &st.target {
                        TagRef::Parent => vec![c.node],
                        t => match self.resolve(&mut c, body, t, &prev) {
                            Nodes::Ref(NodeRef::Node(id)) => vec![id],
                            Nodes::Entity(Some(ms)) => ms,
                            _ => Vec::new(),
                        },
                    };
                    c.pc += 1;
                    let res = match &st.op {
                        StmtOp::Wait => {
                            if let Some((first, rest)) = targets.split_first() {
                                let rest = rest.to_vec();
                                self.wait_on(&mut c, *first, WaitFor::Plain, rest);
                                let resumed = c.resume.is_some();
                                self.conts.push(c);
                                if resumed {
                                    self.runq.push_back(node);
                                }
                                return;
                            }
                            Ok(())
                        }
                        StmtOp::Terminate => targets
                            .iter()
                            .try_for_each(|t| self.engine.terminate(now, *t)),
                        StmtOp::MaxActivations(e) => {
                            let n = count(&e.eval(&c.env)).unwrap_or(u32::MAX);
                            targets
                                .iter()
                                .try_for_each(|t| self.engine.set_max_activations(now, *t, n))
                        }
                        StmtOp::MaxTriggers(e) => {
                            let n = count(&e.eval(&c.env)).unwrap_or(u32::MAX);
                            targets
                                .iter()
                                .try_for_each(|t| self.engine.set_max_triggers(now, *t, n))
                        }
                        StmtOp::Period(t) => {
                            let d = time_or_second(t, &c.env);
                            targets
                                .iter()
                                .try_for_each(|m| self.engine.set_period(now, *m, d))
                        }
                        StmtOp::Constrain(ci) => {
                            let lowered = self.lower(&mut c, body, ci, &prev);
                            targets.iter().try_for_each(|t| match &lowered {
                                Lowered::Each(cs) => cs
                                    .iter()
                                    .try_for_each(|k| self.engine.constrain(now, *t, *k)),
                                Lowered::Entity {
                                    members,
                                    facet,
                                    point,
                                    delay,
                                    then,
                                } => trigger_entity(
                                    &mut self.engine,
                                    now,
                                    *t,
                                    members.as_deref(),
                                    *facet,
                                    *point,
                                    *delay,
                                    *then,
                                ),
                            })
                        }
                    };
                    if let Err(e) = res {
                        self.conts.push(c);
                        self.finish(cx, node, Err(error_failure(&e)));
                        return;
                    }
                }
                Op::Bind(t) => {
                    c.tags[*t as usize] = TagVal::Unset;
                    c.pc += 1;
                }
                Op::Succeed | Op::End => {
                    self.conts.push(c);
                    self.finish(cx, node, Ok(()));
                    return;
                }
                Op::Fail(e) => {
                    let f = match e {
                        Some(e) => failure(prog, e, "raised by `fail`"),
                        None => Failure::new("Fail", "fail without an exception"),
                    };
                    self.conts.push(c);
                    self.finish(cx, node, Err(f));
                    return;
                }
                Op::Bypass => {
                    let res = self
                        .engine
                        .request_bypass(now, c.node)
                        .map_err(|e| error_failure(&e));
                    self.conts.push(c);
                    self.finish(cx, node, res);
                    return;
                }
                Op::Trigger => {
                    if let Err(e) = self.engine.trigger(now, c.node) {
                        self.conts.push(c);
                        self.finish(cx, node, Err(error_failure(&e)));
                        return;
                    }
                    c.pc += 1;
                }
                Op::Retry => match self.engine.retry(now, c.node) {
                    Ok(id) => {
                        c.pc += 1;
                        self.wait_on(&mut c, id, WaitFor::Plain, Vec::new());
                        let resumed = c.resume.is_some();
                        self.conts.push(c);
                        if resumed {
                            self.runq.push_back(node);
                        }
                        return;
                    }
                    Err(e) => {
                        self.conts.push(c);
                        self.finish(cx, node, Err(error_failure(&e)));
                        return;
                    }
                },
                Op::If { cond, else_pc } => match cond.eval(&c.env) {
                    Value::Bool(true) => c.pc += 1,
                    Value::Bool(false) => c.pc = *else_pc,
                    _ => {
                        c.choice = Some(2);
                        self.choice = Some(node);
                        self.conts.push(c);
                        return;
                    }
                },
                Op::Match(arms) => match arms.len() {
                    0 => c.pc += 1,
                    1 => c.pc = arms[0],
                    n => {
                        c.choice = Some(u8::try_from(n).unwrap_or(u8::MAX));
                        self.choice = Some(node);
                        self.conts.push(c);
                        return;
                    }
                },
                Op::Jump(pc) => c.pc = *pc,
                Op::Resource(op, r) => {
                    c.pc += 1;
                    let name = prog.resources.get(*r as usize).map_or("", |d| d.name);
                    let res = match self.engine.resource_id(name) {
                        Some(id) => match op {
                            ResOp::Lock => self.engine.lock_resource(now, id),
                            ResOp::Unlock => self.engine.unlock_resource(now, id),
                            ResOp::Reserve => self.engine.reserve_resource(now, id, c.node),
                            ResOp::Unreserve => self.engine.unreserve_resource(now, id),
                        },
                        None => Ok(()),
                    };
                    if let Err(e) = res {
                        self.conts.push(c);
                        self.finish(cx, node, Err(error_failure(&e)));
                        return;
                    }
                }
                Op::LoopStart { id, iter } => {
                    let l = &mut c.loops[*id as usize];
                    *l = LoopState {
                        count: 0,
                        n: None,
                        start: 0,
                    };
                    match iter {
                        Iter::Range {
                            start,
                            end,
                            inclusive,
                            ..
                        } => {
                            if let (Value::Int(a), Value::Int(b)) =
                                (start.eval(&c.env), end.eval(&c.env))
                            {
                                let n = (b - a + i64::from(*inclusive)).max(0);
                                l.n = Some(u32::try_from(n).unwrap_or(u32::MAX));
                                l.start = a;
                            }
                        }
                        Iter::Count(n) => l.n = Some(*n),
                        Iter::While(_) | Iter::Unknown | Iter::Forever => {}
                    }
                    c.pc += 1;
                }
                Op::LoopTest { id, exit } => {
                    let k = cx.opts.loops;
                    let iter = loop_iter(body, *id);
                    let var = loop_var(body, *id);
                    let l = c.loops[*id as usize].clone();
                    // Counted: exactly n times.
                    if let Some(n) = l.n {
                        if l.count < n {
                            if let Some(v) = var {
                                c.env.set(v, Value::Int(l.start + i64::from(l.count)));
                            }
                            c.loops[*id as usize].count += 1;
                            c.pc += 1;
                        } else {
                            c.pc = *exit;
                        }
                        continue;
                    }
                    let cond = match iter {
                        Some(Iter::While(e)) => e.eval(&c.env),
                        Some(Iter::Forever) => Value::Bool(true),
                        _ => Value::Unknown,
                    };
                    match cond {
                        Value::Bool(false) => c.pc = *exit,
                        Value::Bool(true) => {
                            if l.count >= k {
                                self.cut = Some(format!(
                                    "a loop at {} ran {k} times (the loop bound)",
                                    prog.place(c.task, body.lines[c.pc as usize])
                                ));
                                self.conts.push(c);
                                return;
                            }
                            c.loops[*id as usize].count += 1;
                            c.pc += 1;
                        }
                        _ => {
                            if l.count >= k {
                                c.pc = *exit;
                            } else {
                                c.choice = Some(2);
                                self.choice = Some(node);
                                self.conts.push(c);
                                return;
                            }
                        }
                    }
                }
                Op::GroupStart(gid) => {
                    let group = &body.groups[*gid as usize];
                    let _ = group;
                    if let Some(parent) = c.frames.last_mut() {
                        if body.groups[parent.gid as usize].uses_previous {
                            parent.snapshot = Some(c.prev.clone());
                        }
                    }
                    c.frames.push(Frame {
                        gid: *gid,
                        members: Vec::new(),
                        snapshot: None,
                    });
                    self.group_tag_update(&mut c, body, *gid);
                    c.pc += 1;
                }
                Op::GroupEnd(gid) => {
                    if let Some(f) = c.frames.pop() {
                        c.prev = Some(f.members);
                    }
                    if let Some(parent) = c.frames.last_mut() {
                        parent.snapshot = None;
                    }
                    let _ = gid;
                    c.pc += 1;
                }
            }
        }
    }

    /// The members of group `gid` so far, into its tag if it has one.
    fn group_tag_update(&self, c: &mut Cont, body: &Body, gid: GroupId) {
        let _ = body;
        let members = c
            .frames
            .iter()
            .find(|f| f.gid == gid)
            .map(|f| f.members.clone())
            .unwrap_or_default();
        if let Some(t) = body.groups[gid as usize].tag {
            c.tags[t as usize] = TagVal::Members(members);
        }
    }

    /// The nodes a tag denotes now (`prev`: `previous` at this place).
    fn resolve(
        &mut self,
        c: &mut Cont,
        body: &Body,
        r: &TagRef,
        prev: &Option<Vec<NodeId>>,
    ) -> Nodes {
        match r {
            TagRef::Previous => Nodes::Entity(prev.clone()),
            TagRef::This => Nodes::Ref(NodeRef::This),
            TagRef::Parent => Nodes::Ref(NodeRef::Parent),
            TagRef::Opaque => Nodes::None,
            TagRef::Named(t, idx) => {
                let def = &body.tags[*t as usize];
                match (&c.tags[*t as usize], def.kind.clone()) {
                    (TagVal::One(id), _) => Nodes::Ref(NodeRef::Node(*id)),
                    (TagVal::Members(ms), _) => Nodes::Entity(Some(ms.clone())),
                    (TagVal::Map(_), _) => {
                        let mut keys = Vec::new();
                        for (i, ix) in idx.iter().enumerate() {
                            let k = match ix {
                                IndexIr::Current(l) => {
                                    i64::from(c.loops.get(*l as usize).map_or(0, |l| l.count)) - 1
                                }
                                IndexIr::Expr(e) => match e.eval(&c.env) {
                                    Value::Int(v) => v,
                                    _ => return Nodes::None,
                                },
                            };
                            let _ = i;
                            keys.push(k);
                        }
                        if keys.len() == def.loops.len() {
                            match self.slot(c, *t, &def.reserve_as, keys) {
                                Some(id) => Nodes::Ref(NodeRef::Node(id)),
                                None => Nodes::None,
                            }
                        } else if let TagVal::Map(m) = &c.tags[*t as usize] {
                            Nodes::Entity(Some(
                                m.iter()
                                    .filter(|(k, _)| k.starts_with(&keys))
                                    .map(|(_, n)| *n)
                                    .collect(),
                            ))
                        } else {
                            Nodes::None
                        }
                    }
                    (TagVal::Unset, _) => Nodes::None,
                }
            }
        }
    }

    /// The node of an iteration-indexed tag, reserved on first use.
    fn slot(&mut self, c: &mut Cont, t: u16, name: &str, key: Vec<i64>) -> Option<NodeId> {
        let TagVal::Map(m) = &mut c.tags[t as usize] else {
            return None;
        };
        if let Some((_, id)) = m.iter().find(|(k, _)| *k == key) {
            return Some(*id);
        }
        let now = self.engine.now();
        let id = self.engine.reserve(now, c.node, name.to_owned()).ok()?;
        m.push((key, id));
        m.sort();
        Some(id)
    }

    /// The current iteration's key for a spawn inside `loops`.
    fn key(c: &Cont, loops: &[LoopId]) -> Vec<i64> {
        loops
            .iter()
            .map(|l| i64::from(c.loops.get(*l as usize).map_or(0, |l| l.count)) - 1)
            .collect()
    }

    /// A constraint with its tags resolved (codegen/lower.rs).
    fn lower(
        &mut self,
        c: &mut Cont,
        body: &Body,
        ci: &CIr,
        prev: &Option<Vec<NodeId>>,
    ) -> Lowered {
        let each = |nodes: Nodes, f: &dyn Fn(NodeRef) -> Constraint| -> Lowered {
            Lowered::Each(match nodes {
                Nodes::Ref(r) => vec![f(r)],
                Nodes::Entity(Some(ms)) => ms.into_iter().map(|m| f(NodeRef::Node(m))).collect(),
                Nodes::Entity(None) | Nodes::None => Vec::new(),
            })
        };
        match ci {
            CIr::ExpandFirst => Lowered::Each(vec![Constraint::ExpandFirst]),
            CIr::DelayExpansion => Lowered::Each(vec![Constraint::DelayExpansion]),
            CIr::Sequential(f, r) => {
                let nodes = self.resolve(c, body, r, prev);
                each(nodes, &|n| Constraint::Sequential(*f, n))
            }
            CIr::Serial(r) => {
                let nodes = self.resolve(c, body, r, prev);
                each(nodes, &|n| Constraint::Serial(n))
            }
            CIr::Trigger { when, then } => {
                let env = c.env.clone();
                let nodes = match when.event() {
                    Some(e) => self.resolve(c, body, &e.tag, prev),
                    None => Nodes::Ref(NodeRef::This),
                };
                let delay = match when {
                    WhenIr::After(t, _) => Some(time_or_second(t, &env)),
                    _ => None,
                };
                if let (Nodes::Entity(members), Some(e), Then::Terminate | Then::Activate) =
                    (&nodes, when.event(), then)
                {
                    return Lowered::Entity {
                        members: members.clone(),
                        facet: e.facet,
                        point: e.point,
                        delay,
                        then: *then,
                    };
                }
                let now = self.engine.now();
                let engine = &mut self.engine;
                let mut make = |n: NodeRef| -> Constraint {
                    let w = match when {
                        WhenIr::Now => When::Now,
                        WhenIr::At(tod) => When::At(Time::from_nanos(*tod)),
                        WhenIr::In(t) => When::In(time_or_second(t, &env)),
                        WhenIr::Event(e) => When::Event(event(e, n)),
                        WhenIr::After(t, e) => When::After(time_or_second(t, &env), event(e, n)),
                        WhenIr::External(name) => {
                            When::External(engine.external(name.as_deref().unwrap_or("")))
                        }
                    };
                    let _ = now;
                    Constraint::Trigger(w, *then)
                };
                match nodes {
                    Nodes::Ref(r) => Lowered::Each(vec![make(r)]),
                    Nodes::Entity(Some(ms)) if !ms.is_empty() => {
                        Lowered::Each(ms.into_iter().map(|m| make(NodeRef::Node(m))).collect())
                    }
                    Nodes::Entity(_) => match delay {
                        // `… for D after` nothing: the `after` part is dropped.
                        Some(d) => Lowered::Each(vec![Constraint::Trigger(When::In(d), *then)]),
                        None => Lowered::Each(Vec::new()),
                    },
                    Nodes::None => Lowered::Each(Vec::new()),
                }
            }
        }
    }

    /// `previous` for the constraints of frame `i` (the innermost sees the live one).
    fn frame_prev(c: &Cont, i: usize) -> Option<Vec<NodeId>> {
        if i + 1 == c.frames.len() {
            return c.prev.clone();
        }
        match &c.frames[i].snapshot {
            Some(s) => s.clone(),
            None => c.prev.clone(),
        }
    }

    /// A spawn statement, as the generated code does it (codegen/spawn.rs).
    fn spawn(&mut self, cx: &Ctx<'_>, c: &mut Cont, body: &Body, sid: u32) -> Result<NodeId, Stop> {
        let prog = cx.prog;
        let sp = &body.spawns[sid as usize];
        let name = prog.callee_name(sp.call.callee);
        // The recursion bound: instances of this task above the new node. One more is spawned as
        // a command of the checker's choice; beyond that the path ends.
        let path = self.engine.path(c.node);
        let depth = path.split('/').filter(|n| *n == name).count() as u32;
        let abstracted = depth >= cx.opts.recursion && matches!(sp.call.callee, Callee::Task(_));
        if depth > cx.opts.recursion {
            return Err(Stop::Cut(format!(
                "`{name}` nested {} deep at {} (beyond the recursion bound)",
                depth + 1,
                prog.place(c.task, sp.line)
            )));
        }
        if let Callee::Task(id) = sp.call.callee {
            if prog.task(id).kind == TaskKind::Handler {
                return Err(Stop::Fail(Failure::new(
                    "Error",
                    format!("`{name}` is a handler, not a task to spawn"),
                )));
            }
        }
        let args: Arc<[Value]> = sp.call.args.iter().map(|a| a.eval(&c.env)).collect();
        let instance = sp.name.as_ref().and_then(|n| match n.eval(&c.env) {
            Value::Str(s) => Some(s.to_string()),
            _ => None,
        });
        let act = Act {
            callee: sp.call.callee,
            args,
            abstracted,
            remote: sp.remote,
        };
        let mut spec = self.task_spec(cx, c.node, act, instance);
        let mut armed: Vec<Lowered> = Vec::new();
        // The groups' constraints (outermost first, each with its own `previous`), then its own.
        let mut lists: Vec<(&[CIr], Option<Vec<NodeId>>)> = Vec::new();
        for (i, g) in sp.groups.iter().enumerate() {
            let fi = c.frames.iter().position(|f| f.gid == *g).unwrap_or(i);
            lists.push((&body.groups[*g as usize].cons, Self::frame_prev(c, fi)));
        }
        lists.push((&sp.cons, c.prev.clone()));
        for (cons, prev) in lists {
            for ci in cons {
                match self.lower(c, body, ci, &prev) {
                    Lowered::Each(cs) => spec.constraints.extend(cs),
                    e @ Lowered::Entity { .. } => armed.push(e),
                }
            }
        }
        // Monitor parameters: the groups', then its own; the last given wins.
        if let Some(m) = spec.monitor.as_mut() {
            for g in sp
                .groups
                .iter()
                .map(|g| &body.groups[*g as usize].monitor)
                .chain([&sp.monitor])
            {
                if let Some(e) = &g.max_activations {
                    m.max_activations = count(&e.eval(&c.env));
                }
                if let Some(e) = &g.max_triggers {
                    m.max_triggers = count(&e.eval(&c.env));
                }
                if let Some(t) = &g.period {
                    m.period = Some(time_or_second(t, &c.env));
                }
            }
        }
        // Resources: the groups', then its own (amounts add up, the last priority given wins).
        for u in sp
            .groups
            .iter()
            .map(|g| &body.groups[*g as usize].uses)
            .chain([&sp.uses])
        {
            add_uses(&self.engine, prog, &mut spec, u, &c.env);
        }
        for h in &sp.handlers {
            spec.handlers.push(handler_spec(prog, h, &c.env));
        }
        for (call, tag) in &sp.on_terminate {
            let a: Arc<[Value]> = call.args.iter().map(|e| e.eval(&c.env)).collect();
            let fulfils = match tag {
                Some(t) => match c.tags[*t as usize].clone() {
                    TagVal::One(id) => Some(id),
                    TagVal::Map(_) => {
                        let key = Self::key(c, &body.tags[*t as usize].loops);
                        let reserve_as = body.tags[*t as usize].reserve_as.clone();
                        self.slot(c, *t, &reserve_as, key)
                    }
                    _ => None,
                },
                None => None,
            };
            spec.on_terminate.push(OnTerminate {
                kind: kind_of(prog, call.callee),
                name: prog.callee_name(call.callee).into(),
                action: Act {
                    callee: call.callee,
                    args: a,
                    abstracted: false,
                    remote: false,
                },
                fulfils,
            });
        }
        if let Some(t) = sp.tag {
            spec.fulfils = match c.tags[t as usize].clone() {
                TagVal::One(id) => Some(id),
                TagVal::Map(_) => {
                    let key = Self::key(c, &body.tags[t as usize].loops);
                    let reserve_as = body.tags[t as usize].reserve_as.clone();
                    self.slot(c, t, &reserve_as, key)
                }
                _ => None,
            };
        }
        let now = self.engine.now();
        let id = self
            .engine
            .spawn(now, spec)
            .map_err(|e| Stop::Fail(error_failure(&e)))?;
        if sp.propagate {
            let _ = self.engine.propagate_to_parent(id);
        }
        for a in armed {
            if let Lowered::Entity {
                members,
                facet,
                point,
                delay,
                then,
            } = a
            {
                trigger_entity(
                    &mut self.engine,
                    now,
                    id,
                    members.as_deref(),
                    facet,
                    point,
                    delay,
                    then,
                )
                .map_err(|e| Stop::Fail(error_failure(&e)))?;
            }
        }
        for f in &mut c.frames {
            f.members.push(id);
        }
        let gids: Vec<GroupId> = c.frames.iter().map(|f| f.gid).collect();
        for g in gids {
            self.group_tag_update(c, body, g);
        }
        c.prev = Some(vec![id]);
        if sp.terminable {
            self.terminable.retain(|n| self.engine.info(*n).is_some());
            self.terminable.push(id);
        }
        Ok(id)
    }

    // ----- hashing -----

    /// Feeds `h` the canonical form of the state (docs/verification.md, "State").
    pub(crate) fn hash_canonical(&self, h: &mut impl Hasher) -> Canonical {
        let canon = self.engine.canonical_hash(h);
        let now = self.engine.now();
        let r = |id: NodeId, h: &mut dyn Hasher| {
            let mut w = HashWrap(h);
            self.engine.hash_node_ref(&canon, id, &mut w);
        };
        let mut conts: Vec<(Option<u32>, &Cont)> = self
            .conts
            .iter()
            .map(|c| (canon.index(c.node), c))
            .collect();
        conts.sort_by_key(|(i, _)| *i);
        conts.len().hash(h);
        for (i, c) in conts {
            i.hash(h);
            c.task.hash(h);
            c.pc.hash(h);
            c.env.hash(h);
            c.loops.hash(h);
            c.choice.hash(h);
            for t in &c.tags {
                match t {
                    TagVal::Unset => 0u8.hash(h),
                    TagVal::One(id) => {
                        1u8.hash(h);
                        r(*id, h);
                    }
                    TagVal::Map(m) => {
                        2u8.hash(h);
                        m.len().hash(h);
                        for (k, id) in m {
                            k.hash(h);
                            r(*id, h);
                        }
                    }
                    TagVal::Members(ms) => {
                        3u8.hash(h);
                        ms.len().hash(h);
                        for id in ms {
                            r(*id, h);
                        }
                    }
                }
            }
            match &c.prev {
                None => 0u8.hash(h),
                Some(p) => {
                    1u8.hash(h);
                    p.len().hash(h);
                    for id in p {
                        r(*id, h);
                    }
                }
            }
            c.frames.len().hash(h);
            for f in &c.frames {
                f.gid.hash(h);
                f.members.len().hash(h);
                for id in &f.members {
                    r(*id, h);
                }
                match &f.snapshot {
                    None => 0u8.hash(h),
                    Some(None) => 1u8.hash(h),
                    Some(Some(s)) => {
                        2u8.hash(h);
                        s.len().hash(h);
                        for id in s {
                            r(*id, h);
                        }
                    }
                }
            }
            match &c.wait {
                None => 0u8.hash(h),
                Some(w) => {
                    1u8.hash(h);
                    r(w.node, h);
                    w.kind.hash(h);
                    w.rest.len().hash(h);
                    for id in &w.rest {
                        r(*id, h);
                    }
                }
            }
            match &c.resume {
                None => 0u8.hash(h),
                Some(o) => {
                    1u8.hash(h);
                    std::mem::discriminant(o).hash(h);
                }
            }
        }
        self.runq.len().hash(h);
        for n in &self.runq {
            r(*n, h);
        }
        self.choice.map(|n| canon.index(n)).hash(h);
        let mut cmds: Vec<(Option<u32>, &Cmd)> =
            self.cmds.iter().map(|c| (canon.index(c.node), c)).collect();
        cmds.sort_by_key(|(i, _)| *i);
        cmds.len().hash(h);
        for (i, c) in cmds {
            i.hash(h);
            c.callee.hash(h);
            c.abstracted.hash(h);
            c.remote.hash(h);
            c.args.hash(h);
            c.hung.hash(h);
            // How many deadlines it outlasted (it may outlast `Options::ticks`).
            c.ticks.hash(h);
            match &c.model {
                None => 0u8.hash(h),
                Some(Modelled::Undecided(e)) => {
                    1u8.hash(h);
                    e.hash(h);
                }
                Some(Modelled::Decided(at, e)) => {
                    2u8.hash(h);
                    at.as_nanos().saturating_sub(now.as_nanos()).hash(h);
                    e.hash(h);
                }
            }
        }
        self.stops.len().hash(h);
        self.raised.hash(h);
        self.hangs.hash(h);
        let mut term: Vec<u32> = self
            .terminable
            .iter()
            .filter_map(|n| canon.index(*n))
            .collect();
        term.sort_unstable();
        term.hash(h);
        self.cut.is_some().hash(h);
        self.fault.hash(h);
        self.broken.hash(h);
        self.watch.as_ref().map(|w| w.seen).hash(h);
        canon
    }

    /// What the run waits for when nothing can happen: the engine's stuck report, with each
    /// body's wait (docs/semantics.md, "Run outcome").
    pub(crate) fn stuck_report(&self) -> Vec<String> {
        let awaits: Vec<(NodeId, Event)> = self
            .conts
            .iter()
            .filter_map(|c| {
                c.wait.as_ref().map(|w| {
                    (
                        c.node,
                        Event::on(w.node, Facet::Execution, Point::Completed),
                    )
                })
            })
            .collect();
        let mut out: Vec<String> = self
            .engine
            .blocked_awaiting(&awaits)
            .iter()
            .map(ToString::to_string)
            .collect();
        for c in &self.cmds {
            if c.hung {
                out.push(format!(
                    "{} was chosen to run until it is terminated, and nothing terminates it",
                    self.engine.path(c.node)
                ));
            }
        }
        out
    }

    /// The commands left running forever on this path.
    pub(crate) fn hung(&self) -> Vec<String> {
        self.cmds
            .iter()
            .filter(|c| c.hung)
            .map(|c| self.engine.path(c.node))
            .collect()
    }

    /// Words for an action, for counterexamples.
    pub(crate) fn describe(&mut self, cx: &Ctx<'_>, a: &Action) -> String {
        match a {
            Action::Pick(i) => {
                let Some(node) = self.choice else {
                    return format!("choice {i}");
                };
                let Some(c) = self.conts.iter().find(|c| c.node == node) else {
                    return format!("choice {i}");
                };
                let body = &cx.prog.task(c.task).body;
                let line = body.lines.get(c.pc as usize).copied().unwrap_or(0);
                let place = cx.prog.place(c.task, line);
                let what = match body.ops.get(c.pc as usize) {
                    Some(Op::If { .. }) => {
                        if *i == 0 {
                            "takes the `if` branch".to_owned()
                        } else {
                            "takes the `else` branch".to_owned()
                        }
                    }
                    Some(Op::Match(_)) => format!("takes arm {} of the `match`", i + 1),
                    Some(Op::LoopTest { .. }) => {
                        if *i == 0 {
                            "leaves the loop".to_owned()
                        } else {
                            "runs the loop again".to_owned()
                        }
                    }
                    Some(Op::Exit(_)) => {
                        if *i == 0 {
                            "goes on".to_owned()
                        } else {
                            "leaves by a `return`, `break` or `continue`".to_owned()
                        }
                    }
                    _ => format!("takes way {i}"),
                };
                format!(
                    "{} {what} at {place} (a condition the checker does not evaluate)",
                    self.engine.path(node)
                )
            }
            Action::End { node, outcome } => {
                let path = self.engine.path(*node);
                let Some(cmd) = self.cmds.iter().find(|c| c.node == *node) else {
                    return format!("{path} ends");
                };
                match &cmd.model {
                    Some(Modelled::Decided(_, Ending::Succeeds(_))) => {
                        return format!("{path} succeeds");
                    }
                    Some(Modelled::Decided(_, Ending::Fails(e, _))) => {
                        return format!("{path} fails with {e}");
                    }
                    _ => {}
                }
                if *outcome == 0 {
                    format!("{path} succeeds")
                } else {
                    let raises = self.raises(cx, cmd.callee, cmd.abstracted, cmd.remote);
                    format!(
                        "{path} fails with {}",
                        raises.get(*outcome as usize - 1).copied().unwrap_or("?")
                    )
                }
            }
            Action::Hang(node) => format!(
                "{} keeps running until it is terminated",
                self.engine.path(*node)
            ),
            Action::Decide { node, i } => {
                format!(
                    "the model of {} chooses ending {i}",
                    self.engine.path(*node)
                )
            }
            Action::Raise(i) => format!(
                "external event `{}` is raised",
                cx.prog
                    .external_events
                    .get(*i as usize)
                    .map_or("?", String::as_str)
            ),
            Action::Tick => match self.next_tick() {
                Some(t) => format!("time passes to {}", fmt_secs(t)),
                None => "time passes".to_owned(),
            },
        }
    }
}

/// Seconds, as short as they go.
pub(crate) fn fmt_secs(t: Time) -> String {
    format!("{} s", t.as_nanos() as f64 / 1e9)
}

/// Why a spawn stops the body.
enum Stop {
    Fail(Failure),
    Cut(String),
}

struct HashWrap<'a>(&'a mut dyn Hasher);

impl Hasher for HashWrap<'_> {
    fn finish(&self) -> u64 {
        self.0.finish()
    }
    fn write(&mut self, bytes: &[u8]) {
        self.0.write(bytes);
    }
}

fn public_value(v: &Value) -> crate::model::Arg {
    match v {
        Value::Unknown => crate::model::Arg::Unknown,
        Value::Int(i) => crate::model::Arg::Int(*i),
        Value::Bool(b) => crate::model::Arg::Bool(*b),
        Value::Str(s) => crate::model::Arg::Str(s.to_string()),
        Value::Float(f) => crate::model::Arg::Float(f64::from_bits(*f)),
    }
}

fn count(v: &Value) -> Option<u32> {
    match v {
        Value::Int(i) => Some(u32::try_from((*i).max(0)).unwrap_or(u32::MAX)),
        _ => None,
    }
}

/// A relative time; one the checker cannot compute is taken as one second (noted at load).
fn time_or_second(t: &TimeIr, env: &Env) -> Duration {
    duration(t, env).unwrap_or(Duration::from_secs(1))
}

fn kind_of(prog: &Program, c: Callee) -> NodeKind {
    match c {
        Callee::Task(id) => match prog.task(id).kind {
            TaskKind::Goal | TaskKind::Handler => NodeKind::Goal,
            TaskKind::Command | TaskKind::Monitor => NodeKind::Command,
        },
        Callee::Extern(_) => NodeKind::Command,
    }
}

fn handler_spec(prog: &Program, h: &crate::ir::HandlerUse, env: &Env) -> HandlerSpec<Fac> {
    let def = prog.task(h.handler);
    let args: Arc<[Value]> = h.args.iter().map(|e| e.eval(env)).collect();
    let own = def
        .max_activations
        .as_ref()
        .and_then(|e| count(&e.eval(&Env::default())));
    let max = h.max.as_ref().map_or(own, |e| count(&e.eval(env)));
    HandlerSpec {
        name: def.name.into(),
        exception: def.handles.unwrap_or_default().into(),
        max_activations: max,
        body: Fac::Handler(h.handler, args),
    }
}

/// Adds `u` (evaluated in `env`) to what the spawn `spec` asks of the resources, as the generated
/// `.uses(r, n)`, `.priority(p)` and `.deny_if_busy()` do: amounts add up, a priority replaces the
/// one before, `deny if busy` stays. An amount or priority the checker cannot evaluate is 1 or 0.
fn add_uses(engine: &Eng, prog: &Program, spec: &mut Spawn<Act, Fac>, u: &UsesIr, env: &Env) {
    if u.is_empty() {
        return;
    }
    let req = spec.uses.get_or_insert_with(Box::default);
    for (r, amount) in &u.amounts {
        let Some(id) = prog
            .resources
            .get(*r as usize)
            .and_then(|d| engine.resource_id(d.name))
        else {
            continue;
        };
        req.amounts
            .push((id, count(&amount.eval(env)).unwrap_or(1)));
    }
    if let Some(p) = &u.priority {
        req.priority = match p.eval(env) {
            Value::Int(i) => i32::try_from(i).unwrap_or(if i < 0 { i32::MIN } else { i32::MAX }),
            _ => 0,
        };
    }
    req.deny_if_busy |= u.deny_if_busy;
}

fn event(e: &EventIr, n: NodeRef) -> Event {
    match e.outcome {
        Some(o) => Event::ended(n, o),
        None => Event::on(n, e.facet, e.point),
    }
}

/// `tdl::codegen::trigger_entity`: a termination or activation once every member reached the
/// event; at once (or after the delay) when there is none.
#[allow(clippy::too_many_arguments)]
fn trigger_entity(
    engine: &mut Eng,
    now: Time,
    target: NodeId,
    members: Option<&[NodeId]>,
    facet: Facet,
    point: Point,
    delay: Option<Duration>,
    then: Then,
) -> Result<(), tcm_core::EngineError> {
    let when = match (members, delay) {
        (None, None) => return Ok(()),
        (None | Some([]), Some(d)) => When::In(d),
        (Some([]), None) => When::Now,
        (Some([one]), None) => When::Event(Event::on(*one, facet, point)),
        (Some([one]), Some(d)) => When::After(d, Event::on(*one, facet, point)),
        (Some(many), _) => {
            return engine.trigger_group(now, target, many, facet, point, delay, then);
        }
    };
    engine.constrain(now, target, Constraint::Trigger(when, then))
}

fn loop_iter(body: &Body, id: LoopId) -> Option<&Iter> {
    body.ops.iter().find_map(|op| match op {
        Op::LoopStart { id: l, iter } if *l == id => Some(iter),
        _ => None,
    })
}

fn loop_var(body: &Body, id: LoopId) -> Option<crate::value::Sym> {
    match loop_iter(body, id) {
        Some(Iter::Range { var, .. }) => *var,
        _ => None,
    }
}
