//! An agent's side of an executive that comes back (docs/distributed.md, "An executive that comes
//! back"). With a hold ([`AgentBuilder::hold`](super::AgentBuilder::hold)), the bodies of an
//! executive whose token went keep running, and the ends of bodies are kept, so that the
//! executive, resumed from its journal under the same id, re-attaches to each task it still wants
//! (`Reattach`, numbered 0): the agent answers `Attached` with where the task's two sequences
//! stand and its end if it ended (its `Done` may have been lost with the executive), or
//! `Unattached`. A body not re-attached when the hold ends is aborted and cleaned up.

use super::{AgentInner, AgentState};
use crate::body::Link;
use crate::failure::RemoteFailure;
use crate::wire::{Json, Msg, ToExec};
use std::collections::{BTreeMap, VecDeque};
use std::sync::Arc;

/// How many ended bodies' ends an agent with a hold keeps.
const OUTCOMES_KEPT: usize = 4096;

/// The end of a body, kept for an executive that re-attaches.
struct Outcome {
    received: u64,
    link: Arc<Link>,
    done: Result<Json, RemoteFailure>,
}

/// The ends kept, by executive and task, the oldest dropped first past [`OUTCOMES_KEPT`].
#[derive(Default)]
pub(super) struct Outcomes {
    by_task: BTreeMap<(String, u64), Outcome>,
    order: VecDeque<(String, u64)>,
}

impl Outcomes {
    pub(super) fn keep(
        &mut self,
        key: (String, u64),
        received: u64,
        link: Arc<Link>,
        done: Result<Json, RemoteFailure>,
    ) {
        let outcome = Outcome {
            received,
            link,
            done,
        };
        if self.by_task.insert(key.clone(), outcome).is_none() {
            self.order.push_back(key);
        }
        while self.order.len() > OUTCOMES_KEPT {
            if let Some(old) = self.order.pop_front() {
                self.by_task.remove(&old);
            }
        }
    }
}

impl AgentInner {
    /// Executive `exec`'s token went: its bodies are orphaned, and those still orphaned when
    /// the hold ends are aborted, unless the executive went again meanwhile (that absence ends
    /// them).
    pub(super) fn hold_for(self: &Arc<Self>, exec: &str) {
        let absence = {
            let mut s = self.lock();
            for (key, r) in s.running.iter_mut() {
                if key.0 == exec {
                    r.orphaned = true;
                }
            }
            let n = s.absences.entry(exec.to_string()).or_default();
            *n += 1;
            *n
        };
        let weak = Arc::downgrade(self);
        let exec = exec.to_string();
        let hold = self.hold;
        self.rt.spawn(async move {
            tokio::time::sleep(hold).await;
            let Some(me) = weak.upgrade() else { return };
            if me.lock().absences.get(&exec) == Some(&absence) {
                me.abandon(&exec, |r| r.orphaned);
            }
        });
    }

    /// Executive `exec` re-attaches to `task`: answered with the task as it stands, once the
    /// answer can go out.
    pub(super) fn reattach(self: &Arc<Self>, exec: String, task: u64) {
        let key = (exec.clone(), task);
        let answer = {
            let mut s: std::sync::MutexGuard<'_, AgentState> = self.lock();
            if let Some(r) = s.running.get_mut(&key) {
                r.orphaned = false;
                let (received, link) = (r.last_seq, r.link.clone());
                s.stats.reattached += 1;
                Some((received, link, None))
            } else if let Some(o) = s.outcomes.by_task.get(&key) {
                let found = (o.received, o.link.clone(), Some(o.done.clone()));
                s.stats.reattached += 1;
                Some(found)
            } else {
                None
            }
        };
        let had = answer.is_none() && self.lock().ended.contains_key(&key);
        let me = self.clone();
        self.rt.spawn(async move {
            match answer {
                Some((received, link, done)) => {
                    link.send_aside(|sent| ToExec::Attached {
                        received,
                        sent,
                        done,
                    })
                    .await;
                }
                None => {
                    let reason = if had {
                        format!(
                            "agent {} no longer has task {task} of executive {exec} (cancelled, or \
                             aborted when its hold ended)",
                            me.name
                        )
                    } else {
                        format!(
                            "agent {} never had task {task} of executive {exec}: its start did not \
                             reach it",
                            me.name
                        )
                    };
                    let bytes = Msg {
                        task,
                        seq: 0,
                        body: ToExec::Unattached {
                            reason,
                            started: had,
                        },
                    }
                    .encode();
                    let sent = match me.outlet(&exec).await {
                        Ok(p) => me.put(&exec, p.as_deref(), bytes).await,
                        Err(e) => Err(e),
                    };
                    if let Err(e) = sent {
                        tracing::warn!(target: "tcm_zenoh", agent = me.name, executive = exec,
                            "cannot answer a reattach: {e}");
                    }
                }
            }
        });
    }
}
