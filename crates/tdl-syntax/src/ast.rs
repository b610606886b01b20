//! The TDL syntax tree: items (tasks, exceptions, plain Rust), task bodies as statement trees, and
//! constraints.
//!
//! The tree is plain data with public fields so a code generator can walk it with `match`.
//! Rust fragments are kept as `syn` nodes (types, expressions, patterns, items) or, for ordinary
//! statements, as their token streams with spans intact. Every TDL node carries the [`Span`] used
//! by diagnostics. The parser that builds it is `parser.rs`; names are resolved in `hir` (`hir.rs`, `hir/resolve.rs`)
//! and the tree is diagnosed in `diagnose.rs`. The constraints and what they are made of (tags,
//! events, facets, times) are in `ast/constraint.rs`, re-exported here.

#![allow(
    clippy::large_enum_variant,
    reason = "the tree is built once and walked by `match`; boxing variants would only add noise"
)]

mod cond;
mod constraint;

pub use cond::{
    Cond, CondExpr, EnvEntry, EnvTarget, EnvironmentDecl, Raise, SetState, StateDecl, StateLit,
    state_type,
};
pub use constraint::{
    Constraint, ConstraintKind, Count, Event, ExternalName, Facet, HandlerRef, OnTerminate,
    Persistent, Point, RelTime, Tag, TagIndex, TagKind, TaskConstraint, TaskConstraintKind, Then,
    TimeOfDay, When,
};

use proc_macro2::{Ident, Span, TokenStream};

/// A parsed TDL file or `tdl!{}` invocation.
#[derive(Clone, Debug, Default)]
pub struct Ast {
    /// Top-level items in source order.
    pub items: Vec<Item>,
    /// The warnings accepted with `#[allow(tdl::NAME)]` on tasks and statements, in source
    /// order (docs/language.md, "Accepting a warning").
    pub allows: Vec<Allow>,
}

/// One lint of `#[allow(tdl::NAME, …)]` on a task or on a statement of a body: the warnings of
/// that class whose span starts between `from` and `to` are accepted.
#[derive(Clone, Debug)]
pub struct Allow {
    /// The lint allowed.
    pub lint: crate::Lint,
    /// Span of its name in the attribute.
    pub span: Span,
    /// The first token covered: the attribute's `#`.
    pub from: Span,
    /// The last token covered: the task body's closing brace, or the statement's last token.
    pub to: Span,
}

/// A top-level item.
#[derive(Clone, Debug)]
pub enum Item {
    /// `goal`, `command`, `monitor` or `handler`.
    Task(Task),
    /// `exception Name [: Parent] (; | { fields })`.
    Exception(ExceptionDecl),
    /// `resource name(capacity) [pending N];` (docs/semantics.md, "Resources").
    Resource(ResourceDecl),
    /// `state name: type [= literal];` (docs/language.md, "State and conditions").
    State(StateDecl),
    /// `environment { … }`: what the outside may change, for the tools (docs/verification.md,
    /// "The environment").
    Environment(EnvironmentDecl),
    /// `extern goal|command name(args) [-> T];`: a task implemented outside TDL (in Rust, by an
    /// agent, by ROS 2), declared so that its arguments and value are typed.
    Extern(ExternDecl),
    /// Any Rust item (`fn`, `use`, `struct`, ...), passed through verbatim.
    Rust(Box<syn::Item>),
}

/// `extern goal|command name(args) [-> T];`: the signature of a task implemented elsewhere. The
/// compiled program calls the Rust function of that name; an interpreted one, what its registry
/// or an agent offers under that name (docs/language.md, "Running programs without compiling
/// them").
#[derive(Clone, Debug)]
pub struct ExternDecl {
    /// Outer attributes, including doc comments.
    pub attrs: Vec<syn::Attribute>,
    /// Goal or command.
    pub kind: TaskKind,
    /// Task name.
    pub name: Ident,
    /// Its parameters.
    pub args: Vec<Arg>,
    /// `-> T`: the value a waited spawn of it yields.
    pub result: Option<syn::Type>,
    /// Span of the name.
    pub span: Span,
}

/// The kind of a task definition (docs/semantics.md, "Task kinds").
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum TaskKind {
    /// `goal`: expands into children.
    Goal,
    /// `command`: an executable leaf.
    Command,
    /// `monitor`: a body run once per activation.
    Monitor,
    /// `handler ... handles Exc`: an exception handler.
    Handler,
}

