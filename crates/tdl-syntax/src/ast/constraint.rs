//! The constraints of the TDL syntax tree: task-level constraints ([`TaskConstraint`]) and those
//! on spawns, `with` groups and constraint statements ([`Constraint`]), with what they are made
//! of: triggers ([`When`], [`Then`]), events, tags, facets and points, times and counts.
//! Re-exported by `ast.rs`, so each is `crate::ast::X` like the rest of the tree.

use proc_macro2::{Ident, Span};

use super::{Cond, Priority, ResourceAmount};

/// A task-level constraint with its span.
#[derive(Clone, Debug)]
pub struct TaskConstraint {
    /// What the constraint says.
    pub kind: TaskConstraintKind,
    /// Where it is written.
    pub span: Span,
}

/// Task-level constraints (docs/semantics.md, "Constraints"). Which kinds allow which is diagnosed in `diagnose.rs`.
#[derive(Clone, Debug)]
pub enum TaskConstraintKind {
    /// `expand first`.
    ExpandFirst,
    /// `delay expansion`.
    DelayExpansion,
    /// `exception handler H(args) [maximum activate N]`.
    ExceptionHandler(HandlerRef),
    /// `on terminate [spawn] T(args)`.
    OnTerminate(OnTerminate),
    /// `persistent name: Type [= init]`.
    Persistent(Persistent),
    /// `maximum activate N` (monitors and handlers).
    MaximumActivate(Count),
    /// `maximum trigger N` (monitors).
    MaximumTrigger(Count),
    /// `period T` (monitors).
    Period(RelTime),
    /// `initial wait`: skip the first periodic activation (monitors).
    InitialWait,
    /// `serial`: each activation waits for the previous one (monitors).
    Serial,
    /// `sequential expansion|execution` between activations (monitors).
    Sequential(Facet),
    /// `uses r, r2(n)`: every node of the task uses these resources (goals and commands).
    Uses(Vec<ResourceAmount>),
    /// `priority N`: the priority of every node's request for resources.
    Priority(Priority),
}

/// `persistent name: Type [= init]`: per-instance state surviving across activations.
#[derive(Clone, Debug)]
pub struct Persistent {
    /// Variable name.
    pub name: Ident,
    /// Variable type.
    pub ty: syn::Type,
    /// Initial value; `Default::default()` when absent.
    pub init: Option<syn::Expr>,
}

/// `exception handler H(args) [maximum activate N]`.
///
/// The maximum number of uses of the handler instance is written after the arguments, without a
/// comma: `exception handler retry_move(3) maximum activate 2`.
#[derive(Clone, Debug)]
pub struct HandlerRef {
    /// Handler task name.
    pub name: Ident,
    /// Arguments, evaluated when the task instance is created.
    pub args: Vec<syn::Expr>,
    /// How many times this handler instance may be used.
    pub max_activate: Option<Count>,
}

/// `on terminate [label:]* [spawn] T(args)`.
#[derive(Clone, Debug)]
pub struct OnTerminate {
    /// Labels naming the on-terminate task, usable as tags.
    pub labels: Vec<Ident>,
    /// Task to spawn when the node is terminated while running.
    pub task: Ident,
    /// Its arguments.
    pub args: Vec<syn::Expr>,
}

/// A constraint with its span.
#[derive(Clone, Debug)]
pub struct Constraint {
    /// What the constraint says.
    pub kind: ConstraintKind,
    /// Where it is written (its first keyword).
    pub span: Span,
}

