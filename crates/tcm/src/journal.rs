//! A run's journal (docs/semantics.md, "Durable runs"): the inputs its engine takes, written by a
//! `tcm_journal::Writer` before the effects they cause are carried out, so that nothing the robot
//! did follows an input the journal lost. A failed write ends the run at its next turn with the
//! unhandled exception `JournalFailed` at the root: it never goes on unjournaled.

use tcm_core::{Engine, InputRecord};
use tcm_journal::{Input, Writer};

use crate::task::{Action, Factory};

/// How a journal writes an action's value: JSON, or `None` for a value it cannot write (then the
/// entry has none).
pub type ValueEncoder = fn(&(dyn std::any::Any + Send)) -> Option<serde_json::Value>;

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
    encoders: std::collections::HashMap<u64, std::sync::Arc<crate::task::EncodeFn>>,
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

    /// Node `display`'s task says how its value is journaled (`Task::journaled`).
    pub(crate) fn durable(&mut self, display: u64, d: &crate::task::Durable) {
        if let Some(e) = &d.encode {
            self.encoders.insert(display, e.clone());
        }
    }

    /// An action of node `display` returned `value`: kept, written, to go with its end.
    pub(crate) fn value(&mut self, display: u64, value: &(dyn std::any::Any + Send)) {
        let own = if self.encoders.is_empty() {
            None
        } else {
            self.encoders.remove(&display)
        };
        let json = match own {
            Some(encode) => encode(value),
            None => (self.encode)(value),
        };
        if let Some(json) = json {
            self.values.push((display, json));
        }
    }

    /// Writes the inputs the engine took since the last call.
    #[cold]
    #[inline(never)]
    pub(crate) fn drain(&mut self, engine: &mut Engine<Action, Factory>) {
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
        InputRecord::Control { what, by } => Input::Control { what, by },
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
    pub(crate) fn recorded(
        &mut self,
        engine: &mut Engine<Action, Factory>,
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

/// Where a value read from outside comes from (`Ctx::record`).
enum Look {
    // The replay hands back the run's, read at the run's step `at`.
    Replayed(serde_json::Value, u64),
    // Read live; journaled as node `Some(display)`'s, if the run keeps a journal.
    Live(Option<u64>),
}

fn record_failed(why: String) -> tcm_core::Failure {
    tcm_core::Failure::new("RecordFailed", why)
}

impl crate::Ctx {
    /// Reads a value from outside the run (a sensor, a file, the wall clock, a random number)
    /// through the run's journal (docs/semantics.md, "Durable runs"): `read` is called and its
    /// value journaled, if the run keeps a journal; a replay of the run hands back the value the
    /// run read instead of calling `read`, so that a body that decides on it decides the same.
    /// A value that cannot be written as JSON fails the body (`RecordFailed`), as does one the
    /// replay cannot read back as `T`.
    pub fn record<T, F>(&self, read: F) -> Result<T, tcm_core::Failure>
    where
        T: serde::Serialize + serde::de::DeserializeOwned,
        F: FnOnce() -> T,
    {
        match self.look()? {
            Look::Replayed(v, _) => replayed(v),
            Look::Live(display) => {
                let value = read();
                self.keep_recorded(display, &value, false)?;
                Ok(value)
            }
        }
    }

    /// [`Ctx::record`] for a value read by awaiting (a query to another process).
    pub async fn record_async<T, F, Fut>(&self, read: F) -> Result<T, tcm_core::Failure>
    where
        T: serde::Serialize + serde::de::DeserializeOwned,
        F: FnOnce() -> Fut,
        Fut: std::future::Future<Output = T>,
    {
        match self.look()? {
            Look::Replayed(v, at) => {
                // Not before the run's step of the read: as in the run, where it took its time.
                let wait = {
                    let mut inner = self.shared.enter().map_err(tcm_core::Failure::from)?;
                    let steps = inner.engine.steps();
                    inner.replay.as_mut().and_then(|r| r.read_at(at, steps))
                };
                if let Some(rx) = wait {
                    let _ = rx.await;
                }
                replayed(v)
            }
            Look::Live(display) => {
                let value = read().await;
                self.keep_recorded(display, &value, false)?;
                Ok(value)
            }
        }
    }

    /// [`Ctx::record`], the value synced to disk before this returns whatever the journal's
    /// durability: for what an action is about to do outside and a resumed run must find (where
    /// a remote task is placed, before its start is sent; see [`crate::Task::reattach`]).
    pub fn record_durable<T>(&self, value: T) -> Result<T, tcm_core::Failure>
    where
        T: serde::Serialize + serde::de::DeserializeOwned,
    {
        match self.look()? {
            Look::Replayed(v, _) => replayed(v),
            Look::Live(display) => {
                self.keep_recorded(display, &value, true)?;
                Ok(value)
            }
        }
    }

    /// Whether the run is replaying its journal now ([`crate::Runtime::replay`],
    /// [`crate::Runtime::resume`] before it goes live): the bodies run again, and what they do
    /// outside the run must not be done twice.
    pub fn replaying(&self) -> bool {
        self.shared
            .enter()
            .is_ok_and(|inner| inner.replay.as_ref().is_some_and(|r| r.active()))
    }

    fn look(&self) -> Result<Look, tcm_core::Failure> {
        let mut inner = self.shared.enter().map_err(tcm_core::Failure::from)?;
        let display = inner
            .engine
            .kind_and_display(self.node)
            .map_or(0, |(_, d)| d);
        if let Some(r) = inner.replay.as_mut().filter(|r| r.active()) {
            match r.recorded(display) {
                Some((v, at)) => return Ok(Look::Replayed(v, at)),
                // The replay stops there (`replay.rs`, rule 4); the driver ends the run.
                None => self.shared.wake.notify_one(),
            }
        }
        Ok(Look::Live(inner.journal.is_some().then_some(display)))
    }

    fn keep_recorded<T: serde::Serialize>(
        &self,
        display: Option<u64>,
        value: &T,
        durable: bool,
    ) -> Result<(), tcm_core::Failure> {
        let Some(display) = display else {
            return Ok(());
        };
        let json = serde_json::to_value(value)
            .map_err(|e| record_failed(format!("the value cannot be journaled: {e}")))?;
        let mut inner = self.shared.enter().map_err(tcm_core::Failure::from)?;
        let fields = &mut *inner;
        if let Some(j) = fields.journal.as_mut() {
            j.recorded(&mut fields.engine, display, json, durable);
        }
        Ok(())
    }
}

fn replayed<T: serde::de::DeserializeOwned>(v: serde_json::Value) -> Result<T, tcm_core::Failure> {
    serde_json::from_value(v)
        .map_err(|e| record_failed(format!("the journal's value does not read back: {e}")))
}
