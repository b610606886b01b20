//! `tdl graph`: the static structure of a program ([`crate::model`]) as a Graphviz `dot` or a
//! Mermaid flowchart.
//!
//! Each task is a node, its kind shown by shape and colour (goal: rounded box, command: box,
//! monitor: hexagon, handler: octagon; exceptions are notes). A task whose body spawns has a
//! cluster holding its node and one node per spawn site; an edge goes from the task to each spawn
//! (labelled with the spawn's labels and `wait`, `propagate`, `outcome`), a dotted one from the
//! spawn to the spawned task's own node, and the constraints between spawns are dashed edges from
//! what they wait for to the spawn they hold back, terminate or activate. Handlers hang off the
//! task or spawn they are attached to, and point to the exception they handle; `raises` edges go
//! from a task to the exceptions its body fails with.
//!
//! Both formats use the same node ids, `t_<task>`, `s_<task>_<n>`, `e_<exception>`, `x_<name>`,
//! made of `[A-Za-z0-9_]` only; names are only ever written inside quoted labels, escaped.

use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;

use tdl_syntax::TaskKind;

use crate::model::{Endpoint, Origin, Program, RelationKind, TaskInfo, unique_id};

/// The output format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum Format {
    /// Graphviz `dot` (render with `dot -Tsvg`).
    Dot,
    /// A Mermaid flowchart.
    Mermaid,
}

/// What to draw and how.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Options<'o> {
    /// Only what this task reaches.
    pub(crate) task: Option<&'o str>,
    /// Give task and exception nodes links to the pages `tdl doc` writes (`dot` only: Mermaid
    /// text is shown as text).
    pub(crate) links: bool,
}

/// The graph of `program` in `format`; `Err` names an unknown `--task`.
pub(crate) fn render(
    program: &Program<'_>,
    format: Format,
    options: Options<'_>,
) -> Result<String, String> {
    let graph = build(program, options)?;
    Ok(match format {
        Format::Dot => dot(&graph),
        Format::Mermaid => mermaid(&graph),
    })
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Class {
    Goal,
    Command,
    Monitor,
    Handler,
    Exception,
    /// A task or exception the program uses but does not define (a Rust function or type).
    Rust,
}

impl Class {
    fn of(kind: TaskKind) -> Class {
        match kind {
            TaskKind::Goal => Class::Goal,
            TaskKind::Command => Class::Command,
            TaskKind::Monitor => Class::Monitor,
            TaskKind::Handler => Class::Handler,
        }
    }

    fn name(self) -> &'static str {
        match self {
            Class::Goal => "goal",
            Class::Command => "command",
            Class::Monitor => "monitor",
            Class::Handler => "handler",
            Class::Exception => "exception",
            Class::Rust => "rust",
        }
    }

    /// Fill and line colour.
    fn colours(self) -> (&'static str, &'static str) {
        match self {
            Class::Goal => ("#dbe9f8", "#3b6ea5"),
            Class::Command => ("#e3f2dc", "#4a7f3a"),
            Class::Monitor => ("#fbf0d0", "#9a7b1c"),
            Class::Handler => ("#f8dcdc", "#a33333"),
            Class::Exception => ("#eeeeee", "#777777"),
            Class::Rust => ("#ffffff", "#777777"),
        }
    }
}

struct Node {
    id: String,
    lines: Vec<String>,
    class: Class,
    /// A spawn site (drawn unfilled, smaller) rather than a definition.
    site: bool,
    url: Option<String>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Style {
    Spawn,
    OnTerminate,
    /// From a spawn site to the spawned task's node.
    Instance,
    Order,
    Terminate,
    Activate,
    Handler,
    Handles,
    Raises,
    IsA,
}

impl Style {
    fn colour(self) -> &'static str {
        match self {
            Style::Spawn => "#333333",
            Style::OnTerminate | Style::Instance | Style::Handles | Style::IsA => "#777777",
            Style::Order => "#1f5fa8",
            Style::Terminate | Style::Raises => "#b22222",
            Style::Activate => "#8a6d00",
            Style::Handler => "#a33333",
        }
    }
}

struct Edge {
    from: String,
    to: String,
    label: String,
    style: Style,
}

struct Cluster {
    id: String,
    title: String,
    nodes: Vec<Node>,
}

#[derive(Default)]
struct Graph {
    clusters: Vec<Cluster>,
    nodes: Vec<Node>,
    edges: Vec<Edge>,
}

