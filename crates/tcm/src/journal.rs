//! A run's journal (docs/semantics.md, "Durable runs"): the inputs its engine takes, written by a
//! `tcm_journal::Writer` before the effects they cause are carried out, so that nothing the robot
//! did follows an input the journal lost. A failed write ends the run at its next turn with the
//! unhandled exception `JournalFailed` at the root: it never goes on unjournaled.

use tcm_core::{Engine, InputRecord};
use tcm_journal::{Input, Writer};

/// How a journal writes an action's value: JSON, or `None` for a value it cannot write (then the
/// entry has none).
pub type ValueEncoder = fn(&(dyn std::any::Any + Send)) -> Option<serde_json::Value>;
/// A task's own [`ValueEncoder`] (`Task::journaled`).
pub(crate) type EncodeFn =
    dyn Fn(&(dyn std::any::Any + Send)) -> Option<serde_json::Value> + Send + Sync;

/// The default [`ValueEncoder`]: a value that is JSON already (what a task from an agent, or a
/// fault from a file, gives).
pub fn json_values(value: &(dyn std::any::Any + Send)) -> Option<serde_json::Value> {
    value.downcast_ref::<serde_json::Value>().cloned()
}

/// The journal of a run, kept beside its engine (`Inner::journal`).
pub(crate) struct Journaled {
    writer: Writer,
    // The first failed write: the run ends with it.
    pub(crate) failed: Option<String>,
    encode: ValueEncoder,
    // The values of ends reported and not yet journaled, by node display number.
    values: Vec<(u64, serde_json::Value)>,
    // The encoders of tasks with their own (`Task::journaled`), by node display number, until
    // the node's action returns.
    encoders: std::collections::HashMap<u64, std::sync::Arc<EncodeFn>>,
}

impl Journaled {
    pub(crate) fn new(writer: Writer, encode: ValueEncoder) -> Journaled {
        Journaled {
            writer,
            failed: None,
            encode,
            values: Vec::new(),
            encoders: std::collections::HashMap::new(),
        }
    }

    /// Node `display`'s task journals its value with its own encoder (`Task::journaled`).
    pub(crate) fn encoder(&mut self, display: u64, encode: std::sync::Arc<EncodeFn>) {
        self.encoders.insert(display, encode);
    }

    /// An action returned `value`: kept, written, to go with its end. `display` gives its node's
    /// display number, looked up only if the value is written (most are not: `()`).
    pub(crate) fn value(
        &mut self,
        display: impl Fn() -> Option<u64>,
        value: &(dyn std::any::Any + Send),
    ) {
        let own = if self.encoders.is_empty() {
            None
        } else {
            display().and_then(|d| self.encoders.remove(&d))
        };
        let json = match own {
            Some(encode) => encode(value),
            None => (self.encode)(value),
        };
        if let (Some(json), Some(display)) = (json, display()) {
            self.values.push((display, json));
        }
    }

    /// Whether everything written is synced before the run starts or cancels a command
    /// (`Durability::BeforeActing`).
    #[inline]
    pub(crate) fn syncs_before_acting(&self) -> bool {
        self.writer.syncs_before_acting()
    }

