//! Running a body: from its start or a wait to its next wait, choice or end, one instruction family
//! at a time, and a choice taken.

use tcm_core::{Event, Facet, Failure, NodeId, NodeRef, Point, Time, WatchOutcome, WatchToken};

use super::spawn::{Lowered, Nodes, Stop, trigger_entity};
use super::{
    Cont, Ctx, Frame, LoopState, State, TagVal, WaitFor, Waiting, count, error_failure, failure,
    time_or_second,
};
use crate::ir::{Body, GroupId, Iter, LoopId, Op, ResOp, StmtOp, TagRef, Wait};
use crate::value::Value;

/// Where a body is after an instruction, or after the wait it came back from.
enum Step {
    /// On to the instruction at its `pc`.
    Next,
    /// It stops here (at a choice, or a bound cut the path): its continuation is kept.
    Park,
    /// It waits: its continuation is kept, and queued to run again if the wait is already over.
    Wait,
    /// It ends: its node's action finished with this result.
    Finish(Result<(), Failure>),
}

impl State {
    pub(super) fn cont_index(&self, node: NodeId) -> Option<usize> {
        self.conts.iter().position(|c| c.node == node)
    }

    /// The body at a choice takes way `i`, then runs on.
    pub(super) fn pick(&mut self, cx: &Ctx<'_>, node: NodeId, i: u8) {
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
            Op::SetState { var, values } => {
                if let Some(v) = values.get(i as usize) {
                    self.set_state(cx, *var, v.clone());
                }
                c.pc += 1;
            }
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

    /// Runs the body of `node` until it waits, ends or reaches a choice: each instruction by the
    /// function of its family, until one says the body stops ([`Step`]).
    pub(super) fn run(&mut self, cx: &Ctx<'_>, node: NodeId) {
        let Some(ix) = self.cont_index(node) else {
            return;
        };
        let mut c = self.conts.swap_remove(ix);
        let body: &Body = &cx.prog.task(c.task).body;
        // Back from a wait.
        if let Some(outcome) = c.resume.take() {
            let step = self.resume(&mut c, &outcome);
            if !matches!(step, Step::Next) {
                self.stop(cx, c, step);
                return;
            }
        }
        loop {
            let Some(op) = body.ops.get(c.pc as usize) else {
                self.stop(cx, c, Step::Finish(Ok(())));
                return;
            };
            let now = self.engine.now();
            let step = match op {
                Op::Let(..) | Op::Forget(_) | Op::Bind(_) => Self::local(&mut c, op),
                Op::Exit(_)
                | Op::If { .. }
                | Op::Match(_)
                | Op::Jump(_)
                | Op::Succeed
                | Op::End
                | Op::Fail(_) => self.control(cx, &mut c, op),
                Op::LoopStart { .. } | Op::LoopTest { .. } => self.looping(cx, &mut c, body, op),
                Op::GroupStart(_) | Op::GroupEnd(_) => self.group(&mut c, body, op),
                Op::Spawn(sid) => self.spawn_op(cx, &mut c, body, *sid),
                Op::Stmt(i) => self.stmt(&mut c, body, *i, now),
                Op::Bypass | Op::Trigger | Op::Retry | Op::Resource(..) => {
                    self.own_call(cx, &mut c, op, now)
                }
                Op::SetState { var, values } => match values.as_slice() {
                    [] => {
                        c.pc += 1;
                        Step::Next
                    }
                    [v] => {
                        self.set_state(cx, *var, v.clone());
                        c.pc += 1;
                        Step::Next
                    }
                    vs => self.choose(&mut c, u8::try_from(vs.len()).unwrap_or(u8::MAX)),
                },
                Op::Raise(i) => {
                    if let Some(name) = cx.prog.external_events.get(*i as usize) {
                        let id = self.engine.external(name);
                        self.engine.handle_external(now, id);
                    }
                    c.pc += 1;
                    Step::Next
                }
            };
            if !matches!(step, Step::Next) {
                self.stop(cx, c, step);
                return;
            }
        }
    }

    /// The program's state variable `var` takes `value` (an input to the engine, as `set` is).
    pub(super) fn set_state(&mut self, cx: &Ctx<'_>, var: u16, value: tcm_core::Value) {
        let Some(def) = cx.prog.states.get(var as usize) else {
            return;
        };
        if let Some(id) = self.engine.state_id(&def.name) {
            let now = self.engine.now();
            // The value is of the variable's type (the loader made it so).
            let _ = self.engine.set_state(now, id, value);
        }
    }

    /// Keeps the continuation of a body that stops running, as `step` says.
    fn stop(&mut self, cx: &Ctx<'_>, c: Cont, step: Step) {
        let node = c.node;
        match step {
            Step::Next | Step::Park => self.conts.push(c),
            Step::Wait => {
                let resumed = c.resume.is_some();
                self.conts.push(c);
                if resumed {
                    self.runq.push_back(node);
                }
            }
            Step::Finish(result) => {
                self.conts.push(c);
                self.finish(cx, node, result);
            }
        }
    }

    /// The body stops at a choice of `ways` ways.
    fn choose(&mut self, c: &mut Cont, ways: u8) -> Step {
        c.choice = Some(ways);
        self.choice = Some(c.node);
        Step::Park
    }

    /// Back from a wait that ended with `outcome`: a value waited for that never came fails the
    /// body, a wait on a group waits for the next member.
    fn resume(&mut self, c: &mut Cont, outcome: &WatchOutcome) -> Step {
        let now = self.engine.now();
        let _ = self.engine.hold_children(now, c.node, true);
        let Some(w) = c.wait.take() else {
            return Step::Park;
        };
        match (w.kind, outcome) {
            (WaitFor::Value, WatchOutcome::Failed(f) | WatchOutcome::Handled(f)) => {
                return Step::Finish(Err(f.clone()));
            }
            (
                WaitFor::Value,
                WatchOutcome::Terminated | WatchOutcome::Dead | WatchOutcome::Skipped,
            ) => {
                return Step::Finish(Err(Failure::new(
                    "Error",
                    "the child was terminated before it gave its value",
                )));
            }
            _ => {}
        }
        if let Some((next, rest)) = w.rest.split_first() {
            let rest = rest.to_vec();
            self.wait_on(c, *next, w.kind, rest);
            return Step::Wait;
        }
        Step::Next
    }

    /// Locals: `let`, a local forgotten, a tag bound afresh.
    fn local(c: &mut Cont, op: &Op) -> Step {
        match op {
            Op::Let(s, e) => {
                let v = e.eval(&c.env);
                c.env.set(*s, v);
            }
            Op::Forget(syms) => {
                for s in syms {
                    c.env.set(*s, Value::Unknown);
                }
            }
            Op::Bind(t) => c.tags[*t as usize] = TagVal::Unset,
            _ => unreachable!("not a local: {op:?}"),
        }
        c.pc += 1;
        Step::Next
    }

    /// Control flow: a statement that may leave (`return`, `break`, `continue`), `if`, `match`, a
    /// jump, and the body's end (`succeed`, its last statement, `fail`).
    fn control(&mut self, cx: &Ctx<'_>, c: &mut Cont, op: &Op) -> Step {
        match op {
            Op::Exit(x) => {
                let n =
                    1 + u8::from(x.ret) + u8::from(x.brk.is_some()) + u8::from(x.cont.is_some());
                return self.choose(c, n);
            }
            Op::If { cond, else_pc } => match cond.eval(&c.env) {
                Value::Bool(true) => c.pc += 1,
                Value::Bool(false) => c.pc = *else_pc,
                _ => return self.choose(c, 2),
            },
            Op::Match(arms) => match arms.len() {
                0 => c.pc += 1,
                1 => c.pc = arms[0],
                n => return self.choose(c, u8::try_from(n).unwrap_or(u8::MAX)),
            },
            Op::Jump(pc) => c.pc = *pc,
            Op::Succeed | Op::End => return Step::Finish(Ok(())),
            Op::Fail(e) => {
                let f = match e {
                    Some(e) => failure(cx.prog, e, "raised by `fail`"),
                    None => Failure::new("Fail", "fail without an exception"),
                };
                return Step::Finish(Err(f));
            }
            _ => unreachable!("not control flow: {op:?}"),
        }
        Step::Next
    }

    /// Loops: a loop's start (how many times it runs, when known) and its test before each
    /// iteration (counted, a condition, or a choice within the loop bound).
    fn looping(&mut self, cx: &Ctx<'_>, c: &mut Cont, body: &Body, op: &Op) -> Step {
        match op {
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
                    return Step::Next;
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
                                cx.prog.place(c.task, body.lines[c.pc as usize])
                            ));
                            return Step::Park;
                        }
                        c.loops[*id as usize].count += 1;
                        c.pc += 1;
                    }
                    _ => {
                        if l.count >= k {
                            c.pc = *exit;
                        } else {
                            return self.choose(c, 2);
                        }
                    }
                }
            }
            _ => unreachable!("not a loop instruction: {op:?}"),
        }
        Step::Next
    }

    /// Groups (`with` and its block): a group's start and end, with its members and `previous`.
    fn group(&self, c: &mut Cont, body: &Body, op: &Op) -> Step {
        match op {
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
                self.group_tag_update(c, body, *gid);
            }
            Op::GroupEnd(gid) => {
                if let Some(f) = c.frames.pop() {
                    c.prev = Some(f.members);
                }
                if let Some(parent) = c.frames.last_mut() {
                    parent.snapshot = None;
                }
                let _ = gid;
            }
            _ => unreachable!("not a group instruction: {op:?}"),
        }
        c.pc += 1;
        Step::Next
    }

    /// A spawn statement (`spawn.rs`), and the wait that follows it if it says so.
    fn spawn_op(&mut self, cx: &Ctx<'_>, c: &mut Cont, body: &Body, sid: u32) -> Step {
        let sp = &body.spawns[sid as usize];
        match self.spawn(cx, c, body, sid) {
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
                    self.wait_on(c, id, kind, Vec::new());
                    return Step::Wait;
                }
                Step::Next
            }
            Err(Stop::Fail(f)) => Step::Finish(Err(f)),
            Err(Stop::Cut(why)) => {
                self.cut = Some(why);
                Step::Park
            }
        }
    }

    /// A statement on a tag's nodes (or the parent's): wait, terminate, a monitor's parameters,
    /// a constraint.
    fn stmt(&mut self, c: &mut Cont, body: &Body, i: u32, now: Time) -> Step {
        let st = &body.stmts[i as usize];
        let prev = c.prev.clone();
        let targets: Vec<NodeId> = match &st.target {
            TagRef::Parent => vec![c.node],
            t => match self.resolve(c, body, t, &prev) {
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
                    self.wait_on(c, *first, WaitFor::Plain, rest);
                    return Step::Wait;
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
                let lowered = self.lower(c, body, ci, &prev);
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
        match res {
            Ok(()) => Step::Next,
            Err(e) => Step::Finish(Err(error_failure(&e))),
        }
    }

    /// What the body asks of the engine for its own node: bypass (ending the body), trigger,
    /// retry (and wait for the retry), lock, unlock, reserve or unreserve a resource.
    fn own_call(&mut self, cx: &Ctx<'_>, c: &mut Cont, op: &Op, now: Time) -> Step {
        match op {
            Op::Bypass => {
                let res = self
                    .engine
                    .request_bypass(now, c.node)
                    .map_err(|e| error_failure(&e));
                Step::Finish(res)
            }
            Op::Trigger => {
                if let Err(e) = self.engine.trigger(now, c.node) {
                    return Step::Finish(Err(error_failure(&e)));
                }
                c.pc += 1;
                Step::Next
            }
            Op::Retry => match self.engine.retry(now, c.node) {
                Ok(id) => {
                    c.pc += 1;
                    self.wait_on(c, id, WaitFor::Plain, Vec::new());
                    Step::Wait
                }
                Err(e) => Step::Finish(Err(error_failure(&e))),
            },
            Op::Resource(op, r) => {
                c.pc += 1;
                let name = cx.prog.resources.get(*r as usize).map_or("", |d| d.name);
                let res = match self.engine.resource_id(name) {
                    Some(id) => match op {
                        ResOp::Lock => self.engine.lock_resource(now, id),
                        ResOp::Unlock => self.engine.unlock_resource(now, id),
                        ResOp::Reserve => self.engine.reserve_resource(now, id, c.node),
                        ResOp::Unreserve => self.engine.unreserve_resource(now, id),
                    },
                    None => Ok(()),
                };
                match res {
                    Ok(()) => Step::Next,
                    Err(e) => Step::Finish(Err(error_failure(&e))),
                }
            }
            _ => unreachable!("not a call on the body's own node: {op:?}"),
        }
    }

    /// The members of group `gid` so far, into its tag if it has one.
    pub(super) fn group_tag_update(&self, c: &mut Cont, body: &Body, gid: GroupId) {
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
