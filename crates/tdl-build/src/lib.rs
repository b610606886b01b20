//! Compiles `.tdl` files into Rust from a build script.
//!
//! ```no_run
//! // build.rs: the files of one program, whose names resolve across all of them.
//! tdl_build::compile_all(["src/walk.tdl", "src/faults.tdl"]);
//! // src/lib.rs:
//! // include!(concat!(env!("OUT_DIR"), "/walk.rs"));
//! // include!(concat!(env!("OUT_DIR"), "/faults.rs"));
//! ```
//!
//! On errors every diagnostic is printed to stderr as rustc prints its own (`error: message`,
//! ` --> file:line:col`, the source with the span underlined, a hint), without colour, and the
//! build script exits with status 1: cargo then fails the build and shows that stderr verbatim (a
//! panic would add a `panicked at` line and a backtrace note).
//! Warnings are passed to cargo as `cargo:warning=` lines.
//!
//! Architecture Invariant: no logic here; it all lives in `tdl-syntax` (`compile_program`).

use std::path::Path;

/// Compiles one `.tdl` file, a program of its own; see [`compile_all`].
pub fn compile(path: impl AsRef<Path>) {
    compile_all([path]);
}

/// Compiles the `.tdl` files of one program (paths relative to the package root), each into
/// `$OUT_DIR/<file stem>.rs`, and tells cargo to re-run when any changes. Task and exception names
/// resolve across every file: a handler in one file may handle an exception declared in another,
/// and a name no file declares is an error. Exits the build script with status 1 on errors, after
/// printing those of every file.
pub fn compile_all<P: AsRef<Path>>(paths: impl IntoIterator<Item = P>) {
    let fail = |text: String| -> ! {
        eprintln!("{text}");
        std::process::exit(1)
    };
    let mut files = Vec::new();
    for path in paths {
        let path = path.as_ref().to_path_buf();
        let shown = path.display().to_string();
        println!("cargo:rerun-if-changed={shown}");
        let src = std::fs::read_to_string(&path)
            .unwrap_or_else(|e| fail(format!("error: cannot read {shown}: {e}")));
        files.push((path, shown, src));
    }
    let program: Vec<(&str, &str)> = files
        .iter()
        .map(|(_, shown, src)| (shown.as_str(), src.as_str()))
        .collect();
    let results = tdl_syntax::compile_program(&program);
    let mut errors = Vec::new();
    for ((_, shown, src), (code, diagnostics)) in files.iter().zip(&results) {
        if code.is_none() {
            errors.push(tdl_syntax::render_all(diagnostics, shown, Some(src)));
            continue;
        }
        for diag in diagnostics {
            let (line, col) = (diag.line(), diag.column());
            println!("cargo:warning={shown}:{line}:{col}: {}", diag.message());
        }
    }
    if !errors.is_empty() {
        fail(errors.join("\n"));
    }
    let out_dir = std::env::var_os("OUT_DIR").unwrap_or_else(|| {
        fail("error: OUT_DIR is not set; call tdl_build::compile from build.rs".into())
    });
    for ((path, _, _), (code, _)) in files.iter().zip(&results) {
        let Some(code) = code else { continue };
        let stem = path.file_stem().unwrap_or(path.as_os_str());
        let out = Path::new(&out_dir).join(stem).with_extension("rs");
        std::fs::write(&out, tdl_syntax::pretty(code))
            .unwrap_or_else(|e| fail(format!("error: cannot write {}: {e}", out.display())));
    }
}
