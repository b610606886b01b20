//! The checker's form of a task body: the statement tree flattened into instructions with jumps,
//! so that a suspended body is a program counter and a few locals (a continuation) that hashes
//! and clones cheaply.
//!
//! It keeps what the generated code asks of the runtime (spawns with their constraints, constraint
//! statements, waits, `fail`, `trigger`, `retry`, `bypass`, `with` groups, `previous`, tags and
//! their reservations; crates/tdl-syntax/src/codegen/) and, of the Rust between them, only what
//! decides which TDL statement runs next: conditions, loops, and the `return`, `break` and
//! `continue` a Rust statement may take. Compilation is [`crate::program`]'s.

use crate::value::{Sym, VExpr};
use tcm_core::{Facet, Outcome, Point, Then};

/// A task of the program, by number.
pub(crate) type TaskId = u16;
/// A loop of one body, by number.
pub(crate) type LoopId = u16;
/// A tag of one body, by number.
pub(crate) type TagId = u16;
/// A `with` group of one body, by number.
pub(crate) type GroupId = u16;

/// What a spawn names: a task of the TDL program, or a Rust function outside it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub(crate) enum Callee {
    Task(TaskId),
    Extern(u16),
}

/// A task and its arguments.
#[derive(Clone, Debug)]
pub(crate) struct Call {
    pub(crate) callee: Callee,
    pub(crate) args: Vec<VExpr>,
}

/// One instruction.
#[derive(Clone, Debug)]
pub(crate) enum Op {
    /// `let x = e;` with a value the checker can follow.
    Let(Sym, VExpr),
    /// Variables a Rust statement may change in ways the checker does not follow.
    Forget(Vec<Sym>),
    /// A Rust statement that may leave the body (`return`), the loop (`break`) or the iteration
    /// (`continue`): a choice between going on and each way out.
    Exit(Exits),
    Spawn(u32),
    /// A constraint statement (`X c;`, `X wait;`, `X terminate;`, monitor limits).
    Stmt(u32),
    /// `bind name = expr;`: the node is Rust's, so the tag names nothing the checker knows.
    Bind(TagId),
    Succeed,
    Fail(Option<String>),
    Bypass,
    Trigger,
    Retry,
    /// Jumps to `else_pc` unless `cond` holds; an unknown condition is a choice.
    If {
        cond: VExpr,
        else_pc: u32,
    },
    /// A `match` whose scrutinee the checker does not know: a choice among the arms.
    Match(Vec<u32>),
    Jump(u32),
    LoopStart {
        id: LoopId,
        iter: Iter,
    },
    /// The top of each iteration: go on at the next instruction or leave for `exit`.
    LoopTest {
        id: LoopId,
        exit: u32,
    },
    GroupStart(GroupId),
    GroupEnd(GroupId),
    /// `lock r;`, `unlock r;`, `reserve r;` (for the body's own node), `unreserve r;`, on the
    /// resource declared `r` (its number in [`crate::Program`]'s resources).
    Resource(ResOp, u16),
    /// `set VAR = value;`: the program's state variable `var` (its number in
    /// [`crate::Program`]'s states) takes a value, or one of several (a value computed in Rust, a
    /// choice).
    SetState {
        var: u16,
        values: Vec<tcm_core::Value>,
    },
    /// `raise "name";`: the external event (its number in [`crate::Program`]'s events) is raised.
    Raise(u16),
    End,
}

/// What a resource statement does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum ResOp {
    Lock,
    Unlock,
    Reserve,
    Unreserve,
}

/// The resources a node uses (a task's `uses` and `priority`, a spawn's or its groups' `uses`,
/// `priority` and `deny if busy`), as the generated code asks for them.
#[derive(Clone, Debug, Default)]
pub(crate) struct UsesIr {
    /// Each declared resource (by number) and the amount.
    pub(crate) amounts: Vec<(u16, VExpr)>,
    pub(crate) priority: Option<VExpr>,
    pub(crate) deny_if_busy: bool,
}

impl UsesIr {
    pub(crate) fn is_empty(&self) -> bool {
        self.amounts.is_empty() && self.priority.is_none() && !self.deny_if_busy
    }
}

/// The ways out a Rust statement may take.
#[derive(Clone, Debug, Default)]
pub(crate) struct Exits {
    pub(crate) ret: bool,
    /// `break`: the loop and the instruction after it.
    pub(crate) brk: Option<(LoopId, u32)>,
    /// `continue`: the loop and its test.
    pub(crate) cont: Option<(LoopId, u32)>,
}

