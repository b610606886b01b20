//! State variables and conditions as the runtime offers them (docs/semantics.md, "State and
//! conditions"). A variable is named by its declaration, a [`StateVar`], wherever it is used:
//! the run declares it on first use (TDL's `state battery_ok: bool = true;` generates one per
//! use). It is set from a body ([`Ctx::set_state`]), from the program or any thread
//! ([`EventHandle::set_state`](crate::EventHandle::set_state),
//! [`Session::set_state`](crate::Session::set_state)), or declared on the runtime beforehand
//! ([`Runtime::state`](crate::Runtime::state)); each set is an input to the engine, recorded in
//! the trace with its value. Conditions over variables ([`Ctx::condition`]) are constraint
//! sources: `When::Condition`, [`Constraint::skip_if`](crate::Constraint::skip_if),
//! [`Constraint::invariant`](crate::Constraint::invariant),
//! [`Constraint::pause_while`](crate::Constraint::pause_while).

use crate::Error;
use crate::ctx::Ctx;
use crate::task::Exception;
use tcm_core::{Engine, EngineError};

pub use tcm_core::{BinOp, CondId, Expr, InvariantFailed, StateId};
pub use tcm_core::{Type as StateType, Value as StateValue};

impl Exception for InvariantFailed {}

/// A state variable's declaration: its name, type and initial value.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StateVar {
    name: String,
    ty: StateType,
    initial: StateValue,
}

impl StateVar {
    /// `name: ty = initial` (an integer initial value of a `float` variable is taken as a float).
    pub fn new(name: impl Into<String>, ty: StateType, initial: impl Into<StateValue>) -> StateVar {
        StateVar {
            name: name.into(),
            ty,
            initial: initial.into(),
        }
    }

    /// Its name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Its type.
    pub fn ty(&self) -> StateType {
        self.ty
    }

    /// Declares it on `engine` (a variable already declared keeps its value).
    pub(crate) fn declare<A, F: Clone>(
        &self,
        engine: &mut Engine<A, F>,
    ) -> Result<StateId, EngineError> {
        engine.declare_state(&self.name, self.ty, self.initial.clone())
    }
}

/// A Rust type a state variable's value is read as ([`Ctx::read_state`]): `bool`, `i64`, `f64`
/// (also from an integer) and `String`.
pub trait FromState: Sized {
    /// The value as `Self`, `None` if it is unknown or of another type.
    fn from_state(value: &StateValue) -> Option<Self>;
}

impl FromState for bool {
    fn from_state(value: &StateValue) -> Option<bool> {
        match value {
            StateValue::Bool(b) => Some(*b),
            _ => None,
        }
    }
}

impl FromState for i64 {
    fn from_state(value: &StateValue) -> Option<i64> {
        match value {
            StateValue::Int(i) => Some(*i),
            _ => None,
        }
    }
}

impl FromState for f64 {
    fn from_state(value: &StateValue) -> Option<f64> {
        match value {
            StateValue::Int(i) => Some(*i as f64),
            StateValue::Float(x) => Some(*x),
            _ => None,
        }
    }
}

impl FromState for String {
    fn from_state(value: &StateValue) -> Option<String> {
        match value {
            StateValue::Str(s) => Some(s.clone()),
            _ => None,
        }
    }
}

impl FromState for StateValue {
    fn from_state(value: &StateValue) -> Option<StateValue> {
        Some(value.clone())
    }
}

/// Sets the variable `name` on `engine`: declared already, or declared now with the value's type
/// (an unknown value cannot say its type: that is an error).
pub(crate) fn set_by_name<A, F: Clone>(
    engine: &mut Engine<A, F>,
    now: tcm_core::Time,
    name: &str,
    value: StateValue,
) -> Result<(), EngineError> {
    let id = match engine.state_id(name) {
        Some(id) => id,
        None => match value.type_of() {
            Some(ty) => engine.declare_state(name, ty, value.clone())?,
            None => return Err(EngineError::UnknownState(name.to_string())),
        },
    };
    engine.set_state(now, id, value)
}

impl Ctx {
    /// The variable's id, declaring it on first use: for `When::Changed`.
    pub fn state_var(&self, var: &StateVar) -> Result<StateId, Error> {
        self.with_engine(|e, _| var.declare(e))
    }

    /// Registers a condition over the variables `vars` (each declared on first use), for
    /// `When::Condition` and the condition constraints.
    pub fn condition(&self, vars: &[StateVar], expr: Expr) -> Result<CondId, Error> {
        self.with_engine(|e, _| {
            for v in vars {
                v.declare(e)?;
            }
            e.condition(&expr)
        })
    }

    /// Sets a variable (declared on first use): an input to the engine, recorded with its value;
    /// the conditions that read it act if it changed.
    pub fn set_state(&self, var: &StateVar, value: impl Into<StateValue>) -> Result<(), Error> {
        let value = value.into();
        self.with_engine(|e, now| {
            let id = var.declare(e)?;
            e.set_state(now, id, value)
        })
    }

    /// A variable's value now (declared on first use), as `T`: `None` while it is unknown.
    pub fn read_state<T: FromState>(&self, var: &StateVar) -> Result<Option<T>, Error> {
        self.with_engine(|e, _| {
            let id = var.declare(e)?;
            Ok(e.state(id).and_then(|(_, _, v)| T::from_state(v)))
        })
    }

    /// Sets the variable `name` (declared by the program or the runtime; an undeclared one is
    /// declared with the value's type): for code that names variables at run time, as a
    /// distribution layer does for an agent's sets.
    pub fn set_state_named(&self, name: &str, value: impl Into<StateValue>) -> Result<(), Error> {
        let value = value.into();
        self.with_engine(|e, now| set_by_name(e, now, name, value))
    }

    /// The value of the variable `name`, if it is declared.
    pub fn state(&self, name: &str) -> Result<Option<StateValue>, Error> {
        self.with_engine(|e, _| {
            Ok(e.state_id(name)
                .and_then(|id| e.state(id).map(|(_, _, v)| v.clone())))
        })
    }
}
