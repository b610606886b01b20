//! Replaying a run's journal (docs/semantics.md, "Durable runs"): a run rebuilt from the inputs
//! its engine took, then stopped ([`Runtime::replay`](crate::Runtime::replay)) or gone on live
//! ([`Runtime::resume`](crate::Runtime::resume)).
//!
//! Rules of the replay:
//! 1. Bodies run again (goals, monitor activations, handlers, wiretap checks): they ask the engine
//!    what they asked it in the run. Commands do not: the host keeps a command's start as a *stub*
//!    whose end comes from the journal, with its value (decoded by a [`ValueDecoder`]) or its typed
//!    failure.
//! 2. The journal is the run's clock: each reading the engine takes is the journal's reading of
//!    the same step (`clock.rs`, [`Feed`], `replay/feed.rs`); the shell reads the latest; nothing
//!    waits for tokio's time; timers fire where the journal says time passed.
//! 3. The inputs are given in the journal's order, each once the run has taken as many steps as
//!    when it took it (`Entry::at`: the inputs and requests it had been given a time for, a
//!    command's own requests aside), between the polls of actions ([`ActionPoll`]), and, for an
//!    end, once its job waits for it: a stub, or a body that ended again. A body's end (or its
//!    stop) is held until the journal gives it; the stop of a body aborted at once is held from
//!    its abort. An input a body gave itself (`Entry::body`) is the replay's body's to give again,
//!    and a read through `Ctx::record_async` goes on at the run's step of the read.
//! 4. At the first difference (the run took more steps than the journal's run had, a body ended
//!    otherwise than the journal says, a node the journal names does not exist, or nothing left
//!    to run gives the next input) the replay stops: the run ends [`RunOutcome::Diverged`] with a
//!    report naming the entry, the node and both versions.
//! 5. At the journal's end a replay ends ([`RunOutcome::JournalEnded`], unless the run ended
//!    first); a resumed run goes on live: its time from the journal's last, its new inputs
//!    journaled, a `control` record by `journal` saying where it resumed, the bodies' held ends
//!    given, and each command still running at the crash re-attached (`Task::reattach`), started
//!    again (`Task::idempotent`), or failed with the typed exception `Interrupted` (a stop, if it
//!    was being cancelled).

use crate::RunOutcome;
use crate::host::{Ended, Inner, Shared};
use crate::task::Value;
use std::collections::{BTreeMap, HashMap};
use std::sync::Arc;
use std::sync::atomic::Ordering;
use tcm_core::{Failure, Job, NodeId, Time};
use tcm_journal::{Entry, Input, Journal};

mod feed;

pub(crate) use crate::clock::Feed;
pub(crate) use feed::ActionPoll;
use feed::{REPLAYS, in_action};

/// Who asks for the `control` record that says where a run resumed.
pub const RESUMED_BY: &str = "journal";

/// The exception a command fails with when the run that started it crashed and was resumed: its
/// end is unknown, and it is not run twice.
pub const INTERRUPTED: &str = "Interrupted";

/// How a replay makes an action's value from its journal entry (the inverse of a
/// [`ValueEncoder`](crate::ValueEncoder)); `None`: no value.
pub type ValueDecoder = fn(serde_json::Value) -> Option<Value>;

/// The default [`ValueDecoder`]: the JSON value itself (what [`json_values`](crate::json_values)
/// wrote).
pub fn json_decoded(value: serde_json::Value) -> Option<Value> {
    Some(Box::new(value))
}

/// A command started in the replay.
struct Stub {
    display: u64,
    // It is being cancelled: at the journal's end, it stopped.
    cancelled: bool,
    // Its action, if it may run twice: at the journal's end, started again.
    again: Option<crate::task::Action>,
    // How its task lives through a crash, if it says (`Task::journaled`, `Task::reattach`).
    durable: Option<Arc<crate::task::Durable>>,
}

/// What happens at the journal's end (rule 5).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum AtEnd {
    Stop,
    GoLive,
}

