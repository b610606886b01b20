//! The TDL statements, run as the code the generator writes for them runs (`tdl-syntax`'s
//! `codegen/spawn.rs`, `codegen/lower.rs`): the same `tcm` calls, in the same order, so that an
//! interpreted program and the compiled one give the same trace, record for record. A spawn
//! builds its task, then its builder chain step by step (reservations made as the chain reaches
//! them), then the triggers on whole entities, then waits; `previous` and the groups' members are
//! the TDL slots the generator keeps in `tdl_*` locals.

use ::tdl::{
    Constraint, Event, Failure, NodeId, NodeRef, ResourceRef, Spawner, StateValue, Task, When,
};

use crate::eval::{Flow, Frame, R, TdlVal};
use crate::ir::{
    BindTo, ConstrainSt, CountEx, DurEx, EntityEx, KeyEx, Low, Lowered, NameEx, NodeEx, Nodes,
    ResRef, SpawnSt, St, Step, TaskCall, WhenEx, WithSt,
};
use crate::value::Value;

impl Frame {
    /// A TDL statement that does not await.
    pub(crate) fn tdl_sync(&mut self, st: &St) -> R<()> {
        match st {
            St::Spawn(s) => {
                self.spawn_start(s)?;
            }
            St::With(w) => {
                self.with_start(w);
                self.block_sync(&w.body)?;
                self.with_end(w);
            }
            St::Constrain(c) => self.constrain(c)?,
            St::Bind(var, e) => {
                let v = self.eval(e)?;
                let Value::Node(n) = v else {
                    return Err(Flow::Fail(crate::builtin::bad("`bind`", &v)));
                };
                if let Some(var) = var {
                    self.set_tdl(*var, TdlVal::Maybe(Some(vec![n])));
                }
            }
            St::Succeed => return Err(Flow::Return(Value::Unit)),
            St::Fail(f) => {
                let mut fields = Vec::with_capacity(f.fields.len());
                for (name, e) in &f.fields {
                    fields.push((name.clone(), self.eval(e)?));
                }
                return Err(Flow::Fail(crate::program::raise(f, fields)));
            }
            St::Bypass => {
                return match self.ctx()?.bypass() {
                    Ok(()) => Err(Flow::Return(Value::Unit)),
                    Err(f) => Err(Flow::Fail(f)),
                };
            }
            St::Trigger => self.ctx()?.trigger()?,
            St::Resource(op, r) => {
                use tdl_syntax::ast::ResourceOp;
                let r = resource(r);
                match op {
                    ResourceOp::Lock => self.ctx()?.lock_resource(r)?,
                    ResourceOp::Unlock => self.ctx()?.unlock_resource(r)?,
                    ResourceOp::Reserve => self.ctx()?.reserve_resource(r, self.ctx()?.node())?,
                    ResourceOp::Unreserve => self.ctx()?.unreserve_resource(r)?,
                }
            }
            St::Set(var, value) => {
                let v = match value {
                    None => StateValue::Unknown,
                    Some(e) => state_value(&self.eval(e)?)?,
                };
                self.ctx()?.set_state(var, v)?;
            }
            St::Raise(name) => {
                let name = self.name(name)?;
                self.ctx()?.raise(&name)?;
            }
            St::Log(line) => {
                let line = self.eval(line)?.to_string();
                self.ctx()?.log(line)?;
            }
            _ => {
                return Err(Flow::Fail(Failure::new(
                    "Interpreter",
                    "a statement that awaits was run without awaiting",
                )));
            }
        }
        Ok(())
    }

    /// A TDL statement that may await.
    pub(crate) async fn tdl_async(&mut self, st: &St) -> R<()> {
        match st {
            St::Spawn(s) => self.spawn_wait(s).await,
            St::With(w) => {
                self.with_start(w);
                self.block_async(&w.body).await?;
                self.with_end(w);
                Ok(())
            }
            St::Constrain(c) => match &**c {
                ConstrainSt::Wait(nodes) => {
                    for n in self.targets(nodes)? {
                        self.ctx()?.wait(n).await?;
                    }
                    Ok(())
                }
                other => self.constrain(other),
            },
            St::Retry(args) => {
                let node = match args {
                    None => self.ctx()?.retry()?,
                    Some(args) => {
                        let args = self.eval_all_async(args).await?;
                        self.ctx()?.retry_with(crate::value::Args(args, None))?
                    }
                };
                self.ctx()?.wait(node).await?;
                Ok(())
            }
            other => self.tdl_sync(other),
        }
    }

