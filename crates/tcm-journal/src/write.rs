//! Writing a journal: [`Writer`], each entry one checksummed line, synced as its [`Durability`]
//! says.

use std::fs::File;
use std::io::Write;
use std::path::Path;
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::Duration;

use crate::{Entry, Header, Input, JournalError, line};

/// When what was appended reaches the disk.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Durability {
    /// Every record is synced before [`Writer::append`] (or the [`Writer::commit`] of its batch)
    /// returns: nothing the engine received is lost in a crash, at the cost of a sync per input
    /// (per batch of inputs taken together).
    EveryRecord,
    /// Group commit: records are synced together at most this long after they were appended (and
    /// when the writer is closed). A crash loses at most that much of the run's end.
    Group(Duration),
    /// Group commit, and everything appended synced before the run acts outside the process:
    /// before it starts or cancels a command ([`Writer::commit_before_acting`]). Nothing the
    /// robot does follows an input the journal could lose; a crash loses at most this long of
    /// the inputs whose effects stayed inside the process (a command's end among them: resumed,
    /// such a command is taken for one in flight).
    BeforeActing(Duration),
}

impl std::str::FromStr for Durability {
    type Err = String;

    /// `every`, `group:MS` or `acting:MS` (milliseconds), as `--journal-sync` takes it.
    fn from_str(text: &str) -> Result<Durability, String> {
        if text == "every" {
            return Ok(Durability::EveryRecord);
        }
        let wrong = || format!("--journal-sync {text}: give `every`, `group:MS` or `acting:MS`");
        let (mode, ms) = text.split_once(':').ok_or_else(wrong)?;
        let every = ms
            .parse::<u64>()
            .map(Duration::from_millis)
            .map_err(|_| format!("--journal-sync {text}: MS is a number of milliseconds"))?;
        match mode {
            "group" => Ok(Durability::Group(every)),
            "acting" => Ok(Durability::BeforeActing(every)),
            _ => Err(wrong()),
        }
    }
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

/// What the writer and its flusher share (group commit).
struct Shared {
    // Records appended and not yet handed to the store.
    pending: Vec<u8>,
    // The first failure; nothing is written after it.
    failed: Option<String>,
    // The writer is closing: the flusher writes what is left and stops.
    closing: bool,
    // Bytes handed to the flusher so far, and how many of them are synced.
    appended: u64,
    synced: u64,
    // A durable commit waits until this many are synced.
    wanted: u64,
}

/// Appends a run's inputs to its journal (see the crate's documentation).
pub struct Writer {
    file: String,
    // With a sync per record: the store, written by `append` itself.
    store: Option<Box<dyn Store>>,
    // With group commit: what `append` and the flusher share, and the flusher.
    shared: Arc<(Mutex<Shared>, Condvar)>,
    flusher: Option<JoinHandle<()>>,
    // Everything appended is synced before the run acts outside (`Durability::BeforeActing`).
    before_acting: bool,
    // The first failure of a sync per record.
    failed: Option<String>,
    // The record being made, reused.
    scratch: Vec<u8>,
    // The records added and not committed yet (`Writer::add`, `Writer::commit`).
    batch: Vec<u8>,
    next: u64,
}

fn lock(m: &Mutex<Shared>) -> MutexGuard<'_, Shared> {
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
        Writer::create_with(path, Header::new(program), durability)
    }

    /// [`Writer::create`] with a header of the caller's (what the run started, say).
    pub fn create_with(
        path: &Path,
        header: Header,
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
        Writer::start_on(name, Box::new(file), &header, durability)
    }

    /// Goes on writing the journal at `path`, as read (`journal`, by [`crate::read`]): a last
    /// record cut short is cut off the file, and the next entry is numbered after the last read.
    /// For a run resumed from it, so that a second crash finds every input of both runs.
    pub fn reopen(
        path: &Path,
        journal: &crate::Journal,
        durability: Durability,
    ) -> Result<Writer, JournalError> {
        let name = path.display().to_string();
        let io = |source| JournalError::Io {
            file: name.clone(),
            source,
        };
        let file = File::options().write(true).open(path).map_err(io)?;
        file.set_len(journal.length).map_err(io)?;
        let mut file = file;
        std::io::Seek::seek(&mut file, std::io::SeekFrom::End(0)).map_err(io)?;
        file.sync_all().map_err(io)?;
        let mut writer = Writer::start(name, Box::new(file), durability)?;
        writer.next = journal.entries.len() as u64;
        Ok(writer)
    }

    /// A journal written to `store` (named `name` in errors), its header written and synced.
    pub fn on(
        name: String,
        store: Box<dyn Store>,
        program: &str,
        durability: Durability,
    ) -> Result<Writer, JournalError> {
        Writer::start_on(name, store, &Header::new(program), durability)
    }

    /// A journal written to `store`, its header `header`.
    fn start_on(
        name: String,
        mut store: Box<dyn Store>,
        header: &Header,
        durability: Durability,
    ) -> Result<Writer, JournalError> {
        let json = serde_json::to_string(header).unwrap_or_default();
        let written = store
            .write_all(line(&json).as_bytes())
            .and_then(|()| store.flush())
            .and_then(|()| store.sync());
        written.map_err(|source| JournalError::Write {
            file: name.clone(),
            source,
        })?;
        Writer::start(name, store, durability)
    }

    /// A writer of entries to `store`, whose header is written.
    fn start(
        name: String,
        store: Box<dyn Store>,
        durability: Durability,
    ) -> Result<Writer, JournalError> {
        let shared = Arc::new((
            Mutex::new(Shared {
                pending: Vec::with_capacity(HANDED_OVER),
                failed: None,
                closing: false,
                appended: 0,
                synced: 0,
                wanted: 0,
            }),
            Condvar::new(),
        ));
        let (store, flusher) = match durability {
            Durability::EveryRecord => (Some(store), None),
            Durability::Group(every) | Durability::BeforeActing(every) => {
                let shared = shared.clone();
                let spawned = std::thread::Builder::new()
                    .name("tcm-journal".into())
                    .spawn(move || flush_every(&shared, store, every));
                let flusher = spawned.map_err(|source| JournalError::Io {
                    file: name.clone(),
                    source,
                })?;
                (None, Some(flusher))
            }
        };
        Ok(Writer {
            file: name,
            store,
            shared,
            flusher,
            before_acting: matches!(durability, Durability::BeforeActing(_)),
            failed: None,
            scratch: Vec::with_capacity(256),
            batch: Vec::with_capacity(4096),
            next: 0,
        })
    }

    /// Appends one input, received at the engine's time `t` (nanoseconds); with
    /// [`Durability::EveryRecord`], synced before it returns. An error, a write or a sync that
    /// failed now or earlier, means the input is not journaled: the run must stop.
    pub fn append(&mut self, t: u64, at: u64, input: Input) -> Result<(), JournalError> {
        self.add(t, at, input)?;
        self.commit()
    }

    /// Adds one input to the batch [`Writer::commit`] writes (`at`: see [`Entry::at`]).
    pub fn add(&mut self, t: u64, at: u64, input: Input) -> Result<(), JournalError> {
        self.add_given(t, at, input, false)
    }

    /// [`Writer::add`], `body` saying whether a body of the run gave the input itself
    /// ([`Entry::body`]).
    pub fn add_given(
        &mut self,
        t: u64,
        at: u64,
        input: Input,
        body: bool,
    ) -> Result<(), JournalError> {
        let entry = Entry {
            n: self.next,
            t,
            at,
            body,
            input,
        };
        self.scratch.clear();
        encode(&entry, &mut self.scratch).map_err(|e| JournalError::Write {
            file: self.file.clone(),
            source: std::io::Error::other(e),
        })?;
        self.seal();
        Ok(())
    }

    /// Adds the plainest input, an action's end with no value, to the batch: the same record as
    /// [`Writer::add`] with [`Input::Ended`] makes, handed over in a compact form that whoever
    /// writes the batch out turns into its line ([`render`]): with group commit, the flusher, off
    /// the run's thread.
    pub fn add_ended(&mut self, t: u64, at: u64, node: u64) {
        let mut record = [0u8; ENDED_LEN];
        for (i, v) in [self.next, t, at, node].into_iter().enumerate() {
            record[1 + 8 * i..9 + 8 * i].copy_from_slice(&v.to_le_bytes());
        }
        self.batch.extend_from_slice(&record);
        self.next += 1;
    }

    /// Moves the record in `scratch` into the batch, its checksum before it.
    fn seal(&mut self) {
        self.batch
            .extend_from_slice(&hex(crc32fast::hash(&self.scratch)));
        self.batch.push(b' ');
        self.batch.extend_from_slice(&self.scratch);
        self.batch.push(b'\n');
        self.next += 1;
    }

    /// Writes the batch: with [`Durability::EveryRecord`], written and synced before it returns
    /// (one sync for the batch: its inputs came together, before the effects they cause); with
    /// group commit, handed to the flusher. An error, a write or a sync that failed now or
    /// earlier, means the batch is not journaled: the run must stop.
    pub fn commit(&mut self) -> Result<(), JournalError> {
        if self.batch.is_empty() {
            return Ok(());
        }
        let written = match self.store.as_mut() {
            Some(store) => {
                if let Some(why) = &self.failed {
                    return Err(JournalError::Failed {
                        file: self.file.clone(),
                        why: why.clone(),
                    });
                }
                self.scratch.clear();
                render(&self.batch, &mut self.scratch);
                let written = store
                    .write_all(&self.scratch)
                    .and_then(|()| store.flush())
                    .and_then(|()| store.sync());
                if let Err(e) = &written {
                    self.failed = Some(e.to_string());
                }
                written
            }
            None => {
                let mut s = lock(&self.shared.0);
                if let Some(why) = &s.failed {
                    return Err(JournalError::Failed {
                        file: self.file.clone(),
                        why: why.clone(),
                    });
                }
                s.pending.extend_from_slice(&self.batch);
                s.appended += self.batch.len() as u64;
                Ok(())
            }
        };
        self.batch.clear();
        written.map_err(|source| JournalError::Write {
            file: self.file.clone(),
            source,
        })
    }

    /// Whether everything appended must be synced before the run acts outside the process
    /// ([`Durability::BeforeActing`]).
    #[inline]
    pub fn syncs_before_acting(&self) -> bool {
        self.before_acting
    }

    /// With [`Durability::BeforeActing`], [`Writer::commit_durable`]: the run is about to start
    /// or cancel a command. Otherwise [`Writer::commit`].
    pub fn commit_before_acting(&mut self) -> Result<(), JournalError> {
        if self.before_acting {
            self.commit_durable()
        } else {
            self.commit()
        }
    }

    /// [`Writer::commit`], and then, whatever the durability, waits until everything appended is
    /// synced: for an entry that must be on disk before the run acts on it outside (a remote
    /// task's placement, before its start is sent), with group commit too.
    pub fn commit_durable(&mut self) -> Result<(), JournalError> {
        self.commit()?;
        if self.store.is_some() {
            return Ok(());
        }
        let (m, cv) = &*self.shared;
        let mut s = lock(m);
        let target = s.appended;
        if s.synced >= target && s.failed.is_none() {
            return Ok(());
        }
        s.wanted = s.wanted.max(target);
        cv.notify_all();
        while s.synced < target && s.failed.is_none() && self.flusher.is_some() {
            s = cv
                .wait(s)
                .unwrap_or_else(std::sync::PoisonError::into_inner);
        }
        match &s.failed {
            Some(why) => Err(JournalError::Failed {
                file: self.file.clone(),
                why: why.clone(),
            }),
            None => Ok(()),
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
        // What was added and not committed yet is written too.
        let committed = self.commit();
        if let Some(f) = self.flusher.take() {
            lock(&self.shared.0).closing = true;
            self.shared.1.notify_all();
            let _ = f.join();
        }
        let failed = self
            .failed
            .clone()
            .or_else(|| lock(&self.shared.0).failed.clone());
        match failed {
            Some(why) => Err(JournalError::Failed {
                file: self.file.clone(),
                why,
            }),
            None => committed,
        }
    }
}

