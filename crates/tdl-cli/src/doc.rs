//! `tdl doc`: HTML documentation of a program, from its static structure ([`crate::model`]).
//!
//! `index.html` lists the tasks by kind with the first sentence of their doc comments, the
//! exceptions (anchors `#exception-<id>`) and the tasks spawned but defined in Rust, and embeds
//! the program's graph: the SVG `dot -Tsvg` draws (its nodes link to the pages) when Graphviz is on
//! `PATH`, else the Mermaid text with a note. `task.<id>.html` is one page per task: its
//! signature, doc comments, task-level constraints and handlers, every spawn (anchors
//! `#spawn-<n>`) with its constraints, the exceptions it raises and handles, and who spawns it.
//! Every task or exception name links to its page or anchor; all text is escaped. Plain HTML with
//! a little inline CSS, no JavaScript.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use anyhow::Context as _;
use quote::ToTokens as _;
use tdl_syntax::TaskKind;

use crate::graph::{self, Format, Options};
use tdl_syntax::print::type_text;

use crate::model::{Origin, Piece, Program, TaskInfo, Text};

/// Writes the documentation of `program` (made of `files`) into `dir`, created if needed; returns
/// the files written.
pub(crate) fn write(
    program: &Program<'_>,
    files: &[String],
    dir: &Path,
) -> anyhow::Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let figure = figure(program)?;
    let mut pages = vec![("index.html".to_string(), index(program, files, &figure))];
    for t in &program.tasks {
        pages.push((format!("task.{}.html", t.id), task_page(program, t)));
    }
    let mut written = Vec::new();
    for (name, html) in pages {
        let path = dir.join(name);
        std::fs::write(&path, html).with_context(|| format!("cannot write {}", path.display()))?;
        written.push(path);
    }
    Ok(written)
}

/// The program's graph for the index: SVG from `dot`, or Mermaid text when `dot` is missing.
fn figure(program: &Program<'_>) -> anyhow::Result<String> {
    let options = Options {
        task: None,
        links: true,
    };
    let dot_text = graph::render(program, Format::Dot, options).map_err(anyhow::Error::msg)?;
    match run_dot(&dot_text)? {
        Some(svg) => Ok(format!("<figure class=\"graph\">\n{svg}</figure>\n")),
        None => {
            let mermaid =
                graph::render(program, Format::Mermaid, options).map_err(anyhow::Error::msg)?;
            Ok(format!(
                "<p class=\"note\">Graphviz (<code>dot</code>) was not found on PATH, so the graph \
                 is given as Mermaid text: paste it into a Mermaid renderer, or install Graphviz \
                 and run <code>tdl doc</code> again.</p>\n<pre class=\"mermaid\">{}</pre>\n",
                esc(&mermaid)
            ))
        }
    }
}

/// `dot -Tsvg` of `graph`, from its `<svg` element on; `None` when there is no `dot` to run.
fn run_dot(graph: &str) -> anyhow::Result<Option<String>> {
    let child = Command::new("dot")
        .arg("-Tsvg")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn();
    let mut child = match child {
        Ok(child) => child,
        Err(err) if err.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(err) => return Err(err).context("cannot run dot"),
    };
    let stdin = child.stdin.take();
    let output = std::thread::scope(|s| {
        s.spawn(move || {
            if let Some(mut stdin) = stdin {
                // A write error shows as dot's failure below.
                let _ = stdin.write_all(graph.as_bytes());
            }
        });
        child.wait_with_output()
    })
    .context("cannot run dot")?;
    if !output.status.success() {
        anyhow::bail!(
            "dot -Tsvg failed ({}): {}",
            output.status,
            String::from_utf8_lossy(&output.stderr).trim()
        );
    }
    let svg = String::from_utf8_lossy(&output.stdout);
    let start = svg
        .find("<svg")
        .context("dot -Tsvg wrote no <svg> element")?;
    Ok(Some(svg[start..].to_string()))
}