fn build(program: &Program<'_>, options: Options<'_>) -> Result<Graph, String> {
    let (tasks, mut exceptions): (Vec<&TaskInfo<'_>>, BTreeSet<String>) = match options.task {
        Some(name) => {
            let (tasks, exceptions) = program.reach(name).ok_or_else(|| {
                let known: Vec<&str> = program.tasks.iter().map(|t| t.name.as_str()).collect();
                format!(
                    "no task `{name}` in the program (its tasks: {})",
                    known.join(", ")
                )
            })?;
            (
                program
                    .tasks
                    .iter()
                    .filter(|t| tasks.contains(&t.name))
                    .collect(),
                exceptions,
            )
        }
        None => (
            program.tasks.iter().collect(),
            program.exceptions.iter().map(|e| e.name.clone()).collect(),
        ),
    };
    let shown: BTreeSet<&str> = tasks.iter().map(|t| t.name.as_str()).collect();
    // Exceptions named by the tasks shown but declared nowhere in the program (Rust types).
    for t in &tasks {
        exceptions.extend(t.raises.iter().cloned());
        exceptions.extend(t.task.handles.iter().map(ToString::to_string));
    }
    let mut g = Graph::default();
    let mut rust_ids = BTreeSet::new();
    let mut rust_nodes: BTreeMap<String, String> = BTreeMap::new();
    let mut rust_node = |g: &mut Graph, name: &str, class_word: &str| -> String {
        if let Some(id) = rust_nodes.get(name) {
            return id.clone();
        }
        let id = format!("x_{}", unique_id(name, &mut rust_ids));
        g.nodes.push(Node {
            id: id.clone(),
            lines: vec![name.to_string(), format!("({class_word} in Rust)")],
            class: Class::Rust,
            site: false,
            url: None,
        });
        rust_nodes.insert(name.to_string(), id.clone());
        id
    };
    let task_node = |name: &str| -> Option<String> {
        shown
            .contains(name)
            .then(|| program.task(name).map(|t| format!("t_{}", t.id)))
            .flatten()
    };
    let exception_node = |name: &str| -> String {
        match program.exception(name) {
            Some(e) => format!("e_{}", e.id),
            None => format!("e_rust_{}", unique_id(name, &mut BTreeSet::new())),
        }
    };
    let url = |page: String| options.links.then_some(page);

    for t in &tasks {
        let id = format!("t_{}", t.id);
        let mut lines = vec![format!("{} {}", t.task.kind.as_str(), t.name)];
        if let Some(handles) = &t.task.handles {
            lines.push(format!("handles {handles}"));
        }
        let notes: Vec<String> = t.notes.iter().map(crate::model::plain).collect();
        if !notes.is_empty() {
            lines.push(notes.join(", "));
        }
        let node = Node {
            id: id.clone(),
            lines,
            class: Class::of(t.task.kind),
            site: false,
            url: url(format!("task.{}.html", t.id)),
        };
        if t.sites.is_empty() {
            g.nodes.push(node);
        } else {
            let mut nodes = vec![node];
            for (n, site) in t.sites.iter().enumerate() {
                let spawned = program.task(&site.task);
                let mut lines = vec![site.task.clone()];
                lines.extend(site.notes.iter().cloned());
                nodes.push(Node {
                    id: format!("s_{}_{n}", t.id),
                    lines,
                    class: spawned.map_or(Class::Rust, |s| Class::of(s.task.kind)),
                    site: true,
                    url: spawned.and_then(|s| url(format!("task.{}.html", s.id))),
                });
            }
            g.clusters.push(Cluster {
                id: format!("c_{}", t.id),
                title: t.name.clone(),
                nodes,
            });
        }
        // Spawns, on-terminate tasks, and the spawned tasks' own nodes.
        for (n, site) in t.sites.iter().enumerate() {
            let site_id = format!("s_{}_{n}", t.id);
            let mut words: Vec<String> = site.labels.iter().map(|l| format!("{l}:")).collect();
            let (from, style) = match site.origin {
                Origin::Body => (id.clone(), Style::Spawn),
                Origin::OnTerminate(Some(of)) => {
                    words.insert(0, "on terminate".into());
                    (format!("s_{}_{of}", t.id), Style::OnTerminate)
                }
                Origin::OnTerminate(None) => {
                    words.insert(0, "on terminate".into());
                    (id.clone(), Style::OnTerminate)
                }
            };
            words.extend(site.flags.iter().map(|f| (*f).to_string()));
            g.edges.push(Edge {
                from,
                to: site_id.clone(),
                label: words.join(" "),
                style,
            });
            if let Some(def) = task_node(&site.task) {
                g.edges.push(Edge {
                    from: site_id.clone(),
                    to: def,
                    label: String::new(),
                    style: Style::Instance,
                });
            }
            for h in &site.handlers {
                let to =
                    task_node(&h.name).unwrap_or_else(|| rust_node(&mut g, &h.name, "handler"));
                g.edges.push(Edge {
                    from: site_id.clone(),
                    to,
                    label: handler_label(h),
                    style: Style::Handler,
                });
            }
        }
        for r in &t.relations {
            let from = match r.from {
                Endpoint::Task => id.clone(),
                Endpoint::Site(s) => format!("s_{}_{s}", t.id),
            };
            g.edges.push(Edge {
                from,
                to: format!("s_{}_{}", t.id, r.to),
                label: r.label.clone(),
                style: match r.kind {
                    RelationKind::Order => Style::Order,
                    RelationKind::Terminate => Style::Terminate,
                    RelationKind::Activate => Style::Activate,
                },
            });
        }
        for h in &t.handlers {
            let to = task_node(&h.name).unwrap_or_else(|| rust_node(&mut g, &h.name, "handler"));
            g.edges.push(Edge {
                from: id.clone(),
                to,
                label: handler_label(h),
                style: Style::Handler,
            });
        }
        if let Some(target) = &t.task.for_task {
            let from = task_node(&target.to_string())
                .unwrap_or_else(|| rust_node(&mut g, &target.to_string(), "task"));
            g.edges.push(Edge {
                from,
                to: id.clone(),
                label: "handler (for)".into(),
                style: Style::Handler,
            });
        }
        if let Some(handles) = &t.task.handles {
            g.edges.push(Edge {
                from: id.clone(),
                to: exception_node(&handles.to_string()),
                label: "handles".into(),
                style: Style::Handles,
            });
        }
        for e in &t.raises {
            g.edges.push(Edge {
                from: id.clone(),
                to: exception_node(e),
                label: "raises".into(),
                style: Style::Raises,
            });
        }
    }
    for name in &exceptions {
        let id = exception_node(name);
        match program.exception(name) {
            Some(e) => {
                g.nodes.push(Node {
                    id: id.clone(),
                    lines: vec![format!("exception {name}")],
                    class: Class::Exception,
                    site: false,
                    url: url(format!("index.html#exception-{}", e.id)),
                });
                if let Some(parent) = &e.decl.parent {
                    let parent = parent.to_string();
                    if exceptions.contains(&parent) {
                        g.edges.push(Edge {
                            from: id,
                            to: exception_node(&parent),
                            label: "is a".into(),
                            style: Style::IsA,
                        });
                    }
                }
            }
            None => g.nodes.push(Node {
                id,
                lines: vec![format!("exception {name}"), "(Rust type)".into()],
                class: Class::Exception,
                site: false,
                url: None,
            }),
        }
    }
    Ok(g)
}