impl Drop for Writer {
    fn drop(&mut self) {
        let _ = self.finish();
    }
}

/// Writes `entry` as JSON: the usual input of a run, an action that ended well with no value,
/// by hand (it is most of a journal: serde's flattening costs more than the rest of a record);
/// every other through serde. Both read back alike.
fn encode(entry: &Entry, out: &mut Vec<u8>) -> Result<(), serde_json::Error> {
    if let Input::Ended {
        node,
        tap: None,
        value: None,
    } = entry.input
    {
        ended(entry.n, entry.t, entry.at, node, out);
        return Ok(());
    }
    serde_json::to_writer(out, entry)
}

/// The record of entry `n`, at `t`, after `at` at: node `node`'s action ended, with no value.
fn ended(n: u64, t: u64, at: u64, node: u64, out: &mut Vec<u8>) {
    out.extend_from_slice(b"{\"n\":");
    decimal(n, out);
    out.extend_from_slice(b",\"t\":");
    decimal(t, out);
    if at != 0 {
        out.extend_from_slice(b",\"at\":");
        decimal(at, out);
    }
    out.extend_from_slice(b",\"in\":\"ended\",\"node\":");
    decimal(node, out);
    out.push(b'}');
}

/// The room made at first for what the run hands the flusher between two of its turns (the
/// batches swap, so both keep what they grew to).
const HANDED_OVER: usize = 1 << 16;