const STYLE: &str = "body{font-family:system-ui,sans-serif;max-width:62rem;margin:1.5rem auto;padding:0 1rem;line-height:1.45;color:#222}\
code,pre{font-family:ui-monospace,Menlo,Consolas,monospace;font-size:.92em}\
pre{background:#f5f5f5;padding:.6rem .8rem;overflow-x:auto}\
a{color:#1f5fa8;text-decoration:none}a:hover{text-decoration:underline}\
nav{font-size:.9em;color:#666;margin-bottom:1rem}\
.kind{display:inline-block;font-size:.75em;padding:0 .35em;border-radius:.25em;border:1px solid;margin-right:.3em;vertical-align:middle}\
.goal{background:#dbe9f8;border-color:#3b6ea5}.command{background:#e3f2dc;border-color:#4a7f3a}\
.monitor{background:#fbf0d0;border-color:#9a7b1c}.handler{background:#f8dcdc;border-color:#a33333}\
.rust{background:#fff;border-color:#777;border-style:dashed}\
.note,.none,.src{color:#666;font-size:.9em}\
ol.spawns>li{margin-bottom:.5rem}ol.spawns ul{margin:.2rem 0}\
figure.graph{margin:0;overflow-x:auto}figure.graph svg{max-width:100%;height:auto}\
dt{margin-top:.6rem}";

fn page(title: &str, body: &str) -> String {
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n\
         <title>{}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n{body}</body>\n</html>\n",
        esc(title)
    )
}

