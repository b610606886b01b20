//! What an action reads through the run's journal (docs/semantics.md, "Durable runs"):
//! values from outside the run (`Ctx::record`), and whether the run replays.

use super::Ctx;

impl Ctx {
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

fn replayed<T: serde::de::DeserializeOwned>(v: serde_json::Value) -> Result<T, tcm_core::Failure> {
    serde_json::from_value(v)
        .map_err(|e| record_failed(format!("the journal's value does not read back: {e}")))
}