/// Spawn, `with` group and constraint-statement constraints (TDL paper Fig. 5; docs/semantics.md, "Constraints").
#[derive(Clone, Debug)]
pub enum ConstraintKind {
    /// `expand first`.
    ExpandFirst,
    /// `delay expansion`.
    DelayExpansion,
    /// `sequential handling|expansion|execution [tag]`; `None` means `previous`.
    Sequential {
        /// Which interval waits for the same interval of the tag.
        facet: Facet,
        /// The tag waited for.
        tag: Option<Tag>,
    },
    /// `serial [tag]`; `None` means `previous`.
    Serial {
        /// The tag waited for.
        tag: Option<Tag>,
    },
    /// `parallel` (no constraint; forms a group).
    Parallel,
    /// `wait`: the spawn blocks until the child's execution completes.
    Wait,
    /// `outcome` (a bound spawn only): wait, and bind how the child ended (`tdl::Ended<T>`)
    /// instead of its value.
    Outcome,
    /// `propagate` (spawn only): the child's failure that no handler on it takes fails the
    /// parent (docs/semantics.md, "Failing the parent").
    Propagate,
    /// `approval [within REL]` (spawn only): the child waits at its turn to start until an
    /// operator approves it; refused, or not approved in time, it fails with `ApprovalRefused`
    /// (docs/semantics.md, "Steering a run").
    Approval(Option<RelTime>),
    /// `disable [facet] until|for …`, `terminate […]`, `activate […]`: when something happens,
    /// do something (TDL paper Fig. 5). The three differ only in what they do then.
    Trigger {
        /// When it fires.
        when: When,
        /// What it does then.
        then: Then,
    },
    /// `maximum activate N` (monitors).
    MaximumActivate(Count),
    /// `maximum trigger N` (monitors).
    MaximumTrigger(Count),
    /// `period REL` (monitors).
    Period(RelTime),
    /// `exception handler H(args) [maximum activate N]` (not in `with`).
    ExceptionHandler(HandlerRef),
    /// `on terminate [label:]* [spawn] T(args)` (not in `with`).
    OnTerminate(OnTerminate),
    /// `name "instance name"`.
    Name(syn::Expr),
    /// `parent EXPR` (spawn only): insert the node under the node `EXPR` (a `tdl::NodeId`) instead
    /// of the task whose body runs.
    Parent(syn::Expr),
    /// `on AGENT`: rejected until distributed agents exist.
    OnAgent(syn::Expr),
    /// `uses r, r2(n)`: resources granted, all at once, before the node starts, and released when
    /// its action ends (docs/semantics.md, "Resources").
    Uses(Vec<ResourceAmount>),
    /// `priority N`: the priority of the node's request for resources (lower first).
    Priority(Priority),
    /// `deny if busy`: a request that cannot be granted at once fails the node with
    /// `ResourceDenied` instead of waiting.
    DenyIfBusy,
}

/// When a [`ConstraintKind::Trigger`] fires: the one "when" of `disable`, `terminate` and
/// `activate`. `disable` spells `at` as `until` and `in` as `for`.
#[derive(Clone, Debug)]
pub enum When {
    /// No time given (`terminate`, `activate`): at once.
    Now,
    /// `at H:M:S[.frac]` (`until …` for `disable`): at a time of day.
    At(TimeOfDay),
    /// `in REL` (`for REL`): a delay from when the constraint is applied.
    In(RelTime),
    /// `at EVENT` (`until EVENT`): when a node's facet reaches a state.
    Event(Event),
    /// `in REL after EVENT` (`for REL after EVENT`): a delay from the event.
    After(RelTime, Event),
    /// `at external NAME` (`until external NAME`): when the named external event is raised by
    /// the program (`Runtime::events`, `Session::raise`, `Ctx::raise`). `disable` and `terminate`
    /// are latched (a raise before the constraint counts); `activate` fires on every raise after
    /// it (docs/semantics.md, "Events").
    External(ExternalName),
    /// `until COND` (`disable`), `when COND` (`terminate`, `activate`), and the condition of
    /// `skip if`, `invariant` and `pause while`: a condition over state variables (docs/language.md,
    /// "State and conditions").
    Condition(Cond),
    /// `on change of VAR` (`activate`): each time the state variable changes value.
    Changed(Ident),
}

impl When {
    /// The event it waits for, if any.
    pub fn event(&self) -> Option<&Event> {
        match self {
            When::Event(event) | When::After(_, event) => Some(event),
            When::Now
            | When::At(_)
            | When::In(_)
            | When::External(_)
            | When::Condition(_)
            | When::Changed(_) => None,
        }
    }
}

/// The name of an external event in `external NAME`, bound to the run's event id when the
/// constraint is applied.
#[derive(Clone, Debug)]
pub enum ExternalName {
    /// `external "name"`: a string literal.
    Lit(syn::LitStr),
    /// `external (expr)`: a Rust expression giving the name (anything that is `AsRef<str>`),
    /// evaluated when the constraint is applied.
    Expr(syn::Expr),
}

/// What a [`ConstraintKind::Trigger`] does when it fires.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Then {
    /// `disable [facet] until|for …`: the facet (`None`: handling) is enabled.
    Enable(Option<Facet>),
    /// `terminate …`: the node and its subtree are terminated.
    Terminate,
    /// `activate …` (monitors): the monitor is activated once.
    Activate,
    /// `skip if COND`: when the node's turn comes, it completes without running if the condition
    /// holds (outcome `skipped`).
    Skip,
    /// `invariant COND`: the node fails with `InvariantFailed` when the condition is false while
    /// it runs.
    Invariant,
    /// `pause while COND`: the node's subtree is suspended while the condition holds.
    Pause,
}