impl TaskKind {
    /// The keyword: `goal`, `command`, `monitor` or `handler`.
    pub fn as_str(self) -> &'static str {
        match self {
            TaskKind::Goal => "goal",
            TaskKind::Command => "command",
            TaskKind::Monitor => "monitor",
            TaskKind::Handler => "handler",
        }
    }
}

/// A task definition: `[pub] [persistent] [blocking] [idempotent] goal name(args) [-> T] [with constraints] { body }`.
#[derive(Clone, Debug)]
pub struct Task {
    /// Outer attributes, including doc comments.
    pub attrs: Vec<syn::Attribute>,
    /// Visibility of the generated task type.
    pub vis: syn::Visibility,
    /// The `persistent` qualifier: the node is kept after completion.
    pub persistent: bool,
    /// The `blocking` qualifier (its span), on a command: its body is plain Rust that runs on a
    /// blocking thread (`tcm::Ctx::blocking`; docs/semantics.md, "Blocking actions").
    pub blocking: Option<Span>,
    /// The `idempotent` qualifier, on a command: safe to run twice, so started again when its
    /// run resumes from a journal (`tcm::Task::idempotent`; docs/semantics.md, "Durable runs").
    pub idempotent: bool,
    /// Goal, command, monitor or handler.
    pub kind: TaskKind,
    /// Task name.
    pub name: Ident,
    /// Arguments, copied into the node when it is created.
    pub args: Vec<Arg>,
    /// `-> T`: the value a waited spawn of this task yields.
    pub result: Option<syn::Type>,
    /// For handlers: the exception handled (`handles Exc`).
    pub handles: Option<Ident>,
    /// For handlers: the name bound to the caught exception (`handles Exc as name`), a
    /// `tdl::Caught<Exc>` in the body. Without it the body sees no exception binding.
    pub caught: Option<Ident>,
    /// For handlers: `for T`, the task this handler is attached to from outside, on every node of
    /// it (TCA's recovery added without modifying existing components). Its arguments, if any, are
    /// that node's arguments.
    pub for_task: Option<Ident>,
    /// For a wiretap (`wiretap w(args) before|after T { … }`, a command-like body never spawned):
    /// the task it checks and when. Its arguments, if any, are the checked node's.
    pub tap: Option<TapDecl>,
    /// Task-level constraints (docs/semantics.md, "Constraints").
    pub constraints: Vec<TaskConstraint>,
    /// The body.
    pub body: Block,
    /// Span of the task name.
    pub span: Span,
}

/// Where a wiretap checks (`before T` or `after T`).
#[derive(Clone, Debug)]
pub struct TapDecl {
    /// `after` (the node's action returned successfully), else `before` (it is about to start).
    pub after: bool,
    /// The task whose nodes it checks.
    pub target: Ident,
}

impl Task {
    /// The task's doc comments (`///` lines or `/** */` blocks before it), joined by newlines
    /// with the indentation they share removed; `None` when it has none.
    pub fn doc(&self) -> Option<String> {
        doc_text(&self.attrs)
    }
}

impl ExceptionDecl {
    /// The exception's doc comments, as [`Task::doc`] gives a task's.
    pub fn doc(&self) -> Option<String> {
        doc_text(&self.attrs)
    }
}

