//! Spawning as the generated code does: the engine's spawn request for a task, tags resolved to
//! nodes, constraints lowered, resources and handlers added.

use std::sync::Arc;
use std::time::Duration;

use tcm_core::{
    Constraint, Event, Facet, Failure, HandlerSpec, MonitorSpec, NodeId, NodeKind, NodeRef,
    OnTerminate, Point, Spawn, Then, Time, When,
};
use tdl_syntax::ast::TaskKind;

use super::{Act, Cont, Ctx, Eng, Fac, State, TagVal, count, error_failure, time_or_second};
use crate::ir::{Body, CIr, Callee, EventIr, GroupId, IndexIr, LoopId, TagRef, UsesIr, WhenIr};
use crate::program::{Program, TaskDef};
use crate::value::{Env, Value};

pub(super) enum Nodes {
    Ref(NodeRef),
    Entity(Option<Vec<NodeId>>),
    None,
}

/// A constraint lowered for one spawn: applied per node, or an entity trigger armed after it.
pub(super) enum Lowered {
    Each(Vec<Constraint>),
    Entity {
        members: Option<Vec<NodeId>>,
        facet: Facet,
        point: Point,
        delay: Option<Duration>,
        then: Then,
    },
}

/// Why a spawn stops the body.
pub(super) enum Stop {
    Fail(Failure),
    Cut(String),
}

impl State {
    /// The engine's spawn request for `callee` under `parent`, with everything the task itself
    /// says (the generated `into_task`): kind, handlers, on-terminate tasks, monitor parameters,
    /// `expand first`, `delay expansion`, the retry factory.
    pub(super) fn task_spec(
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

    /// The nodes a tag denotes now (`prev`: `previous` at this place).
    pub(super) fn resolve(
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
    pub(super) fn lower(
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
                        // The program's variables are declared when the machine starts, and
                        // tdl-syntax type-checked the condition: registering it cannot fail; were
                        // it to, the trigger waits on a condition that never holds.
                        WhenIr::Condition(e) => match engine.condition(e) {
                            Ok(c) => When::Condition(c),
                            Err(_) => When::External(engine.external("(bad condition)")),
                        },
                        WhenIr::Changed(v) => match engine.state_id(v) {
                            Some(id) => When::Changed(id),
                            None => When::External(engine.external("(unknown variable)")),
                        },
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
    pub(super) fn spawn(
        &mut self,
        cx: &Ctx<'_>,
        c: &mut Cont,
        body: &Body,
        sid: u32,
    ) -> Result<NodeId, Stop> {
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
        if let Some(within) = &sp.approval {
            let within = within.as_ref().map(|t| time_or_second(t, &c.env));
            spec.constraints
                .push(tcm_core::Constraint::Approval(within));
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
pub(super) fn trigger_entity(
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