    fn name(&mut self, n: &NameEx) -> R<String> {
        Ok(match n {
            NameEx::Lit(s) => s.to_string(),
            NameEx::Expr(e) => match self.eval(e)? {
                Value::Str(s) => s.to_string(),
                other => other.to_string(),
            },
        })
    }

    fn with_start(&mut self, w: &WithSt) {
        if let Some(m) = w.members {
            self.set_tdl(m, TdlVal::Nodes(Vec::new()));
        }
        if let Some((from, into)) = w.snapshot {
            let prev = self.tdl.get(from as usize).cloned().unwrap_or_default();
            self.set_tdl(into, prev);
        }
    }

    fn with_end(&mut self, w: &WithSt) {
        if let (Some(prev), Some(m)) = (w.prev, w.members) {
            let members = match self.tdl.get(m as usize) {
                Some(TdlVal::Nodes(n)) => n.clone(),
                _ => Vec::new(),
            };
            self.set_tdl(prev, TdlVal::Maybe(Some(members)));
        }
    }

    /// The task a call builds.
    pub(crate) fn build(&mut self, call: &TaskCall) -> R<Task> {
        match call {
            TaskCall::Tdl(idx, args) => {
                let args = self.eval_all(args)?;
                Ok(crate::program::task(&self.shared, *idx, args)?)
            }
            TaskCall::Rust(entry, args, params) => {
                let mut args = self.eval_all(args)?;
                // Typed by its `extern` declaration: a value of the wrong type fails the node.
                if let Some(params) = params {
                    for (i, (v, ty)) in args.iter_mut().zip(params.iter()).enumerate() {
                        let given = std::mem::take(v);
                        *v = ty.coerce(given).map_err(|e| {
                            Failure::new("TypeMismatch", format!("argument {}: {e}", i + 1))
                        })?;
                    }
                }
                Ok((entry.make)(&args)?)
            }
            TaskCall::Remote {
                agent,
                name,
                kind,
                args,
            } => {
                let agent = self.eval(agent)?.to_string();
                let args = self.eval_all(args)?;
                let json: Result<Vec<_>, String> = args.iter().map(Value::to_json).collect();
                let json = json.map_err(|e| {
                    Failure::new(
                        "Args",
                        format!("the arguments of `{name}` for its agent: {e}"),
                    )
                })?;
                // One argument crosses as itself, several as an array (as a tuple serializes).
                let json = match json.len() {
                    0 => serde_json::Value::Null,
                    1 => json.into_iter().next().unwrap_or_default(),
                    _ => serde_json::Value::Array(json),
                };
                Ok(self.ctx()?.remote_task(&agent, name, *kind, json)?)
            }
        }
    }

