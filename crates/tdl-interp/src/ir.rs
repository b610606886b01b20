//! The program as the interpreter runs it: each task's body lowered, when the program is loaded,
//! from the resolved program (`tdl_syntax::hir`) into owned trees whose names are all resolved:
//! locals to slots of the body's frame, functions and tasks to registry entries or definitions,
//! tags to the run-time bookkeeping the code generator keeps in `tdl_*` locals (`codegen/body.rs`
//! says which), here the body's *TDL slots*. Nothing is looked up by name while a body runs.

use std::sync::Arc;
use std::time::Duration;

use tdl::{Facet, Point, Then};
use tdl_syntax::ast::{ResourceOp, TaskKind};

use crate::registry::{Function, TaskEntry};
use crate::ty::Ty;
use crate::value::Value;

/// A local of a body's frame.
pub(crate) type Slot = u32;
/// A TDL slot of a body's frame (a reservation, a map of reservations by iteration, a group's
/// members, `previous`, a loop's count).
pub(crate) type TSlot = u32;
/// A task definition of the program, by its place.
pub(crate) type TaskIdx = usize;

/// Where a construct is written, for messages.
#[derive(Clone, Debug)]
pub(crate) struct Loc {
    pub(crate) file: Arc<str>,
    pub(crate) line: usize,
    pub(crate) column: usize,
}

impl std::fmt::Display for Loc {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}:{}:{}", self.file, self.line, self.column + 1)
    }
}

/// A binary operator of Rust.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Bin {
    Add,
    Sub,
    Mul,
    Div,
    Rem,
    Eq,
    Ne,
    Lt,
    Le,
    Gt,
    Ge,
    BitAnd,
    BitOr,
    BitXor,
    Shl,
    Shr,
}

/// What a call names.
#[derive(Clone)]
pub(crate) enum Callee {
    /// A function of the registry.
    Registered(Function),
    /// A function of the interpreter's own (`Some`, `f64::from`, `Duration::from_secs`, ...).
    Builtin(crate::builtin::Builtin),
}

/// An expression.
#[derive(Clone)]
pub(crate) enum Ex {
    Lit(Value),
    Local(Slot),
    Ctx,
    Not(Box<Ex>),
    Neg(Box<Ex>),
    Bin(Bin, Box<Ex>, Box<Ex>),
    And(Box<Ex>, Box<Ex>),
    Or(Box<Ex>, Box<Ex>),
    Call(Callee, Vec<Ex>),
    Method {
        recv: Box<Ex>,
        name: Arc<str>,
        args: Vec<Ex>,
        /// A type named in a turbofish (`downcast::<T>()`).
        turbofish: Option<Arc<str>>,
    },
    Field(Box<Ex>, Arc<str>),
    TupleField(Box<Ex>, usize),
    Index(Box<Ex>, Box<Ex>),
    Await(Box<Ex>),
    Try(Box<Ex>),
    Tuple(Vec<Ex>),
    List(Vec<Ex>),
    /// A struct literal: an exception's data or a record.
    Record(Arc<str>, Vec<(Arc<str>, Ex)>),
    Format(Arc<crate::format::Fmt>, Vec<Ex>),
    Range(Option<Box<Ex>>, Option<Box<Ex>>, bool),
    If(Box<Ex>, Box<Block>, Option<Box<Ex>>),
    Match(Box<Ex>, Vec<Arm>),
    Block(Box<Block>),
    /// A closure, as an argument of a method that calls it (`map`, `is_some_and`, ...).
    Closure(Arc<Closure>),
    Cast(Box<Ex>, Ty),
    /// `let PAT = EXPR` in an `if` or `while` condition.
    Let(Box<Pat>, Box<Ex>),
    Return(Option<Box<Ex>>),
    Break(Option<Arc<str>>),
    Continue(Option<Arc<str>>),
    Assign(Box<Place>, Box<Ex>),
    AssignOp(Bin, Box<Place>, Box<Ex>),
    /// `node!(tag)`.
    Node(Box<NodeEx>),
    /// `state!(x)`: the variable's value as an `Option`.
    State(tdl::StateVar, tcm_expr::Type),
    /// A loop in expression position (a Rust statement).
    Loop(Box<LoopSt>),
}

/// A closure's parameters and body, in the frame of the body it is written in.
pub(crate) struct Closure {
    pub(crate) params: Vec<Pat>,
    pub(crate) body: Ex,
}

