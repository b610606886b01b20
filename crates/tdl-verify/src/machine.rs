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
//! - an operator approves or refuses a node held for approval (`with approval`);
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
use std::hash::Hash;
use std::sync::Arc;
use std::time::Duration;

use tcm_core::{Effect, Engine, Facet, Failure, HandlerSpec, NodeId, Time, WatchOutcome};
use tdl_syntax::ast::TaskKind;

use crate::Options;
use crate::ir::{Callee, GroupId, TagKind, TaskId, TimeIr};
use crate::model::{CommandModel, Ending};
use crate::program::{Program, duration};
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
    /// An operator approves (`yes`) or refuses a node held for approval (`with approval`).
    Approve { node: NodeId, yes: bool },
    /// An external event is raised.
    Raise(u16),
    /// The environment uses entry `entry` of its declaration: sets its variable to its `value`th
    /// value, or raises its event.
    Env { entry: u16, value: u16 },
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
    /// How many times each entry of the environment declaration was used.
    env_used: Vec<u8>,
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

mod canon;
mod run;
mod spawn;
mod transition;

impl State {
    /// The state before anything happened: the root task spawned and settled.
    pub(crate) fn init(cx: &Ctx<'_>, task: &str, tracing: bool) -> State {
        let mut engine: Eng = Engine::new(1);
        engine.set_tracing(tracing);
        engine.hold_by_default(true);
        for fault in &cx.opts.faults {
            engine.inject(Time::ZERO, fault.clone(), "faults file");
        }
        let prog = cx.prog;
        // The declared resources (the generated code declares each on its first use; declared
        // first here, in order, they behave the same).
        let mut error = None;
        for r in &prog.resources {
            if let Err(e) = engine.declare_resource(r.name, r.capacity, r.pending) {
                error = Some(format!("cannot declare resource `{}`: {e}", r.name));
            }
        }
        // The state variables, in order (the generated code declares each where it is first
        // used, with the same type and initial value).
        for v in &prog.states {
            if let Err(e) = engine.declare_state(&v.name, v.ty, v.initial.clone()) {
                error = Some(format!("cannot declare state variable `{}`: {e}", v.name));
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
            env_used: vec![0; prog.environment.as_ref().map_or(0, Vec::len)],
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
        // A body that fails before anything ends (a goal's `fail`, run as it expands) fails in
        // the initial state: no transition would see it.
        s.note_unhandled(cx, 0);
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
                // The checker keeps no values of commands: a fault's is as good as any.
                Effect::Value { .. } => {}
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

    /// Ends a body: its node's action finished with `result`.
    fn finish(&mut self, _cx: &Ctx<'_>, node: NodeId, result: Result<(), Failure>) {
        self.conts.retain(|c| c.node != node);
        self.runq.retain(|n| *n != node);
        let now = self.engine.now();
        let _ = self.engine.handle_action_finished(now, node, result);
    }
}

/// Seconds, as short as they go.
pub(crate) fn fmt_secs(t: Time) -> String {
    format!("{} s", t.as_nanos() as f64 / 1e9)
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
