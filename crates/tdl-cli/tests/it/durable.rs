//! Durable runs from the command line (docs/semantics.md, "Durable runs"): `tdl replay` of a
//! recorded real run gives its trace byte for byte, and a changed program is reported at its first
//! difference; `tdl run --resume` after the run was killed with SIGKILL while a hand-over ran
//! ends as the uncrashed run did, its whole trace checked, the crashed run's trace a prefix of it,
//! the hand-over in flight interrupted and handed over again, nothing else run twice.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use crate::tdl;

const ROUNDS: &str = "tests/data/durable/rounds.tdl";

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("tdl-durable-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("a scratch directory");
    dir
}

fn arg(p: &Path) -> String {
    p.display().to_string()
}

#[test]
fn a_replay_gives_the_recorded_trace_byte_for_byte() {
    let dir = scratch("replay");
    // Rounds of commands and a handler; and timers: a polling monitor ended by a timeout, a step
    // terminated by one.
    for (program, args) in [(ROUNDS, "6"), ("tests/data/durable/watched.tdl", "8")] {
        let (journal, recorded, replayed) = (dir.join("j"), dir.join("t1"), dir.join("t2"));
        let _ = std::fs::remove_file(&journal);
        let (code, out, err) = tdl(&[
            "run",
            program,
            "--args",
            args,
            "--journal",
            &arg(&journal),
            "--trace",
            &arg(&recorded),
        ]);
        assert_eq!(code, 0, "{out}{err}");
        let (code, out, err) = tdl(&[
            "replay",
            &arg(&journal),
            program,
            "--trace",
            &arg(&replayed),
        ]);
        assert_eq!(code, 0, "{program}: {out}{err}");
        assert!(out.starts_with("completed"), "{program}: {out}");
        let (a, b) = (
            std::fs::read_to_string(&recorded).expect("the recorded trace"),
            std::fs::read_to_string(&replayed).expect("the replayed trace"),
        );
        assert!(a.lines().count() > 100, "a real run: {a}");
        for (i, (x, y)) in a.lines().zip(b.lines()).enumerate() {
            assert_eq!(x, y, "{program}: line {} differs", i + 1);
        }
        assert_eq!(a, b, "{program}");
    }
    let journal = dir.join("rounds.journal");
    let (code, out, err) = tdl(&["run", ROUNDS, "--args", "6", "--journal", &arg(&journal)]);
    assert_eq!(code, 0, "{out}{err}");
    // One constraint changed (a drive needs a range above 3): reported where it first shows.
    let (code, out, err) = tdl(&["replay", &arg(&journal), "tests/data/durable/changed.tdl"]);
    assert_eq!(code, 3, "{out}{err}");
    assert!(
        err.contains("the replay stops at the first difference"),
        "{err}"
    );
    assert!(
        out.starts_with("diverged from the journal: journal entry ")
            && out.contains("the program differs from the run's"),
        "{out}"
    );
}

/// A run steered from the terminal (a breakpoint before each `deliver`; standard input closed at
/// once, which releases the run) journals its operations, and `tdl replay` carries them out
/// again: the same trace, byte for byte, its `control` records among them.
#[test]
fn a_steered_run_replays_with_its_operations() {
    let dir = scratch("steered");
    let (journal, recorded, replayed) = (dir.join("j"), dir.join("t1"), dir.join("t2"));
    let (code, out, err) = tdl(&[
        "run",
        ROUNDS,
        "--args",
        "3",
        "--break",
        "deliver",
        "--journal",
        &arg(&journal),
        "--trace",
        &arg(&recorded),
    ]);
    assert_eq!(code, 0, "{out}{err}");
    let (code, out, err) = tdl(&["replay", &arg(&journal), ROUNDS, "--trace", &arg(&replayed)]);
    assert_eq!(code, 0, "{out}{err}");
    let (a, b) = (
        std::fs::read_to_string(&recorded).expect("the recorded trace"),
        std::fs::read_to_string(&replayed).expect("the replayed trace"),
    );
    let controls = a
        .lines()
        .filter(|l| l.contains("\"ev\":\"control\""))
        .count();
    assert!(controls >= 2, "the breakpoint and the release: {a}");
    for (i, (x, y)) in a.lines().zip(b.lines()).enumerate() {
        assert_eq!(x, y, "line {} differs", i + 1);
    }
    assert_eq!(a, b);
}

/// The report's first two lines without the times: outcome and counts.
fn outcome(out: &str) -> (String, String) {
    let mut lines = out.lines();
    let first = lines.next().unwrap_or_default();
    let first = first
        .split(" after ")
        .next()
        .unwrap_or_default()
        .to_string();
    (first, lines.next().unwrap_or_default().to_string())
}

