//! The messages a receiver ignores (duplicates, late ones, ones out of order, ones that do not read,
//! starts past a bound), reported without flooding: per key (on an agent the executive a message's
//! key names, on the executive the remote task it is about), the first one is reported at once
//! with what it was, and what follows within the interval is counted and reported as one line
//! when the interval ends (docs/distributed.md, "Exactly once"). A key with nothing held when its
//! interval ends is forgotten; past so many keys at once (forged messages name any executive and
//! any task), the others share one line.

use std::collections::BTreeMap;
use std::fmt;
use std::time::Duration;
use tokio::time::Instant;

/// At most one line per peer per interval, on an agent.
pub(crate) const INTERVAL: Duration = Duration::from_secs(10);

/// How many peers an agent follows one by one; the others are counted together.
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
    /// From a sender the task is not with, or a start from an executive that is not live.
    Stranger,
    /// A start past one of the agent's bounds.
    OverLimit,
}

/// How many messages of each kind were held.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Counts {
    duplicate: u64,
    late: u64,
    refused: u64,
    malformed: u64,
    stranger: u64,
    over_limit: u64,
}

impl Counts {
    fn add(&mut self, what: Ignored) {
        let n = match what {
            Ignored::Duplicate => &mut self.duplicate,
            Ignored::Late => &mut self.late,
            Ignored::Refused => &mut self.refused,
            Ignored::Malformed => &mut self.malformed,
            Ignored::Stranger => &mut self.stranger,
            Ignored::OverLimit => &mut self.over_limit,
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
            (self.stranger, "stranger's"),
            (self.over_limit, "over a bound"),
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

/// The ignored messages of each key not reported yet. A key is here exactly while a flush of it
/// is due.
pub(crate) struct Noise<K = String> {
    peers: BTreeMap<K, Peer>,
    // The key past `cap` keys at once count under.
    others: K,
    cap: usize,
    interval: Duration,
}

impl Default for Noise<String> {
    /// An agent's: per executive, [`PEERS`] at once, one line per [`INTERVAL`].
    fn default() -> Noise<String> {
        Noise::new(OTHERS.to_string(), PEERS, INTERVAL)
    }
}

impl<K: Ord + Clone> Noise<K> {
    /// Follows `cap` keys at once (the others count under `others`), reporting each at most
    /// once per `interval`.
    pub(crate) fn new(others: K, cap: usize, interval: Duration) -> Noise<K> {
        Noise {
            peers: BTreeMap::new(),
            others,
            cap,
            interval,
        }
    }

    /// A message about `peer` was ignored, at `now`.
    pub(crate) fn note(&mut self, peer: &K, what: Ignored, now: Instant) -> Noted {
        let peer = self.counted_as(peer).clone();
        match self.peers.get_mut(&peer) {
            Some(p) => {
                p.held.add(what);
                Noted::Held
            }
            None => {
                self.peers.insert(
                    peer,
                    Peer {
                        last_line: now,
                        held: Counts::default(),
                    },
                );
                Noted::Log(now + self.interval)
            }
        }
    }

    /// The key's interval ended at `now`: what was held since its last report, over how long,
    /// and when to flush it again; `None` when nothing was held (the key is forgotten: its next
    /// ignored message is reported at once).
    pub(crate) fn flush(&mut self, peer: &K, now: Instant) -> Option<(Counts, Duration, Instant)> {
        let p = self.peers.get_mut(peer)?;
        if !p.held.any() {
            self.peers.remove(peer);
            return None;
        }
        let held = std::mem::take(&mut p.held);
        let over = now.saturating_duration_since(p.last_line);
        p.last_line = now;
        Some((held, over, now + self.interval))
    }

    /// The key a message about `peer` is counted under (itself, or the others' key).
    pub(crate) fn counted_as<'a>(&'a self, peer: &'a K) -> &'a K {
        if self.peers.contains_key(peer) || self.peers.len() < self.cap {
            peer
        } else {
            &self.others
        }
    }
}

/// An agent's line for what `peer` sent that was ignored over `over`.
pub(crate) fn line(held: &Counts, peer: &str, over: Duration) -> String {
    format!(
        "{held} message(s) from {peer} ignored in the last {} ms",
        over.as_millis()
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_first_message_is_logged_at_once_and_the_rest_in_one_line_per_interval() {
        let mut n = Noise::default();
        let t0 = Instant::now();
        let due = t0 + INTERVAL;
        assert_eq!(n.note(&"e1".into(), Ignored::Refused, t0), Noted::Log(due));
        for _ in 0..1000 {
            assert_eq!(n.note(&"e1".into(), Ignored::Duplicate, t0), Noted::Held);
        }
        assert_eq!(n.note(&"e1".into(), Ignored::Late, t0), Noted::Held);
        assert_eq!(n.note(&"e1".into(), Ignored::Malformed, t0), Noted::Held);
        // Another peer has lines of its own.
        assert_eq!(n.note(&"e2".into(), Ignored::Late, t0), Noted::Log(due));
        let (held, over, next) = n.flush(&"e1".into(), due).expect("a line");
        assert_eq!(
            line(&held, "e1", over),
            "1000 duplicate, 1 late, 1 malformed message(s) from e1 ignored in the last 10000 ms"
        );
        assert_eq!(next, due + INTERVAL);
        // Still within the next interval: held.
        assert_eq!(n.note(&"e1".into(), Ignored::Refused, due), Noted::Held);
        let (held, over, _) = n.flush(&"e1".into(), next).expect("a line");
        let l = line(&held, "e1", over);
        assert!(l.starts_with("1 out of order message(s) from e1"), "{l}");
        // A quiet interval forgets the peer; its next message is logged at once.
        assert_eq!(n.flush(&"e1".into(), next + INTERVAL), None);
        assert_eq!(n.flush(&"e2".into(), due), None);
        let later = next + INTERVAL * 3;
        assert_eq!(
            n.note(&"e1".into(), Ignored::Late, later),
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
        assert_eq!(n.counted_as(&"forged-1".into()), OTHERS);
        assert!(matches!(
            n.note(&"forged-1".into(), Ignored::Late, t0),
            Noted::Log(_)
        ));
        assert_eq!(n.note(&"forged-2".into(), Ignored::Late, t0), Noted::Held);
        assert_eq!(n.peers.len(), PEERS + 1);
        let (held, over, _) = n.flush(&OTHERS.into(), t0 + INTERVAL).expect("a line");
        let l = line(&held, OTHERS, over);
        assert!(
            l.contains("1 late message(s) from (other executives)"),
            "{l}"
        );
    }
}
