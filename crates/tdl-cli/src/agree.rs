//! The back ends hold to one answer: every TDL program of the repository goes through the code
//! generator behind `tdl!` (`tdl_syntax::generated_tags`), `tdl verify`'s loader
//! (`tdl_verify::Program::resolved_tags`) and the model `tdl graph` and `tdl doc` draw
//! (`model::Program`), and each tag written in a constraint must name the same nodes in all
//! three (`previous` aside: the generated code and the checker follow it at run time, the
//! drawings statically).
//!
//! A program is a crate's `.tdl` files under `src/` together, or any other `.tdl` file of the
//! repository alone (test data, examples, tests), except those that must fail (`test_data/err`).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use tdl_syntax::hir::{ResolvedTag, TagTarget};

use crate::model;

/// Where each tag is written (file, line, column) and what it names.
type View = BTreeMap<(usize, usize, usize), BTreeSet<TagTarget>>;

/// Every `.tdl` file under `dir`, sorted, skipping build output.
fn tdl_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.filter_map(Result::ok) {
        let path = entry.path();
        let name = entry.file_name();
        if path.is_dir() {
            if name != "target" && name != ".git" {
                tdl_files(&path, out);
            }
        } else if path.extension().is_some_and(|it| it == "tdl") {
            out.push(path);
        }
    }
}

/// The programs of the repository, each a list of `(name, source)`.
fn programs() -> Vec<Vec<(String, String)>> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let mut files = Vec::new();
    tdl_files(&root.join("crates"), &mut files);
    files.sort();
    let mut crates: BTreeMap<PathBuf, Vec<PathBuf>> = BTreeMap::new();
    let mut alone = Vec::new();
    for path in files {
        let rel = path.strip_prefix(&root).unwrap_or(&path).to_path_buf();
        let parts: Vec<String> = rel
            .components()
            .map(|it| it.as_os_str().to_string_lossy().into_owned())
            .collect();
        if parts.iter().any(|it| it == "err") && parts.iter().any(|it| it == "test_data") {
            continue;
        }
        match parts.as_slice() {
            [first, krate, src, ..] if first == "crates" && src == "src" => {
                crates
                    .entry(root.join("crates").join(krate))
                    .or_default()
                    .push(path);
            }
            _ => alone.push(path),
        }
    }
    let read = |paths: &[PathBuf]| -> Vec<(String, String)> {
        paths
            .iter()
            .map(|path| {
                let text = std::fs::read_to_string(path)
                    .unwrap_or_else(|err| panic!("cannot read {}: {err}", path.display()));
                let name = path
                    .strip_prefix(&root)
                    .unwrap_or(path)
                    .display()
                    .to_string();
                (name, text)
            })
            .collect()
    };
    let mut out: Vec<Vec<(String, String)>> = crates.values().map(|it| read(it)).collect();
    out.extend(alone.iter().map(|it| read(std::slice::from_ref(it))));
    out
}

/// A back end's tags as a view; the same tag resolved two ways by one back end is an error.
fn view(tags: Vec<ResolvedTag>, who: &str, names: &[(String, String)]) -> View {
    let mut out = View::new();
    for tag in tags {
        let key = (tag.file, tag.line, tag.column);
        if let Some(before) = out.insert(key, tag.targets.clone()) {
            assert_eq!(
                before, tag.targets,
                "{who} resolves the tag at {}:{}:{} two ways",
                names[tag.file].0, tag.line, tag.column
            );
        }
    }
    out
}

#[test]
fn the_generator_the_checker_and_the_drawings_resolve_every_tag_alike() {
    let programs = programs();
    let mut compared = 0;
    let mut tags = 0;
    let mut by_all_three = Vec::new();
    for files in &programs {
        let named: Vec<(&str, &str)> = files
            .iter()
            .map(|(n, s)| (n.as_str(), s.as_str()))
            .collect();
        let label = files
            .iter()
            .map(|(n, _)| n.as_str())
            .collect::<Vec<_>>()
            .join(", ");
        tdl_syntax::compile_program_with(&named, |program, results| {
            if results.iter().any(|(code, _)| code.is_none()) {
                // A program the front end refuses (a fixture of a failing build): nothing to compare.
                return;
            }
            let generated = view(tdl_syntax::generated_tags(program), "the generator", files);
            let drawn: Vec<ResolvedTag> = model::Program::new(program)
                .tasks
                .into_iter()
                .flat_map(|it| it.tags)
                .collect();
            let drawn = view(drawn, "the model", files);
            assert_eq!(
                generated, drawn,
                "the generator and the model disagree on {label}"
            );
            compared += 1;
            tags += generated.len();
            // The checker refuses what it does not model (`parent`, a handler written in Rust).
            if let Ok(loaded) = tdl_verify::Program::load(files) {
                let checked = view(loaded.resolved_tags(), "the checker", files);
                assert_eq!(
                    generated, checked,
                    "the generator and the checker disagree on {label}"
                );
                by_all_three.push(label);
            }
        });
    }
    // The corpus is the repository's: the demo's mission, the rover's and Nav2's among them.
    for krate in ["crates/xavier/src", "crates/ambler/src", "crates/nav2/src"] {
        assert!(
            by_all_three.iter().any(|it| it.contains(krate)),
            "{krate} was not compared by all three: {by_all_three:?}"
        );
    }
    assert!(compared >= 20, "only {compared} programs compared");
    assert!(tags >= 100, "only {tags} tags compared");
}