/// The text of the `#[doc = "…"]` attributes among `attrs` (what `///` and `/** */` become),
/// joined by newlines, with the indentation every non-blank line shares removed and blank lines
/// at either end dropped; `None` when there is no doc text.
pub fn doc_text(attrs: &[syn::Attribute]) -> Option<String> {
    // (line, whether it counts for the shared indentation): the first line of a `/** */` block
    // continues the `/**` and is only stripped of its leading blanks.
    let mut lines: Vec<(String, bool)> = Vec::new();
    for attr in attrs {
        if !attr.path().is_ident("doc") {
            continue;
        }
        let syn::Meta::NameValue(nv) = &attr.meta else {
            continue;
        };
        let syn::Expr::Lit(syn::ExprLit {
            lit: syn::Lit::Str(text),
            ..
        }) = &nv.value
        else {
            continue;
        };
        let text = text.value();
        let block = text.contains('\n');
        for (i, line) in text.split('\n').enumerate() {
            let line = line.strip_suffix('\r').unwrap_or(line);
            if block && i == 0 {
                lines.push((line.trim_start_matches([' ', '\t']).to_string(), false));
            } else {
                lines.push((line.to_string(), true));
            }
        }
    }
    let indent = lines
        .iter()
        .filter(|(l, counts)| *counts && !l.trim().is_empty())
        .map(|(l, _)| l.len() - l.trim_start_matches([' ', '\t']).len())
        .min()
        .unwrap_or(0);
    let lines: Vec<&str> = lines
        .iter()
        .map(|(l, counts)| {
            let l = if *counts {
                l.get(indent..).unwrap_or("")
            } else {
                l
            };
            l.trim_end()
        })
        .collect();
    let start = lines.iter().position(|l| !l.is_empty())?;
    let end = lines.iter().rposition(|l| !l.is_empty())?;
    Some(lines[start..=end].join("\n"))
}

/// A task argument `[mut] name: Type`.
#[derive(Clone, Debug)]
pub struct Arg {
    /// `mut` was written.
    pub mutable: bool,
    /// Argument name.
    pub name: Ident,
    /// Argument type.
    pub ty: syn::Type,
}

/// `exception Name [: Parent] ( ; | { field: Type, ... } )`.
#[derive(Clone, Debug)]
pub struct ExceptionDecl {
    /// Outer attributes, including doc comments.
    pub attrs: Vec<syn::Attribute>,
    /// Visibility of the generated exception type.
    pub vis: syn::Visibility,
    /// Exception name.
    pub name: Ident,
    /// Parent exception: a handler of the parent also handles this one.
    pub parent: Option<Ident>,
    /// Data fields.
    pub fields: Vec<Field>,
    /// Span of the name.
    pub span: Span,
}

/// `resource name(capacity) [pending N];`: a resource of the program, with its capacity and the
/// most requests that may wait for it (docs/semantics.md, "Resources").
#[derive(Clone, Debug)]
pub struct ResourceDecl {
    /// Outer attributes, including doc comments (kept for the reader; nothing is generated).
    pub attrs: Vec<syn::Attribute>,
    /// Resource name, as spawns name it in `uses`.
    pub name: Ident,
    /// Units it has.
    pub capacity: syn::LitInt,
    /// `pending N`: most requests that may wait for it.
    pub pending: Option<syn::LitInt>,
    /// Span of the name.
    pub span: Span,
}

/// One resource of a `uses` list: `name` or `name(amount)`.
#[derive(Clone, Debug)]
pub struct ResourceAmount {
    /// The resource.
    pub name: Ident,
    /// How much of it; `None`: 1.
    pub amount: Option<Count>,
    /// Span of the amount, or of the name without one.
    pub span: Span,
}

/// A request's priority: lower is granted first.
#[derive(Clone, Debug)]
pub enum Priority {
    /// An integer literal, possibly negative.
    Const(i64),
    /// Any other expression (an `i32`).
    Expr(syn::Expr),
}

/// An exception data field `name: Type`.
#[derive(Clone, Debug)]
pub struct Field {
    /// Field name.
    pub name: Ident,
    /// Field type.
    pub ty: syn::Type,
}

/// `retry;` or `retry with (a, b, ...);`.
#[derive(Clone, Debug)]
pub struct Retry {
    /// The arguments of the new run, in the task's order; `None` for the failed run's own.
    pub args: Option<Vec<syn::Expr>>,
    /// Span of `retry`.
    pub span: Span,
}

/// `lock r;`, `unlock r;`, `reserve r;` or `unreserve r;`.
#[derive(Clone, Debug)]
pub struct ResourceStmt {
    /// What is done to the resource.
    pub op: ResourceOp,
    /// The resource.
    pub name: Ident,
    /// Span of the keyword.
    pub span: Span,
}

/// What a [`ResourceStmt`] does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ResourceOp {
    /// `lock r;`: nobody is granted it until it is unlocked.
    Lock,
    /// `unlock r;`.
    Unlock,
    /// `reserve r;`: only this task's node and its descendants are granted it.
    Reserve,
    /// `unreserve r;`.
    Unreserve,
}

