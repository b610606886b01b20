//! One task body compiled to the checker's instructions ([`crate::ir`]): its statements, spawns,
//! groups and constraint statements, its tags as the front end resolved them (`tdl_syntax::hir`).
//! Rust statements are in `rust.rs`.

use std::collections::{BTreeMap, BTreeSet};

use tcm_core::{Facet, Outcome, Point, Then};
use tdl_syntax::{ast, hir};

use super::rust::idents;
use super::{Builder, EnvTarget, LoadError, facet, line_of};
use crate::ir::{
    Body, CIr, EventIr, GroupId, GroupIr, IndexIr, Iter, LoopId, MonitorOverride, Op, ResOp,
    SpawnIr, StmtIr, StmtOp, TagDef, TagId, TagKind, TagOf, TagRef, TagUse, TagUseOf, UsesIr, Wait,
    WhenIr,
};
use crate::value::Sym;

/// Compiles one body.
pub(super) struct BodyCompiler<'b, 's, 'a> {
    pub(super) b: &'b mut Builder,
    pub(super) file: usize,
    pub(super) task: String,
    /// The body's names, resolved by the front end.
    pub(super) scope: &'s hir::BodyScope<'a>,
    pub(super) body: Body,
    /// Tags created, by what they name.
    pub(super) tags: BTreeMap<TagOf, TagId>,
    /// Tags named by a statement that terminates their node.
    pub(super) terminated: BTreeSet<TagId>,
    // Compilation state.
    pub(super) n_spawns: usize,
    pub(super) n_groups: usize,
    pub(super) n_loops: u16,
    pub(super) loops: Vec<LoopFrame>,
    pub(super) groups: Vec<GroupId>,
}

pub(super) struct LoopFrame {
    pub(super) id: LoopId,
    pub(super) label: Option<String>,
    pub(super) test: u32,
    /// `break` sites to patch with the exit.
    pub(super) breaks: Vec<usize>,
}

impl<'b, 's, 'a> BodyCompiler<'b, 's, 'a> {
    pub(super) fn new(
        b: &'b mut Builder,
        file: usize,
        task: &str,
        scope: &'s hir::BodyScope<'a>,
    ) -> Self {
        BodyCompiler {
            b,
            file,
            task: task.to_owned(),
            scope,
            body: Body::default(),
            tags: BTreeMap::new(),
            terminated: BTreeSet::new(),
            n_spawns: 0,
            n_groups: 0,
            n_loops: 0,
            loops: Vec::new(),
            groups: Vec::new(),
        }
    }

    pub(super) fn unsupported(&self, line: u32, what: impl Into<String>) -> LoadError {
        LoadError::Unsupported {
            file: self.b.prog.files[self.file].clone(),
            line,
            what: what.into(),
        }
    }

    /// `set VAR = value;`: a literal is set as it is; a value computed in Rust is a choice among
    /// the values the environment declaration gives the variable, or `true` and `false` for a
    /// `bool`; another is left as it is, with a note.
    pub(super) fn set_state(&mut self, it: &ast::SetState) {
        let line = line_of(it.span);
        let name = it.name.to_string();
        let Some(var) = self.b.state(&name) else {
            return; // The diagnosis refused the program already.
        };
        let def = &self.b.prog.states[var as usize];
        let ty = def.ty;
        let values = match literal(&it.value) {
            Some(v) => vec![v.coerce(ty).unwrap_or(tcm_core::Value::Unknown)],
            None => {
                let declared: Vec<tcm_core::Value> = self
                    .b
                    .prog
                    .environment
                    .iter()
                    .flatten()
                    .filter(|e| matches!(e.target, EnvTarget::State(v) if v == var))
                    .flat_map(|e| e.values.iter().cloned())
                    .collect();
                if !declared.is_empty() {
                    declared
                } else if ty == tcm_core::Type::Bool {
                    vec![false.into(), true.into()]
                } else {
                    self.note(
                        line,
                        format!(
                            "the value of `set {name} = …` is computed in Rust: the checker leaves \
                             `{name}` as it is (give its values in the environment declaration to \
                             explore them)"
                        ),
                    );
                    Vec::new()
                }
            }
        };
        self.emit(Op::SetState { var, values }, line);
    }