/// The compact form of an [`Writer::add_ended`] record in a batch: a zero byte (no line starts
/// with one: a line starts with its checksum in hex), then its number, time, steps and node, each
/// eight bytes, little-endian.
const ENDED_LEN: usize = 33;

/// Appends to `out` the lines of `batch`: its lines as they are, and each compact record
/// ([`ENDED_LEN`]) as the line [`encode`] makes of it, its checksum in front.
fn render(batch: &[u8], out: &mut Vec<u8>) {
    let mut rest = batch;
    while let Some(&first) = rest.first() {
        if first == 0 && rest.len() >= ENDED_LEN {
            let field = |i: usize| {
                let mut b = [0u8; 8];
                b.copy_from_slice(&rest[1 + 8 * i..9 + 8 * i]);
                u64::from_le_bytes(b)
            };
            let start = out.len();
            out.extend_from_slice(&[b' '; 9]);
            ended(field(0), field(1), field(2), field(3), out);
            let crc = crc32fast::hash(&out[start + 9..]);
            out[start..start + 8].copy_from_slice(&hex(crc));
            out.push(b'\n');
            rest = &rest[ENDED_LEN..];
        } else {
            let end = rest
                .iter()
                .position(|&b| b == b'\n')
                .map_or(rest.len(), |i| i + 1);
            out.extend_from_slice(&rest[..end]);
            rest = &rest[end..];
        }
    }
}

