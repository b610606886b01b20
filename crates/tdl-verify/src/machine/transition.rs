//! The transitions from a state: which there are, the state after one, and words for one.

use tcm_core::{NodeId, Time};

use super::{Action, Ctx, Fault, Modelled, State, Undrawn, failure, fmt_secs, time_plus};
use crate::ir::{Callee, Op};
use crate::model::Ending;
use crate::program::{EnvEntry, EnvTarget};

impl State {
    /// The transitions from here, in a fixed order.
    pub(crate) fn actions(&mut self, cx: &Ctx<'_>, out: &mut Vec<Action>) {
        out.clear();
        if self.stopped() || self.finished() {
            return;
        }
        if let Some(node) = self.choice {
            if let Some(c) = self.conts.iter().find(|c| c.node == node) {
                for i in 0..c.choice.unwrap_or(0) {
                    out.push(Action::Pick(i));
                }
            }
            return;
        }
        let now = self.engine.now();
        let opts = cx.opts;
        for cmd in &self.cmds {
            if cmd.hung {
                continue;
            }
            match &cmd.model {
                Some(Modelled::Undecided(endings)) => {
                    for i in 0..endings.len() {
                        out.push(Action::Decide {
                            node: cmd.node,
                            i: i as u16,
                        });
                    }
                }
                Some(Modelled::Decided(at, _)) => {
                    if *at <= now {
                        out.push(Action::End {
                            node: cmd.node,
                            outcome: 0,
                        });
                    }
                }
                None => {
                    let n = 1 + self
                        .raises(cx, cmd.callee, cmd.abstracted, cmd.remote)
                        .len();
                    for k in 0..n {
                        out.push(Action::End {
                            node: cmd.node,
                            outcome: k as u16,
                        });
                    }
                    if u32::from(self.hangs) < opts.hangs && self.is_terminable(cmd.node) {
                        out.push(Action::Hang(cmd.node));
                    }
                }
            }
        }
        for node in self.engine.held() {
            out.push(Action::Approve { node, yes: true });
            out.push(Action::Approve { node, yes: false });
        }
        match &cx.prog.environment {
            None => {
                for (i, n) in self.raised.iter().enumerate() {
                    if u32::from(*n) < opts.events {
                        out.push(Action::Raise(i as u16));
                    }
                }
            }
            Some(env) => self.env_actions(cx, env, out),
        }
        if let Some(t) = self.next_tick() {
            // Time may pass only as long as no running command outlasts the duration bound, and
            // no modelled command's end is skipped.
            let ok = self.cmds.iter().all(|c| match &c.model {
                _ if c.hung => true,
                None => u32::from(c.ticks) < opts.ticks,
                Some(Modelled::Decided(at, _)) => *at >= t,
                Some(Modelled::Undecided(_)) => false,
            });
            if ok {
                out.push(Action::Tick);
            }
        }
    }

    /// What the environment may do now: each entry with uses left whose condition holds sets its
    /// variable to each of its values but the current one, or raises its event.
    fn env_actions(&self, cx: &Ctx<'_>, env: &[EnvEntry], out: &mut Vec<Action>) {
        for (i, e) in env.iter().enumerate() {
            if u32::from(self.env_used.get(i).copied().unwrap_or(u8::MAX)) >= e.at_most {
                continue;
            }
            if let Some(w) = &e.when {
                if !self.holds(w) {
                    continue;
                }
            }
            match e.target {
                EnvTarget::External(_) => out.push(Action::Env {
                    entry: i as u16,
                    value: 0,
                }),
                EnvTarget::State(v) => {
                    let current = cx
                        .prog
                        .states
                        .get(v as usize)
                        .and_then(|d| self.engine.state_id(&d.name))
                        .and_then(|id| self.engine.state(id))
                        .map(|s| s.2.clone());
                    for (k, value) in e.values.iter().enumerate() {
                        if current.as_ref() != Some(value) {
                            out.push(Action::Env {
                                entry: i as u16,
                                value: k as u16,
                            });
                        }
                    }
                }
            }
        }
    }

    /// A TDL command that succeeds: its `set`s of a literal value and its `raise`s happen, in
    /// the order written, as it ends (the checker does not run a command's Rust, so it does not
    /// know when in the command they come, or whether a `set` in an `if` is reached: it takes
    /// each as reached).
    fn command_effects(&mut self, cx: &Ctx<'_>, callee: &Callee, outside: bool, now: Time) {
        let Callee::Task(id) = *callee else {
            return;
        };
        if outside {
            return;
        }
        for op in &cx.prog.task(id).body.ops {
            match op {
                Op::SetState { var, values } if values.len() == 1 => {
                    self.set_state(cx, *var, values[0].clone());
                }
                Op::Raise(i) => {
                    if let Some(name) = cx.prog.external_events.get(*i as usize) {
                        let ev = self.engine.external(name);
                        self.engine.handle_external(now, ev);
                    }
                }
                _ => {}
            }
        }
    }

