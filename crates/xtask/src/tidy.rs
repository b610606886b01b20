//! The house rules that code review would otherwise have to remember (HOUSE_STYLE.md, section F):
//!
//! - every `.rs` file opens with a `//!` paragraph saying what it is for;
//! - no `#[should_panic]` and no `#[ignore]`: a test asserts the behaviour it expects;
//! - no trailing whitespace;
//! - `tcm-core` names no async runtime, clock, thread or hash-ordered map (its determinism);
//! - internal crates are version `0.0.0` and not published.

use std::fs;
use std::path::{Path, PathBuf};

/// The workspace root (two levels above this crate's manifest).
pub(crate) fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Every broken rule, one line each (`path:line: what`).
pub(crate) fn check(root: &Path) -> Vec<String> {
    let mut problems = Vec::new();
    let mut files = Vec::new();
    collect(&root.join("crates"), &mut files);
    for file in &files {
        let Ok(text) = fs::read_to_string(file) else {
            continue;
        };
        let rel = file
            .strip_prefix(root)
            .unwrap_or(file)
            .display()
            .to_string();
        if file.extension().is_some_and(|e| e == "rs") {
            check_rust(&rel, &text, &mut problems);
        }
        if file.file_name().is_some_and(|n| n == "Cargo.toml") {
            check_manifest(&rel, &text, &mut problems);
        }
    }
    problems
}

fn collect(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = fs::read_dir(dir) else {
        return;
    };
    let mut entries: Vec<PathBuf> = entries.filter_map(|e| e.ok().map(|e| e.path())).collect();
    entries.sort();
    for path in entries {
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
        if path.is_dir() {
            // Generated or foreign trees: build output, fuzz corpora, macro UI expectations.
            if matches!(name, "target" | "fuzz" | "corpus" | "artifacts") || name.starts_with('.') {
                continue;
            }
            collect(&path, out);
        } else if name.ends_with(".rs") || name == "Cargo.toml" {
            out.push(path);
        }
    }
}

fn check_rust(rel: &str, text: &str, problems: &mut Vec<String>) {
    // UI-test inputs are deliberately wrong programs; only the whitespace rule applies to them.
    let ui = rel.contains("/tests/ui/");
    let first = text.lines().find(|l| !l.trim().is_empty()).unwrap_or("");
    if !ui && !first.starts_with("//!") {
        problems.push(format!(
            "{rel}:1: a Rust file opens with a `//!` paragraph saying what it is for"
        ));
    }
    let core = rel.starts_with("crates/tcm-core/src/");
    let tidy = rel.starts_with("crates/xtask/");
    for (i, line) in text.lines().enumerate() {
        let n = i + 1;
        if line.ends_with(' ') || line.ends_with('\t') {
            problems.push(format!("{rel}:{n}: trailing whitespace"));
        }
        if tidy {
            continue;
        }
        for banned in ["#[should_panic", "#[ignore"] {
            if line.contains(banned) {
                problems.push(format!(
                    "{rel}:{n}: `{banned}]`: assert the expected behaviour instead"
                ));
            }
        }
        if core && !line.trim_start().starts_with("//") {
            for banned in [
                "tokio",
                "Instant::now",
                "SystemTime",
                "thread::spawn",
                "HashMap",
                "HashSet",
            ] {
                if line.contains(banned) {
                    problems.push(format!("{rel}:{n}: `{banned}` in tcm-core, which must stay deterministic and free of I/O"));
                }
            }
        }
    }
}

fn check_manifest(rel: &str, text: &str, problems: &mut Vec<String>) {
    if !rel.starts_with("crates/") || !text.contains("[package]") {
        return;
    }
    if !text.contains("version.workspace = true") {
        problems.push(format!(
            "{rel}: internal crates take `version.workspace = true` (0.0.0)"
        ));
    }
    if !text.contains("publish.workspace = true") && !text.contains("publish = false") {
        problems.push(format!(
            "{rel}: internal crates are not published (`publish.workspace = true`)"
        ));
    }
}