    pub(super) fn note(&mut self, line: u32, what: impl std::fmt::Display) {
        let n = format!(
            "{}:{line}: {what} (in `{}`)",
            self.b.prog.files[self.file], self.task
        );
        self.b.prog.notes.push(n);
    }

    /// The tag of what `def` names, created on first use.
    pub(super) fn tag_of(&mut self, def: hir::Def<'_>) -> TagId {
        let scope = self.scope;
        let loops_of = |spawn: usize| -> Vec<LoopId> {
            scope.spawns.get(spawn).map_or_else(Vec::new, |it| {
                let loops = it.site.loops.iter();
                loops
                    .map(|l| LoopId::try_from(*l).unwrap_or(LoopId::MAX))
                    .collect()
            })
        };
        let (kind, of, loops, reserve_as) = match def {
            hir::Def::Spawn(i) => (
                TagKind::Spawn,
                TagOf::Spawn(i),
                loops_of(i),
                scope.spawns[i].spawn.task.to_string(),
            ),
            hir::Def::Group(i) => (TagKind::Group, TagOf::Group(i), Vec::new(), String::new()),
            hir::Def::OnTerminate(id) => {
                let cleanup = &scope.cleanups[id];
                (
                    TagKind::OnTerminate,
                    TagOf::OnTerminate(cleanup.spawn, cleanup.index),
                    loops_of(cleanup.spawn),
                    cleanup.on_terminate.task.to_string(),
                )
            }
            hir::Def::Bound(bind) => (
                TagKind::Bound,
                TagOf::Bound(bind.name.to_string()),
                Vec::new(),
                String::new(),
            ),
        };
        if let Some(t) = self.tags.get(&of) {
            return *t;
        }
        let next = TagId::try_from(self.body.tags.len()).unwrap_or(TagId::MAX);
        self.tags.insert(of.clone(), next);
        self.body.tags.push(TagDef {
            kind,
            loops,
            reserve_as,
            of,
        });
        next
    }

    /// Keeps what a tag written in a constraint was taken for.
    pub(super) fn used(&mut self, tag: &ast::Tag, of: TagUseOf) {
        let at = tag.span.start();
        self.body.tag_uses.push(TagUse {
            line: at.line,
            column: at.column,
            tag: of,
        });
    }

    pub(super) fn tag(&mut self, tag: &ast::Tag) -> TagRef {
        match &tag.kind {
            ast::TagKind::Previous => TagRef::Previous,
            ast::TagKind::Child => {
                self.used(tag, TagUseOf::This);
                TagRef::This
            }
            ast::TagKind::Parent => {
                self.used(tag, TagUseOf::Parent);
                TagRef::Parent
            }
            ast::TagKind::Named { indexes, .. } => {
                let Some(named) = self.scope.named(tag) else {
                    self.used(tag, TagUseOf::Unknown);
                    return TagRef::Opaque;
                };
                let id = self.tag_of(named.def);
                self.used(tag, TagUseOf::Tag(id));
                let def = &self.body.tags[id as usize];
                if matches!(def.kind, TagKind::Bound) {
                    return TagRef::Opaque;
                }
                let site = def.loops.clone();
                let idx = indexes
                    .iter()
                    .enumerate()
                    .map(|(i, ix)| match ix {
                        ast::TagIndex::Current => {
                            IndexIr::Current(site.get(i).copied().unwrap_or_default())
                        }
                        ast::TagIndex::Expr(e) => IndexIr::Expr(self.b.lower(e)),
                    })
                    .collect();
                TagRef::Named(id, idx)
            }
        }
    }