    /// The spawn's builder on `ctx` (the body's), its chain applied; the node of `pre`, if any.
    fn chain<'c>(&mut self, s: &SpawnSt, ctx: &'c ::tdl::Ctx) -> R<(Spawner<'c>, Option<NodeId>)> {
        let pre = match &s.pre {
            Some(n) => Some(self.node_id(n, None)?),
            None => None,
        };
        let mut task = self.build(&s.task)?;
        if let Some(name) = &s.name {
            let name = match self.eval(name)? {
                Value::Str(s) => s.to_string(),
                other => other.to_string(),
            };
            task = task.named(name);
        }
        let mut sp = ctx.spawn(task);
        for step in &s.steps {
            sp = self.step(sp, step, pre)?;
        }
        Ok((sp, pre))
    }

    /// A spawn that does not wait: started; its triggers on entities armed; `previous` and the
    /// groups updated.
    fn spawn_start(&mut self, s: &SpawnSt) -> R<()> {
        let ctx = self.ctx()?.clone();
        let (sp, _) = self.chain(s, &ctx)?;
        let node = sp.start()?;
        self.after_spawn(s, node, None)
    }

    fn after_spawn(&mut self, s: &SpawnSt, node: NodeId, id: Option<NodeId>) -> R<()> {
        let id = id.unwrap_or(node);
        if s.binding.is_none() {
            for arm in &s.armed {
                self.arm(node, arm)?;
            }
            if let Some(var) = s.late {
                self.set_tdl(var, TdlVal::Maybe(Some(vec![node])));
            }
        }
        if s.needs_id {
            for m in &s.members {
                if let Some(TdlVal::Nodes(list)) = self.tdl.get_mut(*m as usize) {
                    list.push(id);
                }
            }
            if let Some(prev) = s.prev {
                match self.tdl.get_mut(prev as usize) {
                    // The list of one node kept: no allocation per spawn.
                    Some(TdlVal::Maybe(Some(m))) => {
                        m.clear();
                        m.push(id);
                    }
                    _ => self.set_tdl(prev, TdlVal::Maybe(Some(vec![id]))),
                }
            }
        }
        Ok(())
    }

    /// A spawn that waits: for its value, its outcome, or its end.
    async fn spawn_wait(&mut self, s: &SpawnSt) -> R<()> {
        let ctx = self.ctx()?.clone();
        let Some((target, ty)) = &s.binding else {
            let (sp, _) = self.chain(s, &ctx)?;
            if !s.needs_id {
                sp.wait().await?;
                return Ok(());
            }
            let node = sp.start()?;
            self.after_spawn(s, node, None)?;
            ctx.wait(node).await?;
            return Ok(());
        };
        // The node is a reservation until the spawn: the triggers are kept on it.
        let (sp, pre) = self.chain(s, &ctx)?;
        let id = match &s.id {
            Some(NodeEx::Pre) => pre,
            Some(n) => Some(self.node_id(n, pre)?),
            None => None,
        };
        if let Some(id) = id {
            for arm in &s.armed {
                self.arm(id, arm)?;
            }
        }
        let value_of = self.value_of(&s.task);
        let ended = sp.wait_outcome_erased().await?;
        let value = |v: Option<Box<dyn std::any::Any + Send>>| {
            v.and_then(|v| value_of(v)).ok_or_else(|| {
                Flow::Fail(Failure::new(
                    "NoValue",
                    format!(
                        "the spawn at {} waited for a value its task did not give",
                        s.loc
                    ),
                ))
            })
        };
        let v = if s.outcome {
            match ended {
                ::tdl::Ended::Succeeded(v) => Value::variant("Ended", "Succeeded", vec![value(v)?]),
                ::tdl::Ended::Failed(f) => Value::variant(
                    "Ended",
                    "Failed",
                    vec![Value::Failure(std::sync::Arc::new(f))],
                ),
                ::tdl::Ended::Terminated => Value::variant("Ended", "Terminated", Vec::new()),
                ::tdl::Ended::Skipped => Value::variant("Ended", "Skipped", Vec::new()),
            }
        } else {
            match ended {
                ::tdl::Ended::Succeeded(v) => value(v)?,
                ::tdl::Ended::Failed(f) => {
                    return Err(Flow::Fail(Failure::from(::tdl::Error::ChildFailed(
                        ::tdl::PassedOn(f),
                    ))));
                }
                ::tdl::Ended::Terminated => {
                    return Err(Flow::Fail(Failure::from(::tdl::Error::ChildTerminated)));
                }
                ::tdl::Ended::Skipped => {
                    return Err(Flow::Fail(Failure::from(::tdl::Error::ChildSkipped)));
                }
            }
        };
        let v = ty.coerce(v).map_err(|e| {
            Flow::Fail(Failure::new(
                "TypeMismatch",
                format!("the value of the spawn at {}: {e}", s.loc),
            ))
        })?;
        match target {
            BindTo::Let(pat) => {
                if !self.bind(pat, &v) {
                    return Err(Flow::Fail(Failure::new(
                        "NoMatch",
                        format!("the pattern at {} does not take `{v:?}`", s.loc),
                    )));
                }
            }
            BindTo::Assign(place) => self.assign(place, v)?,
        }
        if let Some(id) = id {
            self.after_spawn(s, id, Some(id))?;
        }
        Ok(())
    }

    /// How the value of the called task becomes a value.
    fn value_of(&self, call: &TaskCall) -> crate::registry::ValueOf {
        match call {
            TaskCall::Rust(entry, ..) => entry.value.clone(),
            // An agent's value comes back as JSON; the binding's type reads it.
            TaskCall::Remote { .. } => std::sync::Arc::new(|v: Box<dyn std::any::Any + Send>| {
                v.downcast::<serde_json::Value>()
                    .ok()
                    .map(|j| Value::from_json(&j))
            }),
            _ => std::sync::Arc::new(crate::program::value_of_value),
        }
    }

    /// One step of the builder chain.
    fn step<'c>(&mut self, sp: Spawner<'c>, step: &Step, pre: Option<NodeId>) -> R<Spawner<'c>> {
        Ok(match step {
            Step::Propagate => sp.propagate(),
            Step::Approval(None) => sp.approval(None),
            Step::Approval(Some(d)) => sp.approval(Some(self.duration(d)?)),
            Step::Under(e) => match self.eval(e)? {
                Value::Node(n) => sp.under(n),
                other => return Err(Flow::Fail(crate::builtin::bad("`parent`", &other))),
            },
            Step::OnTerminate(call, fulfils) => {
                let task = self.build(call)?;
                match fulfils {
                    Some(n) => {
                        let n = self.node_id(n, pre)?;
                        sp.on_terminate_fulfils(task, n)
                    }
                    None => sp.on_terminate(task),
                }
            }
            Step::Handler(h) => {
                let args = self.eval_all(&h.args)?;
                let mut handler = crate::program::handler(&self.shared, h.task, args)?;
                if let Some(max) = &h.max {
                    handler = handler.max_activations(self.count_of(max)?);
                }
                sp.handler(handler)
            }
            Step::MaxActivations(n) => sp.max_activations(self.count_of(n)?),
            Step::MaxTriggers(n) => sp.max_triggers(self.count_of(n)?),
            Step::Period(d) => sp.period(self.duration(d)?),
            Step::Uses(r, n) => sp.uses(resource(r), self.count_of(n)?),
            Step::Priority(e) => {
                let p = self.eval(e)?.as_int().unwrap_or(0);
                sp.priority(i32::try_from(p).unwrap_or(if p < 0 { i32::MIN } else { i32::MAX }))
            }
            Step::DenyIfBusy => sp.deny_if_busy(),
            Step::Fulfils(n) => {
                let n = self.node_id(n, pre)?;
                sp.fulfils(n)
            }
            Step::Low(nodes, low, empty) => {
                let mut sp = sp;
                match nodes {
                    Nodes::One(n) => {
                        let n = self.node_ref(n, pre)?;
                        sp = self.low_method(sp, low, n)?;
                    }
                    Nodes::None => {}
                    // `previous` of one node (a spawn after a spawn): no list made.
                    Nodes::Entity(e) if self.single(e).is_some() => {
                        if let Some(one) = self.single(e) {
                            sp = self.low_method(sp, low, NodeRef::Node(one))?;
                        }
                    }
                    Nodes::Entity(e) => {
                        let members = self.members(e)?;
                        for m in members.iter().flatten() {
                            sp = self.low_method(sp, low, NodeRef::Node(*m))?;
                        }
                        if let (Some(empty), true) =
                            (empty, members.as_ref().is_none_or(Vec::is_empty))
                        {
                            sp = self.low_method(sp, empty, NodeRef::This)?;
                        }
                    }
                }
                sp
            }
        })
    }

    fn low_method<'c>(&mut self, sp: Spawner<'c>, low: &Low, n: NodeRef) -> R<Spawner<'c>> {
        Ok(match low {
            Low::ExpandFirst => sp.expand_first(),
            Low::DelayExpansion => sp.delay_expansion(),
            Low::Sequential(f) => sp.sequential(*f, n),
            Low::Serial => sp.serial(n),
            Low::Trigger(..) => sp.with(self.low_value(low, n)?),
        })
    }

    /// The constraint `low` on the node `n`.
    fn low_value(&mut self, low: &Low, n: NodeRef) -> R<Constraint> {
        Ok(match low {
            Low::ExpandFirst => Constraint::ExpandFirst,
            Low::DelayExpansion => Constraint::DelayExpansion,
            Low::Sequential(f) => Constraint::Sequential(*f, n),
            Low::Serial => Constraint::Serial(n),
            Low::Trigger(when, then) => {
                let when = match when {
                    WhenEx::Now => When::Now,
                    WhenEx::At(secs) => When::At(self.ctx()?.time_of_day(*secs)),
                    WhenEx::In(d) => When::In(self.duration(d)?),
                    WhenEx::Event(ev) => When::Event(event(ev, n)),
                    WhenEx::After(d, ev) => When::After(self.duration(d)?, event(ev, n)),
                    WhenEx::External(name) => {
                        let name = self.name(name)?;
                        When::External(self.ctx()?.external(&name)?)
                    }
                    WhenEx::Condition(vars, expr) => {
                        let c = self.ctx()?.condition(vars, expr.clone())?;
                        return Ok(match then {
                            ::tdl::Then::Enable(f) => Constraint::disable(*f, When::Condition(c)),
                            ::tdl::Then::Terminate => Constraint::terminate(When::Condition(c)),
                            // TDL writes no trigger with data (`Ctx::activate_when`).
                            ::tdl::Then::Activate | ::tdl::Then::ActivateWith(_) => {
                                Constraint::activate(When::Condition(c))
                            }
                            ::tdl::Then::Skip => Constraint::skip_if(c),
                            ::tdl::Then::Invariant => Constraint::invariant(c),
                            ::tdl::Then::Pause => Constraint::pause_while(c),
                        });
                    }
                    WhenEx::Changed(var) => {
                        let when = When::Changed(self.ctx()?.state_var(var)?);
                        return Ok(match then {
                            ::tdl::Then::Terminate => Constraint::terminate(when),
                            ::tdl::Then::Enable(f) => Constraint::disable(*f, when),
                            _ => Constraint::activate(when),
                        });
                    }
                };
                Constraint::Trigger(when, *then)
            }
        })
    }

    /// Arms a trigger on a whole entity, or applies a per-node constraint, on `target`.
    fn arm(&mut self, target: NodeId, l: &Lowered) -> R<()> {
        match l {
            Lowered::Entity {
                members,
                delay,
                facet,
                point,
                then,
            } => {
                let members = self.members(members)?;
                let delay = match delay {
                    Some(d) => Some(self.duration(d)?),
                    None => None,
                };
                ::tdl::codegen::trigger_entity(
                    self.ctx()?,
                    target,
                    members.as_deref(),
                    *facet,
                    *point,
                    delay,
                    *then,
                )?;
            }
            Lowered::Each { nodes, low, empty } => {
                self.apply(target, nodes, low, empty.as_ref())?;
            }
        }
        Ok(())
    }

    /// `ctx.constrain(target, low(n))` for each node `n` of `nodes` (or `empty` when an entity
    /// has no member).
    fn apply(&mut self, target: NodeId, nodes: &Nodes, low: &Low, empty: Option<&Low>) -> R<()> {
        match nodes {
            Nodes::One(n) => {
                let n = self.node_ref(n, None)?;
                let c = self.low_value(low, n)?;
                self.ctx()?.constrain(target, c)?;
            }
            Nodes::None => {}
            Nodes::Entity(e) => {
                let members = self.members(e)?;
                for m in members.iter().flatten() {
                    let c = self.low_value(low, NodeRef::Node(*m))?;
                    self.ctx()?.constrain(target, c)?;
                }
                if let (Some(empty), true) = (empty, members.as_ref().is_none_or(Vec::is_empty)) {
                    let c = self.low_value(empty, NodeRef::This)?;
                    self.ctx()?.constrain(target, c)?;
                }
            }
        }
        Ok(())
    }

    /// A constraint statement.
    fn constrain(&mut self, c: &ConstrainSt) -> R<()> {
        match c {
            ConstrainSt::Wait(_) => Err(Flow::Fail(Failure::new(
                "Interpreter",
                "`wait` run without awaiting",
            ))),
            ConstrainSt::Terminate(nodes) => {
                for n in self.targets(nodes)? {
                    self.ctx()?.terminate(n)?;
                }
                Ok(())
            }
            ConstrainSt::MaxActivations(nodes, count) => {
                for n in self.targets(nodes)? {
                    let c = self.count_of(count)?;
                    self.ctx()?.set_max_activations(n, c)?;
                }
                Ok(())
            }
            ConstrainSt::MaxTriggers(nodes, count) => {
                for n in self.targets(nodes)? {
                    let c = self.count_of(count)?;
                    self.ctx()?.set_max_triggers(n, c)?;
                }
                Ok(())
            }
            ConstrainSt::Period(nodes, d) => {
                for n in self.targets(nodes)? {
                    let d = self.duration(d)?;
                    self.ctx()?.set_period(n, d)?;
                }
                Ok(())
            }
            ConstrainSt::Apply(nodes, lowered) => {
                for target in self.targets(nodes)? {
                    self.arm(target, lowered)?;
                }
                Ok(())
            }
        }
    }

    /// The nodes a constraint statement's tag names.
    fn targets(&mut self, nodes: &Nodes) -> R<Vec<NodeId>> {
        Ok(match nodes {
            Nodes::One(n) => vec![self.node_id(n, None)?],
            Nodes::Entity(e) => self.members(e)?.unwrap_or_default(),
            Nodes::None => Vec::new(),
        })
    }

    /// The one member of an entity held in a slot (`previous` after a spawn), if it has exactly
    /// one.
    fn single(&self, e: &EntityEx) -> Option<NodeId> {
        match e {
            EntityEx::Prev(slot) | EntityEx::Held(slot) => match self.tdl.get(*slot as usize) {
                Some(TdlVal::Maybe(Some(m)) | TdlVal::Nodes(m)) if m.len() == 1 => {
                    m.first().copied()
                }
                _ => None,
            },
            EntityEx::Prefix(..) => None,
        }
    }

    /// An entity's members; `None` when there is no entity at all.
    fn members(&mut self, e: &EntityEx) -> R<Option<Vec<NodeId>>> {
        Ok(match e {
            EntityEx::Prev(slot) | EntityEx::Held(slot) => match self.tdl.get(*slot as usize) {
                Some(TdlVal::Maybe(m)) => m.clone(),
                Some(TdlVal::Nodes(n)) => Some(n.clone()),
                Some(TdlVal::Map(map)) => Some(map.values().copied().collect()),
                _ => None,
            },
            EntityEx::Prefix(slot, keys) => {
                let keys = self.keys(keys)?;
                match self.tdl.get(*slot as usize) {
                    Some(TdlVal::Map(map)) => Some(
                        map.iter()
                            .filter(|(k, _)| k.starts_with(&keys))
                            .map(|(_, n)| *n)
                            .collect(),
                    ),
                    _ => Some(Vec::new()),
                }
            }
        })
    }

    fn keys(&mut self, keys: &[KeyEx]) -> R<Vec<i64>> {
        keys.iter()
            .map(|k| match k {
                KeyEx::Expr(e) => match self.eval(e)? {
                    Value::Int(i) => Ok(i),
                    other => Err(Flow::Fail(crate::builtin::bad(
                        "an iteration index",
                        &other,
                    ))),
                },
                KeyEx::Current(slot) => Ok(match self.tdl.get(*slot as usize) {
                    Some(TdlVal::Count(n)) => *n,
                    _ => 0,
                }),
            })
            .collect()
    }

    /// A node expression as a `NodeRef`.
    fn node_ref(&mut self, n: &NodeEx, pre: Option<NodeId>) -> R<NodeRef> {
        Ok(match n {
            // A constraint naming no node (`expand first`) is given `self`, which it ignores.
            NodeEx::This | NodeEx::Nothing => NodeRef::This,
            NodeEx::Parent => NodeRef::Parent,
            other => NodeRef::Node(self.node_id(other, pre)?),
        })
    }

    /// The node of `node!(tag)`.
    pub(crate) fn node_sync(&mut self, n: &NodeEx) -> R<NodeId> {
        self.node_id(n, None)
    }

    /// A node expression's node: a reservation, an entry of an iteration map (reserved on first
    /// use), a bound tag, the body's own node.
    fn node_id(&mut self, n: &NodeEx, pre: Option<NodeId>) -> R<NodeId> {
        Ok(match n {
            NodeEx::Reserved(slot) => match self.tdl.get(*slot as usize) {
                Some(TdlVal::Node(n)) => *n,
                _ => return Err(no_node("a reservation was not made")),
            },
            NodeEx::Slot(slot, keys, name) => {
                let keys = self.keys(keys)?;
                if let Some(TdlVal::Map(map)) = self.tdl.get(*slot as usize) {
                    if let Some(n) = map.get(&keys) {
                        return Ok(*n);
                    }
                }
                let node = self.ctx()?.reserve(name)?;
                if let Some(TdlVal::Map(map)) = self.tdl.get_mut(*slot as usize) {
                    map.insert(keys, node);
                }
                node
            }
            NodeEx::Bound(slot, name) => match self.tdl.get(*slot as usize) {
                Some(TdlVal::Maybe(Some(nodes))) if !nodes.is_empty() => nodes[0],
                _ => {
                    return Err(Flow::Fail(Failure::new(
                        "Unbound",
                        format!(
                            "`node!({name})`: `{name}` is not bound yet (its `bind` or spawn has not run)"
                        ),
                    )));
                }
            },
            NodeEx::Own | NodeEx::Parent => self.ctx()?.node(),
            NodeEx::Pre => pre.ok_or_else(|| no_node("the spawn's node was not made"))?,
            NodeEx::Fresh(name) => self.ctx()?.reserve(name)?,
            NodeEx::This | NodeEx::Nothing => return Err(no_node("`self` names no node here")),
        })
    }

    fn count_of(&mut self, c: &CountEx) -> R<u32> {
        Ok(match c {
            CountEx::Const(n) => *n,
            CountEx::Expr(e) => match self.eval(e)? {
                Value::Int(i) => u32::try_from(i).unwrap_or(u32::MAX),
                other => return Err(Flow::Fail(crate::builtin::bad("a count", &other))),
            },
        })
    }

    pub(crate) fn duration(&mut self, d: &DurEx) -> R<std::time::Duration> {
        Ok(match d {
            DurEx::Fixed(d) => *d,
            DurEx::Secs(e) => match self.eval(e)?.as_float() {
                Some(x) if x >= 0.0 && x.is_finite() => std::time::Duration::from_secs_f64(x),
                _ => {
                    return Err(Flow::Fail(Failure::new(
                        "TypeMismatch",
                        "a duration in seconds must be a finite number, at least 0",
                    )));
                }
            },
        })
    }
}