fn handler_label(h: &crate::model::HandlerUse) -> String {
    match &h.max {
        Some(n) => format!("handler, max {n}"),
        None => "handler".into(),
    }
}

/// A `dot` quoted string: `"` and `\` escaped, lines joined by `\n` (centred line breaks).
fn dot_quote(lines: &[String]) -> String {
    let escaped: Vec<String> = lines
        .iter()
        .map(|l| l.replace('\\', "\\\\").replace('"', "\\\""))
        .collect();
    format!("\"{}\"", escaped.join("\\n"))
}

fn dot(g: &Graph) -> String {
    let mut out = String::new();
    out.push_str("digraph \"tdl\" {\n");
    out.push_str(
        "    graph [rankdir=TB, ordering=out, fontname=\"Helvetica\", fontsize=10, nodesep=0.3, ranksep=0.45];\n",
    );
    out.push_str("    node [fontname=\"Helvetica\", fontsize=10, margin=\"0.1,0.04\"];\n");
    out.push_str("    edge [fontname=\"Helvetica\", fontsize=8, arrowsize=0.7];\n");
    for c in &g.clusters {
        let _ = writeln!(
            out,
            "    subgraph {} {{\n        graph [label={}, labeljust=l, style=\"rounded,dashed\", color=\"#bbbbbb\", fontcolor=\"#888888\", fontsize=8];",
            dot_quote(&[format!("cluster_{}", c.id)]),
            dot_quote(&[format!("body of {}", c.title)]),
        );
        for n in &c.nodes {
            let _ = writeln!(out, "        {}", dot_node(n));
        }
        out.push_str("    }\n");
    }
    for n in &g.nodes {
        let _ = writeln!(out, "    {}", dot_node(n));
    }
    for e in &g.edges {
        let mut attrs = vec![format!("color=\"{}\"", e.style.colour())];
        if !e.label.is_empty() {
            attrs.push(format!(
                "label={}",
                dot_quote(std::slice::from_ref(&e.label))
            ));
            attrs.push(format!("fontcolor=\"{}\"", e.style.colour()));
        }
        attrs.push(
            match e.style {
                Style::Spawn => "penwidth=1.2",
                Style::OnTerminate => "style=dashed",
                Style::Instance => "style=dotted, arrowhead=empty",
                Style::Order | Style::Terminate | Style::Activate => {
                    "style=dashed, constraint=false"
                }
                Style::Handler => "style=bold, arrowhead=odiamond",
                Style::Handles => "style=dashed, arrowhead=vee",
                Style::Raises => "style=dotted, arrowhead=vee",
                Style::IsA => "arrowhead=empty",
            }
            .to_string(),
        );
        let _ = writeln!(
            out,
            "    {} -> {} [{}];",
            dot_quote(std::slice::from_ref(&e.from)),
            dot_quote(std::slice::from_ref(&e.to)),
            attrs.join(", ")
        );
    }
    out.push_str("}\n");
    out
}