    /// When nothing can happen: whether something waits on a variable the environment may
    /// change but has changed as often as its declaration allows, and which (the run waits on
    /// its outside, which would act again: it is not stuck).
    pub(crate) fn held_by_environment(&self, cx: &Ctx<'_>) -> Option<String> {
        let env = cx.prog.environment.as_ref()?;
        for id in self.engine.states_waited_on() {
            let Some((name, _, _)) = self.engine.state(id) else {
                continue;
            };
            let var = cx.prog.states.iter().position(|d| d.name == name)?;
            for (i, e) in env.iter().enumerate() {
                let used = u32::from(self.env_used.get(i).copied().unwrap_or(0));
                if matches!(e.target, EnvTarget::State(v) if v as usize == var) && used >= e.at_most
                {
                    return Some(format!(
                        "the run waits on `{name}`, which the environment changed as often as its \
                         declaration allows (at most {})",
                        e.at_most
                    ));
                }
            }
        }
        None
    }

    /// Whether a condition over the state variables holds now.
    pub(crate) fn holds(&self, cond: &tcm_core::Expr) -> bool {
        let engine = &self.engine;
        cond.holds(&|n| {
            engine
                .state_id(n)
                .and_then(|id| engine.state(id))
                .map(|s| s.2.clone())
        })
        .unwrap_or(false)
    }

    /// The next time something is due: a timer of the engine or a modelled command's end.
    pub(crate) fn next_tick(&mut self) -> Option<Time> {
        let mut e = self.engine.poll_timeout();
        for c in &self.cmds {
            if let Some(Modelled::Decided(at, _)) = &c.model {
                if *at > self.engine.now() {
                    e = Some(e.map_or(*at, |t: Time| t.min(*at)));
                }
            }
        }
        e
    }

