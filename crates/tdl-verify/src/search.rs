//! The search: breadth-first over the program's states, each explored once.
//!
//! Every state is identified by a 64-bit hash of its canonical form ([`State::hash_canonical`]);
//! the search keeps, per distinct state, the state it was first reached from, by which transition,
//! and its depth, so the first violation found of each property is one of the shortest, and its
//! path is rebuilt by replaying those transitions from the first state with tracing on. Every
//! transition is also kept as an edge, so that once the search is over the strongly connected
//! components of the state graph (petgraph's Kosaraju) show the runs that never end: a component
//! with a cycle is a loop the program can take forever.
//!
//! Why not `stateright`, which the issue suggested: its breadth-first checker keeps no edges and
//! offers its `eventually` properties only at terminal states, so it cannot find a run that loops
//! forever (the seeded "missing `terminate at`" bug is one); it carries each queued state's whole
//! path (a vector as long as the depth) instead of a parent link; and it cannot be stopped from
//! outside (Ctrl-C) except by a timeout. The loop here is short; petgraph does the graph work.

use std::collections::VecDeque;
use std::collections::hash_map::{Entry, HashMap};
use std::hash::{BuildHasherDefault, Hasher};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use petgraph::graph::{DiGraph, NodeIndex};

use crate::machine::{Ctx, Fault, State};
use crate::{Builtin, Cut, memory};

/// A hasher for keys that are already hashes.
#[derive(Default)]
pub(crate) struct Identity(u64);

impl Hasher for Identity {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for b in bytes {
            self.0 = (self.0 << 8) | u64::from(*b);
        }
    }
    fn write_u64(&mut self, n: u64) {
        self.0 = n;
    }
}

pub(crate) fn fingerprint(s: &State) -> u64 {
    let mut h = Fingerprinter::default();
    let _ = s.hash_canonical(&mut h);
    h.finish()
}

/// The hasher of fingerprints: two independent multiply-rotate lanes over 64-bit words, mixed
/// at the end (a 64-bit fingerprint of a canonical form of a few kilobytes; SipHash, the
/// standard library's, spent a fifth of the search's time here).
#[derive(Clone, Copy)]
pub(crate) struct Fingerprinter {
    a: u64,
    b: u64,
}

impl Default for Fingerprinter {
    fn default() -> Self {
        Fingerprinter {
            a: 0x243f_6a88_85a3_08d3,
            b: 0x1319_8a2e_0370_7344,
        }
    }
}

const K1: u64 = 0x9e37_79b9_7f4a_7c15;
const K2: u64 = 0xc2b2_ae3d_27d4_eb4f;

fn mix(mut x: u64) -> u64 {
    x ^= x >> 30;
    x = x.wrapping_mul(0xbf58_476d_1ce4_e5b9);
    x ^= x >> 27;
    x = x.wrapping_mul(0x94d0_49bb_1331_11eb);
    x ^ (x >> 31)
}

impl Hasher for Fingerprinter {
    fn finish(&self) -> u64 {
        mix(self.a ^ mix(self.b))
    }
    fn write(&mut self, bytes: &[u8]) {
        let mut chunks = bytes.chunks_exact(8);
        for c in &mut chunks {
            let mut w = [0u8; 8];
            w.copy_from_slice(c);
            self.write_u64(u64::from_le_bytes(w));
        }
        let rest = chunks.remainder();
        if !rest.is_empty() {
            let mut w = [0u8; 8];
            w[..rest.len()].copy_from_slice(rest);
            self.write_u64(u64::from_le_bytes(w) ^ ((rest.len() as u64) << 59));
        }
    }
    fn write_u8(&mut self, i: u8) {
        self.write_u64(u64::from(i) | 0x100);
    }
    fn write_u16(&mut self, i: u16) {
        self.write_u64(u64::from(i) | 0x2_0000);
    }
    fn write_u32(&mut self, i: u32) {
        self.write_u64(u64::from(i) | 0x4_0000_0000);
    }
    fn write_u64(&mut self, x: u64) {
        self.a = (self.a ^ x).wrapping_mul(K1).rotate_left(29);
        self.b = (self.b.wrapping_add(x)).wrapping_mul(K2).rotate_left(31) ^ self.a;
    }
    fn write_usize(&mut self, i: usize) {
        self.write_u64(i as u64);
    }
}

/// One distinct state: how it was first reached.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Seen {
    pub(crate) parent: u32,
    pub(crate) action: u16,
    pub(crate) depth: u32,
    /// No command runs there (but those left running until terminated).
    pub(crate) quiet: bool,
}

/// What a property's first violation is, found at a state.
#[derive(Clone, Debug)]
pub(crate) enum Found {
    Stuck(u32),
    Unhandled(u32),
    User(usize, u32),
    /// A run that never ends: a path to `entry`, then `cycle` (transitions) back to it.
    Cycle {
        entry: u32,
        cycle: Vec<u16>,
    },
    /// A user liveness property broken at the end of a run.
    NotEventually(usize, u32),
}