    pub(super) fn event(&mut self, e: &ast::Event) -> EventIr {
        let (point, outcome) = match e.point {
            ast::Point::Enabled => (Point::Enabled, None),
            ast::Point::Active => (Point::Active, None),
            ast::Point::Completed => (Point::Completed, None),
            ast::Point::Succeeded => (Point::Completed, Some(Outcome::Succeeded)),
            ast::Point::Failed => (Point::Completed, Some(Outcome::Failed)),
            ast::Point::Terminated => (Point::Completed, Some(Outcome::Terminated)),
        };
        let f = match (e.facet, point, outcome) {
            (_, _, Some(_)) => Facet::Execution,
            (Some(f), _, None) => facet(f),
            (None, Point::Completed, None) => Facet::Execution,
            (None, _, None) => Facet::Handling,
        };
        EventIr {
            tag: self.tag(&e.tag),
            facet: f,
            point,
            outcome,
        }
    }

    pub(super) fn when(&mut self, w: &ast::When, line: u32) -> WhenIr {
        match w {
            ast::When::Now => WhenIr::Now,
            ast::When::At(t) => WhenIr::At(t.nanos_since_midnight()),
            ast::When::In(t) => WhenIr::In(self.b.time(t)),
            ast::When::Event(e) => WhenIr::Event(self.event(e)),
            ast::When::After(t, e) => {
                let t = self.b.time(t);
                WhenIr::After(t, self.event(e))
            }
            ast::When::External(ast::ExternalName::Lit(l)) => {
                let name = l.value();
                if !self.b.prog.external_events.contains(&name) {
                    self.b.prog.external_events.push(name.clone());
                }
                WhenIr::External(Some(name))
            }
            ast::When::External(ast::ExternalName::Expr(_)) => {
                let name = format!("(computed at {}:{line})", self.b.prog.files[self.file]);
                self.note(line, "an external event's name is computed in Rust: the checker raises it as one event of its own");
                if !self.b.prog.external_events.contains(&name) {
                    self.b.prog.external_events.push(name.clone());
                }
                WhenIr::External(Some(name))
            }
            ast::When::Condition(c) => WhenIr::Condition(c.to_expr()),
            ast::When::Changed(v) => WhenIr::Changed(v.to_string()),
        }
    }

    /// A constraint that waits or triggers, as the checker applies it; `None` for the others.
    /// A spawn's or a group's `uses`, `priority` or `deny if busy`, into `uses`.
    pub(super) fn uses(&mut self, uses: &mut UsesIr, c: &ast::Constraint) {
        match &c.kind {
            ast::ConstraintKind::Uses(list) => {
                for it in list {
                    match self.b.resource_amount(it) {
                        Some(u) => uses.amounts.push(u),
                        None => self.note(
                            line_of(c.span),
                            format!(
                                "`uses {}` left out: the program does not declare the resource",
                                it.name
                            ),
                        ),
                    }
                }
            }
            ast::ConstraintKind::Priority(p) => uses.priority = Some(self.b.priority(p)),
            ast::ConstraintKind::DenyIfBusy => uses.deny_if_busy = true,
            _ => {}
        }
    }

