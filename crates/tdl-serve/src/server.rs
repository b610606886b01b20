//! The serving executive's state and its operations ([`Server::handle`]), apart from how requests
//! arrive (`serve.rs` answers them over zenoh). The rules:
//!
//! 1. A load checks the program as `tdl check` does, against the server's registry and the tasks
//!    its agents offer now; any error refuses it with the rendered diagnostics, and nothing
//!    changes. A program's version is `name@hash`, the hash of its sources; loading the same
//!    version again changes nothing.
//! 2. A new version of a program that runs use is swapped in as the request says
//!    ([`Swap`]): for new spawns (refused when a task changes kind or parameters), or by
//!    restarting each run's top-level task, at once or when a named task completes. The old
//!    version's on-terminate cleanup runs before the new version's task starts.
//! 3. The handlers a program declares `for` a task, and its wiretaps, are attached to every run,
//!    present and to come, whatever program it runs (TCA's modules adding recovery and wiretap
//!    monitors to the running tree), and removed when the program is unloaded or replaced.
//! 4. Every operation on a run is a `control` record of its trace, naming who asked; each run
//!    writes its trace to a file of its own.
//! 5. The state is behind one lock, never held across an await; a run's end is seen by a task of
//!    its own, which finishes the run's session.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::{Arc, Mutex, PoisonError, Weak};

use tdl::{AttachId, Control, NodeId, Task};
use tdl_interp::{Program, Registry};

use crate::proto::{File, ProgramInfo, Reply, Request, Response, RunInfo, Swap, Verify};

/// A serving executive: see the module's rules. Cheap to clone.
#[derive(Clone)]
pub struct Server {
    inner: Arc<Inner>,
}

struct Inner {
    base: Registry,
    exec: Option<tcm_zenoh::Executive>,
    traces: PathBuf,
    // The clients it takes requests from; any when empty.
    clients: Vec<String>,
    state: Mutex<State>,
}

#[derive(Default)]
struct State {
    programs: BTreeMap<String, Loaded>,
    runs: BTreeMap<u64, RunEntry>,
    next_run: u64,
}

struct Loaded {
    program: Program,
    files: Vec<(String, String)>,
    version: String,
    by: String,
}

struct RunEntry {
    program: String,
    version: String,
    task: String,
    args: serde_json::Value,
    control: Control,
    root: NodeId,
    running: bool,
    // The next version's task, to start when the root has ended (a swap by restart).
    pending: Option<(String, Task)>,
    // The wiretap a swap `after` a task waits on, removed once the swap is made.
    swap_tap: Option<tdl::WiretapId>,
    outcome: Option<String>,
    trace: PathBuf,
    // The handlers attached to this run, by the program that declares them.
    attached: Vec<(String, AttachId)>,
    // The wiretaps added to this run, by the program that declares them.
    taps: Vec<(String, tdl::WiretapId)>,
}

impl Server {
    /// A server whose programs may call what `base` registers and the tasks `exec`'s agents
    /// offer (none without an executive), writing each run's trace to `traces/run-<n>.jsonl`.
    pub fn new(
        base: Registry,
        exec: Option<tcm_zenoh::Executive>,
        traces: impl Into<PathBuf>,
    ) -> Server {
        Server {
            inner: Arc::new(Inner {
                base,
                exec,
                traces: traces.into(),
                clients: Vec::new(),
                state: Mutex::new(State::default()),
            }),
        }
    }

    /// The same server, taking requests only from the clients named in `clients` (the names in
    /// the last segment of a request's key: with the system's access rules,
    /// `tcm_zenoh::config::with_access` and its roster's clients, a client can ask under its own
    /// name only). Any other's request is refused and changes nothing. Call before serving.
    pub fn clients(mut self, clients: Vec<String>) -> Server {
        if let Some(inner) = Arc::get_mut(&mut self.inner) {
            inner.clients = clients;
        }
        self
    }