    /// The exceptions a command may raise: a TDL command's `fail`s, else every exception the
    /// program declares or handles (and, with the option, one nobody declares).
    pub(crate) fn raises<'p>(
        &self,
        cx: &'p Ctx<'_>,
        callee: Callee,
        abstracted: bool,
        remote: bool,
    ) -> Vec<&'p str> {
        let mut out: Vec<&str> = match (callee, abstracted || remote) {
            (Callee::Task(id), false) => {
                cx.prog.task(id).raises.iter().map(String::as_str).collect()
            }
            _ => cx.prog.raisable.to_vec(),
        };
        if cx.opts.unknown_exception && (abstracted || matches!(callee, Callee::Extern(_))) {
            out.push(crate::UNKNOWN_EXCEPTION);
        }
        // Placed on an agent: the agent may be lost while it runs the task.
        if remote {
            out.push(crate::AGENT_LOST);
        }
        out
    }

    /// The commands started and not yet given their ending by the seeded simulation (`sim.rs`),
    /// in the order they started.
    pub(crate) fn undrawn<'p>(&self, cx: &'p Ctx<'_>) -> Vec<Undrawn<'p>> {
        let mut out = Vec::new();
        for c in &self.cmds {
            if c.hung {
                continue;
            }
            let endings = match &c.model {
                Some(Modelled::Decided(..)) => continue,
                Some(Modelled::Undecided(e)) => Some(e.clone()),
                None => None,
            };
            out.push(Undrawn {
                node: c.node,
                raises: self.raises(cx, c.callee, c.abstracted, c.remote),
                may_hang: u32::from(self.hangs) < cx.opts.hangs && self.is_terminable(c.node),
                endings,
            });
        }
        out
    }

    /// Gives a command its ending, as the seeded simulation drew it: it ends (succeeds or fails)
    /// once its duration has passed since it started, or runs until it is terminated.
    pub(crate) fn draw(&mut self, node: NodeId, ending: Ending) {
        let Some(c) = self.cmds.iter_mut().find(|c| c.node == node) else {
            return;
        };
        match ending {
            Ending::Never => {
                c.hung = true;
                c.model = None;
                self.hangs = self.hangs.saturating_add(1);
            }
            e => c.model = Some(Modelled::Decided(time_plus(c.start, e.after()), e)),
        }
    }

    fn is_terminable(&self, node: NodeId) -> bool {
        let mut cur = Some(node);
        while let Some(n) = cur {
            if self.terminable.contains(&n) {
                return true;
            }
            cur = self.engine.parent(n);
        }
        false
    }

    /// The state after `action`.
    pub(crate) fn step(&self, cx: &Ctx<'_>, action: &Action) -> State {
        self.clone().step_owned(cx, action)
    }

    /// [`State::step`], taking the state instead of copying it.
    pub(crate) fn step_owned(self, cx: &Ctx<'_>, action: &Action) -> State {
        let mut s = self;
        let before = s.engine.unhandled().len();
        let now = s.engine.now();
        match action {
            Action::Pick(i) => {
                if let Some(node) = s.choice.take() {
                    s.pick(cx, node, *i);
                }
            }
            Action::End { node, outcome } => {
                if let Some(pos) = s.cmds.iter().position(|c| c.node == *node) {
                    let cmd = s.cmds.remove(pos);
                    let result = match &cmd.model {
                        Some(Modelled::Decided(_, Ending::Succeeds(_))) => Ok(()),
                        Some(Modelled::Decided(_, Ending::Fails(e, _))) => Err(failure(
                            cx.prog,
                            e,
                            if cx.sim {
                                "drawn by tdl sim"
                            } else {
                                "chosen by the command's model"
                            },
                        )),
                        _ if *outcome == 0 => Ok(()),
                        _ => {
                            let raises = s.raises(cx, cmd.callee, cmd.abstracted, cmd.remote);
                            let e = raises
                                .get(*outcome as usize - 1)
                                .copied()
                                .unwrap_or("Error");
                            Err(failure(cx.prog, e, "chosen by tdl verify"))
                        }
                    };
                    if result.is_ok() {
                        s.command_effects(cx, &cmd.callee, cmd.abstracted || cmd.remote, now);
                    }
                    if let Err(e) = s.engine.handle_action_finished(now, *node, result) {
                        s.error = Some(format!("the end of a command was refused: {e}"));
                    }
                }
            }
            Action::Hang(node) => {
                if let Some(c) = s.cmds.iter_mut().find(|c| c.node == *node) {
                    c.hung = true;
                    s.hangs += 1;
                }
            }
            Action::Decide { node, i } => {
                if let Some(c) = s.cmds.iter_mut().find(|c| c.node == *node) {
                    if let Some(Modelled::Undecided(endings)) = &c.model {
                        match endings.get(*i as usize).cloned() {
                            Some(Ending::Never) | None => {
                                c.hung = true;
                                c.model = None;
                            }
                            Some(e) => {
                                let at = time_plus(c.start, e.after());
                                c.model = Some(Modelled::Decided(at, e));
                            }
                        }
                    }
                }
            }
            Action::Approve { node, yes: true } => {
                let _ = s.engine.approve(now, *node, "operator");
            }
            Action::Approve { node, yes: false } => {
                let _ = s.engine.refuse(now, *node, "operator", "refused");
            }
            Action::Raise(i) => {
                if let Some(n) = s.raised.get_mut(*i as usize) {
                    *n += 1;
                }
                if let Some(name) = cx.prog.external_events.get(*i as usize) {
                    let id = s.engine.external(name);
                    s.engine.handle_external(now, id);
                }
            }
            Action::Env { entry, value } => {
                let e = cx
                    .prog
                    .environment
                    .as_ref()
                    .and_then(|e| e.get(*entry as usize));
                if let Some(e) = e {
                    if let Some(n) = s.env_used.get_mut(*entry as usize) {
                        *n = n.saturating_add(1);
                    }
                    match e.target {
                        EnvTarget::External(i) => {
                            if let Some(name) = cx.prog.external_events.get(i as usize) {
                                let id = s.engine.external(name);
                                s.engine.handle_external(now, id);
                            }
                        }
                        EnvTarget::State(v) => {
                            if let Some(value) = e.values.get(*value as usize) {
                                s.set_state(cx, v, value.clone());
                            }
                        }
                    }
                }
            }
            Action::Tick => {
                if let Some(t) = s.next_tick() {
                    for c in &mut s.cmds {
                        if !c.hung && c.model.is_none() {
                            c.ticks = c.ticks.saturating_add(1);
                        }
                    }
                    s.engine.handle_timeout(t);
                }
            }
        }
        s.settle(cx);
        s.observe(cx);
        s.done = s.compute_finished();
        s.note_unhandled(cx, before);
        s
    }

    /// Records as the state's fault the first failure no handler took since the engine had
    /// `before` of them (an exception allowed to go unhandled aside).
    pub(crate) fn note_unhandled(&mut self, cx: &Ctx<'_>, before: usize) {
        let unhandled = self.engine.unhandled();
        if unhandled.len() > before && self.fault.is_none() {
            for f in &unhandled[before..] {
                let name = f.failure.exception.to_string();
                if !cx.opts.allowed.iter().any(|a| a == &name) {
                    self.fault = Some(Fault::Unhandled {
                        exception: name,
                        path: f.path.clone(),
                    });
                    break;
                }
            }
        }
    }

    /// Words for an action, for counterexamples.
    pub(crate) fn describe(&mut self, cx: &Ctx<'_>, a: &Action) -> String {
        match a {
            Action::Pick(i) => {
                let Some(node) = self.choice else {
                    return format!("choice {i}");
                };
                let Some(c) = self.conts.iter().find(|c| c.node == node) else {
                    return format!("choice {i}");
                };
                let body = &cx.prog.task(c.task).body;
                let line = body.lines.get(c.pc as usize).copied().unwrap_or(0);
                let place = cx.prog.place(c.task, line);
                let what = match body.ops.get(c.pc as usize) {
                    Some(Op::If { .. }) => {
                        if *i == 0 {
                            "takes the `if` branch".to_owned()
                        } else {
                            "takes the `else` branch".to_owned()
                        }
                    }
                    Some(Op::Match(_)) => format!("takes arm {} of the `match`", i + 1),
                    Some(Op::LoopTest { .. }) => {
                        if *i == 0 {
                            "leaves the loop".to_owned()
                        } else {
                            "runs the loop again".to_owned()
                        }
                    }
                    Some(Op::Exit(_)) => {
                        if *i == 0 {
                            "goes on".to_owned()
                        } else {
                            "leaves by a `return`, `break` or `continue`".to_owned()
                        }
                    }
                    _ => format!("takes way {i}"),
                };
                format!(
                    "{} {what} at {place} (a condition the checker does not evaluate)",
                    self.engine.path(node)
                )
            }
            Action::End { node, outcome } => {
                let path = self.engine.path(*node);
                let Some(cmd) = self.cmds.iter().find(|c| c.node == *node) else {
                    return format!("{path} ends");
                };
                match &cmd.model {
                    Some(Modelled::Decided(_, Ending::Succeeds(_))) => {
                        return format!("{path} succeeds");
                    }
                    Some(Modelled::Decided(_, Ending::Fails(e, _))) => {
                        return format!("{path} fails with {e}");
                    }
                    _ => {}
                }
                if *outcome == 0 {
                    format!("{path} succeeds")
                } else {
                    let raises = self.raises(cx, cmd.callee, cmd.abstracted, cmd.remote);
                    format!(
                        "{path} fails with {}",
                        raises.get(*outcome as usize - 1).copied().unwrap_or("?")
                    )
                }
            }
            Action::Hang(node) => format!(
                "{} keeps running until it is terminated",
                self.engine.path(*node)
            ),
            Action::Decide { node, i } => {
                format!(
                    "the model of {} chooses ending {i}",
                    self.engine.path(*node)
                )
            }
            Action::Approve { node, yes } => format!(
                "an operator {} {}",
                if *yes { "approves" } else { "refuses" },
                self.engine.path(*node)
            ),
            Action::Raise(i) => format!(
                "external event `{}` is raised",
                cx.prog
                    .external_events
                    .get(*i as usize)
                    .map_or("?", String::as_str)
            ),
            Action::Env { entry, value } => {
                let e = cx
                    .prog
                    .environment
                    .as_ref()
                    .and_then(|e| e.get(*entry as usize));
                match e.map(|e| (&e.target, e.values.get(*value as usize))) {
                    Some((EnvTarget::State(v), Some(value))) => format!(
                        "the environment sets {} = {value}",
                        cx.prog
                            .states
                            .get(*v as usize)
                            .map_or("?", |d| d.name.as_str())
                    ),
                    Some((EnvTarget::External(i), _)) => format!(
                        "the environment raises external event `{}`",
                        cx.prog
                            .external_events
                            .get(*i as usize)
                            .map_or("?", String::as_str)
                    ),
                    _ => "the environment acts".to_owned(),
                }
            }
            Action::Tick => match self.next_tick() {
                Some(t) => format!("time passes to {}", fmt_secs(t)),
                None => "time passes".to_owned(),
            },
        }
    }
}
