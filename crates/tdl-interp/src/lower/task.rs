//! One task definition lowered ([`lower_task`]): its parameters, its task-level constraints as
//! the modifiers and monitor parameters the generator gives it (`codegen.rs`, `task_items`, in
//! the same order), what a handler binds (the caught exception, `failing`, `attached`), its
//! persistent variables, and its body (`lower/body.rs`).

use std::sync::Arc;

use tdl_syntax::Diagnostic;
use tdl_syntax::ast::{Facet, Task, TaskConstraintKind, TaskKind};
use tdl_syntax::hir::FileScope;

use super::{Lower, ProgramNames};
use crate::ir::{HandlerCall, Modifier, TaskCall, TaskDef};
use crate::registry::Registry;
use crate::ty::Ty;

/// Lowers `task`, a task of the file `file` named `file_name`.
pub(crate) fn lower_task(
    registry: &Registry,
    names: &ProgramNames,
    file: &FileScope<'_>,
    file_name: &str,
    task: &Task,
    diags: &mut Vec<Diagnostic>,
) -> TaskDef {
    let scope = file.body(task);
    let mut l = Lower::new(registry, names, file, file_name, scope, diags);
    let mut params: Vec<(Arc<str>, _)> = Vec::new();
    for arg in &task.args {
        let ty = l.ty(&arg.ty);
        l.check_type(&ty, arg.name.span());
        l.declare(&arg.name.to_string());
        params.push((Arc::from(arg.name.to_string()), ty));
    }
    let result = task.result.as_ref().map(|t| {
        let ty = l.ty(t);
        l.check_type(&ty, task.name.span());
        ty
    });
    let mut def = TaskDef {
        name: crate::program::intern(&task.name.to_string()),
        kind: task.kind,
        shown: params.iter().cloned().collect(),
        params,
        result,
        persistent: task.persistent && task.kind != TaskKind::Handler,
        blocking: task.blocking.is_some(),
        idempotent: task.idempotent,
        modifiers: Vec::new(),
        monitor: tdl::Monitor::default(),
        monitor_counts: (None, None),
        handles: task.handles.as_ref().map(|h| Arc::from(h.to_string())),
        caught: None,
        failing: None,
        attached: None,
        for_task: task.for_task.as_ref().map(|t| Arc::from(t.to_string())),
        tap: task
            .tap
            .as_ref()
            .map(|t| (t.after, Arc::from(t.target.to_string()))),
        persistents: Vec::new(),
        prelude: Vec::new(),
        body: crate::ir::Block::default(),
        holds: true,
        awaits: true,
        locals: 0,
        tdl_slots: 0,
        loc: l.loc(task.name.span()),
    };
    for c in &task.constraints {
        let span = c.span;
        match &c.kind {
            TaskConstraintKind::ExpandFirst if task.kind == TaskKind::Monitor => {
                def.monitor.each.expand_first = true;
            }
            TaskConstraintKind::DelayExpansion if task.kind == TaskKind::Monitor => {
                def.monitor.each.delay_expansion = true;
            }
            TaskConstraintKind::ExpandFirst => def.modifiers.push(Modifier::ExpandFirst),
            TaskConstraintKind::DelayExpansion => def.modifiers.push(Modifier::DelayExpansion),
            TaskConstraintKind::OnTerminate(it) => {
                let args = it.args.iter().map(|a| l.expr(a)).collect();
                if let Some(call) = l.task_call(&it.task, args, span) {
                    def.modifiers.push(Modifier::OnTerminate(call));
                }
            }
            TaskConstraintKind::ExceptionHandler(it) => {
                if let Some(h) = l.handler_call(it, span) {
                    def.modifiers.push(Modifier::Handler(h));
                }
            }
            TaskConstraintKind::MaximumActivate(n) => {
                let n = l.count(n, span);
                match task.kind {
                    TaskKind::Handler => def.modifiers.push(Modifier::MaxActivations(n)),
                    _ => def.monitor_counts.0 = Some(n),
                }
            }
            TaskConstraintKind::MaximumTrigger(n) => def.monitor_counts.1 = Some(l.count(n, span)),
            TaskConstraintKind::Period(t) => match l.duration(t) {
                crate::ir::DurEx::Fixed(d) => def.monitor.period = Some(d),
                crate::ir::DurEx::Secs(_) => {
                    l.unsupported(span, "a computed monitor period");
                }
            },
            TaskConstraintKind::Uses(list) => {
                for it in list {
                    let (r, n) = l.uses(it);
                    def.modifiers.push(Modifier::Uses(r, n));
                }
            }
            TaskConstraintKind::Priority(p) => {
                def.modifiers.push(Modifier::Priority(l.priority(p)))
            }
            TaskConstraintKind::InitialWait => def.monitor.initial_wait = true,
            TaskConstraintKind::Serial => def.monitor.each.serial = true,
            TaskConstraintKind::Sequential(Facet::Execution) => {
                def.monitor.each.sequential_execution = true;
            }
            TaskConstraintKind::Sequential(_) => def.monitor.each.sequential_expansion = true,
            TaskConstraintKind::Persistent(_) => {}
        }
    }
    // Persistent variables, in order; their initial values see the parameters.
    for c in &task.constraints {
        if let TaskConstraintKind::Persistent(p) = &c.kind {
            let ty = l.ty(&p.ty);
            let init = p.init.as_ref().map(|e| l.expr(e));
            let slot = l.declare(&p.name.to_string());
            def.persistents.push((slot, ty, init));
        }
    }
    if task.kind == TaskKind::Handler {
        if let Some(exc) = &task.handles {
            l.check_exception(exc);
        }
        if let (Some(_), Some(var)) = (&task.handles, &task.caught) {
            def.caught = Some(l.declare(&var.to_string()));
        }
        let failing = l.declare("failing");
        let attached = l.declare("attached");
        let (prelude, body) = l.body(task);
        def.prelude = prelude;
        def.body = body;
        def.failing = l.used.contains(&failing).then_some(failing);
        def.attached = l.used.contains(&attached).then_some(attached);
    } else {
        let (prelude, body) = l.body(task);
        def.prelude = prelude;
        def.body = body;
    }
    def.holds = crate::walk::block(&def.body, &crate::walk::makes_children);
    def.awaits = crate::walk::block(&def.body, &crate::walk::awaits);
    let (locals, tdl_slots) = l.sizes();
    def.locals = locals;
    def.tdl_slots = tdl_slots;
    def
}

