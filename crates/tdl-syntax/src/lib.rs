//! `tdl-syntax`: the TDL front end shared by the `tdl!` macro, `tdl-build` and the `tdl` CLI.
//!
//! TDL (Simmons & Apfelbaum, 1998) is a language for task-level robot control: tasks (`goal`,
//! `command`, `monitor`, `handler`), `spawn` with synchronisation constraints, `with (...)` groups,
//! exceptions and monitors. Here it is written with Rust bodies.
//!
//! Key types, in the order data flows through them:
//! - [`parse_str`] / [`parse_tokens`] turn a `.tdl` file or a macro's tokens into a [`Parse`]:
//!   the [`Ast`] plus every [`Diagnostic`] found. Parsing never fails; it recovers at item and
//!   statement boundaries (the parser is `parser.rs`).
//! - The [`ast`] module is the tree: [`Item`]s, task bodies as trees of [`Stmt`]s, and
//!   [`Constraint`]s over [`Tag`]s and [`Event`]s. Every timed or event-driven constraint
//!   (`disable … until|for`, `terminate …`, `activate …`) is one [`ConstraintKind::Trigger`] of a
//!   [`When`] and a [`Then`]. A code generator walks it with `match`.
//! - [`hir`], the resolved program, works out once what every name means: the tasks,
//!   exceptions and resources of every file, and per body its spawns, groups, loops, what each
//!   tag denotes and `previous` at each statement. Every back end reads it: the static diagnosis,
//!   the code generator, and outside this crate `tdl verify`'s loader, `tdl graph` and `tdl doc`
//!   ([`compile_program_with`] hands it over). Nothing else resolves a name.
//! - The static diagnosis of docs/semantics.md, "Tags and forward references" (unknown and ambiguous tags, duplicate labels, `wait`
//!   on a forward reference, ...) and the static checks of docs/language.md, "Static checks"
//!   (circular constraints, waits that cannot end, unhandled exceptions, unbounded recursion) run
//!   as part of parsing and add to the same diagnostics (`diagnose.rs`, `diagnose/`). Every
//!   warning has a [`Lint`]; `#[allow(tdl::NAME)]` on a task or a statement accepts it there
//!   (`lint.rs`, docs/language.md, "Accepting a warning").
//! - [`generate`] turns the tree into Rust calling the `tcm` runtime through the `tdl` crate
//!   (`codegen.rs`, `codegen/`).
//! - [`Diagnostic::render`] prints a diagnostic as rustc does, with `annotate-snippets`:
//!   `error: message`, ` --> file:line:col`, the source with the span underlined and a `= help:`
//!   hint ([`Diagnostic::render_styled`] in colour); [`dump`] prints the tree compactly (used by
//!   the snapshot tests), its constraints and times in the one canonical spelling of [`mod@print`].
//!
//! ```
//! let src = "
//! goal deliver_mail(room: u32) {
//!     let (x, y) = get_room_coordinates(room);
//!     spawn navigate_to_locn(x, y);
//!     spawn center_on_door(x, y) with sequential execution previous, terminate in 30s;
//!     spawn speak(\"Xavier here with your mail\")
//!         with sequential execution center_on_door, terminate at monitor_pickup completed;
//!     spawn monitor_pickup() with sequential execution center_on_door;
//! }
//! ";
//! let parse = tdl_syntax::parse_str("deliver.tdl", src);
//! assert!(parse.diagnostics.is_empty());
//! let tdl_syntax::Item::Task(task) = &parse.file.items[0] else { panic!() };
//! assert_eq!(task.name, "deliver_mail");
//!
//! let bad = tdl_syntax::parse_str("bad.tdl", "goal g() { spawn a() with serial nowhere; }");
//! let text = bad.render("bad.tdl", Some("goal g() { spawn a() with serial nowhere; }"));
//! assert!(text.starts_with("error: unknown tag `nowhere`\n --> bad.tdl:1:34\n"));
//! ```
//!
//! Language choices (the full reference is `docs/language.md`):
//! - TDL keywords keep TDL's words. Constraint keywords are case-insensitive and two-word ones may
//!   be joined with underscores (`expand_first`, `disable_until`); `planning` ≡ `expansion`,
//!   `achievement` ≡ `execution`. Statement and item keywords are lowercase.
//! - A handler's use limit is written after its arguments: `exception handler h(x) maximum activate 3`.
//! - Times: `30s`, `1.5s`, `200ms`, `2min`, `0:0:30.0`, or `(expr)` in seconds; times of day `13:00:00`.
//! - `let v = spawn t(args) with wait;` yields the child's result (`command t() -> T`).
//!
//! Architecture Invariants: this crate never names `proc_macro`, only `proc_macro2` and `syn`, so
//! every consumer shares it; and no input makes it panic (a property test feeds it random tokens).

#![warn(missing_docs)]

pub mod ast;
mod codegen;
mod diagnose;
mod diagnostic;
mod dump;
pub mod hir;
mod keyword;
mod lint;
mod parser;
pub mod print;
mod time;

use std::str::FromStr;

use proc_macro2::{Span, TokenStream, TokenTree};
use syn::parse::{ParseStream, Parser};

pub use ast::*;
pub use codegen::{
    Generated, compile_program, compile_program_with, compile_str, expand_macro, generate,
    generated_tags, pretty, stubs,
};
pub use diagnostic::{Diagnostic, Label, LineCol, Severity, render_all, render_all_styled};
pub use dump::dump;
pub use lint::Lint;
pub use parser::parse_tag_tokens;
pub use time::format_nanos;

