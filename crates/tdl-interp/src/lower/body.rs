//! A task body lowered as `tdl-syntax`'s `codegen/body.rs` and `codegen/spawn.rs` generate it:
//! the TDL slots made at the top (reservations in the generator's order), then the statements;
//! a spawn as its task call, its builder steps from the enclosing groups' constraints (outermost
//! first) then its own, the triggers on whole entities, the wait; `with` groups tracking their
//! members and `previous`; constraint statements; loops counting their iterations where a tag
//! needs it. An `if`, `match` or block holding TDL statements is an expression, so that in last
//! place it gives the body's value, as the generated block does.

use std::sync::Arc;

use tdl_syntax::ast::{
    BindTarget, Block as AstBlock, Constraint, ConstraintKind, ConstraintStmt, Else, Fail, If,
    Spawn, Stmt, TagKind, Task, TaskKind, Then, When, WithGroup,
};
use tdl_syntax::hir::uses_previous;

use super::Lower;
use crate::ir::{
    Arm, BindTo, Block, ConstrainSt, Ex, FailSt, Init, LoopKind, LoopSt, NodeEx, Nodes, SpawnSt,
    St, Step, TSlot, TaskCall, WithSt,
};
use crate::ty::Ty;
use crate::value::Value;

/// A `with` group around the statement being lowered.
pub(crate) struct Frame<'a> {
    constraints: &'a [Constraint],
    /// The TDL slot holding `previous` for this group's current direct child.
    prev: String,
    /// The TDL slot collecting the group's members, when tracked.
    members: Option<String>,
}

const PREV: &str = "tdl_prev";

/// What a spawn's constraints make of it.
#[derive(Default)]
struct Parts {
    steps: Vec<Step>,
    armed: Vec<crate::ir::Lowered>,
    wait: bool,
    outcome: bool,
    name: Option<Ex>,
    on: Option<Ex>,
}