    pub(super) fn constraint(&mut self, c: &ast::Constraint) -> Option<CIr> {
        let line = line_of(c.span);
        Some(match &c.kind {
            ast::ConstraintKind::ExpandFirst => CIr::ExpandFirst,
            ast::ConstraintKind::DelayExpansion => CIr::DelayExpansion,
            ast::ConstraintKind::Sequential { facet: f, tag } => {
                let t = tag.as_ref().map_or(TagRef::Previous, |t| self.tag(t));
                CIr::Sequential(facet(*f), t)
            }
            ast::ConstraintKind::Serial { tag } => {
                CIr::Serial(tag.as_ref().map_or(TagRef::Previous, |t| self.tag(t)))
            }
            ast::ConstraintKind::Trigger { when, then } => {
                let then = match then {
                    ast::Then::Enable(f) => Then::Enable(facet(f.unwrap_or(ast::Facet::Handling))),
                    ast::Then::Terminate => Then::Terminate,
                    ast::Then::Activate => Then::Activate,
                    ast::Then::Skip => Then::Skip,
                    ast::Then::Invariant => Then::Invariant,
                    ast::Then::Pause => Then::Pause,
                };
                CIr::Trigger {
                    when: self.when(when, line),
                    then,
                }
            }
            ast::ConstraintKind::Uses(_)
            | ast::ConstraintKind::Priority(_)
            | ast::ConstraintKind::DenyIfBusy => {
                self.note(
                    line,
                    "a resource constraint given as a statement is left out",
                );
                return None;
            }
            _ => return None,
        })
    }

    pub(super) fn monitor_param(&mut self, m: &mut MonitorOverride, c: &ast::Constraint) -> bool {
        match &c.kind {
            ast::ConstraintKind::MaximumActivate(n) => m.max_activations = Some(self.b.count(n)),
            ast::ConstraintKind::MaximumTrigger(n) => m.max_triggers = Some(self.b.count(n)),
            ast::ConstraintKind::Period(p) => m.period = Some(self.b.time(p)),
            _ => return false,
        }
        true
    }

    pub(super) fn emit(&mut self, op: Op, line: u32) -> usize {
        self.body.ops.push(op);
        self.body.lines.push(line);
        self.body.ops.len() - 1
    }

    pub(super) fn pc(&self) -> u32 {
        u32::try_from(self.body.ops.len()).unwrap_or(u32::MAX)
    }

    pub(super) fn finish(&mut self) {
        self.body.n_loops = self.n_loops;
        for s in &mut self.body.spawns {
            if s.tag.is_some_and(|t| self.terminated.contains(&t)) {
                s.terminable = true;
            }
        }
    }

    pub(super) fn block(&mut self, stmts: &[ast::Stmt]) -> Result<(), LoadError> {
        for s in stmts {
            self.stmt(s)?;
        }
        Ok(())
    }