fn no_node(why: &str) -> Flow {
    Flow::Fail(Failure::new(
        "Interpreter",
        format!("a tag's node is missing: {why}"),
    ))
}

/// The event of `ev` on node `n`.
fn event(ev: &crate::ir::EventEx, n: NodeRef) -> Event {
    if let Some(o) = ev.outcome {
        return Event::ended(n, o);
    }
    match ev.facet {
        None => Event::new(n, ev.point),
        Some(f) => Event::on(n, f, ev.point),
    }
}

/// A resource as `tcm` names it.
pub(crate) fn resource(r: &ResRef) -> ResourceRef {
    match r {
        ResRef::Declared(name, capacity, pending) => {
            let mut res = ::tdl::Resource::new(*name, *capacity);
            if let Some(p) = pending {
                res = res.pending_limit(*p);
            }
            ResourceRef::from(res)
        }
        ResRef::Named(name) => ResourceRef::from(*name),
    }
}

/// A value set into a state variable.
fn state_value(v: &Value) -> R<StateValue> {
    Ok(match v {
        Value::Bool(b) => StateValue::Bool(*b),
        Value::Int(i) => StateValue::Int(*i),
        Value::Float(x) => StateValue::Float(*x),
        Value::Str(s) => StateValue::Str(s.to_string()),
        other => return Err(Flow::Fail(crate::builtin::bad("`set`", other))),
    })
}
