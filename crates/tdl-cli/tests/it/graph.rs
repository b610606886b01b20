//! `tdl graph`: its `dot` output is rendered by Graphviz itself (installed by the test when it
//! runs as root and `dot` is missing) for every example program of the workspace and every valid
//! file of the parser's test data; its Mermaid output has plain ids and escaped labels.

use std::io::Write as _;
use std::path::Path;
use std::process::{Command, Stdio};

use super::tdl;

/// The example programs of the workspace, as paths relative to this crate, one program per entry.
pub(crate) const PROGRAMS: [&[&str]; 3] = [
    &["../xavier/src/mission.tdl"],
    &["../nav2/src/navigate.tdl"],
    &["../ambler/src/walk.tdl", "../ambler/src/terrain.tdl"],
];

/// `(kind, name)` of every task of the files, from the front end's tree.
pub(crate) fn tasks(files: &[&str]) -> Vec<(String, String)> {
    let mut tasks = Vec::new();
    for file in files {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(file);
        let src = std::fs::read_to_string(&path).expect("an example program");
        let parse = tdl_syntax::parse_str(file, &src);
        for item in &parse.file.items {
            if let tdl_syntax::Item::Task(task) = item {
                tasks.push((task.kind.as_str().to_string(), task.name.to_string()));
            }
        }
    }
    assert!(!tasks.is_empty(), "{files:?} define no task");
    tasks
}

/// Graphviz's `dot`, installed if need be; the test fails with the reason when it cannot be had.
pub(crate) fn dot() -> std::path::PathBuf {
    test_support::ensure_tool("dot", "graphviz").unwrap_or_else(|why| panic!("{why}"))
}

/// `dot -Tsvg` of `graph`: the SVG, or a failure with Graphviz's message.
fn svg(dot: &Path, graph: &str) -> String {
    let mut child = Command::new(dot)
        .arg("-Tsvg")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run dot");
    child
        .stdin
        .take()
        .expect("dot's stdin")
        .write_all(graph.as_bytes())
        .expect("write to dot");
    let out = child.wait_with_output().expect("dot's output");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "dot failed: {err}\n{graph}");
    // Graphviz warns on stderr about what it had to guess; the graphs give it nothing to guess.
    assert!(err.trim().is_empty(), "dot warned: {err}\n{graph}");
    let svg = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        svg.contains("<svg") && svg.trim_end().ends_with("</svg>"),
        "{svg}"
    );
    svg
}

#[test]
fn graphviz_renders_the_graph_of_every_example_program_with_every_task() {
    let dot = dot();
    for files in PROGRAMS {
        let mut args = vec!["graph"];
        args.extend(files);
        let (code, out, err) = tdl(&args);
        assert_eq!(code, 0, "{files:?}: {err}");
        let svg = svg(&dot, &out);
        for (kind, name) in tasks(files) {
            assert!(
                svg.contains(&format!(">{kind} {name}</text>")),
                "{files:?}: no node for {kind} {name}"
            );
        }
    }
    // Xavier's mission: the spawns of deliver_mail and the constraints between them.
    let (_, out, _) = tdl(&["graph", "../xavier/src/mission.tdl"]);
    let svg = svg(&dot, &out);
    for text in [
        ">navigate_to_locn</text>",
        ">terminate at execution completed</text>",
        ">sequential execution</text>",
        ">handles Blocked</text>",
        ">exception NoPath</text>",
    ] {
        assert!(svg.contains(text), "no {text} in the mission's SVG");
    }
}

#[test]
fn graphviz_renders_the_graph_of_every_valid_parser_test_file() {
    let dot = dot();
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tdl-syntax/test_data/ok");
    let mut files: Vec<String> = std::fs::read_dir(&dir)
        .expect("the parser's test data")
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "tdl"))
        .map(|p| p.display().to_string())
        .collect();
    files.sort();
    assert!(files.len() >= 10, "{files:?}");
    for file in &files {
        let (code, out, err) = tdl(&["graph", file]);
        assert_eq!(code, 0, "{file}: {err}");
        svg(&dot, &out);
    }
}