/// The result of parsing: the tree and every diagnostic, errors and warnings, in source order.
#[derive(Clone, Debug)]
pub struct Parse {
    /// The syntax tree; items or statements with errors are left out.
    pub file: Ast,
    /// Everything found, sorted by position.
    pub diagnostics: Vec<Diagnostic>,
}

impl Parse {
    /// True when any diagnostic is an error.
    pub fn has_errors(&self) -> bool {
        self.diagnostics.iter().any(Diagnostic::is_error)
    }

    /// Renders all diagnostics (see [`Diagnostic::render`]).
    pub fn render(&self, file_name: &str, source: Option<&str>) -> String {
        render_all(&self.diagnostics, file_name, source)
    }
}

/// Parses the text of a `.tdl` file. `file_name` is only used to name the input in messages from
/// the lexer; diagnostics carry line and column, and [`Parse::render`] takes the name again.
pub fn parse_str(file_name: &str, src: &str) -> Parse {
    let mut parse = parse_str_syntax(file_name, src);
    diagnose::diagnose(&parse.file, &mut parse.diagnostics);
    lint::apply(&parse.file.allows, &mut parse.diagnostics);
    parse
        .diagnostics
        .sort_by_key(|it| (it.start(), it.severity()));
    parse
}

/// Parses the text of a `.tdl` file without the static diagnosis, which [`compile_program`] runs
/// with the names of every file of the program.
pub(crate) fn parse_str_syntax(file_name: &str, src: &str) -> Parse {
    let _ = file_name;
    match TokenStream::from_str(src) {
        Ok(tokens) => {
            let eof = last_span(&tokens);
            parse_syntax(tokens, eof)
        }
        Err(err) => {
            let diag = Diagnostic::error(
                err.span(),
                "cannot read the input as Rust tokens: unbalanced delimiter, unterminated literal or stray character",
            )
            .with_hint("check for an unclosed `{`, `(` or `[`, a missing closing quote, or a character Rust does not accept");
            Parse {
                file: Ast::default(),
                diagnostics: vec![diag],
            }
        }
    }
}

/// Parses tokens, e.g. the input of the `tdl!{}` macro.
pub fn parse_tokens(tokens: TokenStream) -> Parse {
    let mut parse = parse_syntax(tokens, None);
    diagnose::diagnose(&parse.file, &mut parse.diagnostics);
    lint::apply(&parse.file.allows, &mut parse.diagnostics);
    parse
        .diagnostics
        .sort_by_key(|it| (it.start(), it.severity()));
    parse
}

/// The deepest nesting of brackets the parser accepts. The parser (and Rust's own) descends
/// recursively, so deeper input would exhaust the stack; no program needs a tenth of it.
pub const MAX_NESTING: usize = 256;

/// The first construct nested deeper than [`MAX_NESTING`], found without recursing: a bracket
/// group, and, within one statement, generic angle brackets (`Vec<Vec<…>>`) or a run of `&`
/// (`&&&&x`), which the parser also descends into recursively without any group.
fn too_deep(tokens: &TokenStream) -> Option<Span> {
    // Per open stream: its tokens, the `<` not yet closed in this statement, the current `&` run.
    let mut stack: Vec<(proc_macro2::token_stream::IntoIter, usize, usize)> =
        vec![(tokens.clone().into_iter(), 0, 0)];
    while let Some((top, angles, refs)) = stack.last_mut() {
        match top.next() {
            Some(TokenTree::Group(group)) => {
                *refs = 0;
                if stack.len() > MAX_NESTING {
                    return Some(group.span_open());
                }
                stack.push((group.stream().into_iter(), 0, 0));
            }
            Some(TokenTree::Punct(p)) => {
                match p.as_char() {
                    '&' => *refs += 1,
                    '<' => {
                        *angles += 1;
                        *refs = 0;
                    }
                    '>' => {
                        *angles = angles.saturating_sub(1);
                        *refs = 0;
                    }
                    ';' => {
                        *angles = 0;
                        *refs = 0;
                    }
                    _ => *refs = 0,
                }
                if *angles > MAX_NESTING || *refs > MAX_NESTING {
                    return Some(p.span());
                }
            }
            Some(_) => *refs = 0,
            None => {
                stack.pop();
            }
        }
    }
    None
}

fn parse_syntax(tokens: TokenStream, eof: Option<Span>) -> Parse {
    if let Some(span) = too_deep(&tokens) {
        let diag = Diagnostic::error(
            span,
            format!(
                "code nested more than {MAX_NESTING} deep (brackets, generic arguments or `&`)"
            ),
        )
        .with_hint("split the deeply nested code into functions, type aliases or tasks");
        return Parse {
            file: Ast::default(),
            diagnostics: vec![diag],
        };
    }
    let mut cx = parser::Cx::new(eof);
    let res = (|input: ParseStream| Ok(parser::parse_file(input, &mut cx))).parse2(tokens);
    let file = match res {
        Ok(file) => file,
        Err(err) => {
            cx.syn_error(err, None);
            Ast::default()
        }
    };
    let mut diagnostics = cx.diags;
    diagnostics.sort_by_key(|it| (it.start(), it.severity()));
    Parse { file, diagnostics }
}

/// The span of the last token, looking inside groups.
fn last_span(tokens: &TokenStream) -> Option<Span> {
    let last = tokens.clone().into_iter().last()?;
    if let TokenTree::Group(group) = &last {
        return Some(group.span_close());
    }
    Some(last.span())
}
