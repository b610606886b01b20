//! The distributed wire (`tcm-zenoh`) on arbitrary bytes: a stream of messages, one a line, read
//! by the executive's and the agent's decoders and numbered by the rule both apply
//! (`tcm_zenoh::fuzzing`). Nothing panics; what reads encodes again to the same message; and per
//! task, whatever the order, duplicates, gaps or forged kinds of the stream, the messages applied
//! are numbered 1, 2, 3, … with none after the one that ended the task, and every other message
//! is refused for the reason its number gives.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::collections::BTreeMap;
use tcm_zenoh::fuzzing::{Known, Verdict, decode_to_agent, decode_to_exec, start_verdict, verdict};

/// One receiver's view of its tasks, moved only by the verdicts.
#[derive(Default)]
struct Receiver {
    known: BTreeMap<u64, Known>,
    // The numbers applied, by task, in order.
    applied: BTreeMap<u64, Vec<u64>>,
}

impl Receiver {
    fn known(&self, task: u64) -> Known {
        self.known.get(&task).copied().unwrap_or(Known::Unknown)
    }

    /// Checks `v`, the verdict on message `seq` of `task`, against what the receiver knows, and
    /// applies it.
    fn take(&mut self, task: u64, seq: u64, v: Verdict, start: bool, ends: bool) {
        let known = self.known(task);
        match (known, v) {
            (Known::Unknown, Verdict::Apply) => assert!(start && seq == 1),
            (Known::Running(last), Verdict::Apply) => {
                assert!(!start && last.checked_add(1) == Some(seq))
            }
            (Known::Ended(_), Verdict::Apply) => panic!("applied after the end: {task} {seq}"),
            (Known::Running(last) | Known::Ended(last), Verdict::Duplicate) => {
                assert!(start || seq <= last)
            }
            (Known::Unknown, Verdict::Duplicate) => panic!("a duplicate of nothing: {task} {seq}"),
            (Known::Running(last), Verdict::OutOfOrder { expected }) => {
                assert!(!start && seq > last.saturating_add(1) && expected == last + 1)
            }
            (Known::Unknown, Verdict::OutOfOrder { expected }) => {
                assert!(start && seq != 1 && expected == 1)
            }
            (Known::Ended(_), Verdict::OutOfOrder { .. }) => panic!("out of order after the end"),
            (Known::Unknown, Verdict::Late) => assert!(!start),
            (Known::Ended(last), Verdict::Late) => assert!(!start && seq > last),
            (Known::Running(_), Verdict::Late) => panic!("late while running: {task} {seq}"),
        }
        if v == Verdict::Apply {
            let applied = self.applied.entry(task).or_default();
            assert_eq!(applied.len() as u64 + 1, seq, "numbers applied out of turn");
            applied.push(seq);
            let next = if ends {
                Known::Ended(seq)
            } else {
                Known::Running(seq)
            };
            self.known.insert(task, next);
        }
    }
}

fuzz_target!(|data: &[u8]| {
    // The first byte says which tasks (ids 0 to 7) the executive placed before the stream.
    let Some((&placed, stream)) = data.split_first() else {
        return;
    };
    let mut exec = Receiver::default();
    for task in 0..8u64 {
        if placed & (1 << task) != 0 {
            exec.known.insert(task, Known::Running(0));
        }
    }
    let mut agent = Receiver::default();
    for line in stream.split(|b| *b == b'\n') {
        if let Some((task, seq, kind, ends, again)) = decode_to_exec(line) {
            let back = decode_to_exec(&again).expect("an encoded message reads");
            assert_eq!((back.0, back.1, back.2, back.3), (task, seq, kind, ends));
            let v = verdict(exec.known(task), seq);
            exec.take(task, seq, v, false, ends);
        }
        if let Some((task, seq, kind, again)) = decode_to_agent(line) {
            let back = decode_to_agent(&again).expect("an encoded message reads");
            assert_eq!((back.0, back.1, back.2), (task, seq, kind));
            let start = kind == "start";
            let v = if start {
                start_verdict(agent.known(task), seq)
            } else {
                verdict(agent.known(task), seq)
            };
            agent.take(task, seq, v, start, kind == "cancel");
        }
    }
});
