//! Data-driven parser tests: add a case by adding a `.tdl` file under `test_data/ok` (must parse
//! with no error; the tree dump is snapshotted), `test_data/err` (must give at least one error;
//! the rendered diagnostics are snapshotted) or `test_data/warn` (must give warnings and no
//! error; the rendered diagnostics are snapshotted). Snapshots live beside the files as
//! `<stem>.snap`.

use std::path::{Path, PathBuf};

fn data_dir(kind: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("test_data")
        .join(kind)
}

/// The `.tdl` files of `test_data/<kind>`, sorted, as (stem, file name, text).
fn cases(kind: &str) -> Vec<(String, String, String)> {
    let dir = data_dir(kind);
    let mut out: Vec<(String, String, String)> = std::fs::read_dir(&dir)
        .unwrap_or_else(|err| panic!("cannot read {}: {err}", dir.display()))
        .filter_map(Result::ok)
        .map(|it| it.path())
        .filter(|it| it.extension().is_some_and(|ext| ext == "tdl"))
        .map(|path| {
            let stem = path
                .file_stem()
                .map(|it| it.to_string_lossy().into_owned())
                .unwrap_or_default();
            let name = format!("{kind}/{stem}.tdl");
            let text = std::fs::read_to_string(&path)
                .unwrap_or_else(|err| panic!("cannot read {}: {err}", path.display()));
            (stem, name, text)
        })
        .collect();
    out.sort();
    out
}

#[test]
fn ok_files_parse_without_errors() {
    let cases = cases("ok");
    assert!(
        cases.len() >= 10,
        "expected the ok/ corpus, found {} files",
        cases.len()
    );
    for (stem, name, text) in cases {
        let parse = tdl_syntax::parse_str(&name, &text);
        let rendered = parse.render(&name, Some(&text));
        assert!(!parse.has_errors(), "{name} has errors:\n{rendered}");
        let mut snapshot = tdl_syntax::dump(&parse.file);
        if !parse.diagnostics.is_empty() {
            snapshot.push_str("\n--- warnings ---\n");
            snapshot.push_str(&rendered);
        }
        insta::with_settings!({
            snapshot_path => data_dir("ok"),
            prepend_module_to_snapshot => false,
            description => name.clone(),
            omit_expression => true,
        }, {
            insta::assert_snapshot!(stem, snapshot);
        });
    }
}

#[test]
fn err_files_give_errors() {
    let cases = cases("err");
    assert!(
        cases.len() >= 15,
        "expected the err/ corpus, found {} files",
        cases.len()
    );
    for (stem, name, text) in cases {
        let parse = tdl_syntax::parse_str(&name, &text);
        let rendered = parse.render(&name, Some(&text));
        assert!(parse.has_errors(), "{name} gives no error:\n{rendered}");
        insta::with_settings!({
            snapshot_path => data_dir("err"),
            prepend_module_to_snapshot => false,
            description => name.clone(),
            omit_expression => true,
        }, {
            insta::assert_snapshot!(stem, rendered);
        });
    }
}

#[test]
fn warn_files_give_warnings_only() {
    let cases = cases("warn");
    assert!(
        cases.len() >= 2,
        "expected the warn/ corpus, found {} files",
        cases.len()
    );
    for (stem, name, text) in cases {
        let parse = tdl_syntax::parse_str(&name, &text);
        let rendered = parse.render(&name, Some(&text));
        assert!(!parse.has_errors(), "{name} has errors:\n{rendered}");
        assert!(
            !parse.diagnostics.is_empty(),
            "{name} gives no warning:\n{rendered}"
        );
        insta::with_settings!({
            snapshot_path => data_dir("warn"),
            prepend_module_to_snapshot => false,
            description => name.clone(),
            omit_expression => true,
        }, {
            insta::assert_snapshot!(stem, rendered);
        });
    }
}

/// The programs of several files under `test_data/err/<name>/`: compiled as one program
/// (`compile_program`, the files in name order), each file's diagnostics rendered with its own
/// name and source, and snapshotted together as `<name>.snap`.
#[test]
fn err_programs_give_errors() {
    let dir = data_dir("err");
    let mut programs: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|err| panic!("cannot read {}: {err}", dir.display()))
        .filter_map(Result::ok)
        .map(|it| it.path())
        .filter(|it| it.is_dir())
        .collect();
    programs.sort();
    assert!(
        !programs.is_empty(),
        "expected programs under {}",
        dir.display()
    );
    for program in programs {
        let stem = program
            .file_name()
            .map(|it| it.to_string_lossy().into_owned())
            .unwrap_or_default();
        let mut files: Vec<(String, String)> = std::fs::read_dir(&program)
            .unwrap_or_else(|err| panic!("cannot read {}: {err}", program.display()))
            .filter_map(Result::ok)
            .map(|it| it.path())
            .filter(|it| it.extension().is_some_and(|ext| ext == "tdl"))
            .map(|path| {
                let name = format!(
                    "{stem}/{}",
                    path.file_name().unwrap_or_default().to_string_lossy()
                );
                let text = std::fs::read_to_string(&path)
                    .unwrap_or_else(|err| panic!("cannot read {}: {err}", path.display()));
                (name, text)
            })
            .collect();
        files.sort();
        let named: Vec<(&str, &str)> = files
            .iter()
            .map(|(n, t)| (n.as_str(), t.as_str()))
            .collect();
        let results = tdl_syntax::compile_program(&named);
        let mut rendered = String::new();
        for ((name, text), (_, diags)) in files.iter().zip(&results) {
            rendered.push_str(&format!("=== {name}\n"));
            rendered.push_str(&tdl_syntax::render_all(diags, name, Some(text)));
        }
        assert!(
            results.iter().flat_map(|it| &it.1).any(|it| it.is_error()),
            "{stem} gives no error:\n{rendered}"
        );
        insta::with_settings!({
            snapshot_path => data_dir("err"),
            prepend_module_to_snapshot => false,
            description => stem.clone(),
            omit_expression => true,
        }, {
            insta::assert_snapshot!(stem, rendered);
        });
    }
}
