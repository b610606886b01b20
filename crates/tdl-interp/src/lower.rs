//! Lowering the resolved program into the interpreter's trees (`ir.rs`), once, when it is
//! loaded: Rust expressions, patterns and statements of the interpreted subset (`lower/expr.rs`,
//! `lower/pat.rs`), TDL statements as the code generator lowers them (`lower/body.rs`, the
//! counterpart of `tdl-syntax`'s `codegen/body.rs` and `codegen/spawn.rs`), constraints
//! (`lower/constraint.rs`, of `codegen/lower.rs`), and task definitions (`lower/task.rs`, of
//! `codegen.rs`'s `task_items`).
//!
//! A construct outside the subset, a name no registry offers and a type it does not know are
//! reported as spanned diagnostics; any of them refuses the program.

mod body;
mod constraint;
mod expr;
mod pat;
mod task;

use std::collections::BTreeMap;
use std::sync::Arc;

use proc_macro2::Span;
use tdl_syntax::Diagnostic;
use tdl_syntax::hir::{BodyScope, FileScope, LoopId};

use crate::ir::{Loc, Slot, TSlot, TaskIdx};
use crate::registry::Registry;

pub(crate) use expr::list;
pub(crate) use task::lower_task;

/// A declared exception: its ancestors (nearest first) and its fields in order.
pub(crate) type ExceptionInfo = (Vec<Arc<str>>, Vec<Arc<str>>);

/// What every body of the program may name: its tasks, exceptions and state variables.
pub(crate) struct ProgramNames {
    pub(crate) tasks: BTreeMap<String, TaskIdx>,
    /// Declared exceptions: their ancestors (nearest first) and fields in order.
    pub(crate) exceptions: BTreeMap<String, ExceptionInfo>,
    pub(crate) states: BTreeMap<String, (tdl::StateVar, tcm_expr::Type)>,
    /// The `extern` tasks: their parameters' and result's types.
    pub(crate) externs: BTreeMap<String, (Vec<crate::ty::Ty>, Option<crate::ty::Ty>)>,
}

/// The hint of every diagnostic of a construct outside the subset.
pub(crate) const SUBSET_HINT: &str = "the compiled path (`tdl!`, `build.rs`) accepts it; docs/language.md, \"Running programs without compiling them\", lists what an interpreted body may contain";

/// The lowering of one task's body.
pub(crate) struct Lower<'s, 'a> {
    pub(crate) registry: &'s Registry,
    pub(crate) names: &'s ProgramNames,
    pub(crate) file: &'s FileScope<'a>,
    pub(crate) file_name: Arc<str>,
    pub(crate) scope: &'s BodyScope<'a>,
    pub(crate) diags: &'s mut Vec<Diagnostic>,
    /// Locals in scope, innermost last.
    scopes: Vec<Vec<(String, Slot)>>,
    next_slot: Slot,
    /// TDL slots: the body's bookkeeping locals (`tdl_*` in generated code), by name.
    pub(crate) tdl: BTreeMap<String, TSlot>,
    next_tdl: TSlot,
    /// The loops around the statement being lowered, outermost first.
    pub(crate) loops: Vec<LoopId>,
    /// The `with` groups around it, innermost last (`lower/body.rs`).
    pub(crate) frames: Vec<body::Frame<'a>>,
    /// While the later alternatives of an or-pattern are lowered: the slots the first bound.
    pub(crate) reuse: Vec<(String, Slot)>,
    /// The locals some expression reads.
    pub(crate) used: std::collections::BTreeSet<Slot>,
}

impl<'s, 'a> Lower<'s, 'a> {
    pub(crate) fn new(
        registry: &'s Registry,
        names: &'s ProgramNames,
        file: &'s FileScope<'a>,
        file_name: &str,
        scope: &'s BodyScope<'a>,
        diags: &'s mut Vec<Diagnostic>,
    ) -> Lower<'s, 'a> {
        Lower {
            registry,
            names,
            file,
            file_name: Arc::from(file_name),
            scope,
            diags,
            scopes: vec![Vec::new()],
            next_slot: 0,
            tdl: BTreeMap::new(),
            next_tdl: 0,
            loops: Vec::new(),
            frames: Vec::new(),
            reuse: Vec::new(),
            used: std::collections::BTreeSet::new(),
        }
    }

    /// Reports a construct outside the interpreted subset.
    pub(crate) fn unsupported(&mut self, span: Span, what: &str) {
        self.diags.push(
            Diagnostic::error(
                span,
                format!("{what} is not in the interpreted subset of TDL"),
            )
            .with_hint(SUBSET_HINT),
        );
    }

    /// Reports an error with a hint.
    pub(crate) fn error(&mut self, span: Span, message: String, hint: String) {
        self.diags
            .push(Diagnostic::error(span, message).with_hint(hint));
    }

    pub(crate) fn loc(&self, span: Span) -> Loc {
        let start = span.start();
        Loc {
            file: self.file_name.clone(),
            line: start.line,
            column: start.column,
        }
    }

    /// A new local named `name`, in scope from now on.
    pub(crate) fn declare(&mut self, name: &str) -> Slot {
        if let Some((_, slot)) = self.reuse.iter().find(|(n, _)| n == name) {
            return *slot;
        }
        let slot = self.next_slot;
        self.next_slot += 1;
        if let Some(scope) = self.scopes.last_mut() {
            scope.push((name.to_string(), slot));
        }
        slot
    }

    /// The local `name` in scope, innermost first.
    pub(crate) fn local(&self, name: &str) -> Option<Slot> {
        self.scopes
            .iter()
            .rev()
            .flat_map(|s| s.iter().rev())
            .find(|(n, _)| n == name)
            .map(|(_, slot)| *slot)
    }

    /// How many locals the innermost scope holds.
    pub(crate) fn scope_len(&self) -> usize {
        self.scopes.last().map_or(0, Vec::len)
    }

    /// The locals the innermost scope gained since it held `mark`.
    pub(crate) fn declared_since(&self, mark: usize) -> Vec<(String, Slot)> {
        self.scopes
            .last()
            .map(|s| s.get(mark..).unwrap_or_default().to_vec())
            .unwrap_or_default()
    }

    pub(crate) fn push_scope(&mut self) {
        self.scopes.push(Vec::new());
    }

    pub(crate) fn pop_scope(&mut self) {
        self.scopes.pop();
    }

    /// The TDL slot of the generated local `name` (`tdl_prev`, `tdl_x`, ...), made on first use.
    pub(crate) fn tdl_slot(&mut self, name: &str) -> TSlot {
        if let Some(slot) = self.tdl.get(name) {
            return *slot;
        }
        let slot = self.next_tdl;
        self.next_tdl += 1;
        self.tdl.insert(name.to_string(), slot);
        slot
    }

    /// The type written `ty`, its names read through the registry's aliases.
    pub(crate) fn ty(&self, ty: &syn::Type) -> crate::ty::Ty {
        crate::ty::Ty::of(ty).rename(&|n| self.registry.aliases.get(n).cloned())
    }

    /// How many locals and TDL slots the body's frame needs.
    pub(crate) fn sizes(&self) -> (usize, usize) {
        (self.next_slot as usize, self.next_tdl as usize)
    }
}