impl ResourceOp {
    /// The keyword.
    pub fn as_str(self) -> &'static str {
        match self {
            ResourceOp::Lock => "lock",
            ResourceOp::Unlock => "unlock",
            ResourceOp::Reserve => "reserve",
            ResourceOp::Unreserve => "unreserve",
        }
    }
}

/// A block of statements `{ ... }`.
#[derive(Clone, Debug)]
pub struct Block {
    /// Statements in order.
    pub stmts: Vec<Stmt>,
    /// For each statement, the identifiers its tokens name (nested groups included), sorted:
    /// whether a variable is named again later, which decides whether an argument is cloned
    /// (`codegen::by_value`).
    pub mentions: Vec<Vec<String>>,
    /// Span of the braces.
    pub span: Span,
}

/// A statement of a task body: Rust, TDL, or Rust control flow containing TDL statements.
#[derive(Clone, Debug)]
pub enum Stmt {
    /// Any Rust statement (or a tail expression), kept as tokens.
    Rust(RustStmt),
    /// `[label:]* spawn task(args) [with constraints];` or `let pat = spawn ... with wait;`.
    Spawn(Spawn),
    /// `[label:]* with (constraints) { ... }`.
    With(WithGroup),
    /// `TAG constraint;`.
    Constrain(ConstraintStmt),
    /// `bind name = expr;`: a node held in Rust made a tag.
    Bind(Bind),
    /// `succeed;`.
    Succeed(Span),
    /// `fail [Exc [{ field: value, ... }]];`.
    Fail(Fail),
    /// `bypass;` (handlers only).
    Bypass(Span),
    /// `trigger;` (monitors only).
    Trigger(Span),
    /// `retry;` or `retry with (args);` (handlers only): run the failed task again, with the
    /// same or with other arguments, and wait for it.
    Retry(Retry),
    /// `lock r;`, `unlock r;`, `reserve r;` (for this task's subtree), `unreserve r;`
    /// (docs/semantics.md, "Resources").
    Resource(ResourceStmt),
    /// `set VAR = expr;`: a state variable set (docs/language.md, "State and conditions").
    Set(SetState),
    /// `raise "name";` or `raise (expr);`: an external event raised.
    Raise(Raise),
    /// `log "format", args…;`: a line for the run's log, stamped with the run's time.
    Log(Log),
    /// `if cond { ... } [else ...]`.
    If(If),
    /// `['label:] for pat in expr { ... }`.
    For(For),
    /// `['label:] while cond { ... }`.
    While(While),
    /// `['label:] loop { ... }`.
    Loop(Loop),
    /// `match expr { arms }`.
    Match(Match),
    /// A nested `{ ... }` block.
    Block(Block),
}

/// A Rust statement kept verbatim.
#[derive(Clone, Debug)]
pub struct RustStmt {
    /// The statement's tokens, including its `;` if it has one.
    pub tokens: TokenStream,
    /// Span of the first token.
    pub span: Span,
}

/// A spawn statement.
#[derive(Clone, Debug)]
pub struct Spawn {
    /// Labels `l1: l2: spawn ...`, usable as tags.
    pub labels: Vec<Ident>,
    /// `let pat [: T] = spawn ...`: where the child's result value goes (needs `wait`).
    pub binding: Option<Binding>,
    /// The task spawned.
    pub task: Ident,
    /// Its arguments.
    pub args: Vec<syn::Expr>,
    /// Constraints after `with`.
    pub constraints: Vec<Constraint>,
    /// Span of the `spawn` keyword.
    pub span: Span,
}

/// `let pat [: T] =` in front of a waited spawn.
#[derive(Clone, Debug)]
pub struct Binding {
    /// What takes the value.
    pub target: BindTarget,
    /// Optional type annotation (`let` only).
    pub ty: Option<syn::Type>,
}

/// What takes a waited spawn's value.
#[derive(Clone, Debug)]
pub enum BindTarget {
    /// `let pat [: T] = spawn …`.
    Let(syn::Pat),
    /// `place = spawn …`: an existing variable (or any place expression) is assigned.
    Assign(syn::Expr),
}