/// Escapes text for HTML content and attribute values.
pub(crate) fn esc(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

fn kind_badge(kind: TaskKind) -> String {
    format!("<span class=\"kind {0}\">{0}</span>", kind.as_str())
}

/// A task name: a link to its page when the program defines it.
fn task_link(program: &Program<'_>, name: &str) -> String {
    match program.task(name) {
        Some(t) => format!(
            "<a href=\"task.{}.html\"><code>{}</code></a>",
            esc(&t.id),
            esc(name)
        ),
        None => format!("<code>{}</code>", esc(name)),
    }
}

/// An exception name: a link to its entry in the index when the program declares it.
fn exception_link(program: &Program<'_>, name: &str) -> String {
    match program.exception(name) {
        Some(e) => format!(
            "<a href=\"index.html#exception-{}\"><code>{}</code></a>",
            esc(&e.id),
            esc(name)
        ),
        None => format!("<code>{}</code>", esc(name)),
    }
}

fn text_html(program: &Program<'_>, text: &Text) -> String {
    text.iter()
        .map(|p| match p {
            Piece::Text(s) => esc(s),
            Piece::Site(i, s) => format!("<a href=\"#spawn-{i}\"><code>{}</code></a>", esc(s)),
            Piece::Task(name) => task_link(program, name),
        })
        .collect()
}

/// One line of doc text: escaped, `code` spans as code, linked when they name a task or an
/// exception of the program.
fn inline(program: &Program<'_>, line: &str) -> String {
    let parts: Vec<&str> = line.split('`').collect();
    let mut out = String::new();
    for (i, part) in parts.iter().enumerate() {
        let last = i + 1 == parts.len();
        if i % 2 == 0 {
            out.push_str(&esc(part));
        } else if last {
            // An unclosed backtick: plain text.
            out.push('`');
            out.push_str(&esc(part));
        } else if program.task(part).is_some() {
            out.push_str(&task_link(program, part));
        } else if program.exception(part).is_some() {
            out.push_str(&exception_link(program, part));
        } else {
            out.push_str(&format!("<code>{}</code>", esc(part)));
        }
    }
    out
}

/// Doc comment text as HTML: paragraphs, `- ` lists, fenced or indented code blocks.
fn doc_html(program: &Program<'_>, doc: &str) -> String {
    let mut out = String::new();
    let mut lines = doc.lines().peekable();
    let mut para: Vec<&str> = Vec::new();
    let flush = |para: &mut Vec<&str>, out: &mut String| {
        if para.is_empty() {
            return;
        }
        if para
            .iter()
            .all(|l| l.starts_with("- ") || l.starts_with("* "))
        {
            out.push_str("<ul>\n");
            for l in para.iter() {
                out.push_str(&format!("<li>{}</li>\n", inline(program, &l[2..])));
            }
            out.push_str("</ul>\n");
        } else if para.iter().all(|l| l.starts_with("    ")) {
            let code: Vec<&str> = para.iter().map(|l| &l[4..]).collect();
            out.push_str(&format!("<pre>{}</pre>\n", esc(&code.join("\n"))));
        } else {
            let text: Vec<String> = para.iter().map(|l| inline(program, l)).collect();
            out.push_str(&format!("<p>{}</p>\n", text.join("\n")));
        }
        para.clear();
    };
    while let Some(line) = lines.next() {
        if line.trim_start().starts_with("```") {
            flush(&mut para, &mut out);
            let mut code = Vec::new();
            for l in lines.by_ref() {
                if l.trim_start().starts_with("```") {
                    break;
                }
                code.push(l);
            }
            out.push_str(&format!("<pre>{}</pre>\n", esc(&code.join("\n"))));
        } else if line.trim().is_empty() {
            flush(&mut para, &mut out);
        } else {
            para.push(line);
        }
    }
    flush(&mut para, &mut out);
    out
}

/// The first sentence of the doc comment's first paragraph.
fn summary(doc: &str) -> String {
    let para: Vec<&str> = doc
        .lines()
        .take_while(|l| !l.trim().is_empty())
        .map(str::trim)
        .collect();
    let text = para.join(" ");
    match text.find(". ") {
        Some(end) => text[..=end].to_string(),
        None => text,
    }
}

fn index(program: &Program<'_>, files: &[String], figure: &str) -> String {
    let mut b = String::new();
    b.push_str("<h1>TDL program</h1>\n<p class=\"src\">");
    let names: Vec<String> = files
        .iter()
        .map(|f| format!("<code>{}</code>", esc(f)))
        .collect();
    b.push_str(&names.join(", "));
    b.push_str("</p>\n<h2 id=\"graph\">Graph</h2>\n");
    b.push_str(figure);
    for (kind, title) in [
        (TaskKind::Goal, "Goals"),
        (TaskKind::Command, "Commands"),
        (TaskKind::Monitor, "Monitors"),
        (TaskKind::Handler, "Handlers"),
    ] {
        let tasks: Vec<&TaskInfo<'_>> = program
            .tasks
            .iter()
            .filter(|t| t.task.kind == kind)
            .collect();
        if tasks.is_empty() {
            continue;
        }
        b.push_str(&format!(
            "<h2 id=\"{}s\">{title}</h2>\n<ul>\n",
            kind.as_str()
        ));
        for t in tasks {
            let line = t
                .task
                .doc()
                .map(|d| format!(": {}", inline(program, &summary(&d))))
                .unwrap_or_default();
            b.push_str(&format!("<li>{}{line}</li>\n", task_link(program, &t.name)));
        }
        b.push_str("</ul>\n");
    }
    if !program.states.is_empty() {
        b.push_str("<h2 id=\"states\">State variables</h2>\n<dl>\n");
        for v in &program.states {
            b.push_str(&format!(
                "<dt id=\"state-{}\"><code>{}</code></dt>\n<dd>",
                esc(&v.name),
                esc(&v.text)
            ));
            if let Some(doc) = &v.doc {
                b.push_str(&doc_html(program, doc));
            }
            if !v.set_by.is_empty() {
                let setters: Vec<String> = v.set_by.iter().map(|t| task_link(program, t)).collect();
                b.push_str(&format!("<p>Set by {}.</p>", setters.join(", ")));
            }
            b.push_str("</dd>\n");
        }
        b.push_str("</dl>\n");
    }
    if !program.exceptions.is_empty() {
        b.push_str("<h2 id=\"exceptions\">Exceptions</h2>\n<dl>\n");
        for e in &program.exceptions {
            let parent = e
                .decl
                .parent
                .as_ref()
                .map(|p| format!(": {}", exception_link(program, &p.to_string())))
                .unwrap_or_default();
            b.push_str(&format!(
                "<dt id=\"exception-{}\"><code>exception {}</code>{parent}</dt>\n<dd>",
                esc(&e.id),
                esc(&e.name)
            ));
            if let Some(doc) = e.decl.doc() {
                b.push_str(&doc_html(program, &doc));
            }
            let raisers: Vec<String> = program
                .tasks
                .iter()
                .filter(|t| t.raises.contains(&e.name))
                .map(|t| task_link(program, &t.name))
                .collect();
            let handlers: Vec<String> = program
                .tasks
                .iter()
                .filter(|t| t.task.handles.as_ref().is_some_and(|h| *h == e.name))
                .map(|t| task_link(program, &t.name))
                .collect();
            if !raisers.is_empty() {
                b.push_str(&format!("<p>Raised by {}.</p>\n", raisers.join(", ")));
            }
            if !handlers.is_empty() {
                b.push_str(&format!("<p>Handled by {}.</p>\n", handlers.join(", ")));
            }
            b.push_str(&format!(
                "<p class=\"src\">Declared in <code>{}</code>, line {}.</p></dd>\n",
                esc(&e.file),
                e.line
            ));
        }
        b.push_str("</dl>\n");
    }
    let external = program.external_tasks();
    if !external.is_empty() {
        b.push_str("<h2 id=\"rust\">Tasks defined in Rust</h2>\n<p class=\"note\">Spawned by the program, defined by Rust functions returning a task.</p>\n<ul>\n");
        for name in &external {
            let by: Vec<String> = program
                .spawners(name)
                .iter()
                .map(|t| task_link(program, &t.name))
                .collect();
            b.push_str(&format!(
                "<li><code>{}</code>, spawned by {}</li>\n",
                esc(name),
                by.join(", ")
            ));
        }
        b.push_str("</ul>\n");
    }
    page("TDL program", &b)
}

fn signature(t: &TaskInfo<'_>) -> String {
    let task = t.task;
    let mut s = String::new();
    let vis = task.vis.to_token_stream().to_string();
    if !vis.is_empty() {
        s.push_str(&vis.replace(" (", "(").replace("( ", "(").replace(" )", ")"));
        s.push(' ');
    }
    if task.persistent {
        s.push_str("persistent ");
    }
    s.push_str(task.kind.as_str());
    s.push(' ');
    s.push_str(&t.name);
    let args: Vec<String> = task
        .args
        .iter()
        .map(|a| {
            format!(
                "{}{}: {}",
                if a.mutable { "mut " } else { "" },
                a.name,
                type_text(&a.ty)
            )
        })
        .collect();
    s.push_str(&format!("({})", args.join(", ")));
    if let Some(result) = &task.result {
        s.push_str(&format!(" -> {}", type_text(result)));
    }
    if let Some(handles) = &task.handles {
        s.push_str(&format!(" handles {handles}"));
        if let Some(caught) = &task.caught {
            s.push_str(&format!(" as {caught}"));
        }
        if let Some(target) = &task.for_task {
            s.push_str(&format!(" for {target}"));
        }
    }
    s
}

fn task_page(program: &Program<'_>, t: &TaskInfo<'_>) -> String {
    let task = t.task;
    let mut b = String::new();
    b.push_str(&format!(
        "<nav><a href=\"index.html\">Index</a> · <a href=\"index.html#{}s\">{}s</a></nav>\n",
        task.kind.as_str(),
        task.kind.as_str()
    ));
    b.push_str(&format!(
        "<h1>{}{}</h1>\n<pre class=\"sig\">{}</pre>\n",
        kind_badge(task.kind),
        esc(&t.name),
        esc(&signature(t))
    ));
    b.push_str(&format!(
        "<p class=\"src\">Defined in <code>{}</code>, line {}.</p>\n",
        esc(&t.file),
        t.line
    ));
    match task.doc() {
        Some(doc) => b.push_str(&doc_html(program, &doc)),
        None => b.push_str("<p class=\"none\">No doc comment.</p>\n"),
    }
    if let Some(handles) = &task.handles {
        b.push_str(&format!(
            "<h2 id=\"handles\">Handles</h2>\n<p>{}",
            exception_link(program, &handles.to_string())
        ));
        if let Some(ancestors) = program
            .exception(&handles.to_string())
            .map(|_| descendants(program, &handles.to_string()))
            .filter(|d| !d.is_empty())
        {
            let links: Vec<String> = ancestors
                .iter()
                .map(|d| exception_link(program, d))
                .collect();
            b.push_str(&format!(" and its descendants {}", links.join(", ")));
        }
        b.push_str(".</p>\n");
        if let Some(target) = &task.for_task {
            b.push_str(&format!(
                "<p>Attached from outside to every node of {}.</p>\n",
                task_link(program, &target.to_string())
            ));
        }
        let users: Vec<String> = program
            .handler_users(&t.name)
            .iter()
            .map(|u| task_link(program, &u.name))
            .collect();
        if !users.is_empty() {
            b.push_str(&format!("<p>Attached by {}.</p>\n", users.join(", ")));
        }
        let mut does = Vec::new();
        if t.retries {
            does.push("<code>retry</code>");
        }
        if t.bypasses {
            does.push("<code>bypass</code>");
        }
        if !does.is_empty() {
            b.push_str(&format!("<p>Its body may {}.</p>\n", does.join(" or ")));
        }
    }
    if !t.sets.is_empty() {
        let vars: Vec<String> = t
            .sets
            .iter()
            .map(|v| {
                format!(
                    "<a href=\"index.html#state-{0}\"><code>{0}</code></a>",
                    esc(v)
                )
            })
            .collect();
        b.push_str(&format!("<p>Sets {}.</p>\n", vars.join(", ")));
    }
    if !t.raises_external.is_empty() {
        let names: Vec<String> = t
            .raises_external
            .iter()
            .map(|n| format!("<code>{}</code>", esc(n)))
            .collect();
        b.push_str(&format!(
            "<p>Raises the external events {}.</p>\n",
            names.join(", ")
        ));
    }
    if !t.notes.is_empty() {
        b.push_str("<h2 id=\"constraints\">Constraints</h2>\n<ul>\n");
        for n in &t.notes {
            b.push_str(&format!(
                "<li><code>{}</code></li>\n",
                text_html(program, n)
            ));
        }
        b.push_str("</ul>\n");
    }
    if task.kind == TaskKind::Monitor && t.triggers {
        b.push_str("<p>Its activations may <code>trigger</code> the monitor.</p>\n");
    }
    if !t.handlers.is_empty() {
        b.push_str("<h2 id=\"handlers\">Exception handlers</h2>\n<p class=\"note\">Tried in this order when the task or a node below it fails.</p>\n<ol>\n");
        for h in &t.handlers {
            b.push_str(&handler_item(program, h));
        }
        b.push_str("</ol>\n");
    }
    let outside = program.attached_to(&t.name);
    if !outside.is_empty() {
        b.push_str("<h2 id=\"attached\">Handlers attached from outside</h2>\n<ul>\n");
        for h in outside {
            let handles = h
                .task
                .handles
                .as_ref()
                .map(|e| format!(" handles {}", exception_link(program, &e.to_string())))
                .unwrap_or_default();
            b.push_str(&format!(
                "<li>{}{handles}</li>\n",
                task_link(program, &h.name)
            ));
        }
        b.push_str("</ul>\n");
    }
    if !t.sites.is_empty() {
        b.push_str("<h2 id=\"spawns\">Spawns</h2>\n<ol class=\"spawns\" start=\"0\">\n");
        for (n, site) in t.sites.iter().enumerate() {
            let labels: String = site
                .labels
                .iter()
                .map(|l| format!("{}: ", esc(l)))
                .collect();
            let kind = program.task(&site.task).map_or_else(
                || "<span class=\"kind rust\">rust</span>".to_string(),
                |s| kind_badge(s.task.kind),
            );
            b.push_str(&format!(
                "<li id=\"spawn-{n}\">{labels}{kind}{}<code>({})</code>",
                task_link(program, &site.task),
                esc(&site.args)
            ));
            let mut where_ = Vec::new();
            match site.origin {
                Origin::Body => {}
                Origin::OnTerminate(Some(of)) => where_.push(format!(
                    "on terminate of <a href=\"#spawn-{of}\"><code>{}</code></a>",
                    esc(t.sites.get(of).map_or("?", |s| s.task.as_str()))
                )),
                Origin::OnTerminate(None) => where_.push("on terminate of this task".to_string()),
            }
            if site.repeated {
                where_.push("in a loop".into());
            }
            if site.conditional {
                where_.push("conditional".into());
            }
            where_.push(format!("line {}", site.line));
            b.push_str(&format!(
                " <span class=\"note\">({})</span>",
                where_.join(", ")
            ));
            if !site.constraints.is_empty() {
                b.push_str("\n<ul>\n");
                for c in &site.constraints {
                    b.push_str(&format!(
                        "<li><code>{}</code></li>\n",
                        text_html(program, c)
                    ));
                }
                b.push_str("</ul>\n");
            }
            b.push_str("</li>\n");
        }
        b.push_str("</ol>\n");
    }
    if !t.raises.is_empty() {
        let links: Vec<String> = t
            .raises
            .iter()
            .map(|e| exception_link(program, e))
            .collect();
        b.push_str(&format!(
            "<h2 id=\"raises\">Raises</h2>\n<p>{}</p>\n",
            links.join(", ")
        ));
    }
    let spawners: Vec<String> = program
        .spawners(&t.name)
        .iter()
        .map(|s| task_link(program, &s.name))
        .collect();
    if !spawners.is_empty() {
        b.push_str(&format!(
            "<h2 id=\"spawned-by\">Spawned by</h2>\n<p>{}</p>\n",
            spawners.join(", ")
        ));
    }
    page(&format!("{} {}", task.kind.as_str(), t.name), &b)
}

fn handler_item(program: &Program<'_>, h: &crate::model::HandlerUse) -> String {
    let max = h
        .max
        .as_ref()
        .map(|n| format!(" maximum activate {}", esc(n)))
        .unwrap_or_default();
    let handles = program
        .task(&h.name)
        .and_then(|t| t.task.handles.as_ref())
        .map(|e| format!(", handles {}", exception_link(program, &e.to_string())))
        .unwrap_or_default();
    format!(
        "<li>{}<code>({}){max}</code>{handles}</li>\n",
        task_link(program, &h.name),
        esc(&h.args)
    )
}

/// The declared exceptions below `name` in the hierarchy, in declaration order.
fn descendants(program: &Program<'_>, name: &str) -> Vec<String> {
    program
        .exceptions
        .iter()
        .filter(|e| e.ancestry.iter().any(|it| it == name))
        .map(|e| e.name.clone())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn doc_text_is_escaped_and_names_are_linked() {
        let parse = tdl_syntax::parse_str(
            "t.tdl",
            "/// Runs `b` & <i>stops</i>. Then `Oops`, `nothing`.\n///\n/// - one\n/// - two\ngoal a() { spawn b(); }\ncommand b() {}\nexception Oops;",
        );
        assert!(!parse.has_errors(), "{:?}", parse.diagnostics);
        let program = Program::new(&tdl_syntax::hir::Program::new(&[("t.tdl", &parse.file)]));
        let doc = program.tasks[0].task.doc().expect("a doc comment");
        assert_eq!(
            doc_html(&program, &doc),
            "<p>Runs <a href=\"task.b.html\"><code>b</code></a> &amp; &lt;i&gt;stops&lt;/i&gt;. Then \
             <a href=\"index.html#exception-Oops\"><code>Oops</code></a>, <code>nothing</code>.</p>\n\
             <ul>\n<li>one</li>\n<li>two</li>\n</ul>\n"
        );
        assert_eq!(summary(&doc), "Runs `b` & <i>stops</i>.");
    }
}
