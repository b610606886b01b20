//! Import circles among a crate's modules: `cargo run -p xtask -- circles crates/tcm/src`.
//!
//! A module is a top-level module of the crate (a file `src/m.rs`, with the files under `src/m/`
//! folded into it). Module `a` imports `b` when a file of `a` names `crate::b::…` (in a `use`, a
//! path, or a `crate::{b::…}` group) or an item the crate root re-exports from `b`
//! (`crate::Name`, where `lib.rs` says `pub use b::Name`). Comments are left out. A circle is a
//! set of two or more modules that reach one another (a strongly connected component).
//!
//! The test holds `crates/tcm` to the one circle ARCHITECTURE.md names, the type cycle of the
//! host, the action and its context.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// The circles among the modules of the crate whose sources are in `src`, each sorted, in order.
pub(crate) fn circles(src: &Path) -> Result<Vec<Vec<String>>, String> {
    let files = sources(src)?;
    let modules: BTreeSet<String> = files.keys().filter_map(|f| module_of(f)).collect();
    let exported = files
        .get("lib.rs")
        .map(|lib| re_exports(&strip_comments(lib), &modules))
        .unwrap_or_default();
    let mut edges: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for (file, text) in &files {
        let Some(from) = module_of(file) else {
            continue;
        };
        let named = edges.entry(from.clone()).or_default();
        for to in named_modules(&strip_comments(text), &modules, &exported) {
            if to != from {
                named.insert(to);
            }
        }
    }
    Ok(strongly_connected(&edges)
        .into_iter()
        .filter(|c| c.len() > 1)
        .collect())
}

/// Every `.rs` file under `src`, by its path relative to `src` (with `/`), but tests.
fn sources(src: &Path) -> Result<BTreeMap<String, String>, String> {
    let mut out = BTreeMap::new();
    let mut dirs = vec![src.to_path_buf()];
    while let Some(dir) = dirs.pop() {
        let entries =
            std::fs::read_dir(&dir).map_err(|e| format!("cannot read {}: {e}", dir.display()))?;
        for entry in entries {
            let path = entry
                .map_err(|e| format!("cannot read {}: {e}", dir.display()))?
                .path();
            if path.is_dir() {
                dirs.push(path);
            } else if path.extension().is_some_and(|e| e == "rs") {
                let rel = path
                    .strip_prefix(src)
                    .map_err(|e| e.to_string())?
                    .to_string_lossy()
                    .replace('\\', "/");
                let is_test = rel.split('/').any(|p| p == "tests" || p == "tests.rs");
                if !is_test {
                    let text = std::fs::read_to_string(&path)
                        .map_err(|e| format!("cannot read {}: {e}", path.display()))?;
                    out.insert(rel, text);
                }
            }
        }
    }
    Ok(out)
}

/// The top-level module a file belongs to (`None` for the crate root).
fn module_of(file: &str) -> Option<String> {
    let first = file.split('/').next()?;
    let name = first.strip_suffix(".rs").unwrap_or(first);
    (name != "lib" && name != "main").then(|| name.to_string())
}

/// The text without `//` comments (doc comments included) and `/* */` comments.
fn strip_comments(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut chars = text.chars().peekable();
    let mut in_string = false;
    while let Some(c) = chars.next() {
        if in_string {
            out.push(c);
            if c == '\\' {
                if let Some(n) = chars.next() {
                    out.push(n);
                }
            } else if c == '"' {
                in_string = false;
            }
            continue;
        }
        match (c, chars.peek()) {
            ('"', _) => {
                in_string = true;
                out.push(c);
            }
            ('/', Some('/')) => {
                for n in chars.by_ref() {
                    if n == '\n' {
                        out.push('\n');
                        break;
                    }
                }
            }
            ('/', Some('*')) => {
                chars.next();
                let mut last = ' ';
                for n in chars.by_ref() {
                    if last == '*' && n == '/' {
                        break;
                    }
                    last = n;
                }
            }
            _ => out.push(c),
        }
    }
    out
}

/// The names `lib.rs` re-exports from a module: `pub use m::{A, B as C};` and `pub use m::A;`.
fn re_exports(lib: &str, modules: &BTreeSet<String>) -> BTreeMap<String, String> {
    let mut out = BTreeMap::new();
    for stmt in lib.split(';') {
        let stmt = stmt.trim();
        let Some(rest) = stmt
            .strip_prefix("pub use ")
            .or_else(|| stmt.strip_prefix("pub(crate) use "))
        else {
            continue;
        };
        let rest = rest
            .trim_start_matches("crate::")
            .trim_start_matches("self::");
        let Some((module, items)) = rest.split_once("::") else {
            continue;
        };
        if !modules.contains(module) {
            continue;
        }
        for item in items.trim_matches(|c| c == '{' || c == '}').split(',') {
            let name = item.split(" as ").last().unwrap_or(item).trim();
            if !name.is_empty() {
                out.insert(name.to_string(), module.to_string());
            }
        }
    }
    out
}