#[test]
fn a_killed_run_resumes_and_ends_as_an_uncrashed_one() {
    let dir = scratch("resume");
    let (code, plain, err) = tdl(&["run", ROUNDS, "--args", "8"]);
    assert_eq!(code, 0, "{plain}{err}");
    // Killed while room `room` is handed over: 100 ms after its measure ended (its value is
    // `room + 1.5`), between its drive's end (30 ms) and its hand-over's (230 ms).
    // The last one steered from the terminal (a breakpoint, standard input closed at once: the
    // run released): resumed, the journal gives its operations again.
    for (room, steer) in [(1u32, false), (4, false), (6, false), (4, true)] {
        let steering: &[&str] = if steer { &["--break", "deliver"] } else { &[] };
        let journal = dir.join(format!("j{room}{steer}"));
        let (before, after) = (
            dir.join(format!("a{room}{steer}")),
            dir.join(format!("b{room}{steer}")),
        );
        let mut child = Command::new(env!("CARGO_BIN_EXE_tdl"))
            .args([
                "run",
                ROUNDS,
                "--args",
                "8",
                "--journal",
                &arg(&journal),
                "--journal-sync",
                "every",
                "--trace",
                &arg(&before),
            ])
            .args(steering)
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("run tdl");
        let measured = format!("\"value\":{}.5", room + 1);
        let deadline = Instant::now() + Duration::from_secs(60);
        loop {
            let written = std::fs::read_to_string(&journal).unwrap_or_default();
            if written.contains(&measured) {
                break;
            }
            assert!(Instant::now() < deadline, "room {room} was never measured");
            assert!(
                child.try_wait().expect("wait").is_none(),
                "the run ended before room {room} was measured"
            );
            std::thread::sleep(Duration::from_millis(2));
        }
        std::thread::sleep(Duration::from_millis(100));
        child.kill().expect("SIGKILL");
        let _ = child.wait();
        let (journal, after_arg) = (arg(&journal), arg(&after));
        let mut resume = vec!["run", ROUNDS, "--resume", &journal, "--trace", &after_arg];
        resume.extend_from_slice(steering);
        let (code, out, err) = tdl(&resume);
        assert_eq!(code, 0, "killed in room {room}: {out}{err}");
        assert_eq!(
            outcome(&out).0,
            outcome(&plain).0,
            "killed in room {room}: {out}"
        );
        assert!(outcome(&out).1.starts_with("0 unhandled"), "{out}");
        let (code, checked, _) = tdl(&["trace", "check", &arg(&after)]);
        assert_eq!(code, 0, "killed in room {room}: {checked}");
        // The resumed trace rebuilds the crashed run's, record for record, then says where it
        // resumed.
        let crashed = std::fs::read_to_string(&before).unwrap_or_default();
        let resumed = std::fs::read_to_string(&after).expect("the resumed trace");
        let whole: Vec<&str> = crashed.lines().take_while(|l| l.ends_with('}')).collect();
        for (i, (x, y)) in whole.iter().zip(resumed.lines()).enumerate() {
            assert_eq!(x, &y, "killed in room {room}: line {} differs", i + 1);
        }
        assert!(
            resumed
                .lines()
                .any(|l| l.contains("\"ev\":\"control\"") && l.contains("\"by\":\"journal\"")),
            "killed in room {room}: no record of the resumption"
        );
        // Every hand-over ran to its end exactly once, or was interrupted and handed over again.
        let handed = resumed
            .lines()
            .filter(|l| l.contains("\"ev\":\"spawned\"") && l.contains("\"name\":\"hand_over\""))
            .count();
        let interrupted = resumed
            .lines()
            .filter(|l| l.contains("\"ev\":\"failed\"") && l.contains("Interrupted"))
            .count();
        assert_eq!(
            interrupted, 1,
            "killed in room {room}: the hand-over in flight"
        );
        assert_eq!(handed, 8 + interrupted, "killed in room {room}");
    }
}

/// A damaged journal stops `tdl replay` and `tdl run --resume` at the damaged record, with its
/// line and byte offset; a journal of another program is refused by `--resume`, clearly; a cut
/// last record is dropped with a warning and the rest replays.
#[test]
fn bad_journals_are_refused_clearly() {
    let dir = scratch("bad");
    let journal = dir.join("j");
    let (code, out, err) = tdl(&["run", ROUNDS, "--args", "2", "--journal", &arg(&journal)]);
    assert_eq!(code, 0, "{out}{err}");
    let good = std::fs::read(&journal).expect("the journal");
    // A flipped byte in the fourth record (line 5).
    let mut flipped = good.clone();
    let starts: Vec<usize> = std::iter::once(0)
        .chain(
            good.iter()
                .enumerate()
                .filter(|(_, b)| **b == b'\n')
                .map(|(i, _)| i + 1),
        )
        .collect();
    let at = starts[4] + 12;
    flipped[at] ^= 0x01;
    std::fs::write(&journal, &flipped).expect("flip");
    for args in [
        vec!["replay", journal.to_str().expect("utf-8"), ROUNDS],
        vec!["run", ROUNDS, "--resume", journal.to_str().expect("utf-8")],
    ] {
        let (code, out, err) = tdl(&args);
        assert_eq!(code, 2, "{out}{err}");
        assert!(
            err.contains(&format!(
                ":5: the record at byte {} does not match its checksum",
                starts[4]
            )),
            "{err}"
        );
    }
    // Another program's journal.
    std::fs::write(&journal, &good).expect("restore");
    let (code, out, err) = tdl(&[
        "run",
        "tests/data/durable/changed.tdl",
        "--resume",
        &arg(&journal),
    ]);
    assert_eq!(code, 2, "{out}{err}");
    assert!(
        err.contains("resume or replay it with the program that wrote it"),
        "{err}"
    );
    // A last record cut short: dropped with a warning; the rest replays to its end.
    std::fs::write(&journal, &good[..good.len() - 5]).expect("cut");
    let (code, out, err) = tdl(&["replay", &arg(&journal), ROUNDS]);
    assert!(
        err.contains("was cut short") && err.contains("it is dropped"),
        "{err}"
    );
    assert_eq!(code, 0, "{out}{err}");
}