/// A run's replay, kept beside its engine (`Inner::replay`).
pub(crate) struct Replay {
    entries: Vec<Entry>,
    pub(crate) feed: Arc<Feed>,
    pub(crate) decode: ValueDecoder,
    // How a body's value is compared with the journal's (the run's encoder).
    pub(crate) encode: crate::ValueEncoder,
    at_end: AtEnd,
    // Commands started in the replay, their ends to come from the journal.
    stubs: BTreeMap<NodeId, Stub>,
    // The nodes of the stubs and held ends by display number, as the journal names them.
    displays: HashMap<u64, NodeId>,
    // What the tasks of nodes not started yet say of crashes (`Task::idempotent`, ...).
    durable: HashMap<NodeId, Arc<crate::task::Durable>>,
    // Ends of bodies run again, held until the journal gives them.
    held: Vec<Ended>,
    // Bodies aborted at once, whose stops were held then, their drops not reported yet.
    dropped: Vec<Job>,
    // Inputs given.
    given: u64,
    // What each body read from outside through `Ctx::record`, by node number, in order.
    recorded: HashMap<u64, std::collections::VecDeque<(serde_json::Value, u64)>>,
    // Bodies that read through `Ctx::record_async`, each waiting until the run has taken the
    // steps it had when it read, as in the run, where the read took its time.
    reads: Vec<(u64, tokio::sync::oneshot::Sender<()>)>,
    // How the run ends, once the replay decided it.
    pub(crate) outcome: Option<RunOutcome>,
}

impl Replay {
    pub(crate) fn new(journal: Journal, decode: ValueDecoder, at_end: AtEnd) -> Replay {
        REPLAYS.store(true, Ordering::Relaxed);
        let feed = Arc::new(Feed::new(&journal.entries));
        let mut recorded: HashMap<u64, std::collections::VecDeque<(serde_json::Value, u64)>> =
            HashMap::new();
        for e in &journal.entries {
            if let Input::Recorded { node, value } = &e.input {
                recorded
                    .entry(*node)
                    .or_default()
                    .push_back((value.clone(), e.at));
            }
        }
        Replay {
            entries: journal.entries,
            feed,
            decode,
            encode: crate::json_values,
            at_end,
            stubs: BTreeMap::new(),
            displays: HashMap::new(),
            durable: HashMap::new(),
            held: Vec::new(),
            dropped: Vec::new(),
            given: 0,
            recorded,
            reads: Vec::new(),
            outcome: None,
        }
    }

    /// What node `display`'s body read next through `Ctx::record` in the run; a report if it read
    /// nothing more there (the replay then stops, rule 4).
    pub(crate) fn recorded(&mut self, display: u64) -> Option<(serde_json::Value, u64)> {
        let value = self.recorded.get_mut(&display).and_then(|q| q.pop_front());
        if value.is_none() && self.outcome.is_none() {
            let pos = self.feed.next_input();
            self.diverge(
                pos,
                format!(
                    "node {display}'s body reads a value through `Ctx::record` that it did not read \
                     in the run: the program differs from the run's"
                ),
            );
        }
        value
    }

    /// Whether the journal is still being replayed.
    pub(crate) fn active(&self) -> bool {
        self.feed.replaying.load(Ordering::Relaxed)
    }

    /// A command started: a stub (rule 1), which keeps its action if it may run twice (rule 5).
    pub(crate) fn stub(&mut self, node: NodeId, display: u64, action: crate::task::Action) {
        let durable = self.durable.remove(&node);
        let again = durable
            .as_ref()
            .is_some_and(|d| d.idempotent)
            .then_some(action);
        self.displays.insert(display, node);
        self.stubs.insert(
            node,
            Stub {
                display,
                cancelled: false,
                again,
                durable,
            },
        );
    }

    /// What `node`'s task says of crashes (`Task::idempotent`, `Task::journaled`,
    /// `Task::reattach`).
    pub(crate) fn durable(&mut self, node: NodeId, d: Arc<crate::task::Durable>) {
        self.durable.insert(node, d);
    }

    /// Whether `node` is a stub; marked as being cancelled.
    pub(crate) fn cancel(&mut self, node: NodeId) -> bool {
        match self.stubs.get_mut(&node) {
            Some(s) => {
                s.cancelled = true;
                true
            }
            None => false,
        }
    }

    /// The node the journal names `display`: a stub's or a held end's, else looked for.
    fn node(
        &self,
        engine: &tcm_core::Engine<crate::task::Action, crate::task::Factory>,
        display: u64,
    ) -> Option<NodeId> {
        self.displays
            .get(&display)
            .copied()
            .or_else(|| engine.node_by_display(display))
    }

    /// A body's end (or stop), of the node numbered `display`, held until the journal gives it
    /// (rule 3).
    pub(crate) fn hold(&mut self, ended: Ended, display: Option<u64>) {
        if let (Some(d), Ended::Dropped(j) | Ended::Returned(j, _)) = (display, &ended) {
            if j.tap().is_none() {
                self.displays.insert(d, j.node());
            }
        }
        self.held.push(ended);
    }