/// The modules a file's code names through `crate::`.
fn named_modules(
    code: &str,
    modules: &BTreeSet<String>,
    exported: &BTreeMap<String, String>,
) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    let mut name = |n: &str| {
        if modules.contains(n) {
            out.insert(n.to_string());
        } else if let Some(m) = exported.get(n) {
            out.insert(m.clone());
        }
    };
    let mut rest = code;
    while let Some(at) = rest.find("crate::") {
        let after = &rest[at + "crate::".len()..];
        // `pub(crate) use` is a visibility, not a path.
        let is_path = rest[..at]
            .chars()
            .next_back()
            .is_none_or(|c| !(c.is_alphanumeric() || c == '_'));
        if is_path {
            if let Some(group) = after.strip_prefix('{') {
                for item in top_level_items(group) {
                    name(leading_ident(item));
                }
            } else {
                name(leading_ident(after));
            }
        }
        rest = after;
    }
    out
}

/// The items of a `{…}` group up to its closing brace, split at its top-level commas.
fn top_level_items(group: &str) -> Vec<&str> {
    let mut items = Vec::new();
    let (mut depth, mut start) = (0usize, 0usize);
    for (i, c) in group.char_indices() {
        match c {
            '{' => depth += 1,
            '}' if depth == 0 => {
                items.push(&group[start..i]);
                return items;
            }
            '}' => depth -= 1,
            ',' if depth == 0 => {
                items.push(&group[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    items
}

/// The identifier a path starts with.
fn leading_ident(path: &str) -> &str {
    let path = path.trim_start();
    let end = path
        .find(|c: char| !(c.is_alphanumeric() || c == '_'))
        .unwrap_or(path.len());
    &path[..end]
}

/// The strongly connected components of a graph (Tarjan), each sorted, in order of their first
/// member.
fn strongly_connected(edges: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    struct Walk<'a> {
        edges: &'a BTreeMap<String, BTreeSet<String>>,
        index: BTreeMap<&'a str, usize>,
        low: BTreeMap<&'a str, usize>,
        stack: Vec<&'a str>,
        on_stack: BTreeSet<&'a str>,
        next: usize,
        out: Vec<Vec<String>>,
    }
    impl<'a> Walk<'a> {
        fn visit(&mut self, v: &'a str) {
            self.index.insert(v, self.next);
            self.low.insert(v, self.next);
            self.next += 1;
            self.stack.push(v);
            self.on_stack.insert(v);
            let edges = self.edges;
            for w in edges.get(v).into_iter().flatten() {
                let w = w.as_str();
                if !self.index.contains_key(w) {
                    self.visit(w);
                    let lw = self.low[w];
                    let lv = self.low[v];
                    self.low.insert(v, lv.min(lw));
                } else if self.on_stack.contains(w) {
                    let iw = self.index[w];
                    let lv = self.low[v];
                    self.low.insert(v, lv.min(iw));
                }
            }
            if self.low[v] == self.index[v] {
                let mut component = Vec::new();
                while let Some(w) = self.stack.pop() {
                    self.on_stack.remove(w);
                    component.push(w.to_string());
                    if w == v {
                        break;
                    }
                }
                component.sort();
                self.out.push(component);
            }
        }
    }
    let mut walk = Walk {
        edges,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on_stack: BTreeSet::new(),
        next: 0,
        out: Vec::new(),
    };
    for v in edges.keys() {
        if !walk.index.contains_key(v.as_str()) {
            walk.visit(v);
        }
    }
    let mut out = walk.out;
    out.sort();
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tcm_has_one_import_circle_the_type_cycle_of_the_host_the_action_and_its_context() {
        let src = crate::tidy::workspace_root().join("crates/tcm/src");
        let found = circles(&src).expect("tcm's sources read");
        assert_eq!(
            found,
            [["cancel", "ctx", "host", "pump", "replay", "task"]],
            "tcm's modules import each other in circles other than the one ARCHITECTURE.md names \
             (Invariants): move what closes the new one above or below it"
        );
    }

    #[test]
    fn paths_groups_and_re_exports_are_imports_and_comments_are_not() {
        let modules: BTreeSet<String> = ["a", "b", "c", "d"].map(String::from).into();
        let exported: BTreeMap<String, String> = [("Thing".to_string(), "d".to_string())].into();
        let code = "use crate::{a::X, b::{Y, Z}};\n// crate::c::Nope\nfn f() { crate::Thing::new(); }\npub(crate) use x::Y;";
        let named = named_modules(&strip_comments(code), &modules, &exported);
        assert_eq!(named, ["a", "b", "d"].map(String::from).into());
        let edges: BTreeMap<String, BTreeSet<String>> = [
            ("a".to_string(), ["b".to_string()].into()),
            ("b".to_string(), ["a".to_string(), "c".to_string()].into()),
            ("c".to_string(), BTreeSet::new()),
        ]
        .into();
        let sccs: Vec<Vec<String>> = strongly_connected(&edges)
            .into_iter()
            .filter(|c| c.len() > 1)
            .collect();
        assert_eq!(sccs, [["a", "b"]]);
    }
}