    pub(super) fn stmt(&mut self, s: &ast::Stmt) -> Result<(), LoadError> {
        match s {
            ast::Stmt::Set(it) => self.set_state(it),
            ast::Stmt::Raise(it) => {
                let line = line_of(it.span);
                let name = match &it.name {
                    ast::ExternalName::Lit(l) => l.value(),
                    ast::ExternalName::Expr(_) => {
                        self.note(line, "a raised event's name is computed in Rust: the checker takes it for one event of its own");
                        format!("(computed at {}:{line})", self.b.prog.files[self.file])
                    }
                };
                let i = self.b.external_event(name);
                self.emit(Op::Raise(i), line);
            }
            // A line for the run's log: it changes nothing the checker explores.
            ast::Stmt::Log(_) => {}
            ast::Stmt::Rust(r) => self.rust(&r.tokens, line_of(r.span)),
            ast::Stmt::Spawn(sp) => self.spawn(sp)?,
            ast::Stmt::With(g) => self.with(g)?,
            ast::Stmt::Constrain(cs) => self.constrain(cs),
            ast::Stmt::Bind(bd) => {
                let line = line_of(bd.span);
                self.note(
                    line,
                    format!(
                        "`bind {}`: the node is Rust's, so constraints on the tag are left out",
                        bd.name
                    ),
                );
                if let hir::Resolution::Named(named) = self.scope.lookup(&bd.name.to_string()) {
                    let t = self.tag_of(named.def);
                    self.emit(Op::Bind(t), line);
                }
            }
            ast::Stmt::Succeed(span) => {
                self.emit(Op::Succeed, line_of(*span));
            }
            ast::Stmt::Resource(r) => {
                let line = line_of(r.span);
                match self.b.resource(&r.name.to_string()) {
                    Some(i) => {
                        let op = match r.op {
                            ast::ResourceOp::Lock => ResOp::Lock,
                            ast::ResourceOp::Unlock => ResOp::Unlock,
                            ast::ResourceOp::Reserve => ResOp::Reserve,
                            ast::ResourceOp::Unreserve => ResOp::Unreserve,
                        };
                        self.emit(Op::Resource(op, i), line);
                    }
                    None => self.note(
                        line,
                        format!(
                            "`{} {}` left out: the program does not declare the resource",
                            r.op.as_str(),
                            r.name
                        ),
                    ),
                }
            }
            ast::Stmt::Fail(f) => {
                let e = f.exception.as_ref().map(|e| e.to_string());
                self.emit(Op::Fail(e), line_of(f.span));
            }
            ast::Stmt::Bypass(span) => {
                self.emit(Op::Bypass, line_of(*span));
            }
            ast::Stmt::Trigger(span) => {
                self.emit(Op::Trigger, line_of(*span));
            }
            ast::Stmt::Retry(r) => {
                if r.args.is_some() {
                    self.note(
                        line_of(r.span),
                        "`retry with (…)` runs the task again with its first arguments",
                    );
                }
                self.emit(Op::Retry, line_of(r.span));
            }
            ast::Stmt::If(it) => self.if_(it)?,
            ast::Stmt::For(f) => {
                let line = line_of(f.span);
                let iter = self.for_iter(&f.pat, &f.expr);
                let label = f.label.as_ref().map(|l| l.ident.to_string());
                self.looped(iter, label, &f.body, line)?;
            }
            ast::Stmt::While(w) => {
                let line = line_of(w.span);
                let cond = self.b.lower(&w.cond);
                let label = w.label.as_ref().map(|l| l.ident.to_string());
                self.looped(Iter::While(cond), label, &w.body, line)?;
            }
            ast::Stmt::Loop(l) => {
                let line = line_of(l.span);
                let label = l.label.as_ref().map(|l| l.ident.to_string());
                self.looped(Iter::Forever, label, &l.body, line)?;
            }
            ast::Stmt::Match(m) => {
                let line = line_of(m.span);
                let at = self.emit(Op::Match(Vec::new()), line);
                let mut arms = Vec::new();
                let mut ends = Vec::new();
                for arm in &m.arms {
                    arms.push(self.pc());
                    self.block(&arm.body.stmts)?;
                    ends.push(self.emit(Op::Jump(0), line));
                }
                let end = self.pc();
                for e in ends {
                    self.body.ops[e] = Op::Jump(end);
                }
                self.body.ops[at] = Op::Match(arms);
            }
            ast::Stmt::Block(bl) => self.block(&bl.stmts)?,
        }
        Ok(())
    }

