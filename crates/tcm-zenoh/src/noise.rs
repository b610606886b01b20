//! The messages an agent ignores (duplicates, late ones, ones out of order, ones that do not read),
//! logged without flooding the log: per peer (the executive a message's key names), the first one
//! is logged at once with what it was, and what follows within [`INTERVAL`] is counted and logged
//! as one line when the interval ends (docs/distributed.md, "Exactly once"). A peer with nothing
//! held when its interval ends is forgotten; past [`PEERS`] peers at once (forged keys name any
//! executive), the others share one line.

use std::collections::BTreeMap;
use std::fmt;
use std::time::Duration;
use tokio::time::Instant;

/// At most one line per peer per interval.
pub(crate) const INTERVAL: Duration = Duration::from_secs(10);

/// How many peers are followed one by one; the others are counted together.
pub(crate) const PEERS: usize = 64;

/// The name the peers past [`PEERS`] are counted under.
pub(crate) const OTHERS: &str = "(other executives)";

/// Why a message was ignored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Ignored {
    /// Numbered at most the last one applied.
    Duplicate,
    /// About a task that ended, or that the agent never had.
    Late,
    /// Numbered past the next one expected.
    Refused,
    /// Did not read.
    Malformed,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Counts {
    duplicate: u64,
    late: u64,
    refused: u64,
    malformed: u64,
}

impl Counts {
    fn add(&mut self, what: Ignored) {
        let n = match what {
            Ignored::Duplicate => &mut self.duplicate,
            Ignored::Late => &mut self.late,
            Ignored::Refused => &mut self.refused,
            Ignored::Malformed => &mut self.malformed,
        };
        *n = n.saturating_add(1);
    }

    fn any(&self) -> bool {
        *self != Counts::default()
    }
}

impl fmt::Display for Counts {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let parts: Vec<String> = [
            (self.duplicate, "duplicate"),
            (self.late, "late"),
            (self.refused, "out of order"),
            (self.malformed, "malformed"),
        ]
        .into_iter()
        .filter(|(n, _)| *n > 0)
        .map(|(n, what)| format!("{n} {what}"))
        .collect();
        f.write_str(&parts.join(", "))
    }
}

struct Peer {
    last_line: Instant,
    held: Counts,
}

/// What to do with a message just ignored.
#[derive(Debug, PartialEq, Eq)]
pub(crate) enum Noted {
    /// Log it now (the peer's first in a while), and [`Noise::flush`] the peer at this instant.
    Log(Instant),
    /// Counted, for the flush already due.
    Held,
}

/// The ignored messages of each peer not logged yet. A peer is here exactly while a flush of it
/// is due.
#[derive(Default)]
pub(crate) struct Noise {
    peers: BTreeMap<String, Peer>,
}

impl Noise {
    /// A message from `peer` was ignored, at `now`.
    pub(crate) fn note(&mut self, peer: &str, what: Ignored, now: Instant) -> Noted {
        let peer = self.counted_as(peer);
        match self.peers.get_mut(peer) {
            Some(p) => {
                p.held.add(what);
                Noted::Held
            }
            None => {
                self.peers.insert(
                    peer.to_string(),
                    Peer {
                        last_line: now,
                        held: Counts::default(),
                    },
                );
                Noted::Log(now + INTERVAL)
            }
        }
    }

    /// The peer's interval ended at `now`: the line of what was held since its last line, and
    /// when to flush it again; `None` when nothing was held (the peer is forgotten: its next
    /// ignored message is logged at once).
    pub(crate) fn flush(&mut self, peer: &str, now: Instant) -> Option<(String, Instant)> {
        let p = self.peers.get_mut(peer)?;
        if !p.held.any() {
            self.peers.remove(peer);
            return None;
        }
        let line = format!(
            "{} message(s) from {peer} ignored in the last {} ms",
            p.held,
            now.saturating_duration_since(p.last_line).as_millis()
        );
        p.held = Counts::default();
        p.last_line = now;
        Some((line, now + INTERVAL))
    }

    /// The peer a message from `peer` is counted under (itself, or [`OTHERS`]).
    pub(crate) fn counted_as<'a>(&self, peer: &'a str) -> &'a str {
        if self.peers.contains_key(peer) || self.peers.len() < PEERS {
            peer
        } else {
            OTHERS
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_first_message_is_logged_at_once_and_the_rest_in_one_line_per_interval() {
        let mut n = Noise::default();
        let t0 = Instant::now();
        let due = t0 + INTERVAL;
        assert_eq!(n.note("e1", Ignored::Refused, t0), Noted::Log(due));
        for _ in 0..1000 {
            assert_eq!(n.note("e1", Ignored::Duplicate, t0), Noted::Held);
        }
        assert_eq!(n.note("e1", Ignored::Late, t0), Noted::Held);
        assert_eq!(n.note("e1", Ignored::Malformed, t0), Noted::Held);
        // Another peer has lines of its own.
        assert_eq!(n.note("e2", Ignored::Late, t0), Noted::Log(due));
        let (line, next) = n.flush("e1", due).expect("a line");
        assert_eq!(
            line,
            "1000 duplicate, 1 late, 1 malformed message(s) from e1 ignored in the last 10000 ms"
        );
        assert_eq!(next, due + INTERVAL);
        // Still within the next interval: held.
        assert_eq!(n.note("e1", Ignored::Refused, due), Noted::Held);
        let (line, _) = n.flush("e1", next).expect("a line");
        assert!(
            line.starts_with("1 out of order message(s) from e1"),
            "{line}"
        );
        // A quiet interval forgets the peer; its next message is logged at once.
        assert_eq!(n.flush("e1", next + INTERVAL), None);
        assert_eq!(n.flush("e2", due), None);
        let later = next + INTERVAL * 3;
        assert_eq!(
            n.note("e1", Ignored::Late, later),
            Noted::Log(later + INTERVAL)
        );
    }

    #[test]
    fn past_so_many_peers_the_others_share_one_line() {
        let mut n = Noise::default();
        let t0 = Instant::now();
        for i in 0..PEERS {
            assert!(matches!(
                n.note(&format!("e{i}"), Ignored::Late, t0),
                Noted::Log(_)
            ));
        }
        assert_eq!(n.counted_as("forged-1"), OTHERS);
        assert!(matches!(
            n.note("forged-1", Ignored::Late, t0),
            Noted::Log(_)
        ));
        assert_eq!(n.note("forged-2", Ignored::Late, t0), Noted::Held);
        assert_eq!(n.peers.len(), PEERS + 1);
        let (line, _) = n.flush(OTHERS, t0 + INTERVAL).expect("a line");
        assert!(
            line.contains("1 late message(s) from (other executives)"),
            "{line}"
        );
    }
}