fn dot_node(n: &Node) -> String {
    let (fill, line) = n.class.colours();
    let shape = match n.class {
        Class::Goal | Class::Command | Class::Rust => "box",
        Class::Monitor => "hexagon",
        Class::Handler => "octagon",
        Class::Exception => "note",
    };
    let mut style: Vec<&str> = Vec::new();
    if n.class == Class::Goal {
        style.push("rounded");
    }
    if n.class == Class::Rust {
        style.push("dashed");
    } else if !n.site {
        style.push("filled");
    }
    let mut attrs = vec![
        format!("label={}", dot_quote(&n.lines)),
        format!("shape={shape}"),
        format!("color=\"{line}\""),
    ];
    if !style.is_empty() {
        attrs.push(format!("style=\"{}\"", style.join(",")));
    }
    if !n.site && n.class != Class::Rust {
        attrs.push(format!("fillcolor=\"{fill}\""));
    }
    if n.site {
        attrs.push("fontsize=9".into());
    }
    if let Some(url) = &n.url {
        attrs.push(format!("URL={}", dot_quote(std::slice::from_ref(url))));
    }
    format!(
        "{} [{}];",
        dot_quote(std::slice::from_ref(&n.id)),
        attrs.join(", ")
    )
}

/// Text for a quoted Mermaid label: characters Mermaid would read as markup written as its
/// entity codes (`#quot;`, `#lt;`, …), lines joined by `<br/>`.
fn mermaid_quote(lines: &[String]) -> String {
    let escaped: Vec<String> = lines
        .iter()
        .map(|l| {
            let mut s = String::new();
            for c in l.chars() {
                match c {
                    '#' => s.push_str("#35;"),
                    '"' => s.push_str("#quot;"),
                    '<' => s.push_str("#lt;"),
                    '>' => s.push_str("#gt;"),
                    '&' => s.push_str("#amp;"),
                    '`' => s.push_str("#96;"),
                    '|' => s.push_str("#124;"),
                    c => s.push(c),
                }
            }
            s
        })
        .collect();
    format!("\"{}\"", escaped.join("<br/>"))
}

fn mermaid(g: &Graph) -> String {
    let mut out = String::from("flowchart TB\n");
    for class in [
        Class::Goal,
        Class::Command,
        Class::Monitor,
        Class::Handler,
        Class::Exception,
    ] {
        let (fill, line) = class.colours();
        let _ = writeln!(
            out,
            "    classDef {} fill:{fill},stroke:{line}",
            class.name()
        );
        let _ = writeln!(
            out,
            "    classDef {}_site fill:#ffffff,stroke:{line}",
            class.name()
        );
    }
    let _ = writeln!(
        out,
        "    classDef rust fill:#ffffff,stroke:#777777,stroke-dasharray:4 3"
    );
    let _ = writeln!(
        out,
        "    classDef rust_site fill:#ffffff,stroke:#777777,stroke-dasharray:4 3"
    );
    for c in &g.clusters {
        let _ = writeln!(
            out,
            "    subgraph {} [{}]",
            c.id,
            mermaid_quote(&[format!("body of {}", c.title)])
        );
        for n in &c.nodes {
            let _ = writeln!(out, "        {}", mermaid_node(n));
        }
        out.push_str("    end\n");
    }
    for n in &g.nodes {
        let _ = writeln!(out, "    {}", mermaid_node(n));
    }
    let mut styles = String::new();
    for (i, e) in g.edges.iter().enumerate() {
        let arrow = match e.style {
            Style::Spawn | Style::IsA => "-->",
            Style::Handler => "==>",
            Style::OnTerminate
            | Style::Instance
            | Style::Order
            | Style::Terminate
            | Style::Activate
            | Style::Handles
            | Style::Raises => "-.->",
        };
        if e.label.is_empty() {
            let _ = writeln!(out, "    {} {arrow} {}", e.from, e.to);
        } else {
            let _ = writeln!(
                out,
                "    {} {arrow}|{}| {}",
                e.from,
                mermaid_quote(std::slice::from_ref(&e.label)),
                e.to
            );
        }
        if e.style != Style::Spawn {
            let _ = writeln!(styles, "    linkStyle {i} stroke:{}", e.style.colour());
        }
    }
    out.push_str(&styles);
    out
}

