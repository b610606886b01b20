//! TDL at run time: a program read from `.tdl` files when the executive runs, checked as the
//! compiler checks it, and run on the same `tcm` runtime as a compiled program, with the same
//! trace (docs/language.md, "Running programs without compiling them").
//!
//! ```ignore
//! let mut registry = tdl_interp::Registry::new();
//! registry.task("move_to", |x: f64, y: f64| my_robot::move_to(x, y));
//! let program = tdl_interp::Program::load(&["mission.tdl"], &registry)?;
//! let report = program.run(tdl::Runtime::new(), "mission", vec![]).await?;
//! ```
//!
//! - `load.rs`: the files parsed and checked (`tdl_syntax::compile_program_with`), then lowered
//!   (`lower.rs`) into the trees of `ir.rs`, every name resolved against the program and the
//!   [`Registry`] (`registry.rs`: tasks built in Rust, functions, host types' methods and fields,
//!   constants; conversions in `convert.rs`).
//! - `program.rs`: the [`Program`] and the tasks it builds, as the generated code builds them.
//! - `exec.rs`, `exec/tdl.rs`: statements, TDL statements as the generated code runs them;
//!   `eval.rs`, `eval/ops.rs`: expressions over [`Value`]s (`value.rs`), typed by `ty.rs`;
//!   `builtin.rs`: the functions and methods of plain values; `format.rs`: `format!`.

mod builtin;
mod convert;
mod eval;
mod exec;
mod format;
mod ir;
mod load;
mod lower;
mod outside;
mod program;
mod registry;
mod tap;
mod ty;
mod value;
mod versions;
mod walk;

pub use convert::{FromValue, IntoOutcome, IntoValue};
pub use convert::{Host, host_err, ok};
pub use exec::Budget;
pub use outside::{default_task, outside};
pub use program::Program;
pub use registry::{
    BoxFuture, Call, Function, IntoAsyncFunction, IntoFunction, IntoTaskFn, Registry, TaskFn,
};
pub use ty::Ty;
pub use value::{Args, ErrorValue, HostValue, Record, Value, Variant};

/// Why a program cannot be loaded.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// No file was given.
    #[error("no TDL file given")]
    NoFile,
    /// A file cannot be read.
    #[error("cannot read {path}: {reason}")]
    Read {
        /// The file.
        path: String,
        /// Why.
        reason: String,
    },
    /// The program has errors: its diagnostics, rendered with their files and lines.
    #[error("the program has errors:\n{0}")]
    Invalid(String),
}

/// Why a loaded program cannot run a task.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// No such task.
    #[error("the program has no task `{name}` (its goals and commands: {offered})")]
    NoTask {
        /// The name asked for.
        name: String,
        /// What it has.
        offered: String,
    },
    /// A monitor or handler is not run by itself.
    #[error("`{0}` is a monitor or a handler: run a goal or a command")]
    NotRunnable(String),
    /// The arguments do not fit the parameters.
    #[error("the arguments of `{task}`: {reason}")]
    Args {
        /// The task.
        task: String,
        /// What does not fit.
        reason: String,
    },
    /// The task could not be built.
    #[error("building the task: {0}")]
    Build(tdl::Failure),
    /// The run failed.
    #[error(transparent)]
    Run(tdl::Error),
}