    /// A body was aborted at once (no grace period): its stop is held now, as in the run its drop
    /// came before anything else took the engine, whenever the drop is reported here.
    pub(crate) fn dropped_at_once(&mut self, job: Job) {
        if self.active() {
            self.dropped.push(job);
            self.held.push(Ended::Dropped(job));
        }
    }

    /// The drop of `job` is reported: whether its stop was held already.
    pub(crate) fn reported(&mut self, job: Job) -> bool {
        match self.dropped.iter().position(|j| *j == job) {
            Some(i) => {
                self.dropped.swap_remove(i);
                true
            }
            None => false,
        }
    }

    /// Jobs the engine counts as running that wait for the journal.
    pub(crate) fn waiting(&self) -> usize {
        self.stubs.len() + self.held.len() + self.reads.len()
    }

    /// A body's read of the run's step `at` waits, if the replay has not taken as many: `None`
    /// when it need not.
    pub(crate) fn read_at(
        &mut self,
        at: u64,
        steps: u64,
    ) -> Option<tokio::sync::oneshot::Receiver<()>> {
        if at <= steps {
            return None;
        }
        let (tx, rx) = tokio::sync::oneshot::channel();
        self.reads.push((at, tx));
        Some(rx)
    }

    /// The reads whose step the replay has come to go on (in the order of their steps).
    fn release_reads(&mut self, steps: u64) {
        if self.reads.is_empty() {
            return;
        }
        self.reads.sort_by_key(|(at, _)| *at);
        while self.reads.first().is_some_and(|(at, _)| *at <= steps) {
            let (_, tx) = self.reads.remove(0);
            let _ = tx.send(());
        }
    }

    /// Stops the replay at entry `pos` with a report (rule 4): nothing more is given, and the run
    /// ends at the driver's next turn (commands still do not run).
    fn diverge(&mut self, pos: usize, why: String) {
        let n = self.entries.get(pos).map_or(pos as u64, |e| e.n);
        self.outcome = Some(RunOutcome::Diverged(format!(
            "journal entry {n} (line {}): {why}",
            n + 2
        )));
    }

    /// Nothing left to run gives the next input: the replay stops (rule 4).
    pub(crate) fn stalled(
        &mut self,
        engine: &tcm_core::Engine<crate::task::Action, crate::task::Factory>,
    ) {
        let pos = self.feed.next_input();
        let Some(e) = self.entries.get(pos) else {
            return;
        };
        let what = self.describe(engine, &e.input);
        let steps = engine.steps();
        let why = if steps < e.at {
            format!(
                "the run had taken {} steps when it took {what}; the replay took {steps} and \
                 nothing left to run takes more: the program differs from the run's",
                e.at
            )
        } else {
            format!(
                "the replay waits for {what}, and nothing left to run gives it: the program differs \
                 from the run's"
            )
        };
        self.diverge(pos, why);
    }
}

impl Replay {
    /// A person's words for an input, naming its node as the replay has it, if it has it.
    fn describe(
        &self,
        engine: &tcm_core::Engine<crate::task::Action, crate::task::Factory>,
        input: &Input,
    ) -> String {
        let node = match input {
            Input::Ended { node, .. }
            | Input::Failed { node, .. }
            | Input::Stopped { node }
            | Input::Overdue { node, .. }
            | Input::Recorded { node, .. } => Some(*node),
            _ => None,
        };
        let name = node
            .and_then(|d| self.node(engine, d))
            .and_then(|id| engine.info(id))
            .map(|i| i.name);
        match name {
            Some(name) => format!("{} ({name} in the replay)", describe(input)),
            None => describe(input),
        }
    }
}

/// A person's words for an input.
fn describe(input: &Input) -> String {
    match input {
        Input::Ended {
            node, tap: None, ..
        } => format!("the end of node {node}"),
        Input::Ended {
            node, tap: Some(t), ..
        } => format!("the end of wiretap {t}'s check on node {node}"),
        Input::Failed {
            node, exception, ..
        } => format!("the failure of node {node} with {exception}"),
        Input::Stopped { node } => format!("the stop of node {node}"),
        Input::Overdue { node, .. } => format!("node {node} overrunning its grace period"),
        Input::External { name, .. } => format!("the event {name}"),
        Input::State { name, .. } => format!("the state variable {name} set"),
        Input::Time => "time passing".into(),
        Input::Clock => "a clock reading".into(),
        Input::Recorded { node, .. } => format!("a value node {node} read"),
        Input::Control { what, by, .. } => format!("the operation `{what}` by {by}"),
        Input::Log { node, .. } => format!("a line node {node} logged"),
    }
}