/// `n` in decimal.
fn decimal(n: u64, out: &mut Vec<u8>) {
    out.extend_from_slice(itoa::Buffer::new().format(n).as_bytes());
}

/// A checksum in eight lowercase hex digits.
fn hex(crc: u32) -> [u8; 8] {
    const DIGITS: &[u8; 16] = b"0123456789abcdef";
    let mut out = [0u8; 8];
    for (i, digit) in out.iter_mut().enumerate() {
        *digit = DIGITS[((crc >> ((7 - i) * 4)) & 0xf) as usize];
    }
    out
}

/// The group-commit flusher: every `every` (and once more when the writer closes), what was
/// appended since is taken under the lock and written and synced outside it, so that an append
/// never waits for the disk; a failure is kept for the next append to report.
fn flush_every(shared: &(Mutex<Shared>, Condvar), mut store: Box<dyn Store>, every: Duration) {
    let (m, cv) = shared;
    let mut spare = Vec::with_capacity(HANDED_OVER);
    let mut text = Vec::new();
    loop {
        let closing;
        let taken;
        {
            let mut s = lock(m);
            // A durable commit waiting is served at once.
            if !s.closing && s.wanted <= s.synced {
                s = cv
                    .wait_timeout(s, every)
                    .map(|(g, _)| g)
                    .unwrap_or_else(|e| e.into_inner().0);
            }
            closing = s.closing;
            if s.failed.is_none() {
                std::mem::swap(&mut s.pending, &mut spare);
            }
            taken = s.appended;
        }
        if !spare.is_empty() {
            text.clear();
            render(&spare, &mut text);
            let written = store
                .write_all(&text)
                .and_then(|()| store.flush())
                .and_then(|()| store.sync());
            spare.clear();
            let mut s = lock(m);
            match written {
                Ok(()) => s.synced = taken,
                Err(e) => s.failed = Some(e.to_string()),
            }
            // A `commit_durable` may wait for this.
            cv.notify_all();
        } else {
            // Nothing new: what was taken before is synced.
            let mut s = lock(m);
            if s.failed.is_none() {
                s.synced = taken;
            }
        }
        if closing {
            return;
        }
    }
}
