//! Writing a journal: [`Writer`], each entry one checksummed line, synced as its [`Durability`]
//! says.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::Duration;

use crate::{Entry, Header, Input, JOURNAL_FORMAT_VERSION, JournalError, line};

/// When what was appended reaches the disk.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Durability {
    /// Every record is synced before [`Writer::append`] returns: nothing the engine received is
    /// lost in a crash, at the cost of a sync per input.
    EveryRecord,
    /// Group commit: records are synced together at most this long after they were appended (and
    /// when the writer is closed). A crash loses at most that much of the run's end.
    Group(Duration),
}

/// Where a journal's bytes go: a file, or (for tests of a failing disk) anything that can be
/// written and synced.
pub trait Store: Write + Send + 'static {
    /// Makes what was written durable (`fsync`'s data part for a file).
    fn sync(&self) -> std::io::Result<()>;
}

impl Store for File {
    fn sync(&self) -> std::io::Result<()> {
        self.sync_data()
    }
}

/// What the writer and its flusher share.
struct State {
    out: BufWriter<Box<dyn Store>>,
    // Records appended and not synced yet.
    dirty: bool,
    // The first failure; nothing is written after it.
    failed: Option<String>,
    // The writer is closing: the flusher stops.
    closing: bool,
}

/// Appends a run's inputs to its journal (see the crate's documentation).
pub struct Writer {
    file: String,
    state: Arc<(Mutex<State>, Condvar)>,
    durability: Durability,
    flusher: Option<JoinHandle<()>>,
    next: u64,
}

fn lock(m: &Mutex<State>) -> MutexGuard<'_, State> {
    // A panic under the lock leaves plain fields, each whole.
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

impl Writer {
    /// Creates the journal at `path` for the program `program`, its header written and synced. An
    /// existing file is not overwritten: it may be the journal of a run to resume.
    pub fn create(
        path: &Path,
        program: &str,
        durability: Durability,
    ) -> Result<Writer, JournalError> {
        let name = path.display().to_string();
        let file = File::options()
            .write(true)
            .create_new(true)
            .open(path)
            .map_err(|source| JournalError::Io {
                file: name.clone(),
                source: if source.kind() == std::io::ErrorKind::AlreadyExists {
                    std::io::Error::new(
                        source.kind(),
                        "it exists already: resume from it, or remove it first",
                    )
                } else {
                    source
                },
            })?;
        Writer::on(name, Box::new(file), program, durability)
    }

    /// A journal written to `store` (named `name` in errors), its header written and synced.
    pub fn on(
        name: String,
        store: Box<dyn Store>,
        program: &str,
        durability: Durability,
    ) -> Result<Writer, JournalError> {
        let header = Header {
            journal: JOURNAL_FORMAT_VERSION,
            program: program.to_string(),
        };
        let mut out = BufWriter::new(store);
        let json = serde_json::to_string(&header).unwrap_or_default();
        let written = out
            .write_all(line(&json).as_bytes())
            .and_then(|()| out.flush())
            .and_then(|()| out.get_ref().sync());
        written.map_err(|source| JournalError::Write {
            file: name.clone(),
            source,
        })?;
        let state = Arc::new((
            Mutex::new(State {
                out,
                dirty: false,
                failed: None,
                closing: false,
            }),
            Condvar::new(),
        ));
        let flusher = match durability {
            Durability::EveryRecord => None,
            Durability::Group(every) => {
                let state = state.clone();
                let spawned = std::thread::Builder::new()
                    .name("tcm-journal".into())
                    .spawn(move || flush_every(&state, every));
                Some(spawned.map_err(|source| JournalError::Io {
                    file: name.clone(),
                    source,
                })?)
            }
        };
        Ok(Writer {
            file: name,
            state,
            durability,
            flusher,
            next: 0,
        })
    }

    /// Appends one input, received at the engine's time `t` (nanoseconds); with
    /// [`Durability::EveryRecord`], synced before it returns. An error, a write or a sync that
    /// failed now or earlier, means the input is not journaled: the run must stop.
    pub fn append(&mut self, t: u64, input: Input) -> Result<(), JournalError> {
        let entry = Entry {
            n: self.next,
            t,
            input,
        };
        let json = serde_json::to_string(&entry).map_err(|e| JournalError::Write {
            file: self.file.clone(),
            source: std::io::Error::other(e),
        })?;
        let mut s = lock(&self.state.0);
        if let Some(why) = &s.failed {
            return Err(JournalError::Failed {
                file: self.file.clone(),
                why: why.clone(),
            });
        }
        let mut written = s.out.write_all(line(&json).as_bytes());
        if written.is_ok() && self.durability == Durability::EveryRecord {
            written = s.out.flush().and_then(|()| s.out.get_ref().sync());
        }
        match written {
            Ok(()) => {
                s.dirty = true;
                self.next += 1;
                Ok(())
            }
            Err(source) => {
                s.failed = Some(source.to_string());
                Err(JournalError::Write {
                    file: self.file.clone(),
                    source,
                })
            }
        }
    }

    /// How many entries were appended.
    pub fn len(&self) -> u64 {
        self.next
    }

    /// Whether no entry was appended.
    pub fn is_empty(&self) -> bool {
        self.next == 0
    }

    /// Syncs what was appended and closes the journal; an error if anything could not be written.
    pub fn close(mut self) -> Result<(), JournalError> {
        self.finish()
    }

    fn finish(&mut self) -> Result<(), JournalError> {
        {
            let mut s = lock(&self.state.0);
            s.closing = true;
            self.state.1.notify_all();
        }
        if let Some(f) = self.flusher.take() {
            let _ = f.join();
        }
        let mut s = lock(&self.state.0);
        if let Some(why) = &s.failed {
            return Err(JournalError::Failed {
                file: self.file.clone(),
                why: why.clone(),
            });
        }
        let synced = s.out.flush().and_then(|()| s.out.get_ref().sync());
        s.dirty = false;
        synced.map_err(|source| {
            s.failed = Some(source.to_string());
            JournalError::Write {
                file: self.file.clone(),
                source,
            }
        })
    }
}

impl Drop for Writer {
    fn drop(&mut self) {
        let _ = self.finish();
    }
}

/// The group-commit flusher: every `every`, what was appended since is written and synced; a
/// failure is kept for the next append to report.
fn flush_every(state: &(Mutex<State>, Condvar), every: Duration) {
    let (m, cv) = state;
    let mut s = lock(m);
    while !s.closing {
        s = cv
            .wait_timeout(s, every)
            .map(|(g, _)| g)
            .unwrap_or_else(|e| e.into_inner().0);
        if s.dirty && s.failed.is_none() {
            let synced = s.out.flush().and_then(|()| s.out.get_ref().sync());
            s.dirty = false;
            if let Err(e) = synced {
                s.failed = Some(e.to_string());
            }
        }
    }
}