/// Gives the engine the journal's inputs, in order, as far as the run has come (rule 3); at the
/// journal's end, stops or goes live (rule 5).
pub(crate) fn feed(inner: &mut Inner, shared: &Arc<Shared>) {
    feed_with(inner, shared, false);
}

/// [`feed`] of the operations from outside the journal's run took before its first task (as
/// `tdl run` sets `--break` before it spawns), and nothing else: called before the replay's first
/// task, which comes before any other input.
pub(crate) fn feed_operations(inner: &mut Inner, shared: &Arc<Shared>) {
    feed_with(inner, shared, true);
}

fn feed_with(inner: &mut Inner, shared: &Arc<Shared>, operations_only: bool) {
    if inner.replay.as_ref().is_some_and(|r| r.active()) && in_action(shared) {
        return;
    }
    loop {
        let Some(r) = inner
            .replay
            .as_mut()
            .filter(|r| r.active() && r.outcome.is_none())
        else {
            return;
        };
        let pos = r.feed.next_input();
        if operations_only
            && !r
                .entries
                .get(pos)
                .is_some_and(|e| matches!(e.input, Input::Control { .. }))
        {
            return;
        }
        let steps = inner.engine.steps();
        r.release_reads(steps);
        let Some(e) = r.entries.get(pos) else {
            // No input left: the bodies catch up with the journal's last entries (a value they
            // read, a reading) before it ends, unless nothing left to run takes them.
            let last = r.entries.last().map_or(0, |e| e.at);
            if steps < last && !inner.quiet() {
                return;
            }
            finish(inner, shared);
            return;
        };
        if steps < e.at {
            return;
        }
        if steps > e.at {
            let why = format!(
                "the run had taken {} steps when it took {}; the replay took {steps} by then: the \
                 program differs from the run's, or its bodies raced with the run's inputs",
                e.at,
                r.describe(&inner.engine, &e.input)
            );
            r.diverge(pos, why);
            shared.wake.notify_one();
            return;
        }
        let (t, input) = (e.t, e.input.clone());
        match give(inner, t, &input) {
            Ok(true) => {
                if let Some(r) = inner.replay.as_mut() {
                    r.feed.given(pos, t);
                    r.given += 1;
                }
                inner.start_effects(shared);
            }
            Ok(false) => return,
            Err(why) => {
                if let Some(r) = inner.replay.as_mut() {
                    r.diverge(pos, why);
                }
                shared.wake.notify_one();
                return;
            }
        }
    }
}