fn mermaid_node(n: &Node) -> String {
    let label = mermaid_quote(&n.lines);
    let shaped = match n.class {
        Class::Goal => format!("({label})"),
        Class::Command | Class::Rust => format!("[{label}]"),
        Class::Monitor => format!("{{{{{label}}}}}"),
        Class::Handler => format!("[[{label}]]"),
        Class::Exception => format!(">{label}]"),
    };
    let class = if n.site {
        format!("{}_site", n.class.name())
    } else {
        n.class.name().to_string()
    };
    format!("{}{shaped}:::{class}", n.id)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn graph(src: &str, format: Format, task: Option<&str>) -> String {
        let parse = tdl_syntax::parse_str("t.tdl", src);
        assert!(!parse.has_errors(), "{:?}", parse.diagnostics);
        let program = Program::new(&tdl_syntax::hir::Program::new(&[("t.tdl", &parse.file)]));
        render(&program, format, Options { task, links: false }).expect("a graph")
    }

    const SRC: &str = "
        exception Stuck;
        goal top() with exception handler unstick() {
            spawn go() with terminate in 5s;
            l: spawn look() with sequential execution go, terminate at go completed;
            spawn r#type(\"x\") with serial l;
        }
        command go() { fail Stuck; }
        handler unstick() handles Stuck { retry; }
        goal other() {}
    ";

    #[test]
    fn dot_has_a_node_per_task_site_and_exception_and_labelled_edges() {
        let out = graph(SRC, Format::Dot, None);
        assert!(out.starts_with("digraph \"tdl\" {\n"), "{out}");
        assert!(out.ends_with("}\n"), "{out}");
        for line in [
            "\"t_top\" [label=\"goal top\", shape=box",
            "\"s_top_0\" [label=\"go\\nterminate in 5s\"",
            "\"s_top_0\" -> \"t_go\" [color=\"#777777\", style=dotted, arrowhead=empty];",
            "\"t_top\" -> \"s_top_1\" [color=\"#333333\", label=\"l:\"",
            "\"s_top_0\" -> \"s_top_1\" [color=\"#1f5fa8\", label=\"sequential execution\"",
            "\"s_top_0\" -> \"s_top_1\" [color=\"#b22222\", label=\"terminate at completed\"",
            "\"s_top_1\" -> \"s_top_2\" [color=\"#1f5fa8\", label=\"serial\"",
            "\"t_top\" -> \"t_unstick\" [color=\"#a33333\", label=\"handler\"",
            "\"t_unstick\" -> \"e_Stuck\" [color=\"#777777\", label=\"handles\"",
            "\"t_go\" -> \"e_Stuck\" [color=\"#b22222\", label=\"raises\"",
            "\"t_other\" [label=\"goal other\"",
            // A raw identifier is written as such in the label, and its id is plain.
            "\"s_top_2\" [label=\"r#type\", shape=box, color=\"#777777\", style=\"dashed\"",
        ] {
            assert!(out.contains(line), "missing {line:?} in\n{out}");
        }
    }

    #[test]
    fn task_restricts_to_what_it_reaches() {
        let out = graph(SRC, Format::Dot, Some("go"));
        assert!(out.contains("\"t_go\""), "{out}");
        assert!(out.contains("\"e_Stuck\""), "{out}");
        assert!(!out.contains("t_top") && !out.contains("t_other"), "{out}");
    }

    #[test]
    fn mermaid_ids_are_plain_and_labels_escaped() {
        let out = graph(
            "goal a() { spawn b() with terminate at external \"<stop> & #go\"; }",
            Format::Mermaid,
            None,
        );
        assert!(out.starts_with("flowchart TB\n"), "{out}");
        assert!(
            out.contains("s_a_0[\"b<br/>terminate at external #quot;#lt;stop#gt; #amp; #35;go#quot;\"]:::rust_site"),
            "{out}"
        );
        assert!(out.contains("    t_a --> s_a_0\n"), "{out}");
    }
}
