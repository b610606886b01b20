//! Compiles `.tdl` files into Rust from a build script.
//!
//! ```no_run
//! // build.rs
//! tdl_build::compile("src/robot.tdl");
//! // src/lib.rs: include!(concat!(env!("OUT_DIR"), "/robot.rs"));
//! ```
//!
//! On errors every diagnostic is printed to stderr as `file:line:col: error: message` with the
//! source line and a hint, and the build script exits with status 1: cargo then fails the build
//! and shows that stderr verbatim (a panic would add a `panicked at` line and a backtrace note).
//! Warnings are passed to cargo as `cargo:warning=` lines.
//!
//! Architecture Invariant: no logic here; it all lives in `tdl-syntax` (`compile_str`).

use std::path::Path;

/// Compiles `path` (relative to the package root) into `$OUT_DIR/<file stem>.rs` and tells cargo
/// to re-run when it changes. Exits the build script with status 1 on errors.
pub fn compile(path: impl AsRef<Path>) {
    let path = path.as_ref();
    let shown = path.display().to_string();
    println!("cargo:rerun-if-changed={shown}");
    let fail = |text: String| -> ! {
        eprintln!("{text}");
        std::process::exit(1)
    };
    let src = std::fs::read_to_string(path)
        .unwrap_or_else(|e| fail(format!("error: cannot read {shown}: {e}")));
    let (code, diagnostics) = tdl_syntax::compile_str(&shown, &src);
    let Some(code) = code else {
        fail(tdl_syntax::render_all(&diagnostics, &shown, Some(&src)))
    };
    for diag in &diagnostics {
        let (line, col) = (diag.line(), diag.column());
        println!("cargo:warning={shown}:{line}:{col}: {}", diag.message());
    }
    let out_dir = std::env::var_os("OUT_DIR").unwrap_or_else(|| {
        fail("error: OUT_DIR is not set; call tdl_build::compile from build.rs".into())
    });
    let stem = path.file_stem().unwrap_or(path.as_os_str());
    let out = Path::new(&out_dir).join(stem).with_extension("rs");
    std::fs::write(&out, tdl_syntax::pretty(&code))
        .unwrap_or_else(|e| fail(format!("error: cannot write {}: {e}", out.display())));
}