    /// The executive whose agents run the programs' outside tasks, if any.
    pub fn executive(&self) -> Option<&tcm_zenoh::Executive> {
        self.inner.exec.as_ref()
    }

    fn state(&self) -> std::sync::MutexGuard<'_, State> {
        self.inner
            .state
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
    }

    /// Carries out `request` for the client `by`. Must be called inside a tokio runtime (a start
    /// starts a run on it).
    pub fn handle(&self, request: Request, by: &str) -> Response {
        if !self.inner.clients.is_empty() && !self.inner.clients.iter().any(|c| c == by) {
            return Response::Refused(format!(
                "the client `{by}` is not one this executive takes requests from; nothing changed"
            ));
        }
        let done = match request {
            Request::Load {
                name,
                files,
                swap,
                verify,
            } => self.load(&name, files, swap, verify.as_ref(), by),
            Request::Unload { name } => self.unload(&name, by),
            Request::List => Ok(Reply::Programs(self.list())),
            Request::Start {
                program,
                task,
                args,
            } => self.start(&program, task.as_deref(), args, by),
            Request::Stop { run } => self.stop(run, by),
            Request::Raise { run, event } => self.raise(run, &event, by),
            Request::Status { run } => Ok(Reply::Runs(self.status(run))),
        };
        match done {
            Ok(reply) => Response::Ok(reply),
            Err(why) => Response::Refused(why),
        }
    }

    fn registry(&self, files: &[(String, String)]) -> Registry {
        let mut r = Registry::new();
        r.extend(&self.inner.base);
        if let Some(exec) = &self.inner.exec {
            crate::program::register_offers(exec, &mut r, &tdl_interp::outside(files));
        }
        r
    }

    fn load(
        &self,
        name: &str,
        files: Vec<File>,
        swap: Swap,
        verify: Option<&Verify>,
        by: &str,
    ) -> Result<Reply, String> {
        if name.is_empty() || name.contains(['/', '*', '$', '#', '?', '@']) {
            return Err(format!(
                "`{name}` cannot name a program: use letters, digits, `-` and `_`"
            ));
        }
        let files: Vec<(String, String)> = files.into_iter().map(|f| (f.name, f.text)).collect();
        let program = Program::from_sources(&files, &self.registry(&files))
            .map_err(|e| format!("the program `{name}` was refused; nothing changed:\n{e}"))?;
        let version = format!("{name}@{}", program.hash());
        let verified = match verify {
            Some(v) => Some(model_check(&files, v).map_err(|why| {
                format!(
                    "the program `{name}` was refused by its model check; nothing changed:\n{why}"
                )
            })?),
            None => None,
        };
        let program = program.stamped(&version);
        let mut st = self.state();
        let old = st.programs.get(name).map(|l| l.program.clone());
        if st.programs.get(name).is_some_and(|l| l.version == version) {
            return Ok(Reply::Loaded {
                version,
                unchanged: true,
                verified,
                swapped: Vec::new(),
            });
        }
        let users: Vec<u64> = st
            .runs
            .iter()
            .filter(|(_, r)| r.running && r.program == name)
            .map(|(id, _)| *id)
            .collect();
        if let (Some(old), Swap::Spawns) = (&old, &swap) {
            if let Err(problems) = old.supersede(&program) {
                return Err(format!(
                    "the new version of `{name}` cannot replace the running one's definitions \
                     ({}); nothing changed. Ask for a swap by restart instead",
                    problems.join("; ")
                ));
            }
        }
        let what = format!("load {version}");
        for (id, run) in st.runs.iter_mut().filter(|(_, r)| r.running) {
            let _ = run.control.note(&what, by);
            // Rule 3: this program's handlers, attached anew.
            detach_program(run, name);
            attach_program(run, name, &program);
            if users.contains(id) && swap == Swap::Spawns {
                run.version = version.clone();
            }
        }
        if !matches!(swap, Swap::Spawns) {
            for id in &users {
                self.schedule_restart(&mut st, *id, &program, &version, &swap)?;
            }
        }
        st.programs.insert(
            name.to_string(),
            Loaded {
                program,
                files,
                version: version.clone(),
                by: by.to_string(),
            },
        );
        Ok(Reply::Loaded {
            version,
            unchanged: false,
            verified,
            swapped: if old.is_some() { users } else { Vec::new() },
        })
    }

    /// Rule 2, by restart: the run's next top-level task is the new version's, started when the
    /// current one has ended; terminates the current one now, or when `task` completes.
    fn schedule_restart(
        &self,
        st: &mut State,
        id: u64,
        program: &Program,
        version: &str,
        swap: &Swap,
    ) -> Result<(), String> {
        let Some(run) = st.runs.get_mut(&id) else {
            return Ok(());
        };
        let task = program
            .task_json(&run.task, &run.args)
            .map_err(|e| format!("run {id}: the new version cannot start `{}`: {e}", run.task))?;
        run.pending = Some((version.to_string(), task));
        match swap {
            Swap::Spawns => {}
            Swap::Now => {
                let _ = run.control.terminate(run.root);
            }
            Swap::After { task } => {
                let server = Arc::downgrade(&self.inner);
                let once = Arc::new(std::sync::atomic::AtomicBool::new(true));
                let tapped = run
                    .control
                    .wiretap(task.clone(), tdl::TapWhen::After, move |_ctx| {
                        if once.swap(false, std::sync::atomic::Ordering::SeqCst) {
                            // Outside the runtime's lock, which may be held here.
                            let server = server.clone();
                            tokio::spawn(async move { restart_now(&server, id) });
                        }
                        async { Ok(()) }
                    });
                match tapped {
                    Ok(tap) => {
                        if let Some(old) = run.swap_tap.replace(tap) {
                            let _ = run.control.untap(old);
                        }
                    }
                    Err(e) => return Err(format!("run {id}: cannot wait for `{task}`: {e}")),
                }
            }
        }
        Ok(())
    }

    fn unload(&self, name: &str, by: &str) -> Result<Reply, String> {
        let mut st = self.state();
        if !st.programs.contains_key(name) {
            return Err(format!("no program `{name}` is loaded"));
        }
        let users: Vec<String> = st
            .runs
            .iter()
            .filter(|(_, r)| r.running && r.program == name)
            .map(|(id, _)| id.to_string())
            .collect();
        if !users.is_empty() {
            return Err(format!(
                "`{name}` is run by run(s) {}: stop them first",
                users.join(", ")
            ));
        }
        st.programs.remove(name);
        let what = format!("unload {name}");
        for run in st.runs.values_mut().filter(|r| r.running) {
            let _ = run.control.note(&what, by);
            detach_program(run, name);
        }
        Ok(Reply::Unloaded)
    }

    /// The loaded programs.
    pub fn list(&self) -> Vec<ProgramInfo> {
        self.state()
            .programs
            .iter()
            .map(|(name, l)| ProgramInfo {
                name: name.clone(),
                version: l.version.clone(),
                tasks: l.program.tasks().into_iter().map(String::from).collect(),
                attaches_to: l.program.attached_tasks(),
                taps: l.program.tapped_tasks(),
                loaded_by: l.by.clone(),
            })
            .collect()
    }

    fn start(
        &self,
        program: &str,
        task: Option<&str>,
        args: serde_json::Value,
        by: &str,
    ) -> Result<Reply, String> {
        let mut st = self.state();
        let loaded = st
            .programs
            .get(program)
            .ok_or_else(|| format!("no program `{program}` is loaded"))?;
        let name = match task {
            Some(t) => t.to_string(),
            None => tdl_interp::default_task(&loaded.program, &loaded.files)?,
        };
        let root_task = loaded
            .program
            .task_json(&name, &args)
            .map_err(|e| format!("cannot start `{name}`: {e}"))?;
        let version = loaded.version.clone();
        let id = st.next_run + 1;
        std::fs::create_dir_all(&self.inner.traces)
            .map_err(|e| format!("cannot make {}: {e}", self.inner.traces.display()))?;
        let trace = self.inner.traces.join(format!("run-{id}.jsonl"));
        let file = std::fs::File::create(&trace)
            .map_err(|e| format!("cannot write {}: {e}", trace.display()))?;
        let mut runtime =
            tdl::Runtime::new().with_sink(tdl::JsonLines(std::io::BufWriter::new(file)));
        if let Some(exec) = &self.inner.exec {
            runtime = runtime.placer(exec.clone());
        }
        let session = runtime
            .start()
            .map_err(|e| format!("cannot start a run: {e}"))?;
        let control = session.control();
        let _ = control.note(&format!("start {name} of {version}"), by);
        let mut entry = RunEntry {
            program: program.to_string(),
            version,
            task: name,
            args,
            control: control.clone(),
            root: control.root(),
            running: true,
            pending: None,
            swap_tap: None,
            outcome: None,
            trace: trace.clone(),
            attached: Vec::new(),
            taps: Vec::new(),
        };
        for (pname, l) in &st.programs {
            attach_program(&mut entry, pname, &l.program);
        }
        entry.root = control
            .spawn(root_task)
            .map_err(|e| format!("cannot start the task: {e}"))?;
        st.next_run = id;
        st.runs.insert(id, entry);
        drop(st);
        let server = self.clone();
        tokio::spawn(async move { server.watch(id, session, control).await });
        Ok(Reply::Started {
            run: id,
            trace: trace.display().to_string(),
        })
    }

    /// Rule 5: waits for the run's top-level task to end, starts the next version's when a swap
    /// is pending, and finishes the run when none is.
    async fn watch(&self, id: u64, session: tdl::Session, control: Control) {
        loop {
            let Some(root) = self.state().runs.get(&id).map(|r| r.root) else {
                break;
            };
            let _ = control.wait(root).await;
            let next = {
                let mut st = self.state();
                let Some(run) = st.runs.get_mut(&id) else {
                    break;
                };
                match run.pending.take() {
                    Some(next) => Some(next),
                    None => {
                        run.running = false;
                        None
                    }
                }
            };
            let Some((version, task)) = next else {
                break;
            };
            match control.spawn(task) {
                Ok(node) => {
                    let mut st = self.state();
                    if let Some(run) = st.runs.get_mut(&id) {
                        let _ = control.note(&format!("swapped to {version}"), "tdl serve");
                        run.root = node;
                        run.version = version;
                        if let Some(tap) = run.swap_tap.take() {
                            let _ = control.untap(tap);
                        }
                    }
                }
                Err(_) => {
                    if let Some(run) = self.state().runs.get_mut(&id) {
                        run.running = false;
                    }
                    break;
                }
            }
        }
        let outcome = match session.finish().await {
            Ok(report) => report.to_string().lines().next().unwrap_or("").to_string(),
            Err(e) => format!("error: {e}"),
        };
        if let Some(run) = self.state().runs.get_mut(&id) {
            run.running = false;
            run.outcome = Some(outcome);
        }
    }

    fn running(&self, id: u64) -> Result<Control, String> {
        match self.state().runs.get(&id) {
            Some(r) if r.running => Ok(r.control.clone()),
            Some(_) => Err(format!("run {id} has ended")),
            None => Err(format!("there is no run {id}")),
        }
    }

    fn stop(&self, id: u64, by: &str) -> Result<Reply, String> {
        let control = self.running(id)?;
        let mut st = self.state();
        let Some(run) = st.runs.get_mut(&id) else {
            return Err(format!("there is no run {id}"));
        };
        // A pending swap does not outlive a stop.
        run.pending = None;
        let _ = control.note("stop", by);
        control
            .terminate(run.root)
            .map_err(|e| format!("run {id}: {e}"))?;
        Ok(Reply::Done)
    }

    fn raise(&self, id: u64, event: &str, by: &str) -> Result<Reply, String> {
        let control = self.running(id)?;
        let _ = control.note_input(&format!("raise {event}"), by);
        control.raise(event).map_err(|e| format!("run {id}: {e}"))?;
        Ok(Reply::Done)
    }

    /// The runs (or run `only`).
    pub fn status(&self, only: Option<u64>) -> Vec<RunInfo> {
        self.state()
            .runs
            .iter()
            .filter(|(id, _)| only.is_none_or(|o| o == **id))
            .map(|(id, r)| RunInfo {
                run: *id,
                version: r.version.clone(),
                task: r.task.clone(),
                running: r.running,
                outcome: r.outcome.clone(),
                live_nodes: if r.running {
                    r.control
                        .stats()
                        .map_or(0, |s| s.live_nodes.saturating_sub(1) as u64)
                } else {
                    0
                },
                trace: r.trace.display().to_string(),
            })
            .collect()
    }
}