    pub(super) fn spawn(&mut self, sp: &ast::Spawn) -> Result<(), LoadError> {
        let line = line_of(sp.span);
        let index = self.n_spawns;
        self.n_spawns += 1;
        let call = self.b.call(&sp.task, &sp.args);
        let mut ir = SpawnIr {
            call,
            tag: None,
            groups: self.groups.clone(),
            cons: Vec::new(),
            wait: Wait::No,
            propagate: false,
            approval: None,
            name: None,
            handlers: Vec::new(),
            on_terminate: Vec::new(),
            monitor: MonitorOverride::default(),
            uses: UsesIr::default(),
            terminable: false,
            remote: false,
            line,
        };
        let mut outcome = false;
        let mut wait = false;
        for c in &sp.constraints {
            let cline = line_of(c.span);
            if self.monitor_param(&mut ir.monitor, c) {
                continue;
            }
            match &c.kind {
                ast::ConstraintKind::Wait => wait = true,
                ast::ConstraintKind::Outcome => outcome = true,
                ast::ConstraintKind::Propagate => ir.propagate = true,
                ast::ConstraintKind::Approval(t) => {
                    ir.approval = Some(t.as_ref().map(|t| self.b.time(t)));
                }
                ast::ConstraintKind::Parallel => {}
                ast::ConstraintKind::Name(e) => ir.name = Some(self.b.lower(e)),
                ast::ConstraintKind::Parent(_) => {
                    return Err(self.unsupported(cline, "`parent` (a spawn under another node)"));
                }
                // Runs on an agent: a command of the checker's choice, which may also lose its
                // agent (docs/verification.md, "Commands").
                ast::ConstraintKind::OnAgent(_) => ir.remote = true,
                ast::ConstraintKind::ExceptionHandler(h) => {
                    let u = self.b.handler_use(h, self.file, cline)?;
                    ir.handlers.push(u);
                }
                ast::ConstraintKind::OnTerminate(o) => {
                    let call = self.b.call(&o.task, &o.args);
                    let tag = self.cleanup_tag(o);
                    ir.on_terminate.push((call, tag));
                }
                ast::ConstraintKind::Uses(_)
                | ast::ConstraintKind::Priority(_)
                | ast::ConstraintKind::DenyIfBusy => self.uses(&mut ir.uses, c),
                _ => {
                    if let Some(ci) = self.constraint(c) {
                        ir.terminable |= ci.terminates();
                        ir.cons.push(ci);
                    }
                }
            }
        }
        ir.wait = match (&sp.binding, outcome, wait) {
            (Some(_), true, _) => Wait::Outcome,
            (Some(_), false, _) => Wait::Value,
            (None, _, true) => Wait::Plain,
            (None, _, false) => Wait::No,
        };
        for g in &self.groups {
            let gi = &self.body.groups[*g as usize];
            ir.terminable |= gi.terminable;
            if gi.wait && ir.wait == Wait::No {
                ir.wait = Wait::Plain;
            }
            ir.propagate |= gi.propagate;
            ir.remote |= gi.remote;
        }
        // Its own tag, if some tag or `node!` of the body names it (references may come later
        // in the body: the front end resolved them all).
        if self.scope.spawn_def(sp).is_some_and(|it| it.var.is_some()) {
            ir.tag = Some(self.tag_of(hir::Def::Spawn(index)));
        }
        let binds = match &sp.binding {
            Some(b) => match &b.target {
                ast::BindTarget::Let(p) => {
                    let mut names = Vec::new();
                    idents(&quote::ToTokens::to_token_stream(p), &mut names);
                    names
                }
                ast::BindTarget::Assign(e) => {
                    let mut names = Vec::new();
                    idents(&quote::ToTokens::to_token_stream(e), &mut names);
                    names
                }
            },
            None => Vec::new(),
        };
        let sid = u32::try_from(self.body.spawns.len()).unwrap_or(u32::MAX);
        self.body.spawns.push(ir);
        self.emit(Op::Spawn(sid), line);
        let syms: Vec<Sym> = binds.iter().map(|n| self.b.sym(n)).collect();
        if !syms.is_empty() {
            self.emit(Op::Forget(syms), line);
        }
        Ok(())
    }

    /// The tag of a labelled on-terminate task, when its first label names it.
    pub(super) fn cleanup_tag(&mut self, o: &ast::OnTerminate) -> Option<TagId> {
        let label = o.labels.first()?;
        let id = self.scope.cleanup_id(o)?;
        match self.scope.lookup(&label.to_string()) {
            hir::Resolution::Named(named) if matches!(named.def, hir::Def::OnTerminate(it) if it == id) => {
                Some(self.tag_of(named.def))
            }
            _ => None,
        }
    }