/// `TAG [facet] state`: a state transition of a node.
#[derive(Clone, Debug)]
pub struct Event {
    /// The node.
    pub tag: Tag,
    /// The interval; `None`: handling for enabled/active, execution for completed.
    pub facet: Option<Facet>,
    /// The state reached.
    pub point: Point,
}

/// A reference to a node from a constraint.
#[derive(Clone, Debug)]
pub struct Tag {
    /// Which node.
    pub kind: TagKind,
    /// Where the tag is written.
    pub span: Span,
}

/// The kinds of tag (docs/semantics.md, "Tags and forward references").
#[derive(Clone, Debug)]
pub enum TagKind {
    /// A task name spawned in this body or a label, with iteration indexes `name[i][j]`.
    Named {
        /// Task name or label.
        name: Ident,
        /// Iteration indexes, outermost loop first.
        indexes: Vec<TagIndex>,
    },
    /// `previous`: the spawn or group executed just before, resolved at run time.
    Previous,
    /// `self` or `child`: the node being spawned.
    Child,
    /// `parent` or `this`: the enclosing task.
    Parent,
}

/// One iteration index of a tag.
#[derive(Clone, Debug)]
pub enum TagIndex {
    /// `[expr]`.
    Expr(syn::Expr),
    /// `[.]`: the current iteration of that loop level.
    Current,
}

/// An interval of a node (TDL paper, "Task Trees").
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Facet {
    /// The node itself (`handling`).
    Handling,
    /// All goals of the subtree (`expansion`, synonym `planning`).
    Expansion,
    /// All commands of the subtree (`execution`, synonym `achievement`).
    Execution,
}

impl Facet {
    /// The keyword.
    pub fn as_str(self) -> &'static str {
        match self {
            Facet::Handling => "handling",
            Facet::Expansion => "expansion",
            Facet::Execution => "execution",
        }
    }
}

/// The point an [`Event`] waits for (a facet's state: `tcm::Point` at run time).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Point {
    /// `enabled`.
    Enabled,
    /// `active`.
    Active,
    /// `completed`: the end, however it came (TDL's meaning).
    Completed,
    /// `succeeded`: the execution completed and the action (or a retry of it) succeeded.
    Succeeded,
    /// `failed`: the execution completed and the action failed, no retry of it succeeding.
    Failed,
    /// `terminated`: the execution completed because the node was terminated.
    Terminated,
}

impl Point {
    /// The keyword.
    pub fn as_str(self) -> &'static str {
        match self {
            Point::Enabled => "enabled",
            Point::Active => "active",
            Point::Completed => "completed",
            Point::Succeeded => "succeeded",
            Point::Failed => "failed",
            Point::Terminated => "terminated",
        }
    }

    /// True for the outcome events (`succeeded`, `failed`, `terminated`): the execution's
    /// completion with that outcome (docs/semantics.md, "Outcomes").
    pub fn is_outcome(self) -> bool {
        matches!(self, Point::Succeeded | Point::Failed | Point::Terminated)
    }
}

/// A relative time.
#[derive(Clone, Debug)]
pub enum RelTime {
    /// A constant: `30s`, `1.5s`, `200ms`, `2min`, `0:0:30.0`, `0.5`.
    Nanos(u64),
    /// `(expr)`: a Rust expression in seconds (an `f64`).
    Seconds(syn::Expr),
}

/// An absolute time of day `H:M:S[.frac]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TimeOfDay {
    /// Hour, 0-23.
    pub hour: u8,
    /// Minute, 0-59.
    pub minute: u8,
    /// Second, 0-59.
    pub second: u8,
    /// Fraction of the second, in nanoseconds.
    pub nanos: u32,
}

impl TimeOfDay {
    /// Nanoseconds since midnight.
    pub fn nanos_since_midnight(self) -> u64 {
        ((u64::from(self.hour) * 60 + u64::from(self.minute)) * 60 + u64::from(self.second))
            * 1_000_000_000
            + u64::from(self.nanos)
    }
}

/// A count such as `maximum activate N`.
#[derive(Clone, Debug)]
pub enum Count {
    /// An integer literal.
    Const(u64),
    /// Any other expression.
    Expr(syn::Expr),
}