    /// Writes the inputs the engine took since the last call.
    #[cold]
    #[inline(never)]
    pub(crate) fn drain<A, F: Clone>(&mut self, engine: &mut Engine<A, F>) {
        // One batch for the inputs of one access: they are written (and, with a sync per record,
        // synced) together, before the effects they cause.
        while let Some((t, at, input, body)) = engine.poll_input_given() {
            if self.failed.is_some() {
                continue;
            }
            let value = match &input {
                InputRecord::Finished {
                    node,
                    tap: None,
                    failure: None,
                } if !self.values.is_empty() => self
                    .values
                    .iter()
                    .position(|(n, _)| n == node)
                    .map(|i| self.values.remove(i).1),
                _ => None,
            };
            let added = match (input, value) {
                (
                    InputRecord::Finished {
                        node,
                        tap: None,
                        failure: None,
                    },
                    None,
                ) => {
                    self.writer.add_ended(t.as_nanos(), at, node);
                    Ok(())
                }
                (InputRecord::Finished { node, tap, .. }, Some(value)) => self.writer.add(
                    t.as_nanos(),
                    at,
                    Input::Ended {
                        node,
                        tap,
                        value: Some(value),
                    },
                ),
                (other, _) => self.writer.add_given(t.as_nanos(), at, entry(other), body),
            };
            if let Err(e) = added {
                self.failed = Some(e.to_string());
            }
        }
        if self.failed.is_none() {
            // With `BeforeActing` durability, synced first when these inputs start or cancel a
            // command: nothing the robot does follows an input the journal could lose.
            let committed = if self.writer.syncs_before_acting() && engine.effects_reach_commands()
            {
                self.writer.commit_before_acting()
            } else {
                self.writer.commit()
            };
            if let Err(e) = committed {
                self.failed = Some(e.to_string());
            }
        }
    }

    /// Syncs and closes the journal; the error of a write that failed, if one did.
    pub(crate) fn close(self) -> Result<(), String> {
        if let Some(why) = self.failed {
            return Err(why);
        }
        self.writer.close().map_err(|e| e.to_string())
    }
}

/// The journal's form of an input.
fn entry(input: InputRecord) -> Input {
    match input {
        InputRecord::Finished {
            node,
            tap,
            failure: None,
        } => Input::Ended {
            node,
            tap,
            value: None,
        },
        InputRecord::Finished {
            node,
            tap,
            failure: Some(f),
        } => Input::Failed {
            node,
            tap,
            data: f.data::<serde_json::Value>().map(|d| (*d).clone()),
            exception: f.exception.to_string(),
            ancestry: f.ancestry.iter().map(ToString::to_string).collect(),
            message: f.message,
        },
        InputRecord::Stopped { node } => Input::Stopped { node },
        InputRecord::Overdue { node, grace } => Input::Overdue {
            node,
            grace_ns: u64::try_from(grace.as_nanos()).unwrap_or(u64::MAX),
        },
        InputRecord::External { name } => Input::External { name, data: None },
        InputRecord::State { name, value } => Input::State {
            name,
            value: serde_json::to_value(&value).unwrap_or_default(),
        },
        InputRecord::Time => Input::Time,
        InputRecord::Clock => Input::Clock,
        InputRecord::Control { what, by, op } => Input::Control {
            what,
            by,
            op: op.and_then(|op| serde_json::to_value(op).ok()),
        },
        InputRecord::Log { node, message } => Input::Log { node, message },
    }
}

/// The outcome of a run whose journal failed: an unhandled failure at the root.
pub(crate) fn failed_outcome(why: &str) -> tcm_core::FatalFailure {
    tcm_core::FatalFailure {
        failure: tcm_core::Failure::new("JournalFailed", why.to_string()),
        node: 0,
        path: String::new(),
    }
}

impl Journaled {
    /// A body of node `display` read `value` from outside the run (`Ctx::record`): written after
    /// the inputs the engine took before it, and committed at once (`durable`: and synced, whatever
    /// the journal's durability).
    pub(crate) fn recorded<A, F: Clone>(
        &mut self,
        engine: &mut Engine<A, F>,
        display: u64,
        value: serde_json::Value,
        durable: bool,
    ) {
        self.drain(engine);
        if self.failed.is_some() {
            return;
        }
        let input = Input::Recorded {
            node: display,
            value,
        };
        let written = self
            .writer
            .add(engine.now().as_nanos(), engine.steps(), input)
            .and_then(|()| {
                if durable {
                    self.writer.commit_durable()
                } else {
                    self.writer.commit()
                }
            });
        if let Err(e) = written {
            self.failed = Some(e.to_string());
        }
    }
}