/// A place assigned to.
#[derive(Clone)]
pub(crate) enum Place {
    Local(Slot),
    Field(Box<Place>, Arc<str>),
    TupleField(Box<Place>, usize),
    Index(Box<Place>, Box<Ex>),
}

/// A pattern.
#[derive(Clone)]
pub(crate) enum Pat {
    Wild,
    Bind(Slot, Option<Box<Pat>>),
    Lit(Value),
    Range(Option<Value>, Option<Value>, bool),
    Tuple(Vec<Pat>),
    /// A variant with fields: `Some(x)`, `Ended::Failed(f)`; the enum's name if written.
    Variant(Option<Arc<str>>, Arc<str>, Vec<Pat>),
    /// A record pattern `Name { a, b: p, .. }`.
    Record(Arc<str>, Vec<(Arc<str>, Pat)>),
    Or(Vec<Pat>),
    /// A constant of the registry, compared with `==`.
    Const(Value),
}

/// A match arm.
#[derive(Clone)]
pub(crate) struct Arm {
    pub(crate) pat: Pat,
    pub(crate) guard: Option<Ex>,
    pub(crate) body: Ex,
}

/// A block: statements and a tail value.
#[derive(Clone, Default)]
pub(crate) struct Block {
    pub(crate) stmts: Vec<St>,
    pub(crate) tail: Option<Ex>,
    /// Which statements may await (or loop), worked out on first run.
    pub(crate) awaits: std::sync::OnceLock<Vec<bool>>,
}

/// A loop.
#[derive(Clone)]
pub(crate) struct LoopSt {
    pub(crate) label: Option<Arc<str>>,
    pub(crate) kind: LoopKind,
    pub(crate) body: Block,
    /// The loop counts its iterations for iteration-indexed tags: its count and its current
    /// iteration's TDL slots.
    pub(crate) counter: Option<(TSlot, TSlot)>,
    pub(crate) loc: Loc,
}

#[derive(Clone)]
pub(crate) enum LoopKind {
    For(Pat, Ex),
    While(Ex),
    Loop,
}

/// A statement.
#[derive(Clone)]
pub(crate) enum St {
    Let(Pat, Option<Ex>, Option<Box<Block>>),
    Expr(Ex),
    Spawn(Box<SpawnSt>),
    With(Box<WithSt>),
    Constrain(Box<ConstrainSt>),
    Bind(Option<TSlot>, Ex),
    Succeed,
    Fail(Box<FailSt>),
    Bypass,
    Trigger,
    Retry(Option<Vec<Ex>>),
    Resource(ResourceOp, ResRef),
    Set(tdl::StateVar, Option<Ex>),
    Raise(NameEx),
    /// `log "format", args…;`: the line, a `format!` expression.
    Log(Ex),
    Loop(Box<LoopSt>),
}

/// `fail [E { fields }]`.
#[derive(Clone)]
pub(crate) struct FailSt {
    pub(crate) exception: Option<&'static str>,
    pub(crate) ancestry: Vec<&'static str>,
    pub(crate) fields: Vec<(Arc<str>, Ex)>,
}

/// An external event's name: written, or computed.
#[derive(Clone)]
pub(crate) enum NameEx {
    Lit(Arc<str>),
    Expr(Ex),
}