/// The exceptions the runtime, the distribution layer and the interpreter raise themselves: a
/// program handles them without declaring them.
const RUNTIME_EXCEPTIONS: &[&str] = &[
    "Fail",
    "ResourceDenied",
    "ResourceDropped",
    "ApprovalRefused",
    "Interrupted",
    "InvariantFailed",
    "AgentLost",
    "RemoteError",
    "RemoteTimeout",
    "RemoteCancelled",
    "RemoteRefused",
    "StepBudgetExceeded",
    "TypeMismatch",
    "NoMatch",
    "NoneValue",
    "Overflow",
    "DivisionByZero",
    "IndexOutOfRange",
    "NotRetryable",
];

impl Lower<'_, '_> {
    /// Refuses a type that names a type no registry declares.
    pub(crate) fn check_type(&mut self, ty: &Ty, span: proc_macro2::Span) {
        let mut named = std::collections::BTreeSet::new();
        ty.named(&mut named);
        for n in named {
            let known = self.registry.host_types.contains(&*n)
                || self.names.exceptions.contains_key(&*n)
                || matches!(&*n, "Ctx" | "Failure" | "Caught");
            if !known {
                let offered: Vec<&str> = self
                    .registry
                    .host_types
                    .iter()
                    .map(String::as_str)
                    .collect();
                self.error(
                    span,
                    format!("the type `{n}` is not known to the interpreter"),
                    if offered.is_empty() {
                        "declare it with `Registry::host_type` (and `tdl_interp::host_type!` on the Rust type)".into()
                    } else {
                        format!(
                            "declare it with `Registry::host_type`; the registry declares {}",
                            super::expr::list(&offered)
                        )
                    },
                );
            }
        }
    }

    /// Refuses a handled exception neither the program nor the registry declares.
    fn check_exception(&mut self, exc: &proc_macro2::Ident) {
        let name = exc.to_string();
        if !self.names.exceptions.contains_key(&name)
            && !self.registry.exceptions.contains_key(&name)
            && !RUNTIME_EXCEPTIONS.contains(&name.as_str())
        {
            self.error(
                exc.span(),
                format!("the exception `{name}` is not declared"),
                "declare it in the program (`exception Name;`) or register it with `Registry::exception`".into(),
            );
        }
    }

    /// A call of a task by its name: a task of the program or one the registry offers.
    pub(crate) fn task_call(
        &mut self,
        name: &proc_macro2::Ident,
        args: Vec<crate::ir::Ex>,
        span: proc_macro2::Span,
    ) -> Option<TaskCall> {
        let text = name.to_string();
        if let Some(idx) = self.names.tasks.get(&text) {
            return Some(TaskCall::Tdl(*idx, args));
        }
        if let Some(entry) = self.registry.tasks.get(&text) {
            let params = self
                .names
                .externs
                .get(&text)
                .map(|(p, _)| Arc::new(p.clone()));
            if let Some(p) = &params {
                if p.len() != args.len() {
                    self.error(
                        name.span(),
                        format!(
                            "`{text}` takes {} argument(s) (its `extern` declaration), given {}",
                            p.len(),
                            args.len()
                        ),
                        "give one argument per parameter".into(),
                    );
                }
            }
            return Some(TaskCall::Rust(entry.clone(), args, params));
        }
        let offered = self.registry.task_names();
        self.error(
            name.span(),
            format!("`{text}` is not a task of the program, nor one the registry offers"),
            if offered.is_empty() {
                "define it in TDL, or declare it `extern` and register it (`Registry::task`) or start the agent that offers it".into()
            } else {
                format!(
                    "define it in TDL or register it with `Registry::task`; the registry offers {}",
                    super::expr::list(&offered)
                )
            },
        );
        let _ = span;
        None
    }

    /// `exception handler h(args) [maximum activate N]`.
    pub(crate) fn handler_call(
        &mut self,
        it: &tdl_syntax::ast::HandlerRef,
        span: proc_macro2::Span,
    ) -> Option<HandlerCall> {
        let text = it.name.to_string();
        let args = it.args.iter().map(|a| self.expr(a)).collect();
        let max = it.max_activate.as_ref().map(|n| self.count(n, span));
        match self.names.tasks.get(&text) {
            Some(idx) => Some(HandlerCall {
                task: *idx,
                args,
                max,
            }),
            None => {
                self.error(
                    it.name.span(),
                    format!("`{text}` is not a handler of the program"),
                    "an interpreted program's handlers are written in TDL".into(),
                );
                None
            }
        }
    }
}
