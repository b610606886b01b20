//! A journal written and read back, and each fault a journal can have: a last record cut short
//! (dropped with a warning), a flipped byte (stops at its record, with its line and offset), a
//! journal of another program or of a newer format (refused), a full disk (the append fails, and
//! every append after it), an existing file (not overwritten).

use std::path::PathBuf;
use std::time::Duration;

use tcm_journal::{Durability, Input, JournalError, Writer, read};

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("tcm-journal-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("a scratch directory");
    dir.join("run.journal")
}

fn inputs() -> Vec<(u64, Input)> {
    vec![
        (
            0,
            Input::External {
                name: "go".into(),
                data: Some(serde_json::json!({"room": 3})),
            },
        ),
        (
            1_500_000_000,
            Input::Ended {
                node: 2,
                tap: None,
                value: Some(serde_json::json!(2.5)),
            },
        ),
        (
            2_000_000_000,
            Input::Failed {
                node: 3,
                tap: Some(1),
                exception: "Blocked".into(),
                message: "a person in the way".into(),
                ancestry: vec!["NavFailure".into()],
                data: None,
            },
        ),
        (3_000_000_000, Input::Time),
        (
            3_000_000_000,
            Input::Ended {
                node: 18_446_744_073_709_551_615,
                tap: None,
                value: None,
            },
        ),
        (
            3_000_000_000,
            Input::State {
                name: "battery".into(),
                value: serde_json::json!(0.4),
            },
        ),
        (
            4_000_000_000,
            Input::Control {
                what: "pause".into(),
                by: "operator".into(),
                op: Some(serde_json::json!({"op": "pause"})),
            },
        ),
        (
            4_500_000_000,
            Input::Log {
                node: 3,
                message: "gripper \"open\"".into(),
            },
        ),
    ]
}

fn write(path: &std::path::Path, durability: Durability) {
    let mut w = Writer::create(path, "mission@3f2a", durability).expect("create");
    for (i, (t, input)) in inputs().into_iter().enumerate() {
        w.append(t, 2 * i as u64, input).expect("append");
    }
    assert_eq!(w.len(), 8);
    w.close().expect("close");
}

#[test]
fn a_journal_reads_back_as_written_with_either_durability() {
    for durability in [
        Durability::EveryRecord,
        Durability::Group(Duration::from_millis(5)),
    ] {
        let path = scratch("roundtrip");
        write(&path, durability);
        let j = read(&path, Some("mission@3f2a")).expect("read");
        assert_eq!(j.header.program, "mission@3f2a");
        assert_eq!(j.warning, None);
        let got: Vec<(u64, u64, u64, Input)> = j
            .entries
            .into_iter()
            .map(|e| (e.n, e.t, e.at, e.input))
            .collect();
        let want: Vec<(u64, u64, u64, Input)> = inputs()
            .into_iter()
            .enumerate()
            .map(|(n, (t, i))| (n as u64, t, 2 * n as u64, i))
            .collect();
        assert_eq!(got, want);
    }
}

/// Plain ends are handed over in a compact form, turned into their lines by whoever writes the
/// batch (the flusher, with group commit): the file is the same, byte for byte, as when each is
/// added whole, mixed in one batch with records of other kinds.
#[test]
fn a_plain_end_added_compact_is_the_line_it_would_be_added_whole() {
    for durability in [
        Durability::EveryRecord,
        Durability::Group(Duration::from_millis(5)),
    ] {
        let mut files = Vec::new();
        for compact in [false, true] {
            let path = scratch(&format!("compact-{compact}-{}", files.len()));
            let mut w = Writer::create(&path, "p", durability).expect("create");
            for (i, (t, input)) in inputs().into_iter().enumerate() {
                let at = 3 * i as u64;
                match input {
                    Input::Ended {
                        node,
                        tap: None,
                        value: None,
                    } if compact => w.add_ended(t, at, node),
                    other => w.add(t, at, other).expect("add"),
                }
                // Two plain ends of their own, and a commit every third input.
                if compact {
                    w.add_ended(t, at + 1, 7 + i as u64);
                } else {
                    let plain = Input::Ended {
                        node: 7 + i as u64,
                        tap: None,
                        value: None,
                    };
                    w.add(t, at + 1, plain).expect("add");
                }
                if i % 3 == 2 {
                    w.commit().expect("commit");
                }
            }
            w.close().expect("close");
            let j = read(&path, Some("p")).expect("read");
            assert_eq!(j.warning, None);
            assert_eq!(j.entries.len(), 16);
            files.push(std::fs::read(&path).expect("the journal"));
        }
        assert_eq!(files[0], files[1], "{durability:?}");
    }
}