/// Terminates run `id`'s top-level task now, for a swap that waited for a task's completion.
fn restart_now(server: &Weak<Inner>, id: u64) {
    let Some(inner) = server.upgrade() else {
        return;
    };
    let st = inner.state.lock().unwrap_or_else(PoisonError::into_inner);
    if let Some(run) = st.runs.get(&id).filter(|r| r.pending.is_some()) {
        let _ = run.control.terminate(run.root);
    }
}

/// Attaches `program`'s `for` handlers and its wiretaps to `run` (rule 3).
fn attach_program(run: &mut RunEntry, name: &str, program: &Program) {
    for h in program.attached() {
        if let Ok(id) = run.control.attach(h) {
            run.attached.push((name.to_string(), id));
        }
    }
    for t in program.taps() {
        if let Ok(id) = run.control.tap(t) {
            run.taps.push((name.to_string(), id));
        }
    }
}

/// Detaches the handlers and removes the wiretaps `name` added to `run`.
fn detach_program(run: &mut RunEntry, name: &str) {
    let control = run.control.clone();
    run.attached.retain(|(p, id)| {
        if p == name {
            let _ = control.detach(*id);
            false
        } else {
            true
        }
    });
    run.taps.retain(|(p, id)| {
        if p == name {
            let _ = control.untap(*id);
            false
        } else {
            true
        }
    });
}