impl Found {
    /// The property it breaks.
    pub(crate) fn property(&self) -> Key {
        match self {
            Found::Stuck(_) => Key::Builtin(Builtin::NoStuck),
            Found::Unhandled(_) => Key::Builtin(Builtin::NoUnhandled),
            Found::Cycle { .. } => Key::Builtin(Builtin::RunsEnd),
            Found::User(k, _) | Found::NotEventually(k, _) => Key::User(*k),
        }
    }
}

/// A property: built in, or the user's by number.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Key {
    Builtin(Builtin),
    User(usize),
}

/// Progress of a search, for a display.
#[derive(Clone, Copy, Debug, Default)]
pub struct Progress {
    /// Transitions computed (successor states generated).
    pub explored: u64,
    /// Distinct states.
    pub unique: u64,
    /// The depth reached.
    pub depth: u32,
    /// States waiting to be expanded.
    pub frontier: usize,
    /// Time since the search started.
    pub elapsed: Duration,
    /// Violations found so far.
    pub violations: usize,
}

pub(crate) struct Outcome {
    pub(crate) seen: Vec<Seen>,
    pub(crate) found: Vec<Found>,
    pub(crate) progress: Progress,
    pub(crate) complete: bool,
    pub(crate) interrupted: bool,
    /// What made the search incomplete, each bound once.
    pub(crate) cuts: Vec<Cut>,
    pub(crate) cut: u64,
    pub(crate) cut_example: Option<String>,
    pub(crate) ended: u64,
    /// Some runs that ended, and the deepest state, for the trace checker.
    pub(crate) samples: Vec<u32>,
    /// Whether the state graph has a cycle (liveness undecided then).
    pub(crate) cyclic: bool,
    pub(crate) errors: Vec<String>,
}

/// How often the progress callback is called, at most.
const PROGRESS_EVERY: Duration = Duration::from_millis(200);