/// `[label:]* with (constraints) { body }`: constraints applied to every spawn inside; a nested
/// group counts as one entity for the outer constraints (TDL paper, "with/do").
#[derive(Clone, Debug)]
pub struct WithGroup {
    /// Labels naming the whole group as a tag.
    pub labels: Vec<Ident>,
    /// The group's constraints.
    pub constraints: Vec<Constraint>,
    /// The body.
    pub body: Block,
    /// Span of the `with` keyword.
    pub span: Span,
}

/// `TAG constraint;`: a constraint on an earlier or later spawn.
#[derive(Clone, Debug)]
pub struct ConstraintStmt {
    /// The constrained task.
    pub tag: Tag,
    /// The constraint.
    pub constraint: Constraint,
    /// Span of the tag.
    pub span: Span,
}

/// `bind name = expr;`: makes the node `expr` (a `tdl::NodeId`) the tag `name` for the
/// constraints after it (TDL's `TDL_BIND(expr, name)`); binding again replaces the node.
#[derive(Clone, Debug)]
pub struct Bind {
    /// The tag.
    pub name: Ident,
    /// The node, a Rust expression.
    pub expr: syn::Expr,
    /// Span of the `bind` keyword.
    pub span: Span,
}

/// `fail [Exc [{ field: value, ... }]];`.
#[derive(Clone, Debug)]
pub struct Fail {
    /// The exception raised; `None` for a bare `fail;`.
    pub exception: Option<Ident>,
    /// Field values.
    pub fields: Vec<syn::FieldValue>,
    /// Span of the `fail` keyword.
    pub span: Span,
}

/// `log "format", args…;`: a line for the run's log (a `log` trace record), formatted as
/// `format!` formats, stamped with the run's time (docs/language.md, "Logging").
#[derive(Clone, Debug)]
pub struct Log {
    /// The format string.
    pub format: syn::LitStr,
    /// The arguments after it, positional or named (`name = expr`).
    pub args: Vec<syn::Expr>,
    /// Span of the `log` keyword.
    pub span: Span,
}

impl Log {
    /// The arguments of `format!` it stands for: `"format", args…`.
    pub fn format_args(&self) -> TokenStream {
        let format = &self.format;
        let args = &self.args;
        quote::quote!(#format #(, #args)*)
    }
}

/// `if cond { ... } [else ...]`.
#[derive(Clone, Debug)]
pub struct If {
    /// The condition (may be a `let` expression).
    pub cond: syn::Expr,
    /// The `then` block.
    pub then_branch: Block,
    /// `else if ...` or `else { ... }`.
    pub else_branch: Option<Box<Else>>,
    /// Span of the `if` keyword.
    pub span: Span,
}

/// The `else` part of an [`If`].
#[derive(Clone, Debug)]
pub enum Else {
    /// `else if ...`.
    If(If),
    /// `else { ... }`.
    Block(Block),
}

/// `['label:] for pat in expr { ... }`.
#[derive(Clone, Debug)]
pub struct For {
    /// Loop label.
    pub label: Option<syn::Lifetime>,
    /// The loop pattern.
    pub pat: syn::Pat,
    /// The iterated expression.
    pub expr: syn::Expr,
    /// The body.
    pub body: Block,
    /// Span of the `for` keyword.
    pub span: Span,
}

/// `['label:] while cond { ... }`.
#[derive(Clone, Debug)]
pub struct While {
    /// Loop label.
    pub label: Option<syn::Lifetime>,
    /// The condition (may be a `let` expression).
    pub cond: syn::Expr,
    /// The body.
    pub body: Block,
    /// Span of the `while` keyword.
    pub span: Span,
}

/// `['label:] loop { ... }`.
#[derive(Clone, Debug)]
pub struct Loop {
    /// Loop label.
    pub label: Option<syn::Lifetime>,
    /// The body.
    pub body: Block,
    /// Span of the `loop` keyword.
    pub span: Span,
}

/// `match expr { arms }`.
#[derive(Clone, Debug)]
pub struct Match {
    /// The scrutinee.
    pub expr: syn::Expr,
    /// The arms.
    pub arms: Vec<Arm>,
    /// Span of the `match` keyword.
    pub span: Span,
}

/// `pat [if guard] => body`. An expression body is kept as a block holding one Rust statement.
#[derive(Clone, Debug)]
pub struct Arm {
    /// The pattern.
    pub pat: syn::Pat,
    /// The guard.
    pub guard: Option<syn::Expr>,
    /// The body.
    pub body: Block,
}