/// The model check a load asked for: what it found when nothing is broken (`ok` or `undecided`,
/// with the states explored), else the broken properties and their counterexamples in words.
fn model_check(files: &[(String, String)], ask: &Verify) -> Result<String, String> {
    let program = tdl_verify::Program::load(files).map_err(|e| e.to_string())?;
    let task = program
        .root_task(ask.task.as_deref())
        .map_err(|e| e.to_string())?;
    let options = tdl_verify::Options {
        max_states: ask.max_states,
        unchecked: if ask.runs_forever {
            vec![tdl_verify::Builtin::RunsEnd]
        } else {
            Vec::new()
        },
        ..tdl_verify::Options::default()
    };
    let report = tdl_verify::verify(
        &program,
        &task,
        &options,
        &[],
        None,
        &tdl_verify::Control::default(),
    );
    match report.status() {
        tdl_verify::Status::Ok => Ok(format!("ok: `{task}`, {} states", report.unique)),
        tdl_verify::Status::Undecided => Ok(format!(
            "undecided: `{task}`, {} states, the bounds cut the search",
            report.unique
        )),
        tdl_verify::Status::Violated => Err(report
            .results
            .iter()
            .filter_map(|r| match &r.verdict {
                tdl_verify::Verdict::Violated(c) => {
                    Some(format!("  VIOLATED {}: {}", r.property, c.summary))
                }
                _ => None,
            })
            .collect::<Vec<_>>()
            .join("\n")),
        tdl_verify::Status::Error => Err(format!("the model check failed: {:?}", report.notes)),
    }
}
