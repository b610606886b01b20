//! The one rule every receiver (the executive, a Rust agent; the Python agent has its copy) applies
//! to the number of a task's message (docs/distributed.md, "Exactly once"), without I/O so that
//! it can be fuzzed and tested alone: a message is applied only when numbered one more than the
//! last applied of its task, a task's first message (an agent's start) being number 1.
#![cfg_attr(not(feature = "fuzzing"), allow(unreachable_pub))]

/// What a receiver does with a message of a task, given what it knows of the task.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// Apply it: it is the next one.
    Apply,
    /// Ignore it: numbered at most the last one applied.
    Duplicate,
    /// Refuse it: numbered past the next one (a gap, a forged number); the number expected stays.
    OutOfOrder {
        /// The number expected.
        expected: u64,
    },
    /// Ignore it: about a task that ended, or that the receiver never had.
    Late,
}

/// What a receiver knows of a task.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Known {
    /// Never had, or forgotten.
    Unknown,
    /// Running; the number of the last message applied.
    Running(u64),
    /// Ended; the number of the last message applied.
    Ended(u64),
}

/// The verdict on message `seq` of a task the receiver knows as `known` (not a start).
pub fn verdict(known: Known, seq: u64) -> Verdict {
    match known {
        Known::Unknown => Verdict::Late,
        Known::Ended(last) if seq <= last => Verdict::Duplicate,
        Known::Ended(_) => Verdict::Late,
        Known::Running(last) if seq <= last => Verdict::Duplicate,
        Known::Running(last) if last.checked_add(1) == Some(seq) => Verdict::Apply,
        Known::Running(last) => Verdict::OutOfOrder {
            expected: last.saturating_add(1),
        },
    }
}

/// The verdict on a start numbered `seq` of a task the agent knows as `known`: a start of a task
/// the agent has (or had) is a duplicate, whatever its number, so a body never runs twice; a
/// task's first message is its start, number 1.
pub fn start_verdict(known: Known, seq: u64) -> Verdict {
    match known {
        Known::Running(_) | Known::Ended(_) => Verdict::Duplicate,
        Known::Unknown if seq == 1 => Verdict::Apply,
        Known::Unknown => Verdict::OutOfOrder { expected: 1 },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_the_next_number_is_applied() {
        assert_eq!(verdict(Known::Running(0), 1), Verdict::Apply);
        assert_eq!(verdict(Known::Running(3), 4), Verdict::Apply);
        assert_eq!(verdict(Known::Running(3), 3), Verdict::Duplicate);
        assert_eq!(verdict(Known::Running(3), 0), Verdict::Duplicate);
        assert_eq!(
            verdict(Known::Running(3), 5),
            Verdict::OutOfOrder { expected: 4 }
        );
        assert_eq!(
            verdict(Known::Running(u64::MAX), u64::MAX),
            Verdict::Duplicate
        );
        assert_eq!(
            verdict(Known::Running(1), u64::MAX),
            Verdict::OutOfOrder { expected: 2 }
        );
        assert_eq!(verdict(Known::Ended(4), 4), Verdict::Duplicate);
        assert_eq!(verdict(Known::Ended(4), 5), Verdict::Late);
        assert_eq!(verdict(Known::Unknown, 1), Verdict::Late);
        assert_eq!(start_verdict(Known::Unknown, 1), Verdict::Apply);
        assert_eq!(
            start_verdict(Known::Unknown, u64::MAX),
            Verdict::OutOfOrder { expected: 1 }
        );
        assert_eq!(start_verdict(Known::Running(1), 1), Verdict::Duplicate);
        assert_eq!(start_verdict(Known::Ended(9), 1), Verdict::Duplicate);
    }
}
