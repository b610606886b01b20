//! Reading a journal back: [`read`], each record's checksum checked, the faults the crate's
//! documentation lists named.

use std::path::Path;

use crate::{Entry, Header, JOURNAL_FORMAT_VERSION, JournalError};

/// A journal as read.
#[derive(Clone, Debug, PartialEq)]
pub struct Journal {
    /// Its header.
    pub header: Header,
    /// Its entries, in order.
    pub entries: Vec<Entry>,
    /// Something a person should know that did not stop the reading: a last record cut short
    /// (a crash mid-write), dropped.
    pub warning: Option<String>,
    /// The bytes of the file up to the end of its last whole record (where a resumed run goes
    /// on writing it: `Writer::reopen`).
    pub length: u64,
}

/// Reads the journal at `path`. With `program`, a journal of another program is refused.
pub fn read(path: &Path, program: Option<&str>) -> Result<Journal, JournalError> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|source| JournalError::Io {
        file: file.clone(),
        source,
    })?;
    let mut lines = Vec::new();
    let mut warning = None;
    let mut length = 0u64;
    let mut start = 0usize;
    while start < bytes.len() {
        match bytes[start..].iter().position(|b| *b == b'\n') {
            Some(len) => {
                lines.push((start, &bytes[start..start + len]));
                start += len + 1;
                length = start as u64;
            }
            None => {
                // No newline: the last write did not finish.
                warning = Some(format!(
                    "{file}: the last record (line {}, byte {start}) was cut short, as by a crash \
                     while it was written: it is dropped",
                    lines.len() + 1
                ));
                break;
            }
        }
    }
    let mut records = lines
        .into_iter()
        .enumerate()
        .map(|(i, (offset, text))| record(&file, i + 1, offset as u64, text));
    let header_json: serde_json::Value = match records.next() {
        Some(r) => {
            let (line, json) = r?;
            serde_json::from_str(json).map_err(|e| JournalError::BadRecord {
                file: file.clone(),
                line,
                why: e.to_string(),
            })?
        }
        None => {
            return Err(JournalError::NotAJournal {
                file,
                why: "it is empty (no header)".into(),
            });
        }
    };
    let version = header_json
        .get("journal")
        .and_then(serde_json::Value::as_u64);
    if let Some(v) = version.filter(|v| *v > u64::from(JOURNAL_FORMAT_VERSION)) {
        return Err(JournalError::NewerFormat {
            file,
            found: u32::try_from(v).unwrap_or(u32::MAX),
            supported: JOURNAL_FORMAT_VERSION,
        });
    }
    let header: Header =
        serde_json::from_value(header_json).map_err(|e| JournalError::NotAJournal {
            file: file.clone(),
            why: format!("its first record is no header: {e}"),
        })?;
    if let Some(expected) = program.filter(|p| *p != header.program) {
        return Err(JournalError::OtherProgram {
            file,
            expected: expected.to_string(),
            found: header.program,
        });
    }
    let mut entries = Vec::new();
    for (i, r) in records.enumerate() {
        let (line, json) = r?;
        let entry: Entry = serde_json::from_str(json).map_err(|e| JournalError::BadRecord {
            file: file.clone(),
            line,
            why: e.to_string(),
        })?;
        if entry.n != i as u64 {
            return Err(JournalError::BadRecord {
                file,
                line,
                why: format!("entry {} where entry {i} comes", entry.n),
            });
        }
        entries.push(entry);
    }
    Ok(Journal {
        header,
        entries,
        warning,
        length,
    })
}

/// One line's record: its checksum checked; its line and JSON.
fn record<'t>(
    file: &str,
    line: usize,
    offset: u64,
    text: &'t [u8],
) -> Result<(usize, &'t str), JournalError> {
    let damaged = || JournalError::Checksum {
        file: file.to_string(),
        line,
        offset,
    };
    let text = std::str::from_utf8(text).map_err(|_| damaged())?;
    let (crc, json) = text.split_once(' ').ok_or_else(damaged)?;
    let crc = u32::from_str_radix(crc, 16).map_err(|_| damaged())?;
    if crc32fast::hash(json.as_bytes()) != crc {
        return Err(damaged());
    }
    Ok((line, json))
}
