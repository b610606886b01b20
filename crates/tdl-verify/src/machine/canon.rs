//! The canonical form of a state, and what a state that cannot go on reports.

use std::hash::{Hash, Hasher};

use tcm_core::{Canonical, Event, Facet, NodeId, Point};

use super::{Cmd, Cont, Modelled, State, TagVal};

impl State {
    /// Feeds `h` the canonical form of the state (docs/verification.md, "State").
    pub(crate) fn hash_canonical(&self, h: &mut impl Hasher) -> Canonical {
        let canon = self.engine.canonical_hash(h);
        let now = self.engine.now();
        let r = |id: NodeId, h: &mut dyn Hasher| {
            let mut w = HashWrap(h);
            self.engine.hash_node_ref(&canon, id, &mut w);
        };
        let mut conts: Vec<(Option<u32>, &Cont)> = self
            .conts
            .iter()
            .map(|c| (canon.index(c.node), c))
            .collect();
        conts.sort_by_key(|(i, _)| *i);
        conts.len().hash(h);
        for (i, c) in conts {
            i.hash(h);
            c.task.hash(h);
            c.pc.hash(h);
            c.env.hash(h);
            c.loops.hash(h);
            c.choice.hash(h);
            for t in &c.tags {
                match t {
                    TagVal::Unset => 0u8.hash(h),
                    TagVal::One(id) => {
                        1u8.hash(h);
                        r(*id, h);
                    }
                    TagVal::Map(m) => {
                        2u8.hash(h);
                        m.len().hash(h);
                        for (k, id) in m {
                            k.hash(h);
                            r(*id, h);
                        }
                    }
                    TagVal::Members(ms) => {
                        3u8.hash(h);
                        ms.len().hash(h);
                        for id in ms {
                            r(*id, h);
                        }
                    }
                }
            }
            match &c.prev {
                None => 0u8.hash(h),
                Some(p) => {
                    1u8.hash(h);
                    p.len().hash(h);
                    for id in p {
                        r(*id, h);
                    }
                }
            }
            c.frames.len().hash(h);
            for f in &c.frames {
                f.gid.hash(h);
                f.members.len().hash(h);
                for id in &f.members {
                    r(*id, h);
                }
                match &f.snapshot {
                    None => 0u8.hash(h),
                    Some(None) => 1u8.hash(h),
                    Some(Some(s)) => {
                        2u8.hash(h);
                        s.len().hash(h);
                        for id in s {
                            r(*id, h);
                        }
                    }
                }
            }
            match &c.wait {
                None => 0u8.hash(h),
                Some(w) => {
                    1u8.hash(h);
                    r(w.node, h);
                    w.kind.hash(h);
                    w.rest.len().hash(h);
                    for id in &w.rest {
                        r(*id, h);
                    }
                }
            }
            match &c.resume {
                None => 0u8.hash(h),
                Some(o) => {
                    1u8.hash(h);
                    std::mem::discriminant(o).hash(h);
                }
            }
        }
        self.runq.len().hash(h);
        for n in &self.runq {
            r(*n, h);
        }
        self.choice.map(|n| canon.index(n)).hash(h);
        let mut cmds: Vec<(Option<u32>, &Cmd)> =
            self.cmds.iter().map(|c| (canon.index(c.node), c)).collect();
        cmds.sort_by_key(|(i, _)| *i);
        cmds.len().hash(h);
        for (i, c) in cmds {
            i.hash(h);
            c.callee.hash(h);
            c.abstracted.hash(h);
            c.remote.hash(h);
            c.args.hash(h);
            c.hung.hash(h);
            // How many deadlines it outlasted (it may outlast `Options::ticks`).
            c.ticks.hash(h);
            match &c.model {
                None => 0u8.hash(h),
                Some(Modelled::Undecided(e)) => {
                    1u8.hash(h);
                    e.hash(h);
                }
                Some(Modelled::Decided(at, e)) => {
                    2u8.hash(h);
                    at.as_nanos().saturating_sub(now.as_nanos()).hash(h);
                    e.hash(h);
                }
            }
        }
        self.stops.len().hash(h);
        self.raised.hash(h);
        self.env_used.hash(h);
        self.hangs.hash(h);
        let mut term: Vec<u32> = self
            .terminable
            .iter()
            .filter_map(|n| canon.index(*n))
            .collect();
        term.sort_unstable();
        term.hash(h);
        self.cut.is_some().hash(h);
        self.fault.hash(h);
        self.broken.hash(h);
        self.watch.as_ref().map(|w| w.seen).hash(h);
        canon
    }

    /// What the run waits for when nothing can happen: the engine's stuck report, with each
    /// body's wait (docs/semantics.md, "Run outcome").
    pub(crate) fn stuck_report(&self) -> Vec<String> {
        let awaits: Vec<(NodeId, Event)> = self
            .conts
            .iter()
            .filter_map(|c| {
                c.wait.as_ref().map(|w| {
                    (
                        c.node,
                        Event::on(w.node, Facet::Execution, Point::Completed),
                    )
                })
            })
            .collect();
        let mut out: Vec<String> = self
            .engine
            .blocked_awaiting(&awaits)
            .iter()
            .map(ToString::to_string)
            .collect();
        for c in &self.cmds {
            if c.hung {
                out.push(format!(
                    "{} was chosen to run until it is terminated, and nothing terminates it",
                    self.engine.path(c.node)
                ));
            }
        }
        out
    }

    /// The commands left running forever on this path.
    pub(crate) fn hung(&self) -> Vec<String> {
        self.cmds
            .iter()
            .filter(|c| c.hung)
            .map(|c| self.engine.path(c.node))
            .collect()
    }
}

struct HashWrap<'a>(&'a mut dyn Hasher);

impl Hasher for HashWrap<'_> {
    fn finish(&self) -> u64 {
        self.0.finish()
    }
    fn write(&mut self, bytes: &[u8]) {
        self.0.write(bytes);
    }
}