/// How many times a loop runs.
#[derive(Clone, Debug)]
pub(crate) enum Iter {
    /// `for v in a..b` (or `a..=b`): counted when both ends are known when the loop starts.
    Range {
        start: VExpr,
        end: VExpr,
        inclusive: bool,
        var: Option<Sym>,
    },
    /// `for _ in [a, b, c]`: a literal array's length.
    Count(u32),
    /// `while cond`.
    While(VExpr),
    /// Over a collection the checker cannot see: 0 to the loop bound times.
    Unknown,
    /// `loop`: until a `break`.
    Forever,
}

/// How a spawn waits for its child.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) enum Wait {
    No,
    /// `with wait`: goes on however the child ended.
    Plain,
    /// `let v = spawn … with wait`: the child's failure is the body's.
    Value,
    /// `let o = spawn … with outcome`: how the child ended, as a value.
    Outcome,
}

/// A spawn statement.
#[derive(Clone, Debug)]
pub(crate) struct SpawnIr {
    pub(crate) call: Call,
    /// Its tag, when some constraint, wait or `node!` of the body names it.
    pub(crate) tag: Option<TagId>,
    /// The `with` groups around it, outermost first.
    pub(crate) groups: Vec<GroupId>,
    pub(crate) cons: Vec<CIr>,
    pub(crate) wait: Wait,
    pub(crate) propagate: bool,
    /// `approval [within T]`: held at its turn to start until the environment approves or
    /// refuses it.
    pub(crate) approval: Option<Option<TimeIr>>,
    pub(crate) name: Option<VExpr>,
    pub(crate) handlers: Vec<HandlerUse>,
    pub(crate) on_terminate: Vec<(Call, Option<TagId>)>,
    pub(crate) monitor: MonitorOverride,
    /// Its `uses`, `priority`, `deny if busy`.
    pub(crate) uses: UsesIr,
    /// A termination constraint (on it or on its group) or a `terminate` statement names it: a
    /// command under it may be left running forever (docs/verification.md, "Commands").
    pub(crate) terminable: bool,
    /// `on AGENT` (on it or on its group): a command of the checker's choice that may also fail
    /// with `AgentLost`.
    pub(crate) remote: bool,
    pub(crate) line: u32,
}

/// Monitor parameters given at a spawn or on its groups, the last one given winning.
#[derive(Clone, Debug, Default)]
pub(crate) struct MonitorOverride {
    pub(crate) max_activations: Option<VExpr>,
    pub(crate) max_triggers: Option<VExpr>,
    pub(crate) period: Option<TimeIr>,
}

/// `exception handler h(args) [maximum activate N]`.
#[derive(Clone, Debug)]
pub(crate) struct HandlerUse {
    pub(crate) handler: TaskId,
    pub(crate) args: Vec<VExpr>,
    pub(crate) max: Option<VExpr>,
}

/// A `with (…) { … }` group.
#[derive(Clone, Debug)]
pub(crate) struct GroupIr {
    pub(crate) cons: Vec<CIr>,
    pub(crate) monitor: MonitorOverride,
    /// Resources every member uses (`uses`, `priority`, `deny if busy` on the group).
    pub(crate) uses: UsesIr,
    pub(crate) wait: bool,
    pub(crate) propagate: bool,
    pub(crate) terminable: bool,
    /// `on AGENT`: every member runs on an agent.
    pub(crate) remote: bool,
    /// Its constraints name `previous`: a nested group then sees the entity before it.
    pub(crate) uses_previous: bool,
    /// Its label's tag, when something names it.
    pub(crate) tag: Option<TagId>,
}

/// A constraint statement.
#[derive(Clone, Debug)]
pub(crate) struct StmtIr {
    pub(crate) target: TagRef,
    pub(crate) op: StmtOp,
}

#[derive(Clone, Debug)]
pub(crate) enum StmtOp {
    Constrain(CIr),
    Wait,
    Terminate,
    MaxActivations(VExpr),
    MaxTriggers(VExpr),
    Period(TimeIr),
}

/// A constraint, with its tags still to be resolved at run time.
#[derive(Clone, Debug)]
pub(crate) enum CIr {
    ExpandFirst,
    DelayExpansion,
    Sequential(Facet, TagRef),
    Serial(TagRef),
    Trigger { when: WhenIr, then: Then },
}

