//! The control protocol of a serving executive: one zenoh query per request, on the key
//! `tdl/<system>/serve/<executive>/<client>`, whose payload is a [`Request`] as JSON and whose one
//! reply is a [`Response`] as JSON. The last segment names the client: the executive records it as
//! who asked, and with the system's access rules a client can ask under its own name only
//! (docs/distributed.md, "A serving executive").

use serde::{Deserialize, Serialize};

/// The key an executive answers on, for `client` (`*` for every client).
pub fn key(system: &str, executive: &str, client: &str) -> String {
    format!("tdl/{system}/serve/{executive}/{client}")
}

/// A file of a program: its name (for diagnostics) and its text.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct File {
    /// The name diagnostics give it.
    pub name: String,
    /// Its text.
    pub text: String,
}

/// When the runs of a program take a newer version of it.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "at")]
pub enum Swap {
    /// New spawns use the new definitions from now on; what runs goes on (the default). Refused
    /// when a task changes kind or parameters.
    #[default]
    Spawns,
    /// Each run's top-level task is terminated at once (its cleanup runs), and the new version's
    /// task starts with the same arguments when it has ended.
    Now,
    /// As `Now`, when a node of the task `task` completes in the run.
    After {
        /// The task whose completion is the point of the swap.
        task: String,
    },
}

/// A load's model check (`tdl verify`; docs/verification.md): the program is refused when a
/// property is broken within the bounds; a search the bounds cut short does not refuse it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Verify {
    /// The task verified (default: the program's default task).
    #[serde(default)]
    pub task: Option<String>,
    /// The most distinct states explored.
    #[serde(default = "default_max_states")]
    pub max_states: u64,
    /// The program is meant to run until stopped: "every run ends" is not checked.
    #[serde(default)]
    pub runs_forever: bool,
}

fn default_max_states() -> u64 {
    100_000
}

impl Default for Verify {
    fn default() -> Verify {
        Verify {
            task: None,
            max_states: default_max_states(),
            runs_forever: false,
        }
    }
}

/// A request to a serving executive.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "op")]
pub enum Request {
    /// Loads a program (or a new version of one) under `name`.
    Load {
        /// The program's name.
        name: String,
        /// Its files, checked as one program.
        files: Vec<File>,
        /// When running runs take it, if it replaces a version they run.
        #[serde(default)]
        swap: Swap,
        /// Model-check it first (`tdl verify`), within bounds: refused if a property is broken.
        #[serde(default)]
        verify: Option<Verify>,
    },
    /// Removes a program: its attached handlers leave every run. Refused while a run runs it.
    Unload {
        /// The program's name.
        name: String,
    },
    /// The loaded programs.
    List,
    /// Starts a task of a program in a run of its own.
    Start {
        /// The program's name.
        program: String,
        /// The task (default: the program's only goal or command no task of it spawns).
        #[serde(default)]
        task: Option<String>,
        /// Its arguments, as `tdl run --args` takes them.
        #[serde(default)]
        args: serde_json::Value,
    },
    /// Stops a run: its top-level task is terminated (its cleanup runs).
    Stop {
        /// The run.
        run: u64,
    },
    /// Raises an external event in a run.
    Raise {
        /// The run.
        run: u64,
        /// The event's name.
        event: String,
    },
    /// The runs (or one run).
    Status {
        /// Only this run.
        #[serde(default)]
        run: Option<u64>,
    },
}

/// A loaded program, as [`Reply::Programs`] lists it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ProgramInfo {
    /// Its name.
    pub name: String,
    /// Its version: `name@hash`, the hash of its sources.
    pub version: String,
    /// Its goals and commands.
    pub tasks: Vec<String>,
    /// The tasks its handlers are attached to (`handler h() handles E for T`).
    pub attaches_to: Vec<String>,
    /// The tasks its wiretaps check (`wiretap w() before T`).
    #[serde(default)]
    pub taps: Vec<String>,
    /// Who loaded it.
    pub loaded_by: String,
}

/// A run, as [`Reply::Runs`] lists it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct RunInfo {
    /// Its number.
    pub run: u64,
    /// The program's version its top-level task runs.
    pub version: String,
    /// The task.
    pub task: String,
    /// Whether it still runs.
    pub running: bool,
    /// How it ended (the report's first line), once it did.
    pub outcome: Option<String>,
    /// Its live nodes now (0 once ended).
    pub live_nodes: u64,
    /// The file its trace is written to.
    pub trace: String,
}

/// A successful answer.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Reply {
    /// A program was loaded.
    Loaded {
        /// Its version.
        version: String,
        /// Whether the same version was loaded already (nothing changed).
        unchanged: bool,
        /// What the model check asked for said (`ok`, or `undecided` and why), if one was.
        #[serde(default)]
        verified: Option<String>,
        /// The runs that take the new version (by the swap asked for).
        swapped: Vec<u64>,
    },
    /// A program was unloaded.
    Unloaded,
    /// The loaded programs.
    Programs(Vec<ProgramInfo>),
    /// A run was started.
    Started {
        /// Its number.
        run: u64,
        /// Its trace's file.
        trace: String,
    },
    /// Done.
    Done,
    /// The runs.
    Runs(Vec<RunInfo>),
}

/// The answer to a request: a reply, or why it was refused (with a program's diagnostics, as
/// `tdl check` renders them, when it was refused for them).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Response {
    /// Done.
    Ok(Reply),
    /// Refused; nothing changed.
    Refused(String),
}
