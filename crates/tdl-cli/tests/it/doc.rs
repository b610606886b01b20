//! `tdl doc`: a page for every task of the program, and no broken link: every `href` of every
//! page written (the SVG graph's included) names a file written and, after `#`, an `id` in it.
//! With Graphviz on PATH the index embeds the SVG; without, the Mermaid text and a note.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Command;

use super::graph::{PROGRAMS, dot, tasks};
use super::tdl;

/// A fresh directory for one test's output.
fn out_dir(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("tdl-doc-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// The values of every `attr="…"` in `html`.
fn values<'h>(html: &'h str, attr: &str) -> Vec<&'h str> {
    let pattern = format!("{attr}=\"");
    let mut out = Vec::new();
    let mut rest = html;
    while let Some(start) = rest.find(&pattern) {
        rest = &rest[start + pattern.len()..];
        let end = rest.find('"').expect("a closing quote");
        out.push(&rest[..end]);
        rest = &rest[end..];
    }
    out
}

/// The `.html` files of `dir`, by name.
fn pages(dir: &Path) -> BTreeMap<String, String> {
    std::fs::read_dir(dir)
        .expect("the output directory")
        .filter_map(Result::ok)
        .map(|e| e.path())
        .map(|p| {
            let name = p
                .file_name()
                .expect("a file name")
                .to_string_lossy()
                .into_owned();
            let html = std::fs::read_to_string(&p).expect("a page");
            (name, html)
        })
        .collect()
}

/// Every broken link of the pages (`page: href`), and how many links were followed.
fn broken_links(pages: &BTreeMap<String, String>) -> (Vec<String>, usize) {
    let mut broken = Vec::new();
    let mut followed = 0;
    for (name, html) in pages {
        // `href` also finds the SVG's `xlink:href`.
        for href in values(html, "href") {
            followed += 1;
            if href.starts_with("https:") || href.starts_with("http:") {
                broken.push(format!("{name}: {href} leaves the documentation"));
                continue;
            }
            let (file, anchor) = href.split_once('#').unwrap_or((href, ""));
            let target = if file.is_empty() { name.as_str() } else { file };
            match pages.get(target) {
                None => broken.push(format!("{name}: {href} (no such page)")),
                Some(page) if !anchor.is_empty() && !values(page, "id").contains(&anchor) => {
                    broken.push(format!("{name}: {href} (no such id)"));
                }
                Some(_) => {}
            }
        }
    }
    (broken, followed)
}

/// Runs `tdl doc` on `files` into a fresh directory named `name`, with `path` as `PATH` if given.
fn doc(name: &str, files: &[&str], path: Option<&Path>) -> (PathBuf, String) {
    let dir = out_dir(name);
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_tdl"));
    cmd.arg("doc")
        .args(files)
        .arg("-o")
        .arg(&dir)
        .current_dir(env!("CARGO_MANIFEST_DIR"));
    if let Some(path) = path {
        cmd.env("PATH", path);
    }
    let out = cmd.output().expect("run tdl doc");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{files:?}: {stderr}");
    (dir, String::from_utf8_lossy(&out.stdout).into_owned())
}

/// Every task of the program has its page, and nothing else is written but the index.
fn assert_a_page_per_task(files: &[&str], pages: &BTreeMap<String, String>) {
    let expected: BTreeSet<String> = tasks(files)
        .into_iter()
        .map(|(_, name)| format!("task.{name}.html"))
        .chain(["index.html".to_string()])
        .collect();
    let written: BTreeSet<String> = pages.keys().cloned().collect();
    assert_eq!(written, expected);
    let index = &pages["index.html"];
    for (kind, name) in tasks(files) {
        assert!(
            index.contains(&format!(
                "<a href=\"task.{name}.html\"><code>{name}</code></a>"
            )),
            "index.html does not link {name}"
        );
        let page = &pages[&format!("task.{name}.html")];
        assert!(
            page.contains(&format!(
                "<h1><span class=\"kind {kind}\">{kind}</span>{name}</h1>"
            )),
            "task.{name}.html has no title"
        );
    }
}