impl CIr {
    pub(crate) fn terminates(&self) -> bool {
        matches!(
            self,
            CIr::Trigger {
                then: Then::Terminate,
                ..
            }
        )
    }

    pub(crate) fn uses_previous(&self) -> bool {
        let r = match self {
            CIr::Sequential(_, r) | CIr::Serial(r) => Some(r),
            CIr::Trigger { when, .. } => when.event().map(|e| &e.tag),
            CIr::ExpandFirst | CIr::DelayExpansion => None,
        };
        matches!(r, Some(TagRef::Previous))
    }
}

/// What a tag names.
#[derive(Clone, Debug)]
pub(crate) enum TagRef {
    /// `previous`: the entity executed just before (one node, or a whole group).
    Previous,
    /// `self`/`child`: the node being spawned.
    This,
    /// `parent`/`this`: the node whose body runs.
    Parent,
    /// A named tag with its iteration indexes.
    Named(TagId, Vec<IndexIr>),
    /// Nothing the checker knows (a tag bound from Rust).
    Opaque,
}

#[derive(Clone, Debug)]
pub(crate) enum IndexIr {
    Current(LoopId),
    Expr(VExpr),
}

#[derive(Clone, Debug)]
pub(crate) enum WhenIr {
    Now,
    /// A time of day, in nanoseconds since midnight (the checker's runs start at midnight).
    At(u64),
    In(TimeIr),
    Event(EventIr),
    After(TimeIr, EventIr),
    /// A named external event; `None` for a name computed in Rust.
    External(Option<String>),
    /// A condition over state variables.
    Condition(tcm_core::Expr),
    /// A change of the named state variable.
    Changed(String),
}

impl WhenIr {
    pub(crate) fn event(&self) -> Option<&EventIr> {
        match self {
            WhenIr::Event(e) | WhenIr::After(_, e) => Some(e),
            _ => None,
        }
    }
}

#[derive(Clone, Debug)]
pub(crate) struct EventIr {
    pub(crate) tag: TagRef,
    pub(crate) facet: Facet,
    pub(crate) point: Point,
    pub(crate) outcome: Option<Outcome>,
}

/// A relative time: a constant, or seconds computed in Rust.
#[derive(Clone, Debug)]
pub(crate) enum TimeIr {
    Nanos(u64),
    Secs(VExpr),
}

/// What a named tag of a body is.
#[derive(Clone, Debug)]
pub(crate) struct TagDef {
    pub(crate) kind: TagKind,
    /// The loops around the spawn (an iteration-indexed tag has one index per loop).
    pub(crate) loops: Vec<LoopId>,
    /// The name its reservation is made under.
    pub(crate) reserve_as: String,
    /// What of the body it names.
    pub(crate) of: TagOf,
}

/// What a named tag of a body names.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) enum TagOf {
    /// A spawn, by its number in the body.
    Spawn(usize),
    /// A `with` group, by its number.
    Group(usize),
    /// The `k`th on-terminate task of spawn `i`.
    OnTerminate(usize, usize),
    /// A tag bound with `bind`.
    Bound(String),
}

/// A tag written in a constraint and what the loader made of it, for
/// [`crate::Program::resolved_tags`].
#[derive(Clone, Debug)]
pub(crate) struct TagUse {
    pub(crate) line: usize,
    pub(crate) column: usize,
    pub(crate) tag: TagUseOf,
}

/// What a tag written in a constraint was taken for.
#[derive(Clone, Copy, Debug)]
pub(crate) enum TagUseOf {
    Tag(TagId),
    Parent,
    This,
    Unknown,
}

#[derive(Clone, Debug)]
pub(crate) enum TagKind {
    Spawn,
    Group,
    /// The label of an on-terminate task of a spawn.
    OnTerminate,
    /// `bind name = …;`: a node the checker cannot see.
    Bound,
}

/// A compiled body.
#[derive(Clone, Debug, Default)]
pub(crate) struct Body {
    pub(crate) ops: Vec<Op>,
    /// The source line of each instruction.
    pub(crate) lines: Vec<u32>,
    pub(crate) spawns: Vec<SpawnIr>,
    pub(crate) groups: Vec<GroupIr>,
    pub(crate) stmts: Vec<StmtIr>,
    pub(crate) tags: Vec<TagDef>,
    /// Every tag written in a constraint, `previous` aside, as it was resolved.
    pub(crate) tag_uses: Vec<TagUse>,
    pub(crate) n_loops: u16,
}
