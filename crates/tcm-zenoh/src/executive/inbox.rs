//! The executive's inbox: each message of an agent handed to its remote task's action once and
//! in order, the answer to a reattach outside the sequence, everything else counted and reported.

use super::{Incoming, Inner, ignored_text};
use crate::noise::Ignored;
use crate::sequence::{Known, Verdict, verdict};
use crate::wire::{self, Msg, ToAgent, ToExec};
use std::sync::Arc;

impl Inner {
    /// A message arrived on the inbox: handed to its task's action once, in order (numbered one
    /// more than the task's last); duplicates, messages out of order and messages of ended tasks
    /// are counted and dropped, and reported without flooding ([`Inner::ignored`]).
    /// A message of a task from another agent than the one it was placed on is refused: only
    /// that agent speaks for the task.
    pub(super) fn receive(self: &Arc<Self>, from: &str, bytes: &[u8]) {
        let msg: Msg<ToExec> = match wire::decode_to_exec(bytes) {
            Ok(m) => m,
            Err(e) => {
                self.lock().stats.malformed += 1;
                self.ignored(None, Ignored::Malformed, None, || {
                    format!("malformed message ignored: {e}")
                });
                return;
            }
        };
        let mut s = self.lock();
        let placed_on = match (s.pending.get(&msg.task), s.ended.get(&msg.task)) {
            (Some(p), _) => Some((p.agent.as_str(), p.ctx.clone())),
            (None, Some((_, agent, ctx))) => Some((agent.as_str(), ctx.clone())),
            (None, None) => None,
        };
        if let Some((agent, ctx)) = placed_on.filter(|(agent, _)| *agent != from) {
            let agent = agent.to_string();
            s.stats.strangers += 1;
            drop(s);
            let from = from.to_string();
            self.ignored(Some(msg.task), Ignored::Stranger, Some(ctx), || {
                let what = format!("message from {from} (not the agent {agent} it runs on)");
                ignored_text(&msg, &what, "remote task")
            });
            return;
        }
        // The answer to a reattach, numbered 0, outside the task's sequence (`remote.rs`).
        if msg.seq == 0 {
            if let Some(p) = s.pending.get_mut(&msg.task).filter(|p| p.questions > 0) {
                let ends = match &msg.body {
                    // An answer may have been made before messages it was overtaken by (a
                    // `done` refused as out of order, which the second question is for): the
                    // number of the last applied never goes back.
                    ToExec::Attached { sent, done, .. } => {
                        p.last_seq = p.last_seq.max(*sent);
                        Some(done.is_some())
                    }
                    // Never started there: the executive sends the start now.
                    ToExec::Unattached { started, .. } => Some(*started),
                    _ => None,
                };
                if let Some(ends) = ends {
                    p.questions -= 1;
                    let last = p.last_seq;
                    let _ = p.tx.send(Incoming::Msg(msg.body));
                    if ends {
                        s.end(msg.task, last);
                    }
                    return;
                }
            }
        }
        let (known, ctx) = match (s.pending.get(&msg.task), s.ended.get(&msg.task)) {
            (Some(p), _) => (Known::Running(p.last_seq), Some(p.ctx.clone())),
            (None, Some((last, _, ctx))) => (Known::Ended(*last), Some(ctx.clone())),
            (None, None) => (Known::Unknown, None),
        };
        let whose = match known {
            Known::Running(_) => "remote task",
            _ => "ended remote task",
        };
        // Zenoh delivers one publisher's messages in order: the agent's next message is numbered
        // one more than the last. Any other number (a gap, or a forged 2^64-1 that would make the
        // real messages look like duplicates) is refused and changes nothing.
        let (kind, what) = match verdict(known, msg.seq) {
            Verdict::Apply => (None, String::new()),
            Verdict::Duplicate => {
                s.stats.duplicates += 1;
                (Some(Ignored::Duplicate), "duplicate message".to_string())
            }
            Verdict::Late => {
                s.stats.late += 1;
                (Some(Ignored::Late), "late message".to_string())
            }
            Verdict::OutOfOrder { expected } => {
                s.stats.refused += 1;
                (
                    Some(Ignored::Refused),
                    format!("out-of-order message (expected {expected})"),
                )
            }
        };
        // A gap in a running task's messages: one was lost on the way (the agent's publisher can
        // send before zenoh routes it to an executive that came back under the same id). The
        // agent is asked where the task stands, once, as a resumed executive asks (`Reattach`,
        // numbered 0); its answer, outside the sequence, closes the gap or ends the task.
        let ask = match (known, s.pending.get_mut(&msg.task)) {
            (Known::Running(last), Some(p)) if msg.seq > last.saturating_add(1) && !p.asked => {
                p.asked = true;
                p.questions += 1;
                Some(p.agent.clone())
            }
            _ => None,
        };
        if let Some(kind) = kind {
            drop(s);
            if let Some(agent) = ask {
                let question = Msg {
                    task: msg.task,
                    seq: 0,
                    body: ToAgent::Reattach,
                };
                self.send_later(&agent, question);
            }
            self.ignored(Some(msg.task), kind, ctx, || {
                ignored_text(&msg, &what, whose)
            });
            return;
        }
        let Some(p) = s.pending.get_mut(&msg.task) else {
            return;
        };
        p.last_seq = msg.seq;
        // Sent before the task is marked ended, so nothing can overtake it.
        let _ = p.tx.send(Incoming::Msg(msg.body.clone()));
        if matches!(msg.body, ToExec::Done { .. } | ToExec::Cancelled) {
            s.end(msg.task, msg.seq);
        }
    }
}
