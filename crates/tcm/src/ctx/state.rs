//! What an action asks of the run's state variables (docs/semantics.md, "State and
//! conditions"): declare, condition, set and read.

use super::Ctx;
use crate::Error;
use crate::state::{FromState, StateVar, set_by_name};
use tcm_core::{CondId, Expr, StateId, Value as StateValue};

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