#[test]
fn group_commit_reaches_the_disk_without_a_close() {
    let path = scratch("group");
    let mut w =
        Writer::create(&path, "p", Durability::Group(Duration::from_millis(20))).expect("create");
    w.append(0, 0, Input::Time).expect("append");
    // The writer stays open: its flusher syncs within the interval.
    let deadline = std::time::Instant::now() + Duration::from_secs(10);
    loop {
        let j = read(&path, None).expect("read");
        if j.entries.len() == 1 {
            break;
        }
        assert!(std::time::Instant::now() < deadline, "not flushed");
        std::thread::sleep(Duration::from_millis(10));
    }
    drop(w);
}

#[test]
fn a_durable_commit_is_on_disk_when_it_returns_with_group_commit_too() {
    let path = scratch("durable");
    // An interval no test waits for: only the durable commit can have flushed.
    let mut w =
        Writer::create(&path, "p", Durability::Group(Duration::from_secs(3600))).expect("create");
    w.add(0, 0, Input::Time).expect("add");
    w.commit().expect("commit");
    assert_eq!(read(&path, None).expect("read").entries.len(), 0);
    w.add(5, 1, Input::Clock).expect("add");
    w.commit_durable().expect("durable commit");
    assert_eq!(read(&path, None).expect("read").entries.len(), 2);
    // Again, with nothing new in between the flushes.
    w.commit_durable().expect("durable commit");
    w.append(9, 2, Input::Time).expect("append");
    w.commit_durable().expect("durable commit");
    assert_eq!(read(&path, None).expect("read").entries.len(), 3);
    drop(w);
}

#[test]
fn a_cut_last_record_is_dropped_with_a_warning() {
    let path = scratch("cut");
    write(&path, Durability::EveryRecord);
    let mut bytes = std::fs::read(&path).expect("read");
    bytes.truncate(bytes.len() - 7);
    std::fs::write(&path, &bytes).expect("cut");
    let j = read(&path, Some("mission@3f2a")).expect("read");
    assert_eq!(j.entries.len(), 7);
    let w = j.warning.clone().expect("a warning");
    assert!(w.contains("line 9") && w.contains("cut short"), "{w}");
    // A resumed run goes on writing it: the cut record is cut off the file, the numbers go on.
    let mut w = Writer::reopen(&path, &j, Durability::EveryRecord).expect("reopen");
    w.append(5_000_000_000, 12, Input::Time).expect("append");
    w.close().expect("close");
    let again = read(&path, Some("mission@3f2a")).expect("read");
    assert_eq!(again.warning, None);
    assert_eq!(again.entries.len(), 8);
    assert_eq!(again.entries[..7], j.entries[..]);
    assert_eq!(
        (
            again.entries[7].n,
            again.entries[7].t,
            &again.entries[7].input
        ),
        (7, 5_000_000_000, &Input::Time)
    );
}

#[test]
fn a_flipped_byte_stops_at_its_record_with_its_offset() {
    let path = scratch("flipped");
    write(&path, Durability::EveryRecord);
    let mut bytes = std::fs::read(&path).expect("read");
    let text = String::from_utf8(bytes.clone()).expect("text");
    let third = text
        .match_indices('\n')
        .nth(2)
        .map(|(i, _)| i + 1)
        .expect("line 4");
    // A digit of the value in line 4 changes.
    let at = third + text[third..].find("Blocked").expect("the failure") + 1;
    bytes[at] ^= 0x01;
    std::fs::write(&path, &bytes).expect("flip");
    match read(&path, None) {
        Err(JournalError::Checksum { line, offset, .. }) => {
            assert_eq!((line, offset), (4, third as u64));
        }
        other => panic!("a checksum error: {other:?}"),
    }
    let e = read(&path, None)
        .err()
        .map(|e| e.to_string())
        .unwrap_or_default();
    assert!(e.contains(":4: the record at byte"), "{e}");
}

