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

use crate::exception::Exception;
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