impl<'a> Lower<'_, 'a> {
    /// The body of `task`: its TDL slots' initial values and its statements.
    pub(crate) fn body(&mut self, task: &'a Task) -> (Vec<(TSlot, Init)>, Block) {
        let prelude = self.prelude();
        let block = self.tdl_block(&task.body, false);
        (prelude, block)
    }

    /// The TDL slots made at the top of the body, in the generator's order.
    fn prelude(&mut self) -> Vec<(TSlot, Init)> {
        let scope = self.scope;
        let mut out = Vec::new();
        let late = scope
            .spawns
            .iter()
            .filter(|it| it.late)
            .filter_map(|it| it.var.as_ref())
            .chain(scope.bound.values().filter_map(|it| it.var.as_ref()));
        for var in late {
            out.push((self.tdl_slot(&var.to_string()), Init::Maybe));
        }
        let reserved =
            scope.spawns.iter().filter(|it| !it.late).filter_map(|it| {
                Some((it.var.as_ref()?, &it.spawn.task, it.site.loops.is_empty()))
            });
        let cleanups = scope.cleanups.iter().filter_map(|it| {
            let loops = &scope.spawns[it.spawn].site.loops;
            Some((it.var.as_ref()?, &it.on_terminate.task, loops.is_empty()))
        });
        for (var, task, no_loops) in reserved.chain(cleanups) {
            let slot = self.tdl_slot(&var.to_string());
            if no_loops {
                out.push((
                    slot,
                    Init::Reserve(crate::program::intern(&task.to_string())),
                ));
            } else {
                out.push((slot, Init::Map));
            }
        }
        for group in &scope.groups {
            if let Some(var) = &group.var {
                out.push((self.tdl_slot(&var.to_string()), Init::Nodes));
            }
        }
        if scope.uses_previous {
            out.push((self.tdl_slot(PREV), Init::Maybe));
        }
        out
    }

    /// A block of TDL statements, in a scope of its own (unless `scoped` is false: the body).
    fn tdl_block(&mut self, block: &'a AstBlock, scoped: bool) -> Block {
        if scoped {
            self.push_scope();
        }
        let mut out = Block::default();
        for stmt in &block.stmts {
            self.tdl_stmt(stmt, &mut out);
        }
        if scoped {
            self.pop_scope();
        }
        out
    }

    fn push(out: &mut Block, st: St) {
        if let Some(tail) = out.tail.take() {
            out.stmts.push(St::Expr(tail));
        }
        out.stmts.push(st);
    }

    fn push_tail(out: &mut Block, ex: Ex) {
        if let Some(tail) = out.tail.take() {
            out.stmts.push(St::Expr(tail));
        }
        out.tail = Some(ex);
    }

    fn tdl_stmt(&mut self, stmt: &'a Stmt, out: &mut Block) {
        match stmt {
            Stmt::Rust(it) => self.rust_stmts(&it.tokens, it.span, out),
            Stmt::Spawn(spawn) => {
                let st = self.spawn(spawn);
                Self::push(out, st);
            }
            Stmt::With(group) => {
                let st = self.with(group);
                Self::push(out, st);
            }
            Stmt::Constrain(it) => {
                if let Some(st) = self.constrain(it) {
                    Self::push(out, St::Constrain(Box::new(st)));
                }
            }
            Stmt::Bind(bind) => {
                let e = self.expr(&bind.expr);
                let var = self
                    .scope
                    .bound
                    .get(&bind.name.to_string())
                    .and_then(|it| it.var.as_ref())
                    .map(ToString::to_string);
                let var = var.map(|v| self.tdl_slot(&v));
                Self::push(out, St::Bind(var, e));
            }
            Stmt::Succeed(_) => Self::push(out, St::Succeed),
            Stmt::Fail(f) => {
                let st = self.fail(f);
                Self::push(out, St::Fail(Box::new(st)));
            }
            Stmt::Bypass(_) => Self::push(out, St::Bypass),
            Stmt::Trigger(_) => Self::push(out, St::Trigger),
            Stmt::Resource(it) => {
                let r = self.resource(&it.name);
                Self::push(out, St::Resource(it.op, r));
            }
            Stmt::Set(it) => {
                let Some((var, _)) = self.names.states.get(&it.name.to_string()).cloned() else {
                    return;
                };
                let unknown = matches!(&it.value, syn::Expr::Path(p) if p.path.is_ident("unknown"));
                let value = (!unknown).then(|| self.expr(&it.value));
                Self::push(out, St::Set(var, value));
            }
            Stmt::Raise(it) => {
                let name = self.name_ex(&it.name);
                Self::push(out, St::Raise(name));
            }
            Stmt::Log(it) => {
                let args = it.format_args();
                let line: syn::Expr = syn::parse_quote!(format!(#args));
                let line = self.expr(&line);
                Self::push(out, St::Log(line));
            }
            Stmt::Retry(it) => {
                let args = it
                    .args
                    .as_ref()
                    .map(|a| a.iter().map(|e| self.expr(e)).collect());
                Self::push(out, St::Retry(args));
            }
            Stmt::If(it) => {
                let ex = self.if_tdl(it);
                Self::push_tail(out, ex);
            }
            Stmt::Match(m) => {
                let scrutinee = Box::new(self.expr(&m.expr));
                let arms = m
                    .arms
                    .iter()
                    .map(|arm| {
                        self.push_scope();
                        let pat = self.pat(&arm.pat);
                        let guard = arm.guard.as_ref().map(|g| self.expr(g));
                        let body = Ex::Block(Box::new(self.tdl_block(&arm.body, true)));
                        self.pop_scope();
                        Arm { pat, guard, body }
                    })
                    .collect();
                Self::push_tail(out, Ex::Match(scrutinee, arms));
            }
            Stmt::Block(b) => {
                let b = self.tdl_block(b, true);
                Self::push_tail(out, Ex::Block(Box::new(b)));
            }
            Stmt::For(it) => {
                let iter = self.expr(&it.expr);
                self.push_scope();
                let pat = self.pat(&it.pat);
                let st = self.tdl_loop(
                    it.label.as_ref(),
                    LoopKind::For(pat, iter),
                    &it.body,
                    it.span,
                );
                self.pop_scope();
                Self::push(out, st);
            }
            Stmt::While(it) => {
                self.push_scope();
                let cond = self.expr(&it.cond);
                let st = self.tdl_loop(it.label.as_ref(), LoopKind::While(cond), &it.body, it.span);
                self.pop_scope();
                Self::push(out, st);
            }
            Stmt::Loop(it) => {
                let st = self.tdl_loop(it.label.as_ref(), LoopKind::Loop, &it.body, it.span);
                Self::push(out, st);
            }
        }
    }

    fn if_tdl(&mut self, it: &'a If) -> Ex {
        self.push_scope();
        let cond = self.expr(&it.cond);
        let then = self.tdl_block(&it.then_branch, true);
        self.pop_scope();
        let els = it.else_branch.as_deref().map(|e| {
            Box::new(match e {
                Else::If(next) => self.if_tdl(next),
                Else::Block(b) => Ex::Block(Box::new(self.tdl_block(b, true))),
            })
        });
        Ex::If(Box::new(cond), Box::new(then), els)
    }

    /// A loop; counted loops number their iterations for iteration-indexed tags.
    fn tdl_loop(
        &mut self,
        label: Option<&syn::Lifetime>,
        kind: LoopKind,
        body: &'a AstBlock,
        span: proc_macro2::Span,
    ) -> St {
        let id = self.scope.loop_id(body);
        self.loops.extend(id);
        let inner = self.tdl_block(body, true);
        if id.is_some() {
            self.loops.pop();
        }
        let counter = id.filter(|id| self.scope.is_counted(*id)).map(|id| {
            (
                self.tdl_slot(&format!("tdl_n_{id}")),
                self.tdl_slot(&format!("tdl_i_{id}")),
            )
        });
        St::Loop(Box::new(LoopSt {
            label: label.map(|l| Arc::from(l.ident.to_string())),
            kind,
            body: inner,
            counter,
            loc: self.loc(span),
        }))
    }

    fn fail(&mut self, f: &Fail) -> FailSt {
        let Some(exc) = &f.exception else {
            return FailSt {
                exception: None,
                ancestry: Vec::new(),
                fields: Vec::new(),
            };
        };
        let name = exc.to_string();
        let declared = self.names.exceptions.get(&name).cloned();
        let (ancestry, order) = match declared {
            Some((ancestry, fields)) => (ancestry, fields),
            None => match self.registry.exceptions.get(&name) {
                Some(a) => (
                    a.iter().map(|it| Arc::from(it.as_str())).collect(),
                    Vec::new(),
                ),
                None => {
                    self.error(
                        exc.span(),
                        format!("the exception `{name}` is not declared"),
                        "declare it in the program (`exception Name;`) or register it with `Registry::exception`".into(),
                    );
                    (Vec::new(), Vec::new())
                }
            },
        };
        let mut fields: Vec<(Arc<str>, Ex)> = f
            .fields
            .iter()
            .filter_map(|fv| match &fv.member {
                syn::Member::Named(n) => Some((Arc::from(n.to_string()), self.expr(&fv.expr))),
                syn::Member::Unnamed(_) => None,
            })
            .collect();
        // As the struct prints them: in the order they are declared.
        fields.sort_by_key(|(n, _)| order.iter().position(|o| o == n).unwrap_or(usize::MAX));
        FailSt {
            exception: Some(crate::program::intern(&name)),
            ancestry: ancestry.iter().map(|a| crate::program::intern(a)).collect(),
            fields,
        }
    }

    fn spawn(&mut self, spawn: &'a Spawn) -> St {
        let (var, loops, late) = match self.scope.spawn_def(spawn) {
            Some(info) => (
                info.var.as_ref().map(ToString::to_string),
                info.site.loops.clone(),
                info.late,
            ),
            None => (None, Vec::new(), false),
        };
        let args: Vec<Ex> = spawn.args.iter().map(|a| self.expr(a)).collect();
        let Parts {
            mut steps,
            armed,
            wait,
            outcome,
            name,
            on,
        } = self.spawn_parts(spawn, &loops);
        let task_name = spawn.task.to_string();
        let task = match on {
            None => self.task_call(&spawn.task, args, spawn.span),
            Some(agent) => {
                let kind = match self.file.task(&task_name).map(|t| t.kind) {
                    Some(TaskKind::Goal) => tdl::NodeKind::Goal,
                    _ => tdl::NodeKind::Command,
                };
                Some(TaskCall::Remote {
                    agent,
                    name: Arc::from(task_name.as_str()),
                    kind,
                    args,
                })
            }
        };
        let task = task.unwrap_or(TaskCall::Tdl(usize::MAX, Vec::new()));
        let members: Vec<String> = self
            .frames
            .iter()
            .filter_map(|f| f.members.clone())
            .collect();
        let binds_late = late && var.is_some();
        let needs_id =
            self.scope.uses_previous || !members.is_empty() || !armed.is_empty() || binds_late;
        let mut pre = None;
        let mut id = None;
        if let (Some(var), false) = (&var, late) {
            let slot = self.own_slot(var, &loops, &task_name);
            if needs_id && spawn.binding.is_some() && !loops.is_empty() {
                pre = Some(slot);
                id = Some(NodeEx::Pre);
            } else {
                id = Some(slot);
            }
        }
        if needs_id && spawn.binding.is_some() && id.is_none() {
            pre = Some(NodeEx::Fresh(crate::program::intern(&task_name)));
            id = Some(NodeEx::Pre);
        }
        if let Some(id) = &id {
            steps.push(Step::Fulfils(id.clone()));
        }
        let binding = spawn.binding.as_ref().map(|b| {
            let ty = match (&b.ty, outcome) {
                (Some(ty), _) => self.ty(ty),
                (None, true) => Ty::Ended(Box::new(self.value_type(spawn))),
                (None, false) => self.value_type(spawn),
            };
            let to = match &b.target {
                BindTarget::Let(pat) => BindTo::Let(self.pat(pat)),
                BindTarget::Assign(place) => match self.place(place) {
                    Some(p) => BindTo::Assign(p),
                    None => BindTo::Let(crate::ir::Pat::Wild),
                },
            };
            (to, ty)
        });
        let late = if binds_late {
            var.as_ref().map(|v| self.tdl_slot(v))
        } else {
            None
        };
        let members = members.iter().map(|m| self.tdl_slot(m)).collect();
        let prev = self.scope.uses_previous.then(|| self.tdl_slot(PREV));
        St::Spawn(Box::new(SpawnSt {
            task,
            name,
            pre,
            id: if spawn.binding.is_some() { id } else { None },
            steps,
            armed,
            wait,
            outcome,
            binding,
            late,
            needs_id,
            members,
            prev,
            loc: self.loc(spawn.span),
        }))
    }

    /// The type of a waited spawn's value: the callee's declared result, else unit.
    fn value_type(&mut self, spawn: &Spawn) -> Ty {
        let name = spawn.task.to_string();
        match self.file.task(&name) {
            Some(task) => task.result.as_ref().map_or(Ty::Unit, |t| self.ty(t)),
            None => match self.names.externs.get(&name) {
                Some((_, result)) => result.clone().unwrap_or(Ty::Unit),
                None => Ty::Any,
            },
        }
    }

    /// The node of a spawn held in the TDL slot `var`: the reservation, or, inside loops, this
    /// iteration's entry of the map.
    fn own_slot(&mut self, var: &str, loops: &[tdl_syntax::hir::LoopId], name: &str) -> NodeEx {
        let slot = self.tdl_slot(var);
        if loops.is_empty() {
            return NodeEx::Reserved(slot);
        }
        let keys = loops
            .iter()
            .map(|l| crate::ir::KeyEx::Current(self.tdl_slot(&format!("tdl_i_{l}"))))
            .collect();
        NodeEx::Slot(slot, keys, crate::program::intern(name))
    }

    /// The builder steps of a spawn inside the loops `loops`, from the constraints of the
    /// enclosing groups (outermost first, each with its own `previous`), then its own.
    fn spawn_parts(&mut self, spawn: &'a Spawn, loops: &[tdl_syntax::hir::LoopId]) -> Parts {
        let mut lists: Vec<(&'a [Constraint], String)> = self
            .frames
            .iter()
            .map(|f| (f.constraints, f.prev.clone()))
            .collect();
        lists.push((&spawn.constraints, PREV.to_string()));
        let mut parts = Parts::default();
        for (list, prev) in &lists {
            for c in *list {
                let step = match &c.kind {
                    ConstraintKind::Wait => {
                        parts.wait = true;
                        continue;
                    }
                    ConstraintKind::Outcome => {
                        parts.wait = true;
                        parts.outcome = true;
                        continue;
                    }
                    ConstraintKind::Propagate => Step::Propagate,
                    ConstraintKind::Approval(t) => {
                        Step::Approval(t.as_ref().map(|t| self.duration(t)))
                    }
                    ConstraintKind::Name(e) => {
                        let mut e = e;
                        while let syn::Expr::Paren(inner) = e {
                            e = &inner.expr;
                        }
                        parts.name = Some(self.expr(e));
                        continue;
                    }
                    ConstraintKind::Parent(e) => Step::Under(self.expr(e)),
                    ConstraintKind::OnAgent(e) => {
                        parts.on = Some(self.expr(e));
                        continue;
                    }
                    ConstraintKind::OnTerminate(it) => {
                        let args = it.args.iter().map(|a| self.expr(a)).collect();
                        let Some(call) = self.task_call(&it.task, args, c.span) else {
                            continue;
                        };
                        let var = self
                            .scope
                            .cleanup(it)
                            .and_then(|c| c.var.as_ref())
                            .map(ToString::to_string);
                        let fulfils = var.map(|v| self.own_slot(&v, loops, &it.task.to_string()));
                        Step::OnTerminate(call, fulfils)
                    }
                    ConstraintKind::ExceptionHandler(it) => match self.handler_call(it, c.span) {
                        Some(h) => Step::Handler(h),
                        None => continue,
                    },
                    ConstraintKind::MaximumActivate(n) => {
                        Step::MaxActivations(self.count(n, c.span))
                    }
                    ConstraintKind::MaximumTrigger(n) => Step::MaxTriggers(self.count(n, c.span)),
                    ConstraintKind::Period(t) => Step::Period(self.duration(t)),
                    ConstraintKind::Uses(list) => {
                        for it in list {
                            let (r, n) = self.uses(it);
                            parts.steps.push(Step::Uses(r, n));
                        }
                        continue;
                    }
                    ConstraintKind::Priority(p) => Step::Priority(self.priority(p)),
                    ConstraintKind::DenyIfBusy => Step::DenyIfBusy,
                    _ => {
                        match self.lower_constraint(c, prev) {
                            Some(crate::ir::Lowered::Each { nodes, low, empty }) => {
                                parts.steps.push(Step::Low(nodes, low, empty));
                            }
                            Some(entity) => parts.armed.push(entity),
                            None => {}
                        }
                        continue;
                    }
                };
                parts.steps.push(step);
            }
        }
        parts
    }

    fn with(&mut self, group: &'a WithGroup) -> St {
        let index = self.scope.group_id(group).unwrap_or_default();
        let label_var = self
            .scope
            .groups
            .get(index)
            .and_then(|it| it.var.as_ref())
            .map(ToString::to_string);
        let members = match &label_var {
            Some(var) => Some(var.clone()),
            None if self.scope.uses_previous => Some(format!("tdl_group_{index}")),
            None => None,
        };
        // The enclosing group sees this group as one entity: its `previous`, for every spawn in
        // here, is the entity before this group.
        let mut saved = None;
        let mut snapshot = None;
        if let Some(parent) = self.frames.last() {
            if uses_previous(parent.constraints) {
                let name = format!("tdl_prev_{index}");
                snapshot = Some((self.tdl_slot(PREV), self.tdl_slot(&name)));
                let last = self.frames.len() - 1;
                saved = Some(std::mem::replace(&mut self.frames[last].prev, name));
            }
        }
        self.frames.push(Frame {
            constraints: &group.constraints,
            prev: PREV.to_string(),
            members: members.clone(),
        });
        let body = self.tdl_block(&group.body, true);
        self.frames.pop();
        if let Some(saved) = saved {
            let last = self.frames.len() - 1;
            self.frames[last].prev = saved;
        }
        let members = members.map(|m| self.tdl_slot(&m));
        let prev = (self.scope.uses_previous && members.is_some()).then(|| self.tdl_slot(PREV));
        St::With(Box::new(WithSt {
            members,
            snapshot,
            body,
            prev,
        }))
    }

    fn constrain(&mut self, stmt: &ConstraintStmt) -> Option<ConstrainSt> {
        let target = match &stmt.tag.kind {
            TagKind::Parent => Nodes::One(NodeEx::Own),
            TagKind::Child => return None,
            _ => self.nodes(&stmt.tag, PREV),
        };
        let c = &stmt.constraint;
        Some(match &c.kind {
            ConstraintKind::Wait => ConstrainSt::Wait(target),
            ConstraintKind::Trigger {
                when: When::Now,
                then: Then::Terminate,
            } => ConstrainSt::Terminate(target),
            ConstraintKind::MaximumActivate(n) => {
                ConstrainSt::MaxActivations(target, self.count(n, c.span))
            }
            ConstraintKind::MaximumTrigger(n) => {
                ConstrainSt::MaxTriggers(target, self.count(n, c.span))
            }
            ConstraintKind::Period(t) => ConstrainSt::Period(target, self.duration(t)),
            ConstraintKind::Parallel
            | ConstraintKind::Name(_)
            | ConstraintKind::OnTerminate(_)
            | ConstraintKind::ExceptionHandler(_)
            | ConstraintKind::Parent(_)
            | ConstraintKind::OnAgent(_)
            | ConstraintKind::Outcome
            | ConstraintKind::Propagate
            | ConstraintKind::Approval(_)
            | ConstraintKind::Uses(_)
            | ConstraintKind::Priority(_)
            | ConstraintKind::DenyIfBusy => return None,
            _ => ConstrainSt::Apply(target, self.lower_constraint(c, PREV)?),
        })
    }
}

#[allow(dead_code)]
fn unit() -> Ex {
    Ex::Lit(Value::Unit)
}