#[test]
fn a_journal_of_another_program_or_a_newer_format_is_refused() {
    let path = scratch("other");
    write(&path, Durability::EveryRecord);
    let e = read(&path, Some("mission@9c1d"))
        .err()
        .map(|e| e.to_string());
    assert_eq!(
        e.as_deref(),
        Some(
            format!(
                "{}: the journal is of program mission@3f2a, not of mission@9c1d: resume or replay it with the program that wrote it",
                path.display()
            )
            .as_str()
        )
    );
    let newer = scratch("newer");
    let json = r#"{"journal":3,"program":"p"}"#;
    let header = format!("{:08x} {json}\n", crc32fast::hash(json.as_bytes()));
    std::fs::write(&newer, header).expect("write");
    assert!(matches!(
        read(&newer, None),
        Err(JournalError::NewerFormat {
            found: 3,
            supported: 2,
            ..
        })
    ));
    std::fs::write(&newer, "").expect("write");
    assert!(matches!(
        read(&newer, None),
        Err(JournalError::NotAJournal { .. })
    ));
}

#[test]
fn an_existing_file_is_not_overwritten() {
    let path = scratch("exists");
    write(&path, Durability::EveryRecord);
    let e = Writer::create(&path, "p", Durability::EveryRecord)
        .err()
        .map(|e| e.to_string())
        .unwrap_or_default();
    assert!(
        e.contains("exists already: resume from it, or remove it first"),
        "{e}"
    );
    assert_eq!(read(&path, None).expect("intact").entries.len(), 8);
}

/// A store that takes `room` bytes, then fails as a full disk does.
struct Full {
    room: usize,
}

impl std::io::Write for Full {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        if buf.len() > self.room {
            return Err(std::io::Error::from_raw_os_error(28));
        }
        self.room -= buf.len();
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl tcm_journal::Store for Full {
    fn sync(&self) -> std::io::Result<()> {
        Ok(())
    }
}

/// A full disk: the append that does not fit fails, saying the run stops, and every append after
/// it fails too, even one that would fit; a device that is always full (`/dev/full`) fails the
/// header.
#[test]
fn a_full_disk_fails_the_append_and_every_one_after() {
    let mut w = Writer::on(
        "small.journal".into(),
        Box::new(Full { room: 150 }),
        "p",
        Durability::EveryRecord,
    )
    .expect("the header fits");
    w.append(0, 0, Input::Time).expect("fits");
    let e = w
        .append(
            1,
            0,
            Input::Control {
                what: "x".repeat(200),
                by: "operator".into(),
                op: None,
            },
        )
        .err()
        .map(|e| e.to_string())
        .unwrap_or_default();
    assert!(
        e.starts_with("small.journal: cannot write the journal: No space left on device")
            && e.ends_with("the run stops rather than go on unjournaled"),
        "{e}"
    );
    assert!(matches!(
        w.append(2, 0, Input::Time),
        Err(JournalError::Failed { .. })
    ));
    assert!(w.close().is_err());
    let full = std::path::Path::new("/dev/full");
    if let Ok(file) = std::fs::File::options().write(true).open(full) {
        let e = Writer::on(
            "/dev/full".into(),
            Box::new(file),
            "p",
            Durability::EveryRecord,
        )
        .err()
        .map(|e| e.to_string())
        .unwrap_or_default();
        assert!(e.contains("No space left on device"), "{e}");
    }
}

#[test]
fn a_durability_reads_as_journal_sync_gives_it() {
    let read = |s: &str| s.parse::<Durability>();
    assert_eq!(read("every"), Ok(Durability::EveryRecord));
    assert_eq!(
        read("group:5"),
        Ok(Durability::Group(Duration::from_millis(5)))
    );
    assert_eq!(
        read("acting:10"),
        Ok(Durability::BeforeActing(Duration::from_millis(10)))
    );
    assert_eq!(
        read("acting:soon"),
        Err("--journal-sync acting:soon: MS is a number of milliseconds".to_string())
    );
    assert_eq!(
        read("always"),
        Err("--journal-sync always: give `every`, `group:MS` or `acting:MS`".to_string())
    );
}