/// Gives one input at `t`: `Ok(false)` if the run has not come to it yet.
fn give(inner: &mut Inner, t: u64, input: &Input) -> Result<bool, String> {
    let now = Time::from_nanos(t);
    let node_of = |inner: &Inner, node: u64| {
        let found = inner
            .replay
            .as_ref()
            .and_then(|r| r.node(&inner.engine, node));
        found.ok_or_else(|| {
            format!(
                "the journal names node {node}, and the replay has no such node: the program \
                 differs from the run's"
            )
        })
    };
    match input {
        Input::Ended { node, tap, value } => {
            let id = node_of(inner, *node)?;
            end(inner, now, (id, *node), *tap, Ok(value.clone()))
        }
        Input::Failed {
            node,
            tap,
            exception,
            message,
            ancestry,
            data,
        } => {
            let id = node_of(inner, *node)?;
            let mut f = Failure::new(exception.clone(), message.clone());
            f.ancestry = ancestry.iter().map(|a| a.clone().into()).collect();
            if let Some(d) = data {
                f.data = Some(Arc::new(d.clone()));
            }
            end(inner, now, (id, *node), *tap, Err(f))
        }
        Input::Stopped { node } => {
            let id = node_of(inner, *node)?;
            let Some(r) = inner.replay.as_mut() else {
                return Ok(false);
            };
            // A stub's stop, or a body's held stop; or a body that ended in the replay where the
            // run's was stopped first (its cancellation came before its end).
            let held = r.held.iter().position(|h| {
                matches!(h, Ended::Dropped(j) if j.node() == id) || held_by(h, id, None)
            });
            if r.stubs.remove(&id).is_none() {
                let Some(i) = held else {
                    return Ok(false);
                };
                r.held.remove(i);
            }
            r.displays.remove(node);
            inner.engine.handle_action_stopped(now, Job::from(id));
            Ok(true)
        }
        Input::Overdue { node, grace_ns } => {
            let id = node_of(inner, *node)?;
            let grace = std::time::Duration::from_nanos(*grace_ns);
            inner
                .engine
                .handle_action_overdue(now, Job::from(id), grace);
            Ok(true)
        }
        Input::External { name, data } => {
            let id = inner.engine.external(name);
            let data = data
                .clone()
                .map(|d| Arc::new(d) as Arc<dyn std::any::Any + Send + Sync>);
            inner.engine.handle_external_with(now, id, data);
            Ok(true)
        }
        Input::State { name, value } => {
            let value: crate::StateValue = serde_json::from_value(value.clone())
                .map_err(|e| format!("the state variable {name}'s value cannot be read: {e}"))?;
            crate::state::set_by_name(&mut inner.engine, now, name, value)
                .map_err(|e| format!("the state variable {name} cannot be set: {e}"))?;
            Ok(true)
        }
        Input::Time => {
            inner.engine.handle_timeout(now);
            Ok(true)
        }
        Input::Log { node, message } => {
            let id = node_of(inner, *node)?;
            inner
                .engine
                .log(now, id, message.clone())
                .map_err(|e| format!("node {node}'s log line cannot be given: {e}"))?;
            Ok(true)
        }
        Input::Clock | Input::Recorded { .. } => Ok(true),
        Input::Control { what, by, .. } if by == RESUMED_BY => {
            inner.engine.note_control(now, what, by);
            Ok(true)
        }
        Input::Control {
            what,
            by,
            op: Some(op),
        } => {
            let op: tcm_core::SteerOp = serde_json::from_value(op.clone())
                .map_err(|e| format!("the operation `{what}` by {by} cannot be read: {e}"))?;
            if op == tcm_core::SteerOp::Noted {
                // Its record only: the input that follows is what was done.
                inner.engine.note_control(now, what, by);
            } else {
                inner
                    .engine
                    .apply_steer(now, &op, by)
                    .map_err(|e| format!("the operation `{what}` by {by} cannot be given: {e}"))?;
            }
            Ok(true)
        }
        Input::Control { what, by, op: None } => Err(format!(
            "the run took the operation `{what}` by {by}, which a replay cannot carry out again \
             (docs/semantics.md, \"Durable runs\", says which it can)"
        )),
    }
}

/// Whether `h` is the held end of `node`'s job (`tap`: a wiretap check's).
fn held_by(h: &Ended, node: NodeId, tap: Option<u32>) -> bool {
    match h {
        Ended::Returned(j, _) => j.node() == node && j.tap().map(|t| t.number()) == tap,
        Ended::Dropped(_) => false,
    }
}

/// Gives the end of `node`'s job from the journal: a stub's result, or a body's held end checked
/// against the journal's.
fn end(
    inner: &mut Inner,
    now: Time,
    (node, display): (NodeId, u64),
    tap: Option<u32>,
    journaled: Result<Option<serde_json::Value>, Failure>,
) -> Result<bool, String> {
    let Some(r) = inner.replay.as_mut() else {
        return Ok(false);
    };
    if let Some(stub) = tap.is_none().then(|| r.stubs.remove(&node)).flatten() {
        r.displays.remove(&display);
        let decode = r.decode;
        let own = stub.durable.and_then(|d| d.decode.clone());
        let result = journaled.map(|v| {
            v.and_then(|v| match &own {
                Some(d) => d(v),
                None => decode(v),
            })
            .unwrap_or_else(|| Box::new(()) as Value)
        });
        inner.report_end(Some(now), Ended::Returned(Job::from(node), Ok(result)));
        return Ok(true);
    }
    let Some(i) = r.held.iter().position(|h| held_by(h, node, tap)) else {
        return Ok(false);
    };
    let held = r.held.remove(i);
    if tap.is_none() {
        r.displays.remove(&display);
    }
    let encode = r.encode;
    if let Ended::Returned(_, res) = &held {
        let name = inner.engine.info(node).map(|i| i.name).unwrap_or_default();
        let replayed = match res {
            Ok(Ok(_)) => None,
            Ok(Err(f)) => Some(f.exception.to_string()),
            Err(_) => Some("ActionPanicked".to_string()),
        };
        let recorded = journaled.as_ref().err().map(|f| f.exception.to_string());
        if replayed != recorded {
            let say = |e: &Option<String>| match e {
                None => "ended well".to_string(),
                Some(x) => format!("failed with {x}"),
            };
            return Err(format!(
                "node {display} ({name}) {} in the run, and {} in the replay: the program differs \
                 from the run's, or its body read something outside the journal",
                say(&recorded),
                say(&replayed)
            ));
        }
        // A value the run journaled, the body returns again.
        if let (Ok(Ok(value)), Ok(Some(was))) = (res, &journaled) {
            if let Some(is) = encode(value.as_ref()).filter(|is| is != was) {
                return Err(format!(
                    "node {display} ({name}) returned {was} in the run, and {is} in the replay: \
                     the program differs from the run's, or its body read something outside the \
                     journal"
                ));
            }
        }
    }
    inner.report_end(Some(now), held);
    Ok(true)
}