/// Searches from `task`, calling `progress` now and then and `on_found` with each violation as
/// soon as it is found (with the states seen so far, from which its path is rebuilt).
pub(crate) fn run(
    cx: &Ctx<'_>,
    task: &str,
    stop: &AtomicBool,
    progress: &mut dyn FnMut(&Progress),
    on_found: &mut dyn FnMut(&Found, &[Seen]),
) -> Outcome {
    let started = Instant::now();
    let tracing = !cx.props.is_empty();
    let init = State::init(cx, task, tracing);
    let mut seen: Vec<Seen> = vec![Seen {
        parent: 0,
        action: 0,
        depth: 0,
        quiet: init.quiet(),
    }];
    let mut visited: HashMap<u64, u32, BuildHasherDefault<Identity>> = HashMap::default();
    visited.insert(fingerprint(&init), 0);
    let mut edges: Vec<(u32, u32, u16)> = Vec::new();
    let mut found: Vec<Found> = Vec::new();
    let mut have = Have::default();
    let mut out = Outcome {
        seen: Vec::new(),
        found: Vec::new(),
        progress: Progress::default(),
        complete: false,
        interrupted: false,
        cuts: Vec::new(),
        cut: 0,
        cut_example: None,
        ended: 0,
        samples: Vec::new(),
        cyclic: false,
        errors: Vec::new(),
    };
    check_new(&init, 0, cx, &mut have, &mut found);
    let mut reported = 0;
    let mut frontier: VecDeque<(u32, State)> = VecDeque::new();
    frontier.push_back((0, init));
    let mut explored: u64 = 0;
    let mut max_depth = 0;
    let mut last_report = Instant::now();
    let mut deepest = 0u32;
    let mut complete = true;
    let mut popped: u64 = 0;
    while let Some((id, state)) = frontier.pop_front() {
        while reported < found.len() {
            on_found(&found[reported], &seen);
            reported += 1;
        }
        if stop.load(Ordering::Relaxed) {
            out.interrupted = true;
            out.cuts.push(Cut::Interrupted);
            complete = false;
            break;
        }
        popped += 1;
        if popped % memory::CHECK_EVERY == 0 {
            let used = memory::used(seen.len(), edges.len(), frontier.len());
            if used >= cx.opts.max_memory {
                out.cuts.push(Cut::MaxMemory {
                    used,
                    limit: cx.opts.max_memory,
                });
                complete = false;
                break;
            }
        }
        if last_report.elapsed() >= PROGRESS_EVERY {
            last_report = Instant::now();
            progress(&Progress {
                explored,
                unique: seen.len() as u64,
                depth: max_depth,
                frontier: frontier.len(),
                elapsed: started.elapsed(),
                violations: found.len(),
            });
        }
        let depth = seen[id as usize].depth;
        if depth > max_depth {
            max_depth = depth;
            deepest = id;
        }
        match expand(cx, depth, state) {
            Expanded::Stopped { cut, error } => {
                if let Some(why) = cut {
                    out.cut += 1;
                    if out.cut_example.is_none() {
                        out.cut_example = Some(why);
                    }
                }
                if let Some(e) = error {
                    if out.errors.len() < 8 {
                        out.errors.push(e);
                    }
                }
            }
            Expanded::End {
                finished,
                not_eventually,
            } => {
                if finished {
                    out.ended += 1;
                    if out.samples.len() < cx.opts.samples {
                        out.samples.push(id);
                    }
                } else if !have.stuck && cx.opts.checks(Builtin::NoStuck) {
                    have.stuck = true;
                    found.push(Found::Stuck(id));
                }
                if let (Some(k), false) = (not_eventually, have.eventually) {
                    have.eventually = true;
                    found.push(Found::NotEventually(k, id));
                }
            }
            Expanded::TooDeep => {
                complete = false;
                if !have.too_long {
                    have.too_long = true;
                    out.cuts.push(Cut::Depth(cx.opts.depth));
                }
            }
            Expanded::Next(next) => {
                if seen.len() as u64 >= cx.opts.max_states {
                    out.cuts.push(Cut::MaxStates(cx.opts.max_states));
                    complete = false;
                    break;
                }
                for (i, fp, next) in next {
                    explored += 1;
                    match visited.entry(fp) {
                        Entry::Occupied(e) => edges.push((id, *e.get(), i)),
                        Entry::Vacant(e) => {
                            let nid = u32::try_from(seen.len()).unwrap_or(u32::MAX);
                            e.insert(nid);
                            seen.push(Seen {
                                parent: id,
                                action: i,
                                depth: depth + 1,
                                quiet: next.quiet(),
                            });
                            edges.push((id, nid, i));
                            check_new(&next, nid, cx, &mut have, &mut found);
                            frontier.push_back((nid, next));
                        }
                    }
                }
            }
        }
    }
    // Besides runs that ended: the deepest state, and states spread over the whole search.
    if deepest != 0 {
        out.samples.push(deepest);
    }
    let n = seen.len() as u32;
    let spread = cx.opts.samples as u32;
    if spread > 0 && n > 1 {
        for k in 1..=spread {
            let id = (u64::from(n - 1) * u64::from(k) / u64::from(spread)) as u32;
            if id != 0 && !out.samples.contains(&id) {
                out.samples.push(id);
            }
        }
    }
    while reported < found.len() {
        on_found(&found[reported], &seen);
        reported += 1;
    }
    // Runs that never end: cycles of the state graph. Every edge kept is a transition, so a cycle
    // of a graph cut by `--max-states` or `--depth` is one too (only its absence needs the whole
    // graph); after Ctrl-C or at the memory bound, the graph is not built.
    let wanted = cx.opts.checks(Builtin::RunsEnd) || cx.props.list.iter().any(|p| p.is_liveness());
    let cut_short = out
        .cuts
        .iter()
        .any(|c| matches!(c, Cut::Interrupted | Cut::MaxMemory { .. }));
    let queued = frontier.len();
    drop(frontier);
    drop(visited);
    if wanted && !cut_short {
        if let Some((entry, cycle)) = find_cycle(seen.len(), &edges, &seen) {
            out.cyclic = true;
            if cx.opts.checks(Builtin::RunsEnd) {
                found.push(Found::Cycle { entry, cycle });
                on_found(&found[reported], &seen);
            }
        }
    }
    out.progress = Progress {
        explored,
        unique: seen.len() as u64,
        depth: max_depth,
        frontier: queued,
        elapsed: started.elapsed(),
        violations: found.len(),
    };
    progress(&out.progress);
    out.complete = complete;
    out.seen = seen;
    out.found = found;
    out
}

/// What expanding one state gave.
enum Expanded {
    /// A bound, a violation or an error ended the path there.
    Stopped {
        cut: Option<String>,
        error: Option<String>,
    },
    /// Nothing can happen: the run ended (or is stuck), and the first `eventually` property it
    /// breaks.
    End {
        finished: bool,
        not_eventually: Option<usize>,
    },
    /// At the depth bound with transitions left.
    TooDeep,
    /// The successors: (transition, fingerprint, state).
    Next(Vec<(u16, u64, State)>),
}