#[test]
fn task_keeps_only_what_the_task_reaches() {
    let (code, out, err) = tdl(&[
        "graph",
        "../xavier/src/mission.tdl",
        "--task",
        "navigate_to_locn",
    ]);
    assert_eq!(code, 0, "{err}");
    for present in [
        "\"t_navigate_to_locn\"",
        "\"t_detour\"",
        "\"t_cool_down\"",
        "\"t_let_motor_cool\"",
        "\"e_Blocked\"",
        "\"e_Overheating\"",
    ] {
        assert!(out.contains(present), "no {present} in\n{out}");
    }
    for absent in [
        "t_deliver_all",
        "t_deliver_mail",
        "t_monitor_pickup",
        "e_NoPath",
    ] {
        assert!(!out.contains(absent), "{absent} in\n{out}");
    }
    let (code, _, err) = tdl(&["graph", "../xavier/src/mission.tdl", "--task", "fly"]);
    assert_eq!(code, 2);
    assert!(err.contains("no task `fly` in the program"), "{err}");
}

/// Whether `id` is a Mermaid-safe node id.
fn plain_id(id: &str) -> bool {
    !id.is_empty() && id.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
}

#[test]
fn mermaid_has_a_node_per_task_plain_ids_and_quoted_labels() {
    for files in PROGRAMS {
        let mut args = vec!["graph", "--format", "mermaid"];
        args.extend(files);
        let (code, out, err) = tdl(&args);
        assert_eq!(code, 0, "{files:?}: {err}");
        assert!(out.starts_with("flowchart TB\n"), "{out}");
        for (kind, name) in tasks(files) {
            assert!(
                out.contains(&format!("t_{name}(\"{kind} {name}")) // goals: rounded
                    || out.contains(&format!("t_{name}[\"{kind} {name}"))
                    || out.contains(&format!("t_{name}{{{{\"{kind} {name}"))
                    || out.contains(&format!("t_{name}[[\"{kind} {name}")),
                "{files:?}: no node for {kind} {name} in\n{out}"
            );
        }
        let mut depth = 0;
        for line in out.lines().skip(1).map(str::trim) {
            assert_eq!(
                line.matches('"').count() % 2,
                0,
                "unbalanced quotes: {line}"
            );
            // What is left outside the quoted labels.
            let bare: String = line.split('"').step_by(2).collect();
            let words: Vec<&str> = bare.split_whitespace().collect();
            match words[..] {
                ["classDef", class, ..] | ["linkStyle", class, ..] => {
                    assert!(plain_id(class), "{line}")
                }
                ["subgraph", id, "[]"] => {
                    assert!(plain_id(id), "{line}");
                    depth += 1;
                }
                ["end"] => depth -= 1,
                [from, arrow, to] => {
                    assert!(plain_id(from) && plain_id(to), "{line}");
                    assert!(
                        ["-->", "-.->", "==>", "-->||", "-.->||", "==>||"].contains(&arrow),
                        "{line}"
                    );
                }
                [node] => {
                    let id: String = node
                        .chars()
                        .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                        .collect();
                    let shape = &node[id.len()..];
                    assert!(plain_id(&id), "{line}");
                    let (shape, class) = shape.split_once(":::").expect("a class");
                    assert!(
                        ["()", "[]", "{{}}", "[[]]", ">]"].contains(&shape) && plain_id(class),
                        "{line}"
                    );
                }
                _ => panic!("unexpected line {line:?}"),
            }
        }
        assert_eq!(depth, 0, "unclosed subgraph");
    }
}

/// A file with errors gives exactly what `tdl check` prints, on standard error, and exit 1.
#[test]
fn graph_of_a_bad_file_prints_the_diagnostics_of_check() {
    let (_, expected, _) = tdl(&["check", "tests/data/three_mistakes.tdl"]);
    assert!(expected.starts_with("error: "), "{expected}");
    for format in ["dot", "mermaid"] {
        let (code, out, err) = tdl(&["graph", "--format", format, "tests/data/three_mistakes.tdl"]);
        assert_eq!((code, out.as_str()), (1, ""), "{err}");
        assert_eq!(err, expected);
    }
}