/// The journal's end (rule 5).
fn finish(inner: &mut Inner, shared: &Arc<Shared>) {
    let Some(r) = inner.replay.as_mut() else {
        return;
    };
    match r.at_end {
        AtEnd::Stop => {
            // The run ends at the driver's next turn; nothing runs live meanwhile.
            r.outcome = Some(RunOutcome::JournalEnded { inputs: r.given });
            shared.wake.notify_one();
        }
        AtEnd::GoLive => {
            let last = r.feed.stop();
            shared.clock.go_on_from(last);
            let held = std::mem::take(&mut r.held);
            let stubs = std::mem::take(&mut r.stubs);
            let what = format!(
                "resumed after entry {} of its journal ({} inputs given again)",
                r.entries.len().saturating_sub(1),
                r.given
            );
            if inner.journal.is_some() {
                inner.engine.record_inputs(true);
            }
            let now = inner.engine.at_clock();
            inner.engine.note_control(now, &what, RESUMED_BY);
            for ended in held {
                inner.report_end(None, ended);
                inner.start_effects(shared);
            }
            for (node, stub) in stubs {
                let now = inner.engine.at_clock();
                let reattach = stub.durable.as_ref().and_then(|d| d.reattach.clone());
                if stub.cancelled {
                    inner.engine.handle_action_stopped(now, Job::from(node));
                } else if let Some(reattach) = reattach {
                    // It goes on with what it started outside, from what it recorded.
                    let recorded = inner
                        .replay
                        .as_mut()
                        .and_then(|r| r.recorded.remove(&stub.display))
                        .map(|q| q.into_iter().map(|(v, _)| v).collect())
                        .unwrap_or_default();
                    let (engine, mut host) = inner.split(shared);
                    tcm_core::Shell::start(&mut host, engine, node, reattach(recorded));
                } else if let Some(action) = stub.again {
                    // Idempotent: started again, as the host starts any action.
                    let (engine, mut host) = inner.split(shared);
                    tcm_core::Shell::start(&mut host, engine, node, action);
                } else {
                    let f = Failure::new(
                        INTERRUPTED,
                        "the run stopped while this command ran, and resumed from its journal: \
                         whether it ended is not known, and it is not run twice",
                    );
                    let _ = inner
                        .engine
                        .handle_action_finished(now, Job::from(node), Err(f));
                }
                inner.start_effects(shared);
            }
            shared.wake.notify_one();
        }
    }
}

/// A turn of the driver while the run replays: the inputs the run has come to are given, effects
/// carried out, trace records taken; no timer fires, and the driver sleeps until woken. When
/// nothing left to run can give the next input, the replay stops (rule 4).
pub(crate) fn turn(inner: &mut Inner, shared: &Arc<Shared>) -> tcm_core::Next {
    feed(inner, shared);
    if inner.quiet() {
        let fields = &mut *inner;
        if let Some(r) = fields
            .replay
            .as_mut()
            .filter(|r| r.active() && r.outcome.is_none())
        {
            r.stalled(&fields.engine);
        }
    }
    let (engine, mut host) = inner.split(shared);
    tcm_core::Driver::effects(engine, &mut host);
    tcm_core::Driver::trace(engine, &mut host);
    let mut next = tcm_core::Driver::next(engine);
    if inner.replay.as_ref().is_some_and(|r| r.active()) {
        next.deadline = None;
    }
    next
}

/// How the run ends, if the replay decided it: at a difference; at the journal's end, unless the
/// run's tasks ended first.
pub(crate) fn outcome(inner: &Inner) -> Option<RunOutcome> {
    match inner.replay.as_ref()?.outcome.as_ref()? {
        RunOutcome::JournalEnded { .. }
            if crate::host::outcome_of_roots(&inner.roots).is_some() =>
        {
            None
        }
        o => Some(o.clone()),
    }
}