/// A resource: declared by the program (with its capacity and pending limit), or only named.
#[derive(Clone)]
pub(crate) enum ResRef {
    Declared(&'static str, u32, Option<u32>),
    Named(&'static str),
}

/// A count (`maximum activate N`): a literal or an expression.
#[derive(Clone)]
pub(crate) enum CountEx {
    Const(u32),
    Expr(Ex),
}

/// A duration: fixed, or seconds computed.
#[derive(Clone)]
pub(crate) enum DurEx {
    Fixed(Duration),
    Secs(Ex),
}

/// A call of a task: what the spawn or the handler builds.
#[derive(Clone)]
pub(crate) enum TaskCall {
    /// A task of the program.
    Tdl(TaskIdx, Vec<Ex>),
    /// A task built in Rust.
    /// A task built in Rust; the parameter types of its `extern` declaration, if any.
    Rust(TaskEntry, Vec<Ex>, Option<Arc<Vec<Ty>>>),
    /// A task of an agent (`on AGENT`), by the run's placer.
    Remote {
        agent: Ex,
        name: Arc<str>,
        kind: tdl::NodeKind,
        args: Vec<Ex>,
    },
}

/// A handler named in a constraint: its definition, arguments and `maximum activate`.
#[derive(Clone)]
pub(crate) struct HandlerCall {
    pub(crate) task: TaskIdx,
    pub(crate) args: Vec<Ex>,
    pub(crate) max: Option<CountEx>,
}

/// One node, as `codegen/lower.rs`'s `Nodes::One` expressions.
#[derive(Clone)]
pub(crate) enum NodeEx {
    /// The reservation in a TDL slot.
    Reserved(TSlot),
    /// The entry of an iteration map for these indexes, reserved on first use.
    Slot(TSlot, Vec<KeyEx>, &'static str),
    /// A tag bound at run time (`node!(tag)` fails when it is not bound yet).
    Bound(TSlot, Arc<str>),
    This,
    Parent,
    /// The body's own node (`ctx.node()`).
    Own,
    /// No node (a constraint naming none).
    Nothing,
    /// The node computed before the spawn (`SpawnSt::pre`).
    Pre,
    /// A fresh reservation for the spawn (a waited spawn some tag needs, named by no tag).
    Fresh(&'static str),
}

/// An iteration index.
#[derive(Clone)]
pub(crate) enum KeyEx {
    Expr(Ex),
    /// The current iteration of a loop, by its TDL slot.
    Current(TSlot),
}

/// The nodes a tag denotes at run time (`codegen/lower.rs`'s `Nodes`).
#[derive(Clone)]
pub(crate) enum Nodes {
    One(NodeEx),
    /// An entity whose members are only known at run time.
    Entity(EntityEx),
    None,
}

/// An entity's members (`None`: no entity at all, as `previous` before anything ran).
#[derive(Clone)]
pub(crate) enum EntityEx {
    /// `previous` as held in this TDL slot.
    Prev(TSlot),
    /// The nodes held in a TDL slot (a group's, a bound tag's).
    Held(TSlot),
    /// The entries of an iteration map whose key starts with these indexes.
    Prefix(TSlot, Vec<KeyEx>),
}

/// A constraint waiting for its node (`codegen/lower.rs`'s `Low`).
#[derive(Clone)]
pub(crate) enum Low {
    ExpandFirst,
    DelayExpansion,
    Sequential(Facet),
    Serial,
    Trigger(WhenEx, Then),
}

/// A trigger's `when`; an event's node is given when the constraint is applied.
#[derive(Clone)]
pub(crate) enum WhenEx {
    Now,
    At(f64),
    In(DurEx),
    Event(EventEx),
    After(DurEx, EventEx),
    External(NameEx),
    Condition(Vec<tdl::StateVar>, tdl::Expr),
    Changed(tdl::StateVar),
}

/// An event's facet and point (its node comes with the constraint).
#[derive(Clone, Copy)]
pub(crate) struct EventEx {
    pub(crate) facet: Option<Facet>,
    pub(crate) point: Point,
    pub(crate) outcome: Option<tdl::Outcome>,
}

/// A constraint lowered with its nodes (`codegen/lower.rs`'s `Lowered`).
#[derive(Clone)]
pub(crate) enum Lowered {
    Each {
        nodes: Nodes,
        low: Low,
        empty: Option<Low>,
    },
    /// A `terminate` or `activate` on an entity's event: armed with `trigger_entity`.
    Entity {
        members: EntityEx,
        delay: Option<DurEx>,
        facet: Facet,
        point: Point,
        then: Then,
    },
}

/// One step of a spawn's builder chain.
#[derive(Clone)]
pub(crate) enum Step {
    Propagate,
    /// `approval [within T]`.
    Approval(Option<DurEx>),
    Under(Ex),
    OnTerminate(TaskCall, Option<NodeEx>),
    Handler(HandlerCall),
    MaxActivations(CountEx),
    MaxTriggers(CountEx),
    Period(DurEx),
    Uses(ResRef, CountEx),
    Priority(Ex),
    DenyIfBusy,
    Fulfils(NodeEx),
    Low(Nodes, Low, Option<Low>),
}

/// What takes a waited spawn's value.
#[derive(Clone)]
pub(crate) enum BindTo {
    Let(Pat),
    Assign(Place),
}

/// A spawn statement.
#[derive(Clone)]
pub(crate) struct SpawnSt {
    pub(crate) task: TaskCall,
    pub(crate) name: Option<Ex>,
    /// `let tdl_node = <slot>;` before anything else (a waited spawn in a loop that some tag
    /// names).
    pub(crate) pre: Option<NodeEx>,
    /// The node of the spawn when some tag names it (after `pre`, `Reserved` of nothing).
    pub(crate) id: Option<NodeEx>,
    pub(crate) steps: Vec<Step>,
    pub(crate) armed: Vec<Lowered>,
    pub(crate) wait: bool,
    pub(crate) outcome: bool,
    pub(crate) binding: Option<(BindTo, Ty)>,
    /// The TDL slot bound when spawned (a spawn with `parent`).
    pub(crate) late: Option<TSlot>,
    pub(crate) needs_id: bool,
    /// The group slots collecting it.
    pub(crate) members: Vec<TSlot>,
    /// The `previous` slot to update, when the body uses `previous`.
    pub(crate) prev: Option<TSlot>,
    pub(crate) loc: Loc,
}

/// A `with` group.
#[derive(Clone)]
pub(crate) struct WithSt {
    /// Cleared at the start (a labelled group), or made afresh (one tracked for `previous`).
    pub(crate) members: Option<TSlot>,
    /// `previous` snapshotted for the enclosing group: (from, into).
    pub(crate) snapshot: Option<(TSlot, TSlot)>,
    pub(crate) body: Block,
    /// `previous` becomes the group's members after it.
    pub(crate) prev: Option<TSlot>,
}

/// A constraint statement `TAG constraint;`.
#[derive(Clone)]
#[allow(
    clippy::large_enum_variant,
    reason = "built once per statement when the program is loaded"
)]
pub(crate) enum ConstrainSt {
    Wait(Nodes),
    Terminate(Nodes),
    MaxActivations(Nodes, CountEx),
    MaxTriggers(Nodes, CountEx),
    Period(Nodes, DurEx),
    Apply(Nodes, Lowered),
}

/// A task of the program, ready to be built into `tdl::Task`s.
pub(crate) struct TaskDef {
    pub(crate) name: &'static str,
    pub(crate) kind: TaskKind,
    pub(crate) params: Vec<(Arc<str>, Ty)>,
    // The parameters, shared by each node's kept arguments to describe them (`value::Args`).
    pub(crate) shown: crate::value::Params,
    pub(crate) result: Option<Ty>,
    pub(crate) persistent: bool,
    pub(crate) blocking: bool,
    // Started again when its run resumes from a journal (`tcm::Task::idempotent`).
    pub(crate) idempotent: bool,
    /// Task-level modifiers, in the order the generator applies them.
    pub(crate) modifiers: Vec<Modifier>,
    pub(crate) monitor: tdl::Monitor,
    pub(crate) monitor_counts: (Option<CountEx>, Option<CountEx>),
    pub(crate) handles: Option<Arc<str>>,
    pub(crate) caught: Option<Slot>,
    pub(crate) failing: Option<Slot>,
    pub(crate) attached: Option<Slot>,
    pub(crate) for_task: Option<Arc<str>>,
    /// For a wiretap: whether it checks after (else before) the nodes of this task.
    pub(crate) tap: Option<(bool, Arc<str>)>,
    /// Persistent variables: slot, type, initial value.
    pub(crate) persistents: Vec<(Slot, Ty, Option<Ex>)>,
    /// TDL slots initialised at the top of the body, in the generator's order.
    pub(crate) prelude: Vec<(TSlot, Init)>,
    pub(crate) body: Block,
    /// Whether the body may make children (it then holds them until it ends or waits).
    pub(crate) holds: bool,
    /// Whether the body may await (else it runs within its action's first poll).
    pub(crate) awaits: bool,
    pub(crate) locals: usize,
    pub(crate) tdl_slots: usize,
    pub(crate) loc: Loc,
}

/// A task-level modifier.
#[derive(Clone)]
pub(crate) enum Modifier {
    ExpandFirst,
    DelayExpansion,
    OnTerminate(TaskCall),
    Handler(HandlerCall),
    /// A handler's `maximum activate`.
    MaxActivations(CountEx),
    Uses(ResRef, CountEx),
    Priority(Ex),
}

/// How a TDL slot starts.
#[derive(Clone)]
pub(crate) enum Init {
    /// `ctx.reserve(name)`.
    Reserve(&'static str),
    /// An empty map of reservations by iteration.
    Map,
    /// An empty list of a group's members.
    Nodes,
    /// No node yet: `previous`, a tag bound at run time.
    Maybe,
}
