//! State variables and conditions in the syntax tree (docs/language.md, "State and conditions"):
//! `state NAME: TYPE [= LITERAL];`, the conditions of `disable until`, `terminate when`,
//! `activate when`, `skip if`, `invariant` and `pause while`, and the statements `set` and
//! `raise`. A condition keeps the span of each of its parts for the diagnosis; what it means is
//! its [`tcm_expr::Expr`] ([`CondExpr::to_expr`]), which the code generator builds and the printer
//! writes. Re-exported by `ast.rs`.

use proc_macro2::{Ident, Span};
use tcm_expr::{BinOp, Expr, Type, Value};

use super::ExternalName;

/// `state NAME: TYPE [= LITERAL];`: a state variable of the program, declared once.
#[derive(Clone, Debug)]
pub struct StateDecl {
    /// Outer attributes, including doc comments (kept for the reader; nothing is generated).
    pub attrs: Vec<syn::Attribute>,
    /// The variable's name, as conditions, `set` and `state!` name it.
    pub name: Ident,
    /// The type as written: `bool`, `int`, `float` or `string` ([`StateDecl::ty`]).
    pub ty_name: Ident,
    /// `= LITERAL`; `None`: unknown.
    pub init: Option<StateLit>,
    /// Span of the name.
    pub span: Span,
}

impl StateDecl {
    /// Its type; `None` when the type name is not one of TDL's four (the parser reported it).
    pub fn ty(&self) -> Option<Type> {
        state_type(&self.ty_name.to_string())
    }

    /// Its initial value as declared, of its type (an integer for a `float` is a float);
    /// unknown without an initialiser or when the literal does not fit (the diagnosis reports it).
    pub fn initial(&self) -> Value {
        match (&self.init, self.ty()) {
            (Some(init), Some(ty)) => init.value.clone().coerce(ty).unwrap_or(Value::Unknown),
            _ => Value::Unknown,
        }
    }
}

/// The type TDL names `name`: `bool`, `int`, `float` or `string`.
pub fn state_type(name: &str) -> Option<Type> {
    match name {
        "bool" | "int" | "float" | "string" => Type::from_name(name),
        _ => None,
    }
}

/// A literal with its span: a state's initial value, or a literal in a condition.
#[derive(Clone, Debug)]
pub struct StateLit {
    /// The value; `unknown` is [`Value::Unknown`].
    pub value: Value,
    /// Where it is written (the sign of a negative number included).
    pub span: Span,
}

/// A condition over state variables, as written after `until`, `when`, `if`, `invariant` or
/// `while`.
#[derive(Clone, Debug)]
pub struct Cond {
    /// The expression.
    pub expr: CondExpr,
    /// Span of the whole condition (its first token where spans cannot be joined).
    pub span: Span,
}

impl Cond {
    /// What it means: the expression the engine evaluates.
    pub fn to_expr(&self) -> Expr {
        self.expr.to_expr()
    }

    /// The variables it reads, each once, in the order they first appear.
    pub fn vars(&self) -> Vec<&Ident> {
        let mut out: Vec<&Ident> = Vec::new();
        self.expr.each_var(&mut |v| {
            if !out.contains(&v) {
                out.push(v);
            }
        });
        out
    }
}

/// A condition's expression, each part with its span. Parentheses are not kept: the tree says
/// what they grouped.
#[derive(Clone, Debug)]
pub enum CondExpr {
    /// `true`, `3`, `-2.5`, `"text"`, or `unknown` (refused by the diagnosis).
    Lit(StateLit),
    /// A state variable.
    Var(Ident),
    /// `!e`; the span is the operator's.
    Not(Box<CondExpr>, Span),
    /// `-e`; the span is the operator's.
    Neg(Box<CondExpr>, Span),
    /// `is_known(e)`; the span is `is_known`'s.
    Known(Box<CondExpr>, Span),
    /// `l op r`.
    Bin {
        /// The operator.
        op: BinOp,
        /// Left operand.
        l: Box<CondExpr>,
        /// Right operand.
        r: Box<CondExpr>,
        /// Span of the operator.
        span: Span,
    },
}

impl CondExpr {
    /// What it means, as the engine's expression.
    pub fn to_expr(&self) -> Expr {
        match self {
            CondExpr::Lit(lit) => Expr::Lit(lit.value.clone()),
            CondExpr::Var(name) => Expr::var(name.to_string()),
            CondExpr::Not(e, _) => Expr::not(e.to_expr()),
            CondExpr::Neg(e, _) => Expr::Neg(Box::new(e.to_expr())),
            CondExpr::Known(e, _) => Expr::known(e.to_expr()),
            CondExpr::Bin { op, l, r, .. } => Expr::bin(*op, l.to_expr(), r.to_expr()),
        }
    }

    /// Where the diagnosis points for this part: a literal or a variable itself, an operator.
    pub fn span(&self) -> Span {
        match self {
            CondExpr::Lit(lit) => lit.span,
            CondExpr::Var(name) => name.span(),
            CondExpr::Not(_, span) | CondExpr::Neg(_, span) | CondExpr::Known(_, span) => *span,
            CondExpr::Bin { span, .. } => *span,
        }
    }

    fn each_var<'a>(&'a self, f: &mut impl FnMut(&'a Ident)) {
        match self {
            CondExpr::Lit(_) => {}
            CondExpr::Var(v) => f(v),
            CondExpr::Not(e, _) | CondExpr::Neg(e, _) | CondExpr::Known(e, _) => e.each_var(f),
            CondExpr::Bin { l, r, .. } => {
                l.each_var(f);
                r.each_var(f);
            }
        }
    }
}

/// `set VAR = EXPR;`: the state variable takes the value of a Rust expression (anything that is
/// `Into<tdl::StateValue>`; `unknown` makes it unknown).
#[derive(Clone, Debug)]
pub struct SetState {
    /// The variable.
    pub name: Ident,
    /// The value.
    pub value: syn::Expr,
    /// Span of the `set` keyword.
    pub span: Span,
}

/// `raise "name";` or `raise (expr);`: raises the named external event.
#[derive(Clone, Debug)]
pub struct Raise {
    /// The event's name.
    pub name: ExternalName,
    /// Span of the `raise` keyword.
    pub span: Span,
}

/// `environment { … }`: what the outside may change, for `tdl verify` and `tdl sim` (docs/
/// verification.md, "The environment"). Nothing is generated from it.
#[derive(Clone, Debug)]
pub struct EnvironmentDecl {
    /// Its entries, in order.
    pub entries: Vec<EnvEntry>,
    /// Span of the `environment` keyword.
    pub span: Span,
}

/// One entry of an environment declaration: `VAR: v1, v2 [at most N] [when COND];` or
/// `external "name" [at most N] [when COND];`.
#[derive(Clone, Debug)]
pub struct EnvEntry {
    /// What the outside changes.
    pub target: EnvTarget,
    /// For a variable: the values it may take.
    pub values: Vec<StateLit>,
    /// `at most N`: how many times per run (1 without it).
    pub at_most: Option<(u32, Span)>,
    /// `when COND`: only while the condition holds.
    pub when: Option<Cond>,
    /// Span of the entry's first token.
    pub span: Span,
}

/// What an environment entry changes.
#[derive(Clone, Debug)]
pub enum EnvTarget {
    /// A state variable.
    State(Ident),
    /// An external event.
    External(syn::LitStr),
}

impl EnvEntry {
    /// How many times per run the outside may use the entry.
    pub fn at_most(&self) -> u32 {
        self.at_most.map_or(1, |(n, _)| n)
    }
}