fn expand(cx: &Ctx<'_>, depth: u32, mut s: State) -> Expanded {
    if s.stopped() {
        return Expanded::Stopped {
            cut: s.cut.take(),
            error: s.error.take(),
        };
    }
    let mut actions = Vec::new();
    s.actions(cx, &mut actions);
    if actions.is_empty() {
        // Waiting on the outside, which has used up what its declaration allows: not stuck
        // (the outside would act again), not a bound of the search either; the path ends here.
        if !s.finished() && s.held_by_environment(cx).is_some() {
            return Expanded::Stopped {
                cut: None,
                error: None,
            };
        }
        return Expanded::End {
            finished: s.finished(),
            not_eventually: s.watch.as_ref().and_then(|w| cx.props.at_end(w)),
        };
    }
    if depth >= cx.opts.depth {
        return Expanded::TooDeep;
    }
    let last = actions.len() - 1;
    let mut out = Vec::with_capacity(actions.len());
    let mut s = Some(s);
    for (i, a) in actions.iter().enumerate() {
        // The last successor takes the state itself instead of a copy.
        let next = if i == last {
            match s.take() {
                Some(owned) => owned.step_owned(cx, a),
                None => break,
            }
        } else {
            match &s {
                Some(st) => st.step(cx, a),
                None => break,
            }
        };
        let fp = fingerprint(&next);
        out.push((i as u16, fp, next));
    }
    Expanded::Next(out)
}

/// Which built-in properties already have their (shortest) counterexample.
#[derive(Default)]
struct Have {
    stuck: bool,
    unhandled: bool,
    too_long: bool,
    eventually: bool,
    user: Vec<usize>,
}

/// The violations a newly found state shows.
fn check_new(s: &State, id: u32, cx: &Ctx<'_>, have: &mut Have, found: &mut Vec<Found>) {
    if let (Some(Fault::Unhandled { .. }), false) = (&s.fault, have.unhandled) {
        if cx.opts.checks(Builtin::NoUnhandled) {
            have.unhandled = true;
            found.push(Found::Unhandled(id));
        }
    }
    if let Some(k) = s.broken {
        if !have.user.contains(&k) {
            have.user.push(k);
            found.push(Found::User(k, id));
        }
    }
}

/// A cycle of the state graph through a quiet state (no command running, but those left running
/// until terminated), reachable at the least depth: its entry state and the transitions around
/// it. A cycle through no quiet state goes on only because some command never ends, which the
/// checker does not count as the program's loop (docs/verification.md, "Runs that never end").
fn find_cycle(n: usize, edges: &[(u32, u32, u16)], seen: &[Seen]) -> Option<(u32, Vec<u16>)> {
    let mut g: DiGraph<(), u16, u32> = DiGraph::with_capacity(n, edges.len());
    for _ in 0..n {
        g.add_node(());
    }
    let mut best: Option<(u32, Vec<u16>)> = None;
    let better = |best: &Option<(u32, Vec<u16>)>, s: u32| {
        best.as_ref()
            .is_none_or(|(b, _)| seen[s as usize].depth < seen[*b as usize].depth)
    };
    for &(a, b, act) in edges {
        if a == b && seen[a as usize].quiet && better(&best, a) {
            best = Some((a, vec![act]));
        }
        g.add_edge(NodeIndex::new(a as usize), NodeIndex::new(b as usize), act);
    }
    for scc in petgraph::algo::kosaraju_scc(&g)
        .into_iter()
        .filter(|c| c.len() > 1)
    {
        let Some(entry) = scc
            .iter()
            .map(|i| i.index() as u32)
            .filter(|i| seen[*i as usize].quiet)
            .min_by_key(|i| seen[*i as usize].depth)
        else {
            continue;
        };
        if !better(&best, entry) {
            continue;
        }
        // The shortest way round inside the component, by breadth-first search.
        let inside: std::collections::BTreeSet<u32> =
            scc.iter().map(|i| i.index() as u32).collect();
        let mut back: HashMap<u32, (u32, u16)> = HashMap::new();
        let mut queue = VecDeque::from([entry]);
        'search: while let Some(v) = queue.pop_front() {
            for e in g.edges(NodeIndex::new(v as usize)) {
                use petgraph::visit::EdgeRef;
                let w = e.target().index() as u32;
                if !inside.contains(&w) {
                    continue;
                }
                if w == entry {
                    let mut path = vec![*e.weight()];
                    let mut cur = v;
                    while cur != entry {
                        let (p, a) = back[&cur];
                        path.push(a);
                        cur = p;
                    }
                    path.reverse();
                    best = Some((entry, path));
                    break 'search;
                }
                if let Entry::Vacant(slot) = back.entry(w) {
                    slot.insert((v, *e.weight()));
                    queue.push_back(w);
                }
            }
        }
    }
    best
}

/// The transitions from the first state to state `id`.
pub(crate) fn path_to(seen: &[Seen], mut id: u32) -> Vec<u16> {
    let mut path = Vec::new();
    while id != 0 {
        let s = seen[id as usize];
        path.push(s.action);
        id = s.parent;
    }
    path.reverse();
    path
}