#[test]
fn the_mission_has_a_page_per_task_an_svg_graph_and_no_broken_link() {
    dot();
    let files = ["../xavier/src/mission.tdl"];
    let (dir, out) = doc("mission", &files, None);
    assert!(out.starts_with("wrote 15 pages to "), "{out}");
    let pages = pages(&dir);
    assert_a_page_per_task(&files, &pages);
    let index = &pages["index.html"];
    assert!(index.contains("<figure class=\"graph\">\n<svg"), "no SVG");
    // The graph's nodes link to the pages.
    assert!(
        index.contains("xlink:href=\"task.deliver_mail.html\""),
        "no link in the SVG"
    );
    let (broken, followed) = broken_links(&pages);
    assert!(broken.is_empty(), "{broken:#?}");
    assert!(followed > 100, "only {followed} links");
    // What deliver_mail's page says: its doc comment, its handlers, spawns and constraints.
    let page = &pages["task.deliver_mail.html"];
    for text in [
        "<pre class=\"sig\">pub goal deliver_mail(m: Mission, room: u32)</pre>",
        "<p>Figure 4&#39;s deliverMail: go to the room",
        "<li><a href=\"task.give_up_no_path.html\"><code>give_up_no_path</code></a><code>(m, room)</code>, handles <a href=\"index.html#exception-NoPath\"><code>NoPath</code></a></li>",
        "<li id=\"spawn-3\"><span class=\"kind rust\">rust</span><code>speak</code><code>(&amp;m.robot, &quot;Xavier here with your mail&quot;)</code>",
        "<li><code>sequential execution <a href=\"#spawn-2\"><code>center_on_door</code></a></code></li>",
        "<li><code>terminate at <a href=\"#spawn-4\"><code>monitor_pickup</code></a> handling completed</code></li>",
        "<h2 id=\"spawned-by\">Spawned by</h2>\n<p><a href=\"task.deliver_all.html\"><code>deliver_all</code></a></p>",
    ] {
        assert!(page.contains(text), "task.deliver_mail.html lacks {text}");
    }
    // A handler's page: what it handles and who attaches it.
    let page = &pages["task.detour.html"];
    assert!(
        page.contains("<p><a href=\"index.html#exception-Blocked\"><code>Blocked</code></a>.</p>")
    );
    assert!(page.contains("<p>Attached by <a href=\"task.navigate_to_locn.html\"><code>navigate_to_locn</code></a>.</p>"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn every_example_program_is_documented_without_broken_links() {
    dot();
    for (n, files) in PROGRAMS.iter().enumerate() {
        let (dir, _) = doc(&format!("example-{n}"), files, None);
        let pages = pages(&dir);
        assert_a_page_per_task(files, &pages);
        let (broken, _) = broken_links(&pages);
        assert!(broken.is_empty(), "{files:?}: {broken:#?}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}

/// Without Graphviz the index holds the Mermaid text, escaped, and says why.
#[test]
fn without_graphviz_the_graph_is_mermaid_text() {
    let empty = out_dir("empty-path");
    std::fs::create_dir_all(&empty).expect("an empty directory");
    let files = ["../xavier/src/mission.tdl"];
    let (dir, _) = doc("no-graphviz", &files, Some(&empty));
    let pages = pages(&dir);
    assert_a_page_per_task(&files, &pages);
    let index = &pages["index.html"];
    assert!(!index.contains("<svg"), "an SVG without dot");
    assert!(
        index.contains("Graphviz (<code>dot</code>) was not found on PATH"),
        "no note"
    );
    assert!(
        index.contains("<pre class=\"mermaid\">flowchart TB\n"),
        "no Mermaid"
    );
    assert!(
        index.contains("t_deliver_all(&quot;goal deliver_all&quot;):::goal"),
        "Mermaid text not escaped"
    );
    let (broken, _) = broken_links(&pages);
    assert!(broken.is_empty(), "{broken:#?}");
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_dir_all(&empty);
}

#[test]
fn doc_of_a_bad_file_prints_the_diagnostics_of_check_and_writes_nothing() {
    let (_, expected, _) = tdl(&["check", "tests/data/three_mistakes.tdl"]);
    let dir = out_dir("bad");
    let dir_arg = dir.display().to_string();
    let (code, out, err) = tdl(&["doc", "tests/data/three_mistakes.tdl", "-o", &dir_arg]);
    assert_eq!((code, out.as_str()), (1, ""), "{err}");
    assert_eq!(err, expected);
    assert!(!dir.exists());
}