    pub(super) fn with(&mut self, g: &ast::WithGroup) -> Result<(), LoadError> {
        let line = line_of(g.span);
        let index = self.n_groups;
        self.n_groups += 1;
        let mut ir = GroupIr {
            cons: Vec::new(),
            monitor: MonitorOverride::default(),
            uses: UsesIr::default(),
            wait: false,
            propagate: false,
            terminable: false,
            remote: false,
            uses_previous: false,
            tag: None,
        };
        for c in &g.constraints {
            if self.monitor_param(&mut ir.monitor, c) {
                continue;
            }
            match &c.kind {
                ast::ConstraintKind::Wait => ir.wait = true,
                ast::ConstraintKind::Propagate => ir.propagate = true,
                ast::ConstraintKind::OnAgent(_) => ir.remote = true,
                ast::ConstraintKind::Parallel | ast::ConstraintKind::Name(_) => {}
                ast::ConstraintKind::Uses(_)
                | ast::ConstraintKind::Priority(_)
                | ast::ConstraintKind::DenyIfBusy => self.uses(&mut ir.uses, c),
                _ => {
                    if let Some(ci) = self.constraint(c) {
                        ir.terminable |= ci.terminates();
                        ir.uses_previous |= ci.uses_previous();
                        ir.cons.push(ci);
                    }
                }
            }
        }
        if self
            .scope
            .groups
            .get(index)
            .is_some_and(|it| it.var.is_some())
        {
            ir.tag = Some(self.tag_of(hir::Def::Group(index)));
        }
        let gid = GroupId::try_from(self.body.groups.len()).unwrap_or(GroupId::MAX);
        self.body.groups.push(ir);
        self.emit(Op::GroupStart(gid), line);
        self.groups.push(gid);
        self.block(&g.body.stmts)?;
        self.groups.pop();
        self.emit(Op::GroupEnd(gid), line);
        Ok(())
    }

    pub(super) fn constrain(&mut self, cs: &ast::ConstraintStmt) {
        let line = line_of(cs.span);
        let target = self.tag(&cs.tag);
        let c = &cs.constraint;
        let op = match &c.kind {
            ast::ConstraintKind::Wait => StmtOp::Wait,
            ast::ConstraintKind::Trigger {
                when: ast::When::Now,
                then: ast::Then::Terminate,
            } => StmtOp::Terminate,
            ast::ConstraintKind::MaximumActivate(n) => StmtOp::MaxActivations(self.b.count(n)),
            ast::ConstraintKind::MaximumTrigger(n) => StmtOp::MaxTriggers(self.b.count(n)),
            ast::ConstraintKind::Period(p) => StmtOp::Period(self.b.time(p)),
            _ => match self.constraint(c) {
                Some(ci) => StmtOp::Constrain(ci),
                None => return,
            },
        };
        let terminates = matches!(op, StmtOp::Terminate)
            || matches!(&op, StmtOp::Constrain(ci) if ci.terminates());
        if let (true, TagRef::Named(t, _)) = (terminates, &target) {
            self.terminated.insert(*t);
        }
        let sid = u32::try_from(self.body.stmts.len()).unwrap_or(u32::MAX);
        self.body.stmts.push(StmtIr { target, op });
        self.emit(Op::Stmt(sid), line);
    }
}

/// The value of a literal Rust expression (`true`, `3`, `-2.5`, `"text"`), if it is one.
fn literal(e: &syn::Expr) -> Option<tcm_core::Value> {
    match e {
        syn::Expr::Lit(l) => match &l.lit {
            syn::Lit::Bool(b) => Some(b.value.into()),
            syn::Lit::Int(i) => i.base10_parse::<i64>().ok().map(Into::into),
            syn::Lit::Float(f) => f.base10_parse::<f64>().ok().map(Into::into),
            syn::Lit::Str(s) => Some(s.value().into()),
            _ => None,
        },
        syn::Expr::Unary(u) if matches!(u.op, syn::UnOp::Neg(_)) => match literal(&u.expr)? {
            tcm_core::Value::Int(i) => i.checked_neg().map(Into::into),
            tcm_core::Value::Float(x) => Some((-x).into()),
            _ => None,
        },
        syn::Expr::Paren(p) => literal(&p.expr),
        _ => None,
    }
}
